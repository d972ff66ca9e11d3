#pragma once
// Private to vibro_io: reading a scene's YAML tree with the file name, line, column and key path
// in every error (SceneError). Every section parser (scene_sections.hpp, each run kind's own
// section in kinds/) reads through one Reader, so "did you mean" and the positions of keys
// without values work alike everywhere.
#include "vibro/io/scene.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace vibro::io::detail {

inline std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

/// Reads a whole string as a double (strtod's syntax, no leading or trailing space). Accepts
/// subnormal values (1e-308: strtod reports ERANGE for them); refuses what over- or underflows
/// to a value other than the one written (1e999 → ∞, 1e-999 → 0). Empty `why` on success.
inline double parse_number(const std::string& s, std::string& why) {
  why.clear();
  if (s.empty() || std::isspace(static_cast<unsigned char>(s.front()))) {
    why = "expected a number, found '" + s + "'";
    return 0.0;
  }
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  const bool range = errno == ERANGE;
  if (end != s.c_str() + s.size() || end == s.c_str()) {
    why = "expected a number, found '" + s + "'";
  } else if (!std::isfinite(v) || (range && std::abs(v) > 1.0)) {
    why = "expected a finite number, found '" + s + "'";
  } else if (range && v == 0.0 && s.find_first_of("123456789") < s.find_first_of("eE")) {
    why = "'" + s + "' is below the smallest double (4.9e-324): write 0 if 0 is meant";
  }
  return v;
}

inline std::string describe(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Null: return "nothing";
    case YAML::NodeType::Scalar: return "'" + n.Scalar() + "'";
    case YAML::NodeType::Sequence: return "a list of " + std::to_string(n.size());
    case YAML::NodeType::Map: return "a mapping";
    default: return "an undefined value";
  }
}

/// Reads the YAML tree of one scene, with the file name and key paths in every error.
class Reader {
 public:
  /// The longest list `{fill, count}` may make (8 × 10⁸ bytes of doubles).
  static constexpr long kMaxFill = 100000000;

  explicit Reader(std::string file, std::vector<std::pair<std::string, double>> overrides = {})
      : file_(std::move(file)), overrides_(std::move(overrides)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& path,
                         const std::string& problem) const {
    YAML::Mark m = node.Mark();
    if (m.is_null() || node.IsNull()) {
      // A key with no value has no position of its own: point at the key.
      const auto it = key_marks_.find(path);
      if (it != key_marks_.end()) m = it->second;
    }
    const int line = m.is_null() ? last_line_ : m.line + 1;
    const int col = m.is_null() ? last_col_ : m.column + 1;
    std::string note;
    for (const auto& [p, v] : overrides_)
      if (p == path || path.rfind(p, 0) == 0)
        note = " (the value comes from --set " + p + "=" + number_text(v) + ")";
    throw SceneError(file_, line, col, path, problem + note);
  }

  void note(const YAML::Node& node) {
    const YAML::Mark m = node.Mark();
    if (!m.is_null()) {
      last_line_ = m.line + 1;
      last_col_ = m.column + 1;
    }
  }

