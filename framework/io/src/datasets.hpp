#pragma once
// Private to vibro_io: building the Datasets of run kinds that write their own groups
// (run.kind: locate, continue; result_file.hpp, ResultFile::write_group).
#include "vibro/io/result_file.hpp"

#include <Eigen/Dense>

#include <chrono>
#include <cmath>
#include <cstdint>
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

inline Dataset integers(std::string name, std::vector<std::int64_t> values) {
  Dataset d;
  d.name = std::move(name);
  d.shape = {values.size()};
  d.integers = std::move(values);
  d.integer = true;
  return d;
}

/// Rows of equal length as one row-major rows × cols dataset.
inline Dataset table(std::string name, const std::vector<Eigen::VectorXd>& rows, std::size_t cols) {
  std::vector<double> values;
  for (const Eigen::VectorXd& r : rows) values.insert(values.end(), r.data(), r.data() + r.size());
  return reals(std::move(name), std::move(values), {rows.size(), cols});
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
