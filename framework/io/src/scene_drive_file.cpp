// `forcing.file` (docs/scenes.md): a periodic drive read from a CSV or an HDF5 file, either its Fourier
// coefficients (`format: harmonics`: one line per harmonic, `k, cosine_0 … cosine_{n−1},
// sine_0 … sine_{n−1}`) or one period sampled at N equal steps (`format: samples`: one line per
// time t_j = j T/N, j = 0 … N−1, `f_0 … f_{n−1}`), reduced here to its mean and harmonics
// 1 … H by the discrete Fourier transform
//
//     F0   = (1/N) Σ_j f_j,
//     Fc_k = (2/N) Σ_j f_j cos(2π k j / N),   Fs_k = (2/N) Σ_j f_j sin(2π k j / N),   1 ≤ k ≤ H < N/2,
//
// which is exact for a signal made of harmonics 0 … H (the sampled cosines and sines of orders
// below N/2 are orthogonal: Σ_j cos(2πkj/N) cos(2πlj/N) = (N/2) δ_kl; any trigonometric
// interpolation text, e.g. W. H. Press et al., Numerical Recipes, 3rd ed., §12.1). The angle
// 2π (k j mod N)/N is reduced exactly in integers before its cosine is taken. Order 1 becomes
// forcing.cosine/sine and orders ≥ 2 forcing.harmonics after any inline ones, in the file's order
// (a sampled period's: increasing), as if written inline. An HDF5 file holds the same table as a
// 2-D dataset of doubles (one row per CSV line; `dataset`, by default /harmonics or /samples), so
// both containers give the same drive bit for bit.
#include "scene_sections.hpp"

#include "vibro/io/result_file.hpp"  // ResultReader: read access to any HDF5 file

#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

namespace vibro::io::detail {
namespace {

/// The drive file named in the scene: relative paths are relative to the scene file's folder (or
/// the working folder for a scene given as text).
std::string resolve(const std::string& name, const std::string& scene_file) {
  const std::filesystem::path p(name);
  if (p.is_absolute() || scene_file.empty() || scene_file.front() == '<') return name;
  const std::filesystem::path folder = std::filesystem::path(scene_file).parent_path();
  return folder.empty() ? name : (folder / p).string();
}

std::string trim(const std::string& s) {
  const std::size_t a = s.find_first_not_of(" \t\r"), b = s.find_last_not_of(" \t\r");
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

/// The numeric rows of a drive file: from a CSV file, comma-separated numbers, one row a line
/// (blank lines and lines starting with '#' skipped); from an HDF5 file, the rows of a dataset.
/// Errors name "FILE:LINE:COLUMN" (CSV) or "FILE:DATASET[row]" (HDF5).
struct Csv {
  std::vector<std::vector<double>> rows;
  std::vector<std::string> where;  ///< where each row is, for messages ("d.csv:3:1")
  std::string label;               ///< the file (CSV) or file:dataset (HDF5), for messages
};

constexpr std::size_t kMaxRows = 1000000;

/// `name`: the file as the scene names it, for the rows' places (`path` is where it is read).
Csv read_csv(const std::string& path, const std::string& name, const std::function<void(const std::string&)>& fail) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path + ": no such file (or not a regular file)");
  std::ifstream in(path);
  if (!in) fail(path + ": cannot be opened");
  Csv csv;
  csv.label = name;
  std::string line;
  long number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string t = trim(line);
    if (t.empty() || t.front() == '#') continue;
    if (csv.rows.size() == kMaxRows) fail(path + ": more than " + std::to_string(kMaxRows) + " rows");
    std::vector<double> row;
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      const std::string field = trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
      std::string why;
      const double v = parse_number(field, why);
      if (!why.empty()) {
        const std::size_t col = line.find_first_not_of(" \t", start);
        fail(path + ":" + std::to_string(number) + ":" + std::to_string((col == std::string::npos ? start : col) + 1) +
             ": " + why);
      }
      row.push_back(v);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    csv.rows.push_back(std::move(row));
    csv.where.push_back(name + ":" + std::to_string(number) + ":1");
  }
  if (in.bad()) fail(path + ": read error");
  if (csv.rows.empty()) fail(path + ": no rows (only blank or '#' lines)");
  return csv;
}