  /// A mapping whose keys must be among `allowed`.
  void expect_map(const YAML::Node& node, const std::string& path,
                  const std::vector<std::string>& allowed) {
    note(node);
    if (!node.IsMap()) fail(node, path, "expected a mapping, found " + describe(node));
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const std::string key = it->first.Scalar();
      if (!seen.insert(key).second)
        fail(it->first, join(path, key), "duplicate key '" + key + "' (each key may appear once)");
      key_marks_[join(path, key)] = it->first.Mark();
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
      std::string best;
      std::size_t best_d = 3;
      for (const auto& a : allowed) {
        const std::size_t d = edit_distance(key, a);
        if (d < best_d) {
          best_d = d;
          best = a;
        }
      }
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      fail(it->first, join(path, key),
           "unknown key '" + key + "'" + (best.empty() ? "" : "; did you mean '" + best + "'?") +
               " (allowed: " + list + ")");
    }
  }

  /// A plain (unquoted, untagged) scalar that reads whole as a finite double. A quoted "0.5"
  /// or `!!str 0.5` is text in YAML, and refused as such.
  double number(const YAML::Node& node, const std::string& path) {
    note(node);
    if (!node.IsScalar()) fail(node, path, "expected a number, found " + describe(node));
    const std::string& s = node.Scalar();
    const std::string& tag = node.Tag();
    if (tag == "!" || tag == "tag:yaml.org,2002:str")
      fail(node, path, "expected a number, found the text '" + s + "' (" + (tag == "!" ? "quoted" : "tagged !!str") +
                           "; write the number without quotes)");
    if (!tag.empty() && tag != "?" && tag != "tag:yaml.org,2002:float" && tag != "tag:yaml.org,2002:int")
      fail(node, path, "expected a number, found '" + s + "' tagged " + tag);
    std::string why;
    const double v = parse_number(s, why);
    if (!why.empty()) fail(node, path, why);
    return v;
  }

  double number_in(const YAML::Node& node, const std::string& path, double lo, double hi,
                   const std::string& rule) {
    const double v = number(node, path);
    if (!(v >= lo && v <= hi)) fail(node, path, "expected " + rule + ", found " + node.Scalar());
    return v;
  }

  long integer(const YAML::Node& node, const std::string& path, long lo, long hi) {
    const double v = number(node, path);
    if (v != std::floor(v) || v < static_cast<double>(lo) || v > static_cast<double>(hi))
      fail(node, path, "expected a whole number in [" + std::to_string(lo) + ", " +
                           std::to_string(hi) + "], found " + node.Scalar());
    return static_cast<long>(v);
  }

  bool boolean(const YAML::Node& node, const std::string& path) {
    note(node);
    if (node.IsScalar()) {
      const std::string& s = node.Scalar();
      if (s == "true" || s == "yes" || s == "on") return true;
      if (s == "false" || s == "no" || s == "off") return false;
    }
    fail(node, path, "expected true or false, found " + describe(node));
  }

  std::string text(const YAML::Node& node, const std::string& path) {
    note(node);
    if (!node.IsScalar()) fail(node, path, "expected a text, found " + describe(node));
    return node.Scalar();
  }

  std::string choice(const YAML::Node& node, const std::string& path,
                     const std::vector<std::string>& options) {
    const std::string s = text(node, path);
    if (std::find(options.begin(), options.end(), s) != options.end()) return s;
    std::string list;
    for (const auto& o : options) list += (list.empty() ? "" : ", ") + o;
    fail(node, path, "expected one of " + list + ", found '" + s + "'");
  }

  /// A list of numbers, of length `size` when size ≥ 0: written out, or filled with one value,
  /// `{fill: value, count: N}` (a long chain in one line; reading it costs O(N), not a YAML node
  /// per entry).
  /// `fillable` false: a short list whose entries mean different things (a pair of masses, a
  /// range), written out.
  std::vector<double> numbers(const YAML::Node& node, const std::string& path, long size,
                              const std::string& what, bool fillable = true) {
    note(node);
    if (fillable && node.IsMap()) {
      expect_map(node, path, {"fill", "count"});
      if (!node["fill"] || !node["count"])
        fail(node, path, "a filled list needs `fill` (the value) and `count` (how many; " + what + ")");
      const double value = number(node["fill"], path + ".fill");
      const long count = integer(node["count"], path + ".count", 0, kMaxFill);
      if (size >= 0 && count != size)
        fail(node["count"], path + ".count", "expected " + std::to_string(size) + " (" + what + "), found " + std::to_string(count));
      return std::vector<double>(static_cast<std::size_t>(count), value);
    }
    if (!node.IsSequence())
      fail(node, path, "expected a list of numbers (" + what + ")" + (fillable ? " or {fill: value, count: N}" : "") +
                           ", found " + describe(node));
    if (size >= 0 && static_cast<long>(node.size()) != size)
      fail(node, path, "expected a list of " + std::to_string(size) + " numbers (" + what +
                           "), found " + std::to_string(node.size()));
    std::vector<double> out;
    for (std::size_t i = 0; i < node.size(); ++i)
      out.push_back(number(node[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }

  /// The node of entry i of a list numbers() read: the entry, or a filled list's `fill`.
  static YAML::Node entry(const YAML::Node& list, std::size_t i) { return list.IsMap() ? list["fill"] : list[i]; }

  Eigen::MatrixXd matrix(const YAML::Node& node, const std::string& path, long n) {
    note(node);
    if (!node.IsSequence() || (n >= 0 && static_cast<long>(node.size()) != n))
      fail(node, path, "expected a list of " + (n >= 0 ? std::to_string(n) : std::string("n")) +
                           " rows, found " + describe(node));
    const long rows = static_cast<long>(node.size());
    Eigen::MatrixXd m(rows, rows);
    for (long i = 0; i < rows; ++i) {
      const auto row = numbers(node[static_cast<std::size_t>(i)], path + "[" + std::to_string(i) + "]",
                               rows, "one entry per degree of freedom");
      for (long j = 0; j < rows; ++j) m(i, j) = row[static_cast<std::size_t>(j)];
    }
    return m;
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

 private:
  std::string file_;
  std::vector<std::pair<std::string, double>> overrides_;
  std::map<std::string, YAML::Mark> key_marks_;
  int last_line_ = 1, last_col_ = 1;
};

inline Eigen::VectorXd to_vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

inline std::vector<double> spaced(const std::vector<double>& spec, bool logarithmic, Reader& r,
                           const YAML::Node& node, const std::string& path) {
  const double a = spec[0], b = spec[1];
  const double count = spec[2];
  if (count != std::floor(count) || count < 1 || count > 1e7)
    r.fail(node, path, "expected [start, stop, count] with a whole count in [1, 1e7], found count " + number_text(count));
  if (logarithmic && !(a > 0 && b > 0))
    r.fail(node, path, "expected positive start and stop for a logarithmic spacing, found " + number_text(a) + ", " + number_text(b));
  const auto n = static_cast<long>(count);
  std::vector<double> out;
  for (long i = 0; i < n; ++i) {
    const double f = n == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(n - 1);
    out.push_back(logarithmic ? std::exp(std::log(a) + f * (std::log(b) - std::log(a)))
                              : (i == n - 1 ? b : a + f * (b - a)));
  }
  return out;
}
}  // namespace vibro::io::detail
