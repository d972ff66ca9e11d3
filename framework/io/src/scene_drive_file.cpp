// `forcing.file` (docs/scenes.md): a periodic drive read from a CSV file, either its Fourier
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
// (a sampled period's: increasing), as if written inline.
#include "scene_sections.hpp"

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

/// The numeric rows of a CSV file: comma-separated numbers, one row a line; blank lines and
/// lines starting with '#' are skipped. Errors name "FILE:LINE:COLUMN".
struct Csv {
  std::vector<std::vector<double>> rows;
  std::vector<long> lines;  ///< the file line of each row
};

constexpr std::size_t kMaxRows = 1000000;

Csv read_csv(const std::string& path, const std::function<void(const std::string&)>& fail) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path + ": no such file (or not a regular file)");
  std::ifstream in(path);
  if (!in) fail(path + ": cannot be opened");
  Csv csv;
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
    csv.lines.push_back(number);
  }
  if (in.bad()) fail(path + ": read error");
  if (csv.rows.empty()) fail(path + ": no rows (only blank or '#' lines)");
  return csv;
}

/// One harmonic of the drive (order ≥ 1) or its mean (order 0).
struct Term {
  long order;
  Eigen::VectorXd cosine, sine;
};

std::vector<Term> coefficients(const Csv& csv, const std::string& path, long n,
                               const std::function<void(const std::string&)>& fail) {
  std::vector<Term> terms;
  for (std::size_t i = 0; i < csv.rows.size(); ++i) {
    const std::vector<double>& row = csv.rows[i];
    const std::string at = path + ":" + std::to_string(csv.lines[i]) + ":1: ";
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

std::vector<Term> transform(const Csv& csv, const std::string& path, long n, long harmonics,
                            const std::function<void(const std::string&)>& fail) {
  const std::size_t N = csv.rows.size();
  for (std::size_t j = 0; j < N; ++j)
    if (static_cast<long>(csv.rows[j].size()) != n)
      fail(path + ":" + std::to_string(csv.lines[j]) + ":1: expected " + std::to_string(n) +
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
  r.expect_map(node, "forcing.file", {"path", "format", "harmonics"});
  if (!node["path"]) r.fail(node, "forcing.file.path", "missing: the CSV file of the drive");
  if (!node["format"])
    r.fail(node, "forcing.file.format",
           "missing: harmonics (one line per harmonic: k, cosines, sines) or samples (one period, one line per time)");
  const std::string format = r.choice(node["format"], "forcing.file.format", {"harmonics", "samples"});
  const std::string name = r.text(node["path"], "forcing.file.path");
  const std::string path = resolve(name, scene_file);
  const auto fail = [&](const std::string& why) { r.fail(node["path"], "forcing.file.path", why); };
  std::vector<Term> terms;
  if (format == "harmonics") {
    if (node["harmonics"])
      r.fail(node["harmonics"], "forcing.file.harmonics", "a file of harmonics gives its own orders: harmonics is for format: samples");
    terms = coefficients(read_csv(path, fail), name, n, fail);
  } else {
    if (!node["harmonics"])
      r.fail(node, "forcing.file.harmonics", "missing: H, the harmonics the sampled period is reduced to (1 … H)");
    const long H = r.integer(node["harmonics"], "forcing.file.harmonics", 1, 100000);
    terms = transform(read_csv(path, fail), name, n, H, fail);
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