/// The rows of dataset `dataset` of the HDF5 file `path` (`name` as the scene gives it, for
/// messages): a 2-D dataset of numbers, one row per row of the CSV layout (a 1-D dataset: one
/// number per row), every value finite.
Csv read_hdf5(const std::string& path, const std::string& name, const std::string& dataset,
              const std::function<void(const std::string&)>& fail) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(name + ": no such file (or not a regular file)");
  Csv csv;
  csv.label = name + ":" + dataset;
  std::vector<std::size_t> shape;
  std::vector<double> values;
  try {
    const ResultReader file(path);
    if (!file.exists(dataset) || !file.is_dataset(dataset)) {
      std::string found;
      for (const std::string& o : file.objects())
        if (file.is_dataset(o)) found += (found.empty() ? "" : ", ") + o;
      fail(csv.label + ": no such dataset (the file's datasets: " + (found.empty() ? "none" : found) + ")");
    }
    const std::string type = file.type(dataset);
    if (type != "f64" && type != "i32" && type != "i64")
      fail(csv.label + ": holds " + (type == "str" ? "text" : "values of another type") +
           ": expected numbers (a 2-D dataset of doubles)");
    shape = file.shape(dataset);
    if (shape.size() != 1 && shape.size() != 2)
      fail(csv.label + ": has " + std::to_string(shape.size()) + " dimensions: expected a table (2-D: one row per " +
           "harmonic or sample)");
    values = file.read(dataset);
  } catch (const SceneError&) {
    throw;
  } catch (const std::exception& e) {
    fail(name + ": cannot be read as HDF5: " + e.what());
  }
  const std::size_t rows = shape[0], cols = shape.size() == 2 ? shape[1] : 1;
  if (rows == 0 || cols == 0) fail(csv.label + ": no rows (an empty dataset)");
  if (rows > kMaxRows) fail(csv.label + ": more than " + std::to_string(kMaxRows) + " rows");
  for (std::size_t i = 0; i < rows; ++i) {
    const std::string at = csv.label + "[" + std::to_string(i) + "]";
    std::vector<double> row(values.begin() + static_cast<std::ptrdiff_t>(i * cols),
                            values.begin() + static_cast<std::ptrdiff_t>((i + 1) * cols));
    for (std::size_t j = 0; j < cols; ++j)
      if (!std::isfinite(row[j]))
        fail(csv.label + "[" + std::to_string(i) + ", " + std::to_string(j) + "]: is " + number_text(row[j]) +
             ": expected a finite number");
    csv.rows.push_back(std::move(row));
    csv.where.push_back(at);
  }
  return csv;
}

/// One harmonic of the drive (order ≥ 1) or its mean (order 0).
struct Term {
  long order;
  Eigen::VectorXd cosine, sine;
};

std::vector<Term> coefficients(const Csv& csv, long n, const std::function<void(const std::string&)>& fail) {
  std::vector<Term> terms;
  for (std::size_t i = 0; i < csv.rows.size(); ++i) {
    const std::vector<double>& row = csv.rows[i];
    const std::string at = csv.where[i] + ": ";
    if (static_cast<long>(row.size()) != 2 * n + 1)
      fail(at + "expected " + std::to_string(2 * n + 1) + " numbers (the order k, then " + std::to_string(n) +
           " cosine and " + std::to_string(n) + " sine amplitudes, one per mass), found " + std::to_string(row.size()));
    const double k = row[0];
    if (!(k >= 1.0 && k <= 1e6 && k == std::floor(k)))
      fail(at + "the order k must be a whole number in [1, 1000000], found " + number_text(k));
    for (const Term& t : terms)
      if (t.order == static_cast<long>(k)) fail(at + "order " + number_text(k) + " is given twice");
    Term t{static_cast<long>(k), Eigen::VectorXd(n), Eigen::VectorXd(n)};
    for (long q = 0; q < n; ++q) {
      t.cosine(q) = row[static_cast<std::size_t>(1 + q)];
      t.sine(q) = row[static_cast<std::size_t>(1 + n + q)];
    }
    terms.push_back(std::move(t));
  }
  return terms;
}

std::vector<Term> transform(const Csv& csv, long n, long harmonics, const std::function<void(const std::string&)>& fail) {
  const std::string& path = csv.label;
  const std::size_t N = csv.rows.size();
  for (std::size_t j = 0; j < N; ++j)
    if (static_cast<long>(csv.rows[j].size()) != n)
      fail(csv.where[j] + ": expected " + std::to_string(n) +
           " numbers (the force on each mass at this time), found " + std::to_string(csv.rows[j].size()));
  if (2 * static_cast<std::size_t>(harmonics) >= N)
    fail(path + ": " + std::to_string(N) + " samples resolve harmonics below N/2 = " + number_text(N / 2.0) +
         " only: forcing.file.harmonics is " + std::to_string(harmonics));
  std::vector<Term> terms;
  Term mean{0, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)};
  for (std::size_t j = 0; j < N; ++j) mean.cosine += Eigen::Map<const Eigen::VectorXd>(csv.rows[j].data(), n);
  mean.cosine /= static_cast<double>(N);
  terms.push_back(std::move(mean));
  const double step = 2.0 * std::numbers::pi / static_cast<double>(N);
  for (long k = 1; k <= harmonics; ++k) {
    Term t{k, Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)};
    for (std::size_t j = 0; j < N; ++j) {
      const double angle = step * static_cast<double>((static_cast<std::size_t>(k) * j) % N);
      const Eigen::Map<const Eigen::VectorXd> f(csv.rows[j].data(), n);
      t.cosine += std::cos(angle) * f;
      t.sine += std::sin(angle) * f;
    }
    t.cosine *= 2.0 / static_cast<double>(N);
    t.sine *= 2.0 / static_cast<double>(N);
    if (!t.cosine.allFinite() || !t.sine.allFinite())
      fail(path + ": the Fourier sums of harmonic " + std::to_string(k) + " overflow (forces too large for doubles)");
    terms.push_back(std::move(t));
  }
  return terms;
}

}  // namespace

