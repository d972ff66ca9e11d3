#pragma once
// Private to vibro_io: building Datasets (result_file.hpp), the one type every dataset of a result
// file is written from (the recorded groups, /scene, and the groups run kinds write themselves
// with ResultFile::write_group), and finishing a run kind's file.
#include "vibro/io/result_file.hpp"

#include <Eigen/Dense>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vibro::io::detail {

inline Dataset reals(std::string name, std::vector<double> values, std::vector<std::size_t> shape) {
  Dataset d;
  d.name = std::move(name);
  d.reals = std::move(values);
  d.shape = std::move(shape);
  return d;
}

/// Integers of `shape`, stored as `type` (i32 or i64).
inline Dataset integers(std::string name, std::vector<std::int64_t> values,
                        std::vector<std::size_t> shape, Dataset::Type type = Dataset::Type::i64) {
  Dataset d;
  d.name = std::move(name);
  d.type = type;
  d.integers = std::move(values);
  d.shape = std::move(shape);
  return d;
}

/// A 1-D dataset of 64-bit integers.
inline Dataset integers(std::string name, std::vector<std::int64_t> values) {
  const std::size_t n = values.size();
  return integers(std::move(name), std::move(values), {n});
}

/// A 1-D dataset of strings.
inline Dataset texts(std::string name, std::vector<std::string> values) {
  Dataset d;
  d.name = std::move(name);
  d.type = Dataset::Type::str;
  d.shape = {values.size()};
  d.texts = std::move(values);
  return d;
}

/// Rows of equal length as one row-major rows × cols dataset.
inline Dataset table(std::string name, const std::vector<Eigen::VectorXd>& rows, std::size_t cols) {
  std::vector<double> values;
  for (const Eigen::VectorXd& r : rows) values.insert(values.end(), r.data(), r.data() + r.size());
  return reals(std::move(name), std::move(values), {rows.size(), cols});
}

/// A vector as a 1-D dataset.
inline Dataset vector_dataset(std::string name, const Eigen::VectorXd& v) {
  return reals(std::move(name), std::vector<double>(v.data(), v.data() + v.size()),
               {static_cast<std::size_t>(v.size())});
}

/// A matrix as a rows × cols dataset.
inline Dataset matrix_dataset(std::string name, const Eigen::MatrixXd& a) {
  std::vector<double> values;
  values.reserve(static_cast<std::size_t>(a.size()));
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) values.push_back(a(i, j));
  return reals(std::move(name), std::move(values),
               {static_cast<std::size_t>(a.rows()), static_cast<std::size_t>(a.cols())});
}

/// rows.size() × cols, one vector per row; a row of another length is a programming error.
inline Dataset rows_dataset(std::string name, const std::vector<Eigen::VectorXd>& rows, Eigen::Index cols) {
  std::vector<double> values;
  values.reserve(rows.size() * static_cast<std::size_t>(cols));
  for (const Eigen::VectorXd& row : rows) {
    if (row.size() != cols)
      throw std::logic_error("results: " + name + ": a row has " + std::to_string(row.size()) +
                             " entries, expected " + std::to_string(cols));
    values.insert(values.end(), row.data(), row.data() + row.size());
  }
  return reals(std::move(name), std::move(values), {rows.size(), static_cast<std::size_t>(cols)});
}

/// columns.cols() × cols from the columns of an n × r matrix (Samples' layout, column-major: its
/// storage is already the r × n array row by row).
inline Dataset rows_dataset(std::string name, const Eigen::MatrixXd& columns, Eigen::Index cols) {
  if (columns.cols() > 0 && columns.rows() != cols)
    throw std::logic_error("results: " + name + ": the columns have " + std::to_string(columns.rows()) +
                           " entries, expected " + std::to_string(cols));
  return reals(std::move(name), std::vector<double>(columns.data(), columns.data() + columns.size()),
               {static_cast<std::size_t>(columns.cols()), static_cast<std::size_t>(cols)});
}

/// A limit that may not exist: "none" is −1 in the file (the limits it stands for are ≥ 0).
inline double or_none(double value) { return std::isfinite(value) ? value : -1.0; }

/// Completes /meta (wall time since `start`, threads) and renames the file into place; returns the
/// wall time in seconds. Call set_outcome() first.
inline double finish_run(ResultFile& file, int threads, std::chrono::steady_clock::time_point start) {
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  RunMeta meta = current_meta(threads);
  meta.wall_seconds = wall;
  file.finish(meta);
  return wall;
}

}  // namespace vibro::io::detail
