#include "vibro/io/scene.hpp"

#include "vibro/io/continuation.hpp"
#include "vibro/io/resources.hpp"

#include "vibro/models/chain.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

namespace vibro::io {
namespace {

std::size_t edit_distance(const std::string& a, const std::string& b) {
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
double parse_number(const std::string& s, std::string& why) {
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

std::string describe(const YAML::Node& n) {
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

  /// A list of numbers, of length `size` when size ≥ 0.
  std::vector<double> numbers(const YAML::Node& node, const std::string& path, long size,
                              const std::string& what) {
    note(node);
    if (!node.IsSequence())
      fail(node, path, "expected a list of numbers (" + what + "), found " + describe(node));
    if (size >= 0 && static_cast<long>(node.size()) != size)
      fail(node, path, "expected a list of " + std::to_string(size) + " numbers (" + what +
                           "), found " + std::to_string(node.size()));
    std::vector<double> out;
    for (std::size_t i = 0; i < node.size(); ++i)
      out.push_back(number(node[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }

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

/// Splits "a.b[2].c" into keys and indices.
struct PathStep {
  std::string key;  // empty for an index step
  std::size_t index = 0;
};

std::vector<PathStep> split_path(const std::string& path) {
  std::vector<PathStep> steps;
  std::size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
      continue;
    }
    if (path[i] == '[') {
      const std::size_t close = path.find(']', i);
      if (close == std::string::npos) throw std::invalid_argument("unclosed '['");
      const std::string digits = path.substr(i + 1, close - i - 1);
      if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos)
        throw std::invalid_argument("index '" + digits + "' is not a whole number");
      if (digits.size() > 9)  // stoul would overflow past 2^64; no list is longer than 1e9
        throw std::invalid_argument("index '" + digits + "' is too large");
      steps.push_back({"", std::stoul(digits)});
      i = close + 1;
      continue;
    }
    const std::size_t end = path.find_first_of(".[", i);
    steps.push_back({path.substr(i, end - i), 0});
    i = end == std::string::npos ? path.size() : end;
  }
  if (steps.empty()) throw std::invalid_argument("empty path");
  return steps;
}

Eigen::VectorXd to_vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

std::vector<double> spaced(const std::vector<double>& spec, bool logarithmic, Reader& r,
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

}  // namespace

SceneError::SceneError(std::string file, int line, int column, std::string path, std::string problem)
    : std::runtime_error(file + (line > 0 ? ":" + std::to_string(line) + ":" + std::to_string(column) : "") +
                         ": " + (path.empty() ? "" : path + ": ") + problem),
      file_(std::move(file)),
      line_(line),
      column_(column),
      path_(std::move(path)),
      problem_(std::move(problem)) {}

double Scene::period() const {
  const double w = forcing().frequency;
  return w > 0.0 ? 2.0 * std::numbers::pi / w : 1.0;
}

std::unique_ptr<vibro::Engine> make_engine(const Scene& scene) {
  if (scene.engine == EngineKind::modal) {
    if (!scene.chain) throw std::logic_error("make_engine: a modal scene without its banded chain");
    return std::make_unique<ModalEngine>(*scene.chain, scene.stops, modal_options(scene.solver));
  }
  return std::make_unique<DenseEngine>(scene.impact_system(), scene.solver);
}

const char* to_string(RunSpec::Kind kind) {
  switch (kind) {
    case RunSpec::Kind::sweep: return "sweep";
    case RunSpec::Kind::locate: return "locate";
    case RunSpec::Kind::continuation: return "continue";
    case RunSpec::Kind::basin: return "basin";
    case RunSpec::Kind::diagram: return "diagram";
    case RunSpec::Kind::lyapunov: return "lyapunov";
    case RunSpec::Kind::orbit: return "orbit";
    case RunSpec::Kind::simulate: break;
  }
  return "simulate";
}

const char* to_string(EngineKind engine) { return engine == EngineKind::modal ? "modal" : "dense"; }

const char* to_string(EngineChoice choice) {
  switch (choice) {
    case EngineChoice::automatic: return "auto";
    case EngineChoice::dense: return "dense";
    case EngineChoice::modal: return "modal";
  }
  return "?";
}

LazySystem::LazySystem(LinearSystem system)
    : dof_(system.dof()), forcing_(system.forcing()), cache_(std::make_shared<Cache>()) {
  cache_->system.emplace(std::move(system));
  std::call_once(cache_->once, [] {});  // built: get() has nothing to do
}

LazySystem::LazySystem(Eigen::Index dof, HarmonicForcing forcing, std::function<LinearSystem()> build)
    : dof_(dof), forcing_(std::move(forcing)), cache_(std::make_shared<Cache>()) {
  cache_->build = std::move(build);
}

const LinearSystem& LazySystem::get() const {
  if (!cache_) throw std::logic_error("Scene: no system (a default-constructed LazySystem)");
  std::call_once(cache_->once, [this] {
    cache_->system.emplace(cache_->build());
    cache_->build = nullptr;  // the chain's data it captured are no longer needed
  });
  return *cache_->system;
}

bool LazySystem::built() const { return cache_ && cache_->system.has_value(); }

struct SceneDocument::Impl {
  std::string file, text;
  YAML::Node root;
  std::vector<std::pair<std::string, double>> overrides;  // set() calls, in order
  /// Every edit in order (set: a number; replace: YAML text), replayed by a copy.
  struct Edit {
    std::string path;
    std::optional<double> number;
    std::string yaml;
  };
  std::vector<Edit> edits;
};

SceneDocument::SceneDocument() : impl_(std::make_unique<Impl>()) {}
SceneDocument::~SceneDocument() = default;
// A copy re-parses the text and replays the edits: YAML::Clone would lose the source positions
// that every error message needs.
SceneDocument::SceneDocument(const SceneDocument& o) : impl_(std::make_unique<Impl>()) { *this = o; }
SceneDocument& SceneDocument::operator=(const SceneDocument& o) {
  if (this != &o) {
    SceneDocument fresh = parse(o.impl_->text, o.impl_->file);
    for (const Impl::Edit& e : o.impl_->edits) e.number ? fresh.set(e.path, *e.number) : fresh.replace(e.path, e.yaml);
    std::swap(impl_, fresh.impl_);
  }
  return *this;
}

const std::string& SceneDocument::file() const { return impl_->file; }
const std::string& SceneDocument::text() const { return impl_->text; }

SceneDocument SceneDocument::load(const std::string& path) {
  // Opened without blocking (a FIFO would wait for a writer for ever) and checked on the open
  // descriptor: only a regular file is read, and only if parsing it fits in memory.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw SceneError(path, 0, 0, "", std::string("cannot open the scene file: ") + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat info {};
  if (::fstat(fd, &info) != 0)
    throw SceneError(path, 0, 0, "", std::string("cannot read the scene file: ") + std::strerror(errno));
  if (!S_ISREG(info.st_mode)) {
    const char* kind = S_ISDIR(info.st_mode)    ? "a directory"
                       : S_ISFIFO(info.st_mode) ? "a FIFO (named pipe)"
                       : S_ISCHR(info.st_mode)  ? "a character device"
                       : S_ISBLK(info.st_mode)  ? "a block device"
                       : S_ISSOCK(info.st_mode) ? "a socket"
                                                : "not a regular file";
    throw SceneError(path, 0, 0, "", std::string("is ") + kind + ": a scene must be a regular file");
  }
  const auto size = static_cast<std::uint64_t>(info.st_size);
  try {
    require_memory(size * kParseBytesPerByte,
                   "parsing the scene file (" + bytes_text(size) + ", about " + std::to_string(kParseBytesPerByte) +
                       " bytes of YAML tree per byte)");
  } catch (const ResourceError& e) {
    throw SceneError(path, 0, 0, "", e.what());
  }
  std::string text(static_cast<std::size_t>(size), '\0');
  std::size_t got = 0;
  while (got < text.size()) {
    const ssize_t r = ::pread(fd, text.data() + got, text.size() - got, static_cast<off_t>(got));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw SceneError(path, 0, 0, "", std::string("cannot read the scene file: ") + std::strerror(errno));
    if (r == 0) break;  // shrank while read
    got += static_cast<std::size_t>(r);
  }
  text.resize(got);
  return parse(text, path);
}

SceneDocument SceneDocument::parse(const std::string& text, const std::string& file) {
  SceneDocument doc;
  doc.impl_->file = file;
  doc.impl_->text = text;
  try {
    doc.impl_->root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(file, e.mark.line + 1, e.mark.column + 1, "", "YAML syntax error: " + e.msg);
  }
  if (!doc.impl_->root.IsMap()) {
    const YAML::Mark m = doc.impl_->root.Mark();
    throw SceneError(file, m.is_null() ? 1 : m.line + 1, m.is_null() ? 1 : m.column + 1, "",
                     "expected a mapping of sections (model, forcing, stops, ...), found " +
                         describe(doc.impl_->root));
  }
  return doc;
}

namespace {

YAML::Node find_node(const YAML::Node& root, const std::string& path, const std::string& file) {
  std::vector<PathStep> steps;
  try {
    steps = split_path(path);
  } catch (const std::invalid_argument& e) {
    throw SceneError(file, 0, 0, path, std::string("malformed path: ") + e.what());
  }
  YAML::Node node = root;
  std::string walked;
  for (const PathStep& step : steps) {
    const YAML::Node& look = node;  // const lookups never insert keys
    if (step.key.empty()) {
      if (!look.IsSequence() || step.index >= look.size())
        throw SceneError(file, node.Mark().line + 1, node.Mark().column + 1, walked,
                         "has no element [" + std::to_string(step.index) + "] (" + describe(node) + ")");
      node.reset(node[step.index]);
      walked += "[" + std::to_string(step.index) + "]";
    } else {
      if (!look.IsMap() || !look[step.key])
        throw SceneError(file, node.Mark().line + 1, node.Mark().column + 1, walked,
                         "has no key '" + step.key + "' (paths name values the scene file already sets)");
      node.reset(node[step.key]);
      walked += (walked.empty() ? "" : ".") + step.key;
    }
  }
  return node;
}

}  // namespace

void SceneDocument::set(const std::string& path, double value) {
  YAML::Node node = find_node(impl_->root, path, impl_->file);
  Reader r(impl_->file);
  r.number(node, path);  // must already be a number
  node = number_text(value);
  // Setting a path again replaces its value: a sweep reuses one working copy for every point.
  const auto same = std::find_if(impl_->overrides.begin(), impl_->overrides.end(),
                                 [&](const auto& o) { return o.first == path; });
  if (same != impl_->overrides.end()) impl_->overrides.erase(same);
  impl_->overrides.emplace_back(path, value);
  impl_->edits.push_back({path, value, {}});
}

void SceneDocument::replace(const std::string& path, const std::string& yaml) {
  std::vector<PathStep> steps;
  try {
    steps = split_path(path);
  } catch (const std::invalid_argument& e) {
    throw SceneError(impl_->file, 0, 0, path, std::string("malformed path: ") + e.what());
  }
  YAML::Node value;
  try {
    if (!yaml.empty()) value = YAML::Load(yaml);
  } catch (const YAML::ParserException& e) {
    throw SceneError(impl_->file, 0, 0, path, "YAML syntax error in the value given: " + e.msg);
  }
  YAML::Node node = impl_->root;
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const std::string& key = steps[k].key;
    if (key.empty() || !node.IsMap())
      throw SceneError(impl_->file, 0, 0, path, "only mappings' keys can be replaced");
    if (k + 1 == steps.size()) {
      if (yaml.empty())
        node.remove(key);
      else
        node[key] = value;
    } else {
      const YAML::Node& look = node;  // a const lookup never inserts the key
      if (!look[key]) node[key] = YAML::Node(YAML::NodeType::Map);
      node.reset(node[key]);
    }
  }
  impl_->edits.push_back({path, std::nullopt, yaml});
}

void SceneDocument::set_assignment(const std::string& assignment, int ordinal) {
  // Errors point into the assignment: "--set:K:C:", the K-th --set, column C of its text.
  auto fail = [&](std::size_t column, const std::string& path, const std::string& problem) {
    throw SceneError("--set", ordinal, static_cast<int>(column), path, problem);
  };
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    fail(1, assignment, "expected PATH=VALUE, e.g. forcing.frequency=0.26");
  const std::string path = assignment.substr(0, eq);
  const std::string value = assignment.substr(eq + 1);
  std::string why;
  const double v = parse_number(value, why);
  if (!why.empty())
    fail(eq + 2, path, why.rfind("expected a number", 0) == 0 ? "expected a finite number, found '" + value + "'" : why);
  try {
    set(path, v);
  } catch (const SceneError& e) {
    fail(1, path, e.problem() + " (in " + e.file() + (e.path().empty() ? "" : " at " + e.path()) + ")");
  }
}

double SceneDocument::get(const std::string& path) const {
  Reader r(impl_->file);
  return r.number(find_node(impl_->root, path, impl_->file), path);
}

Scene SceneDocument::build() const { return build_checked(true); }

Scene SceneDocument::build_checked(bool check_sweep) const {
  Reader r(impl_->file, impl_->overrides);
  const YAML::Node& root = impl_->root;
  r.expect_map(root, "", {"name", "model", "forcing", "stops", "initial", "solver", "record", "run"});

  // --- model ---
  const YAML::Node model = root["model"];
  if (!model) r.fail(root, "model", "missing: a scene needs a model (model.chain or model.matrices)");
  r.expect_map(model, "model", {"chain", "matrices"});
  if (model["chain"] && model["matrices"])
    r.fail(model, "model", "give either model.chain or model.matrices, not both");
  Eigen::MatrixXd M, C, K;
  long n = 0;
  std::optional<models::Chain> chain_links;  // model.chain, assembled only on demand
  if (const YAML::Node chain = model["chain"]) {
    r.expect_map(chain, "model.chain", {"masses", "springs", "dampers", "left_wall", "right_wall"});
    if (!chain["masses"]) r.fail(chain, "model.chain.masses", "missing: one mass per degree of freedom");
    models::Chain c;
    c.masses = r.numbers(chain["masses"], "model.chain.masses", -1, "one mass per degree of freedom");
    n = static_cast<long>(c.masses.size());
    if (n == 0) r.fail(chain["masses"], "model.chain.masses", "expected at least one mass, found an empty list");
    for (long i = 0; i < n; ++i)
      if (!(c.masses[static_cast<std::size_t>(i)] > 0.0))
        r.fail(chain["masses"][static_cast<std::size_t>(i)], "model.chain.masses[" + std::to_string(i) + "]",
               "expected a mass > 0, found " + chain["masses"][static_cast<std::size_t>(i)].Scalar());
    auto links = [&](const char* key, std::vector<double>& out) {
      const std::string path = std::string("model.chain.") + key;
      if (!chain[key]) return;
      out = r.numbers(chain[key], path, n - 1, "one per link between neighbouring masses");
      for (std::size_t i = 0; i < out.size(); ++i)
        if (out[i] < 0.0)
          r.fail(chain[key][i], path + "[" + std::to_string(i) + "]", "expected a value ≥ 0, found " + chain[key][i].Scalar());
    };
    links("springs", c.springs);
    links("dampers", c.dampers);
    if (c.springs.empty() && n > 1) c.springs.assign(static_cast<std::size_t>(n - 1), 0.0);
    auto wall = [&](const char* key, double& spring, double& damper) {
      const YAML::Node w = chain[key];
      if (!w) return;
      const std::string path = std::string("model.chain.") + key;
      r.expect_map(w, path, {"spring", "damper"});
      if (w["spring"]) spring = r.number_in(w["spring"], path + ".spring", 0, 1e300, "a value ≥ 0");
      if (w["damper"]) damper = r.number_in(w["damper"], path + ".damper", 0, 1e300, "a value ≥ 0");
    };
    wall("left_wall", c.left_spring, c.left_damper);
    wall("right_wall", c.right_spring, c.right_damper);
    // What LinearSystem would refuse in the assembled matrices, checked on the links in O(n):
    // every diagonal entry (a sum of two links and a wall) must be finite.
    for (long i = 0; i < n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      double k = (i == 0 ? c.left_spring : 0.0) + (i == n - 1 ? c.right_spring : 0.0);
      double d = (i == 0 ? c.left_damper : 0.0) + (i == n - 1 ? c.right_damper : 0.0);
      if (i > 0) k += c.springs[u - 1], d += c.dampers.empty() ? 0.0 : c.dampers[u - 1];
      if (i < n - 1) k += c.springs[u], d += c.dampers.empty() ? 0.0 : c.dampers[u];
      if (!std::isfinite(k) || !std::isfinite(d))
        r.fail(chain, "model.chain", "the links of mass " + std::to_string(i) +
                                         " add up to an infinite stiffness or damping (values too large)");
    }
    chain_links = std::move(c);
  } else if (const YAML::Node mats = model["matrices"]) {
    r.expect_map(mats, "model.matrices", {"mass", "damping", "stiffness"});
    if (!mats["mass"]) r.fail(mats, "model.matrices.mass", "missing: the mass matrix");
    M = r.matrix(mats["mass"], "model.matrices.mass", -1);
    n = M.rows();
    C = mats["damping"] ? r.matrix(mats["damping"], "model.matrices.damping", n) : Eigen::MatrixXd::Zero(n, n);
    K = mats["stiffness"] ? r.matrix(mats["stiffness"], "model.matrices.stiffness", n) : Eigen::MatrixXd::Zero(n, n);
  } else {
    r.fail(model, "model", "expected model.chain or model.matrices");
  }

  // --- forcing ---
  HarmonicForcing f = HarmonicForcing::zero(n);
  if (const YAML::Node fn = root["forcing"]) {
    r.expect_map(fn, "forcing", {"frequency", "constant", "cosine", "sine"});
    if (fn["frequency"]) f.frequency = r.number_in(fn["frequency"], "forcing.frequency", 0, 1e300, "a frequency ≥ 0 (rad per unit time)");
    if (fn["constant"]) f.constant = to_vector(r.numbers(fn["constant"], "forcing.constant", n, "one force per mass"));
    if (fn["cosine"]) f.cosine = to_vector(r.numbers(fn["cosine"], "forcing.cosine", n, "one amplitude per mass"));
    if (fn["sine"]) f.sine = to_vector(r.numbers(fn["sine"], "forcing.sine", n, "one amplitude per mass"));
  }
  LazySystem dense;
  std::optional<BandedChain> banded;
  std::string not_banded;  // why a chain is not in banded form (its damping is not proportional)
  if (chain_links) {
    models::Chain& c = *chain_links;
    auto list = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
    c.force_constant = list(f.constant);
    c.force_cosine = list(f.cosine);
    c.force_sine = list(f.sine);
    c.frequency = f.frequency;
    try {
      banded = BandedChain::from_links(c.masses, c.springs, c.dampers, c.left_spring, c.left_damper,
                                       c.right_spring, c.right_damper, f);
      banded->validate();
    } catch (const InvalidInput& e) {
      banded.reset();
      not_banded = e.what();
    }
    dense = LazySystem(n, f, [c] { return models::build_chain(c); });
  } else try {
    dense = LazySystem(LinearSystem(M, C, K, f));
  } catch (const InvalidInput& e) {
    // Point at the matrix or forcing entry the message names.
    const std::string msg = e.what();
    const YAML::Node mats = model["matrices"];
    const YAML::Node fn = root["forcing"];
    const std::pair<const char*, const char*> where[] = {
        {"mass matrix", "mass"}, {"damping matrix", "damping"}, {"stiffness matrix", "stiffness"}};
    for (const auto& [prefix, key] : where)
      if (msg.rfind(prefix, 0) == 0 && mats && mats[key])
        r.fail(mats[key], std::string("model.matrices.") + key, msg.substr(msg.find(':') + 2));
    for (const char* key : {"constant", "cosine", "sine", "frequency"})
      if (msg.rfind(std::string("forcing.") + key, 0) == 0 && fn && fn[key])
        r.fail(fn[key], std::string("forcing.") + key, msg.substr(msg.find(':') + 2));
    r.fail(model, "model", msg);
  }

  // --- stops ---
  std::vector<Stop> stops;
  if (const YAML::Node sn = root["stops"]) {
    if (!sn.IsSequence()) r.fail(sn, "stops", "expected a list of stops, found " + describe(sn));
    for (std::size_t j = 0; j < sn.size(); ++j) {
      const YAML::Node s = sn[j];
      const std::string path = "stops[" + std::to_string(j) + "]";
      r.expect_map(s, path, {"mass", "side", "between", "position", "gap", "restitution", "amplitude", "phase", "name"});
      Stop stop;
      if (s["between"]) {
        if (s["mass"] || s["side"] || s["position"])
          r.fail(s, path, "a stop between masses takes 'between' and 'gap', not 'mass', 'side' or 'position'");
        const auto pair = r.numbers(s["between"], path + ".between", 2, "the two masses i, k of x_i - x_k ≤ gap");
        for (int q = 0; q < 2; ++q)
          r.integer(s["between"][static_cast<std::size_t>(q)], path + ".between[" + std::to_string(q) + "]", 0, n - 1);
        if (pair[0] == pair[1])
          r.fail(s["between"], path + ".between", "expected two different masses, found mass " +
                                                      s["between"][0].Scalar() + " twice");
        if (!s["gap"]) r.fail(s, path + ".gap", "missing: the gap of x_i - x_k ≤ gap");
        stop = Stop::between(static_cast<Eigen::Index>(pair[0]), static_cast<Eigen::Index>(pair[1]),
                             r.number(s["gap"], path + ".gap"), 1.0);
      } else {
        if (!s["mass"]) r.fail(s, path + ".mass", "missing: the mass the stop limits (0-based)");
        if (!s["side"]) r.fail(s, path + ".side", "missing: 'upper' (x ≤ position) or 'lower' (x ≥ position)");
        if (!s["position"]) r.fail(s, path + ".position", "missing: where the stop is");
        if (s["gap"]) r.fail(s["gap"], path + ".gap", "'gap' is for stops between masses; use 'position'");
        const long i = r.integer(s["mass"], path + ".mass", 0, n - 1);
        const std::string side = r.choice(s["side"], path + ".side", {"upper", "lower"});
        const double p = r.number(s["position"], path + ".position");
        stop = side == "upper" ? Stop::upper(i, p, 1.0) : Stop::lower(i, p, 1.0);
      }
      if (!s["restitution"]) r.fail(s, path + ".restitution", "missing: the restitution coefficient r ∈ [0, 1]");
      stop.restitution = r.number_in(s["restitution"], path + ".restitution", 0, 1, "a restitution coefficient in [0, 1]");
      if (s["amplitude"]) {
        stop.amplitude = r.number_in(s["amplitude"], path + ".amplitude", 0, 1e300, "an amplitude ≥ 0");
        if (stop.amplitude > 0.0 && !(f.frequency > 0.0))
          r.fail(s["amplitude"], path + ".amplitude",
                 "a moving stop moves at the forcing frequency: set forcing.frequency > 0");
      }
      if (s["phase"]) stop.phase = r.number(s["phase"], path + ".phase");
      if (s["name"]) stop.name = r.text(s["name"], path + ".name");
      stops.push_back(stop);
    }
  }
  try {
    stops = validated_stops(std::move(stops), n, f.frequency);  // O(m log m), no n × m normals
  } catch (const InvalidInput& e) {
    // The message starts with the stop ("stops[j] (name): ..."); point at that stop and do not
    // repeat its label.
    std::string msg = e.what();
    YAML::Node where = root["stops"];
    std::string path = "stops";
    if (msg.rfind("stops[", 0) == 0) {
      const std::size_t j = std::stoul(msg.substr(6));
      if (where && j < where.size()) {
        path = "stops[" + std::to_string(j) + "]";
        where = where[j];
        const std::size_t colon = msg.find("): ");
        if (colon != std::string::npos && msg.find(" and ") > colon) msg = msg.substr(colon + 3);
      }
    }
    r.fail(where ? where : root, path, msg);
  }

  // --- initial state ---
  double t0 = 0.0;
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(n), v0 = Eigen::VectorXd::Zero(n);
  if (const YAML::Node in = root["initial"]) {
    r.expect_map(in, "initial", {"time", "x", "v"});
    if (in["time"]) t0 = r.number(in["time"], "initial.time");
    if (in["x"]) x0 = to_vector(r.numbers(in["x"], "initial.x", n, "one displacement per mass"));
    if (in["v"]) v0 = to_vector(r.numbers(in["v"], "initial.v", n, "one velocity per mass"));
  }
  // --- solver ---
  SimulatorOptions opt;
  EngineChoice engine_choice = EngineChoice::automatic;
  if (const YAML::Node sv = root["solver"]) {
    r.expect_map(sv, "solver", {"trigger", "simultaneity", "chatter_height", "chatter_velocity", "contact_velocity",
                                "max_events", "event_window", "length_scale", "flow_method", "max_condition", "engine",
                                "chatter_rule"});
    if (sv["trigger"]) opt.trigger = r.number_in(sv["trigger"], "solver.trigger", 1e-16, 1e-4, "a relative tolerance in [1e-16, 1e-4]");
    if (sv["simultaneity"]) opt.simultaneity = r.number_in(sv["simultaneity"], "solver.simultaneity", 0, 1e-2, "a relative time in [0, 1e-2]");
    if (sv["chatter_height"]) opt.chatter_height = r.number_in(sv["chatter_height"], "solver.chatter_height", 0, 1e-1, "a relative height in [0, 0.1]");
    if (sv["chatter_velocity"]) opt.chatter_velocity = r.number_in(sv["chatter_velocity"], "solver.chatter_velocity", 0, 1e-1, "a relative speed in [0, 0.1]");
    if (sv["contact_velocity"]) opt.contact_velocity = r.number_in(sv["contact_velocity"], "solver.contact_velocity", 0, 1e-3, "a relative speed in [0, 1e-3]");
    if (sv["max_events"]) opt.max_events = r.integer(sv["max_events"], "solver.max_events", 1, 1000000000L);
    if (sv["event_window"]) opt.event_window = r.number_in(sv["event_window"], "solver.event_window", 0, 1e300, "a time ≥ 0 (0: one forcing period)");
    if (sv["length_scale"]) opt.length_scale = r.number_in(sv["length_scale"], "solver.length_scale", 0, 1e300, "a length ≥ 0 (0: automatic)");
    if (sv["flow_method"]) {
      const std::string m = r.choice(sv["flow_method"], "solver.flow_method", {"automatic", "spectral", "exponential"});
      opt.flow.method = m == "spectral" ? FlowMethod::spectral : m == "exponential" ? FlowMethod::exponential : FlowMethod::automatic;
    }
    if (sv["max_condition"]) opt.flow.max_condition = r.number_in(sv["max_condition"], "solver.max_condition", 1, 1e16, "a condition number in [1, 1e16]");
    if (sv["chatter_rule"]) {
      const std::string c =
          r.choice(sv["chatter_rule"], "solver.chatter_rule", {"third_order", "second_order", "first_order"});
      opt.chatter_rule = c == "first_order"    ? ChatterRule::first_order
                         : c == "second_order" ? ChatterRule::second_order
                                               : ChatterRule::third_order;
    }
    if (sv["engine"]) {
      const std::string e = r.choice(sv["engine"], "solver.engine", {"auto", "dense", "modal"});
      engine_choice = e == "dense" ? EngineChoice::dense : e == "modal" ? EngineChoice::modal : EngineChoice::automatic;
    }
  }

  // The initial state, with the tolerance the run will use (trigger × L): what `check` accepts,
  // the run accepts. L is the engines' (run_length_scale); for an unforced scene the engines take
  // the fastest mode's frequency, unknown here, and the stops' and x0's part of L is used: a lower
  // bound, so the loader is never the more lenient.
  try {
    double kmax = 0.0, mmax = 0.0;
    if (chain_links) {
      const models::Chain& c = *chain_links;
      for (long i = 0; i < n; ++i) {
        const auto u = static_cast<std::size_t>(i);
        double k = (i == 0 ? c.left_spring : 0.0) + (i == n - 1 ? c.right_spring : 0.0);
        if (i > 0) k += c.springs[u - 1];
        if (i < n - 1) k += c.springs[u];
        kmax = std::max({kmax, k, i < n - 1 ? c.springs[u] : 0.0});
        mmax = std::max(mmax, c.masses[u]);
      }
    } else {
      kmax = K.cwiseAbs().maxCoeff();
      mmax = M.cwiseAbs().maxCoeff();
    }
    const bool forced = f.frequency > 0.0;
    const double fmax = forced ? f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff() : 0.0;
    const double L = run_length_scale(opt, forced ? f.frequency : 1.0, kmax, mmax, fmax, stops, x0,
                                      forced ? v0 : Eigen::VectorXd::Zero(n).eval());
    check_admissible(stops, f.frequency, t0, x0, opt.trigger * L);
  } catch (const InvalidInput& e) {
    const YAML::Node in = root["initial"];
    if (in && in["x"]) r.fail(in["x"], "initial.x", e.what());
    // The default initial state (rest at 0) violates a stop: point at that stop's position.
    const std::string msg = e.what();
    const std::size_t at = msg.find("stops[");
    const YAML::Node sn = root["stops"];
    if (at != std::string::npos && sn) {
      const std::size_t j = std::stoul(msg.substr(at + 6));
      if (j < sn.size()) {
        const char* key = sn[j]["between"] ? "gap" : "position";
        r.fail(sn[j][key], "stops[" + std::to_string(j) + "]." + key,
               msg + "; the initial state defaults to rest at x = 0 (set initial.x)");
      }
    }
    r.fail(root, "initial.x", msg);
  }

  // --- record ---
  RecordSpec rec;
  YAML::Node sample_times_node;  // record.samples.times, checked against the run's span below
  if (const YAML::Node rn = root["record"]) {
    r.expect_map(rn, "record", {"events", "contacts", "statistics", "poincare", "samples"});
    if (rn["events"]) rec.events = r.boolean(rn["events"], "record.events");
    if (rn["contacts"]) rec.contacts = r.boolean(rn["contacts"], "record.contacts");
    if (rn["statistics"]) rec.statistics = r.boolean(rn["statistics"], "record.statistics");
    if (rn["poincare"]) rec.poincare = r.boolean(rn["poincare"], "record.poincare");
    if (const YAML::Node sm = rn["samples"]) {
      r.expect_map(sm, "record.samples", {"per_period", "times"});
      if (sm["per_period"] && sm["times"]) r.fail(sm, "record.samples", "give either per_period or times, not both");
      if (sm["per_period"]) rec.samples_per_period = static_cast<int>(r.integer(sm["per_period"], "record.samples.per_period", 1, 1000000));
      if (sm["times"]) {
        sample_times_node = sm["times"];
        rec.sample_times = r.numbers(sm["times"], "record.samples.times", -1, "times from the start of recording");
        for (std::size_t i = 0; i < rec.sample_times.size(); ++i)
          if (rec.sample_times[i] < 0.0)
            r.fail(sm["times"][i], "record.samples.times[" + std::to_string(i) + "]",
                   "expected a time ≥ 0 (from the start of recording), found " + sm["times"][i].Scalar());
        if (!std::is_sorted(rec.sample_times.begin(), rec.sample_times.end()))
          r.fail(sm["times"], "record.samples.times", "expected times in increasing order");
      }
    }
    for (const char* key : {"statistics", "poincare"})
      if (rn[key] && r.boolean(rn[key], std::string("record.") + key) && !(f.frequency > 0.0))
        r.fail(rn[key], std::string("record.") + key,
               "per-period statistics and Poincaré points need a forcing frequency > 0 (forcing.frequency)");
  }

  // --- run ---
  RunSpec run;
  // One varied value: `path` and exactly one of linspace, logspace, values (sweeps and locate).
  auto parse_axis = [&](const YAML::Node& p, const std::string& path, const std::vector<SweepAxis>& others,
                        std::vector<std::string> keys) {
    keys.insert(keys.end(), {"path", "linspace", "logspace", "values"});
    r.expect_map(p, path, keys);
    if (!p["path"]) r.fail(p, path + ".path", "missing: the scene value to vary, e.g. forcing.frequency");
    SweepAxis axis;
    axis.path = r.text(p["path"], path + ".path");
    for (const SweepAxis& other : others)
      if (other.path == axis.path) r.fail(p["path"], path + ".path", "'" + axis.path + "' is swept twice");
    if (axis.path.rfind("run.", 0) == 0) r.fail(p["path"], path + ".path", "the run section cannot be swept");
    try {
      (void)get(axis.path);
    } catch (const SceneError& e) {
      r.fail(p["path"], path + ".path", "'" + axis.path + "' does not name a number in this scene: " + e.problem());
    }
    const int given = (p["linspace"] ? 1 : 0) + (p["logspace"] ? 1 : 0) + (p["values"] ? 1 : 0);
    if (given != 1) r.fail(p, path, "give exactly one of linspace, logspace, values");
    if (p["values"]) {
      axis.values = r.numbers(p["values"], path + ".values", -1, "the values to visit");
      if (axis.values.empty()) r.fail(p["values"], path + ".values", "expected at least one value");
    } else {
      const bool lg = static_cast<bool>(p["logspace"]);
      const std::string key = lg ? "logspace" : "linspace";
      const auto spec = r.numbers(p[key], path + "." + key, 3, "start, stop, count");
      axis.values = spaced(spec, lg, r, p[key], path + "." + key);
    }
    return axis;
  };
  // Every value must make a valid scene: find out now, at the value, not mid-run. Each value's
  // engine is kept to check, once this scene's is resolved, that the whole grid runs on one.
  struct PointEngine {
    YAML::Node at;
    std::string path, what;
    EngineKind engine;
  };
  std::vector<PointEngine> point_engines;
  // Continuation's parameters with their place and dD/dp (checked against the engine below).
  struct ContinuationPath {
    YAML::Node at;
    std::string key, path;
    SystemDerivative derivative;
  };
  std::vector<ContinuationPath> continuation_paths;
  auto check_values = [&](const SweepAxis& axis, const YAML::Node& p, const std::string& path) {
    SceneDocument point(*this);  // one copy, its value replaced per point: no re-parse per point
    for (std::size_t i = 0; i < axis.values.size(); ++i) {
      point.set(axis.path, axis.values[i]);
      const bool listed = static_cast<bool>(p["values"]);
      const YAML::Node at = listed ? p["values"][i] : p[p["linspace"] ? "linspace" : "logspace"];
      const std::string where = listed ? path + ".values[" + std::to_string(i) + "]" : path;
      try {
        const Scene built = point.build_checked(false);
        point_engines.push_back({at, where, axis.path + " = " + number_text(axis.values[i]), built.engine});
      } catch (const SceneError& e) {
        r.fail(at, where,
               axis.path + " = " + number_text(axis.values[i]) + " makes the scene invalid: " + e.problem() +
                   " (" + e.path() + ")");
      }
    }
  };
  // Sample times lie in the recorded span run.periods × period (Recording::for_scene): checked as
  // soon as run.periods is known — before the sweep values, so that times outside every point's
  // span are reported as such — and a sweep checks it at each value (build_checked per value).
  auto check_sample_times = [&] {
    if ((run.kind != RunSpec::Kind::simulate && run.kind != RunSpec::Kind::sweep) || !sample_times_node) return;
    const double span = run.periods * (f.frequency > 0.0 ? 2.0 * std::numbers::pi / f.frequency : 1.0);
    for (std::size_t i = 0; i < rec.sample_times.size(); ++i)
      if (!(rec.sample_times[i] <= span))
        r.fail(sample_times_node[i], "record.samples.times[" + std::to_string(i) + "]",
               "must lie in the recorded span [0, " + number_text(span) + "] (run.periods × the forcing period), found " +
                   number_text(rec.sample_times[i]));
  };
  if (const YAML::Node rn = root["run"]) {
    r.expect_map(rn, "run", {"kind", "transient_periods", "periods", "sweep", "locate", "continue", "basin", "diagram", "lyapunov", "orbit"});
    if (rn["kind"]) {
      const std::string kind = r.choice(rn["kind"], "run.kind", {"simulate", "sweep", "locate", "continue", "basin", "diagram", "lyapunov", "orbit"});
      run.kind = kind == "sweep"      ? RunSpec::Kind::sweep
                 : kind == "locate"   ? RunSpec::Kind::locate
                 : kind == "continue" ? RunSpec::Kind::continuation
                 : kind == "basin"    ? RunSpec::Kind::basin
                 : kind == "diagram"  ? RunSpec::Kind::diagram
                 : kind == "lyapunov" ? RunSpec::Kind::lyapunov
                 : kind == "orbit"    ? RunSpec::Kind::orbit
                                      : RunSpec::Kind::simulate;
    }
    if (rn["transient_periods"]) run.transient_periods = r.number_in(rn["transient_periods"], "run.transient_periods", 0, 1e9, "a number of periods ≥ 0");
    if (rn["periods"]) run.periods = r.number_in(rn["periods"], "run.periods", 1e-12, 1e9, "a number of periods > 0");
    check_sample_times();
    const YAML::Node sw = rn["sweep"], lc = rn["locate"], ct = rn["continue"], bs = rn["basin"];
    if (run.kind == RunSpec::Kind::basin && !bs)
      r.fail(rn, "run.basin", "missing: run.kind: basin needs run.basin.parameters (two scene values and their grids)");
    if (run.kind != RunSpec::Kind::basin && bs) r.fail(bs, "run.basin", "only for run.kind: basin");
    const YAML::Node dg = rn["diagram"], ly = rn["lyapunov"];
    if (run.kind == RunSpec::Kind::diagram && !dg)
      r.fail(rn, "run.diagram", "missing: run.kind: diagram needs run.diagram (path and grid)");
    if (run.kind != RunSpec::Kind::diagram && dg) r.fail(dg, "run.diagram", "only for run.kind: diagram");
    if (run.kind != RunSpec::Kind::lyapunov && ly) r.fail(ly, "run.lyapunov", "only for run.kind: lyapunov");
    if (const YAML::Node ob = rn["orbit"]) {
      if (run.kind != RunSpec::Kind::orbit) r.fail(ob, "run.orbit", "only for run.kind: orbit");
      r.expect_map(ob, "run.orbit", {"period", "phase", "tolerance", "max_iterations", "multipliers"});
      OrbitSpec& o = run.orbit;
      if (ob["period"]) o.period = static_cast<int>(r.integer(ob["period"], "run.orbit.period", 1, 1024));
      if (ob["phase"]) o.phase = r.number_in(ob["phase"], "run.orbit.phase", -1e3, 1e3, "a phase in radians");
      if (ob["tolerance"]) o.tolerance = r.number_in(ob["tolerance"], "run.orbit.tolerance", 1e-15, 1e-4, "a relative tolerance in [1e-15, 1e-4]");
      if (ob["max_iterations"]) o.max_iterations = static_cast<int>(r.integer(ob["max_iterations"], "run.orbit.max_iterations", 1, 1000));
      if (ob["multipliers"]) o.multipliers = static_cast<int>(r.integer(ob["multipliers"], "run.orbit.multipliers", 1, 100));
    }
    if (run.kind == RunSpec::Kind::orbit && !(f.frequency > 0.0))
      r.fail(rn["kind"], "run.kind", "a periodic orbit's period is 2π/Ω: it needs a forcing frequency > 0 (forcing.frequency)");
    // A grid along which a run follows its attractor: at least two values, strictly monotonic.
    auto monotonic = [&](const YAML::Node& node, const std::string& path) {
      const auto& v = run.axes[0].values;
      if (v.size() < 2) r.fail(node, path, "expected at least two grid values");
      for (std::size_t i = 1; i < v.size(); ++i)
        if (!((v[i] - v[i - 1]) * (v[1] - v[0]) > 0.0))
          r.fail(node, path, "the grid must be strictly increasing or decreasing (value " + std::to_string(i) + ")");
    };
    if (dg && check_sweep) {
      DiagramSpec& d = run.diagram;
      run.axes.push_back(parse_axis(dg, "run.diagram", {}, {"transient", "points", "directions", "max_period", "tolerance"}));
      monotonic(dg, "run.diagram");
      if (dg["transient"]) d.transient = r.integer(dg["transient"], "run.diagram.transient", 0, 100000000);
      if (dg["points"]) d.points = static_cast<int>(r.integer(dg["points"], "run.diagram.points", 1, 100000));
      if (dg["directions"]) {
        const std::string dir = r.choice(dg["directions"], "run.diagram.directions", {"both", "up", "down"});
        d.up = dir != "down";
        d.down = dir != "up";
      }
      if (dg["max_period"]) d.max_period = static_cast<int>(r.integer(dg["max_period"], "run.diagram.max_period", 1, 50000));
      if (2 * d.max_period > d.points)
        r.fail(dg["max_period"] ? dg["max_period"] : dg, "run.diagram.max_period",
               "expected at most points / 2 = " + std::to_string(d.points / 2) +
                   " (a period k is recognised on 2k recorded points)");
      if (dg["tolerance"]) d.tolerance = r.number_in(dg["tolerance"], "run.diagram.tolerance", 1e-15, 0.1, "a relative tolerance in [1e-15, 0.1]");
      check_values(run.axes[0], dg, "run.diagram");
      if (!(f.frequency > 0.0))
        r.fail(rn["kind"], "run.kind", "a diagram records stroboscopic points: it needs a forcing frequency > 0 (forcing.frequency)");
    }
    if (check_sweep && run.kind == RunSpec::Kind::lyapunov) {
      LyapunovSpec& l = run.lyapunov;
      if (!(f.frequency > 0.0))
        r.fail(rn["kind"], "run.kind", "Lyapunov exponents are averaged over forcing periods: they need a forcing frequency > 0 (forcing.frequency)");
      if (ly) {
        r.expect_map(ly, "run.lyapunov", {"count", "transient", "align", "periods", "follow", "path", "linspace", "logspace", "values"});
        if (ly["count"]) l.count = static_cast<int>(r.integer(ly["count"], "run.lyapunov.count", 0, 2 * static_cast<long>(n)));
        if (ly["transient"]) l.transient = r.integer(ly["transient"], "run.lyapunov.transient", 0, 100000000);
        if (ly["align"]) l.align = r.integer(ly["align"], "run.lyapunov.align", 0, 100000000);
        if (ly["periods"]) l.periods = r.integer(ly["periods"], "run.lyapunov.periods", 1, 100000000);
        if (ly["path"] || ly["linspace"] || ly["logspace"] || ly["values"]) {
          run.axes.push_back(parse_axis(ly, "run.lyapunov", {}, {"count", "transient", "align", "periods", "follow"}));
          monotonic(ly, "run.lyapunov");
          check_values(run.axes[0], ly, "run.lyapunov");
          l.along = true;
        }
        if (ly["follow"]) {
          l.follow = r.boolean(ly["follow"], "run.lyapunov.follow");
          if (!l.along) r.fail(ly["follow"], "run.lyapunov.follow", "only with a grid (run.lyapunov.path and its values)");
        }
      }
    }
    if (bs && check_sweep) {
      BasinSpec& b = run.basin;
      r.expect_map(bs, "run.basin", {"parameters", "max_period", "max_periods", "tolerance", "match", "seed_stride"});
      const YAML::Node ps = bs["parameters"];
      if (!ps || !ps.IsSequence() || ps.size() != 2)
        r.fail(ps ? ps : bs, "run.basin.parameters",
               "expected a list of two parameters (the image's rows and columns), found " + (ps ? describe(ps) : std::string("nothing")));
      for (std::size_t a = 0; a < 2; ++a)
        run.axes.push_back(parse_axis(ps[a], "run.basin.parameters[" + std::to_string(a) + "]", run.axes, {}));
      if (bs["max_period"]) b.max_period = static_cast<int>(r.integer(bs["max_period"], "run.basin.max_period", 1, 64));
      if (bs["max_periods"]) b.max_periods = r.integer(bs["max_periods"], "run.basin.max_periods", 2, 100000000);
      if (b.max_periods < b.max_period + 1)
        r.fail(bs["max_periods"] ? bs["max_periods"] : bs, "run.basin.max_periods",
               "expected at least max_period + 1 = " + std::to_string(b.max_period + 1) +
                   " periods (a period-k orbit is recognised after k + 1)");
      if (bs["tolerance"]) b.tolerance = r.number_in(bs["tolerance"], "run.basin.tolerance", 1e-15, 1e-2, "a relative tolerance in [1e-15, 1e-2]");
      if (bs["match"]) b.match = r.number_in(bs["match"], "run.basin.match", 1e-15, 1e-1, "a relative distance in [1e-15, 0.1]");
      if (b.match < b.tolerance)
        r.fail(bs["match"] ? bs["match"] : bs, "run.basin.match",
               "must not be below run.basin.tolerance (" +
                   (bs["tolerance"] ? bs["tolerance"].Scalar() : number_text(b.tolerance)) +
                   "): a run that repeats within the tolerance must also match its attractor");
      if (bs["seed_stride"]) b.seed_stride = static_cast<int>(r.integer(bs["seed_stride"], "run.basin.seed_stride", 1, 1000000));
      for (std::size_t a = 0; a < 2; ++a)
        check_values(run.axes[a], ps[a], "run.basin.parameters[" + std::to_string(a) + "]");
      if (!(f.frequency > 0.0))
        r.fail(rn["kind"], "run.kind", "a basin compares stroboscopic points: it needs a forcing frequency > 0 (forcing.frequency)");
    }
    if (run.kind == RunSpec::Kind::continuation && !ct)
      r.fail(rn, "run.continue", "missing: run.kind: continue needs run.continue (path and range)");
    if (run.kind != RunSpec::Kind::continuation && ct) r.fail(ct, "run.continue", "only for run.kind: continue");
    if (run.kind == RunSpec::Kind::sweep && !sw) r.fail(rn, "run.sweep", "missing: a sweep needs run.sweep.parameters");
    if (run.kind != RunSpec::Kind::sweep && sw) r.fail(sw, "run.sweep", "only for run.kind: sweep");
    if (run.kind == RunSpec::Kind::locate && !lc) r.fail(rn, "run.locate", "missing: run.kind: locate needs run.locate (path and grid)");
    if (run.kind != RunSpec::Kind::locate && lc) r.fail(lc, "run.locate", "only for run.kind: locate");
    if (sw && check_sweep) {
      r.expect_map(sw, "run.sweep", {"parameters", "follow", "reverse"});
      if (sw["follow"]) run.follow = r.boolean(sw["follow"], "run.sweep.follow");
      if (sw["reverse"]) run.reverse = r.boolean(sw["reverse"], "run.sweep.reverse");
      const YAML::Node ps = sw["parameters"];
      if (!ps || !ps.IsSequence() || ps.size() == 0 || ps.size() > 2)
        r.fail(ps ? ps : sw, "run.sweep.parameters", "expected a list of one or two parameters, found " + (ps ? describe(ps) : std::string("nothing")));
      for (std::size_t a = 0; a < ps.size(); ++a)
        run.axes.push_back(parse_axis(ps[a], "run.sweep.parameters[" + std::to_string(a) + "]", run.axes, {}));
      for (std::size_t a = 0; a < run.axes.size(); ++a)
        check_values(run.axes[a], ps[a], "run.sweep.parameters[" + std::to_string(a) + "]");
    }
    if (lc && check_sweep) {
      LocateSpec& l = run.locate;
      run.axes.push_back(parse_axis(lc, "run.locate", {}, {"tolerance", "periodicity", "max_period", "max_periods", "jump"}));
      if (run.axes[0].values.size() < 2) r.fail(lc, "run.locate", "expected at least two grid values to scan between");
      for (std::size_t i = 1; i < run.axes[0].values.size(); ++i) {
        const auto& v = run.axes[0].values;
        if ((v[i] - v[i - 1]) * (v[1] - v[0]) <= 0.0)
          r.fail(lc, "run.locate", "the grid must be strictly increasing or decreasing (value " + std::to_string(i) + ")");
      }
      if (lc["tolerance"]) l.tolerance = r.number_in(lc["tolerance"], "run.locate.tolerance", 1e-15, 1e300, "a bracket width > 0 in the parameter's units");
      if (lc["periodicity"]) l.periodicity = r.number_in(lc["periodicity"], "run.locate.periodicity", 1e-15, 1e-2, "a relative tolerance in [1e-15, 1e-2]");
      if (lc["max_period"]) l.max_period = static_cast<int>(r.integer(lc["max_period"], "run.locate.max_period", 1, 64));
      if (lc["max_periods"]) l.max_periods = r.integer(lc["max_periods"], "run.locate.max_periods", 2, 100000000);
      // The first orbit is searched after the transient, each for up to max_period periods:
      // a budget below that would have to be raised behind the user's back (bifurcation.cpp).
      const long needed = static_cast<long>(std::ceil(run.transient_periods)) + l.max_period + 1;
      if (l.max_periods < needed)
        r.fail(lc["max_periods"] ? lc["max_periods"] : lc, "run.locate.max_periods",
               "expected at least " + std::to_string(needed) + " periods (run.transient_periods " +
                   number_text(run.transient_periods) + " + max_period " + std::to_string(l.max_period) +
                   " + 1: the first orbit is tested after the transient), found " + std::to_string(l.max_periods));
      if (lc["jump"]) l.jump = r.number_in(lc["jump"], "run.locate.jump", 0, 1, "a fraction of the period in [0, 1] (0: no jump search)");
      check_values(run.axes[0], lc, "run.locate");
    }
    if (ct && check_sweep) {
      ContinueSpec& c = run.continuation;
      r.expect_map(ct, "run.continue", {"path", "range", "direction", "period", "phase", "step", "min_step", "max_step",
                                        "max_points", "tolerance", "locate", "locate_tolerance", "max_doublings", "curve"});
      // A continuation parameter: a number the file sets, outside `run` (and, below, one that
      // moves the system: continuation.cpp checks that through the parameter's derivative).
      auto parameter = [&](const YAML::Node& node, const std::string& path) {
        if (!node) r.fail(ct, path, "missing: the scene value to continue in, e.g. forcing.frequency");
        const std::string text = r.text(node, path);
        if (text.rfind("run.", 0) == 0) r.fail(node, path, "the run section cannot be a parameter");
        try {
          (void)get(text);
        } catch (const SceneError& e) {
          r.fail(node, path, "'" + text + "' does not name a number in this scene: " + e.problem());
        }
        return text;
      };
      auto range = [&](const YAML::Node& node, const std::string& path, double& lo, double& hi, double value) {
        if (!node) r.fail(ct, path, "missing: [min, max], the limits of the parameter");
        const std::vector<double> v = r.numbers(node, path, 2, "min, max");
        if (!(v[0] < v[1])) r.fail(node, path, "expected min < max, found [" + number_text(v[0]) + ", " + number_text(v[1]) + "]");
        if (!(value >= v[0] && value <= v[1]))
          r.fail(node, path, "the scene's value " + number_text(value) + " lies outside [" + number_text(v[0]) + ", " +
                                 number_text(v[1]) + "]: the branch starts there");
        lo = v[0];
        hi = v[1];
      };
      // The parameter must move the system, linearly or in closed form (io/continuation.hpp).
      // Kept, with their place, for the engine's check below (what the modal engine differentiates).
      auto moves = [&](const YAML::Node& node, const std::string& key, const std::string& path) {
        try {
          continuation_paths.push_back({node, key, path, parameter_derivative(*this, path)});
        } catch (const SceneError& e) {
          r.fail(node, key, "'" + path + "' " + e.problem());
        }
      };
      c.path = parameter(ct["path"], "run.continue.path");
      moves(ct["path"], "run.continue.path", c.path);
      range(ct["range"], "run.continue.range", c.p_min, c.p_max, get(c.path));
      if (ct["direction"]) c.direction = r.choice(ct["direction"], "run.continue.direction", {"up", "down"}) == "up" ? 1 : -1;
      if (ct["period"]) c.period = static_cast<int>(r.integer(ct["period"], "run.continue.period", 1, 1024));
      if (ct["phase"]) c.phase = r.number_in(ct["phase"], "run.continue.phase", -1e3, 1e3, "a phase in radians");
      if (ct["step"]) c.step = r.number_in(ct["step"], "run.continue.step", 1e-12, 1.0, "a step in (0, 1] (scaled arclength)");
      if (ct["min_step"]) c.min_step = r.number_in(ct["min_step"], "run.continue.min_step", 1e-15, 1.0, "a step in (0, 1]");
      if (ct["max_step"]) c.max_step = r.number_in(ct["max_step"], "run.continue.max_step", 1e-12, 1.0, "a step in (0, 1]");
      if (c.min_step > c.max_step) r.fail(ct, "run.continue.min_step", "must not exceed run.continue.max_step");
      if (ct["max_points"]) c.max_points = static_cast<int>(r.integer(ct["max_points"], "run.continue.max_points", 2, 1000000));
      if (ct["tolerance"]) c.tolerance = r.number_in(ct["tolerance"], "run.continue.tolerance", 1e-15, 1e-4, "a relative tolerance in [1e-15, 1e-4]");
      if (ct["locate"]) c.locate = r.boolean(ct["locate"], "run.continue.locate");
      if (ct["locate_tolerance"]) c.locate_tolerance = r.number_in(ct["locate_tolerance"], "run.continue.locate_tolerance", 1e-15, 1e300, "a width > 0 in the parameter's units");
      if (ct["max_doublings"]) c.max_doublings = static_cast<int>(r.integer(ct["max_doublings"], "run.continue.max_doublings", 0, 8));
      if (const YAML::Node cv = ct["curve"]) {
        r.expect_map(cv, "run.continue.curve", {"path", "range", "step", "max_points", "kinds"});
        c.curve_path = parameter(cv["path"], "run.continue.curve.path");
        if (c.curve_path == c.path) r.fail(cv["path"], "run.continue.curve.path", "must differ from run.continue.path");
        moves(cv["path"], "run.continue.curve.path", c.curve_path);
        range(cv["range"], "run.continue.curve.range", c.curve_min, c.curve_max, get(c.curve_path));
        if (cv["step"]) c.curve_step = r.number_in(cv["step"], "run.continue.curve.step", 1e-9, 1.0, "a step in (0, 1] (scaled)");
        if (cv["max_points"]) c.curve_max_points = static_cast<int>(r.integer(cv["max_points"], "run.continue.curve.max_points", 2, 100000));
        if (const YAML::Node k = cv["kinds"]) {
          if (!k.IsSequence() || k.size() == 0) r.fail(k, "run.continue.curve.kinds", "expected a list of grazing and/or rising");
          c.curve_kinds.clear();
          for (std::size_t i = 0; i < k.size(); ++i)
            c.curve_kinds.push_back(r.choice(k[i], "run.continue.curve.kinds[" + std::to_string(i) + "]", {"grazing", "rising"}));
        }
      }
    }
  }

  check_sample_times();  // (with the default run.periods when there is no run section)

  // --- engine (docs/scenes.md, solver.engine) ---
  // The modal engine also needs a stiffness matrix without rigid-body modes (ChainModes refuses
  // them): every mass tied to a wall through springs > 0. Checked on the links in O(n).
  std::string floating;  // a group of masses no spring ties to a wall, if any
  if (chain_links) {
    const models::Chain& c = *chain_links;
    long first = 0;
    bool walled = c.left_spring > 0.0;
    for (long i = 0; i < n; ++i) {
      const bool last = i == n - 1 || !(c.springs[static_cast<std::size_t>(i)] > 0.0);
      if (i == n - 1) walled = walled || c.right_spring > 0.0;
      if (!last) continue;
      if (!walled && floating.empty())
        floating = first == i ? "mass " + std::to_string(i) : "masses " + std::to_string(first) + "…" + std::to_string(i);
      first = i + 1;
      walled = false;
    }
  }
  EngineKind engine = EngineKind::dense;
  std::string reason;
  const YAML::Node engine_node = root["solver"] ? root["solver"]["engine"] : YAML::Node();
  if (engine_choice == EngineChoice::modal) {
    auto refuse = [&](const std::string& why) {
      r.fail(engine_node, "solver.engine", "the modal engine cannot run this scene: " + why +
                                               " (use solver.engine: dense or auto)");
    };
    if (!chain_links) refuse("it needs model.chain (M diagonal, K tridiagonal), this scene gives model.matrices");
    if (!banded) refuse(not_banded);
    if (!floating.empty()) refuse(floating + " tied to no wall by springs: a rigid-body mode (give the chain a wall spring)");
    engine = EngineKind::modal;
    reason = "solver.engine: modal";
  } else if (engine_choice == EngineChoice::dense) {
    reason = "solver.engine: dense";
  } else if (!chain_links) {
    reason = "auto: model.matrices (the modal engine needs model.chain)";
  } else if (!banded) {
    reason = "auto: the chain's damping is not proportional (" + not_banded + ")";
  } else if (!floating.empty()) {
    reason = "auto: " + floating + " tied to no wall (a rigid-body mode; the modal engine needs none)";
  } else if (n < kModalAutomaticMinimumDof) {
    reason = "auto: " + std::to_string(n) + " masses (< " + std::to_string(kModalAutomaticMinimumDof) +
             ": the dense engine is cheap and handles every contact set)";
  } else {
    engine = EngineKind::modal;
    reason = "auto: a proportionally damped chain of " + std::to_string(n) + " masses (≥ " +
             std::to_string(kModalAutomaticMinimumDof) + ")";
  }

  // Continuation on the modal engine differentiates along Ω, the forcing and the stops' data only:
  // a path that moves M, C or K moves the chain's modes (analysis/modal_tangent.hpp).
  if (run.kind == RunSpec::Kind::continuation && engine == EngineKind::modal)
    for (const ContinuationPath& c : continuation_paths) {
      std::vector<std::string> moved;
      const SystemDerivative& d = c.derivative;
      for (const auto& [m, name] : {std::pair{&d.mass, "mass"}, {&d.damping, "damping"}, {&d.stiffness, "stiffness"}})
        if (m->size() > 0 && !m->isZero(0.0)) moved.emplace_back(name);
      if (moved.empty()) continue;
      std::string list = moved.front();
      for (std::size_t i = 1; i < moved.size(); ++i) list += (i + 1 == moved.size() ? " and " : ", ") + moved[i];
      r.fail(c.at, c.key,
             "'" + c.path + "' moves the " + list + (moved.size() > 1 ? " matrices" : " matrix") + ", and this scene resolves to the modal engine (" + reason +
                 "), whose continuation differentiates only along the forcing frequency, the forcing and the stops' "
                 "data (M, C and K fix its modes): set solver.engine: dense, or continue in one of those");
    }
  for (const PointEngine& p : point_engines)
    if (p.engine != engine)
      r.fail(p.at, p.path, p.what + " runs with the " + to_string(p.engine) + " engine, the base scene with the " +
                               to_string(engine) + " engine (" + reason + "): one run uses one engine; " +
                               "set solver.engine to dense or modal");

  Scene scene{impl_->file, impl_->text,
              root["name"] ? r.text(root["name"], "name") : std::string(),
              std::move(dense), std::move(banded), std::move(stops), t0, x0, v0, opt, rec, run,
              engine_choice, engine, reason};
  return scene;
}

}  // namespace vibro::io