void read_drive_file(Reader& r, const YAML::Node& fn, long n, const std::string& scene_file, HarmonicForcing& f) {
  const YAML::Node node = fn["file"];
  r.expect_map(node, "forcing.file", {"path", "format", "harmonics", "type", "dataset"});
  if (!node["path"]) r.fail(node, "forcing.file.path", "missing: the CSV or HDF5 file of the drive");
  if (!node["format"])
    r.fail(node, "forcing.file.format",
           "missing: harmonics (one line per harmonic: k, cosines, sines) or samples (one period, one line per time)");
  const std::string format = r.choice(node["format"], "forcing.file.format", {"harmonics", "samples"});
  const std::string name = r.text(node["path"], "forcing.file.path");
  const std::string path = resolve(name, scene_file);
  // The container: `type`, else the extension (.h5, .hdf5: HDF5; anything else: CSV).
  std::string extension = std::filesystem::path(name).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool hdf5 = node["type"] ? r.choice(node["type"], "forcing.file.type", {"csv", "hdf5"}) == "hdf5"
                                 : extension == ".h5" || extension == ".hdf5";
  if (node["dataset"] && !hdf5)
    r.fail(node["dataset"], "forcing.file.dataset", "a CSV file has no datasets: dataset is for an HDF5 file (type: hdf5, or a "
                                                    ".h5 or .hdf5 file)");
  std::string dataset = "/" + format;
  if (node["dataset"]) {
    dataset = r.text(node["dataset"], "forcing.file.dataset");
    if (dataset.empty()) r.fail(node["dataset"], "forcing.file.dataset", "expected the path of a dataset, found ''");
    if (dataset.front() != '/') dataset = "/" + dataset;
  }
  const auto fail = [&](const std::string& why) { r.fail(node["path"], "forcing.file.path", why); };
  const auto rows = [&] { return hdf5 ? read_hdf5(path, name, dataset, fail) : read_csv(path, name, fail); };
  std::vector<Term> terms;
  if (format == "harmonics") {
    if (node["harmonics"])
      r.fail(node["harmonics"], "forcing.file.harmonics", "a file of harmonics gives its own orders: harmonics is for format: samples");
    terms = coefficients(rows(), n, fail);
  } else {
    if (!node["harmonics"])
      r.fail(node, "forcing.file.harmonics", "missing: H, the harmonics the sampled period is reduced to (1 … H)");
    const long H = r.integer(node["harmonics"], "forcing.file.harmonics", 1, 100000);
    terms = transform(rows(), n, H, fail);
    if (fn["constant"])
      r.fail(fn["constant"], "forcing.constant", "the sampled drive of forcing.file gives the mean force: give it in one place");
  }
  // The inline keys may not give an order the file gives.
  for (const Term& t : terms) {
    if (t.order == 0) {
      f.constant = t.cosine;
      continue;
    }
    if (t.order == 1) {
      for (const char* key : {"cosine", "sine"})
        if (fn[key])
          r.fail(fn[key], std::string("forcing.") + key, "the first harmonic is also given by forcing.file: give it in one place");
      f.cosine = t.cosine;
      f.sine = t.sine;
      continue;
    }
    for (const ForcingHarmonic& h : f.harmonics)
      if (h.order == t.order)
        r.fail(fn["harmonics"], "forcing.harmonics",
               "order " + std::to_string(t.order) + " is also given by forcing.file: give each harmonic in one place");
  }
  // Orders ≥ 2 after the inline ones, in the file's order (a sampled period's: increasing).
  for (const Term& t : terms)
    if (t.order >= 2) f.harmonics.push_back({static_cast<int>(t.order), t.cosine, t.sine});
}

}  // namespace vibro::io::detail
