#include "vibro/io/scene.hpp"

#include "restart.hpp"
#include "scene_reader.hpp"
#include "scene_sections.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/friction_stops.hpp"
#include "vibro/io/resources.hpp"
#include "vibro/io/run_kinds.hpp"

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

using namespace detail;

namespace {

/// Modal chains of at least this many masses set up their modes under run_bounded (make_engine).
constexpr Eigen::Index kBoundedModalFromMasses = 256;

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
    // The modal engine's set-up — the modes of the chain, one LAPACK call that nothing can poll
    // (seconds from a few thousand masses on) — runs under run_bounded with the run's interrupt
    // flag for long chains, as a dense contact set's flow does (bounded_wait.hpp): raising the
    // flag throws Interrupted within 10 ms. The same construction: the same bits.
    const bool long_chain = scene.chain->dof() >= kBoundedModalFromMasses;
    return run_bounded(long_chain ? scene.solver.interrupt : nullptr,
                       [chain = *scene.chain, stops = scene.stops,
                        options = modal_options(scene.solver)]() -> std::unique_ptr<vibro::Engine> {
                         return std::make_unique<ModalEngine>(chain, stops, options);
                       });
  }
  if (scene.engine == EngineKind::taylor) return std::make_unique<TaylorEngine>(scene.impact_system(), scene.forces, scene.solver);
  if (!scene.friction.empty() && !scene.stops.empty())
    return std::make_unique<FrictionStopEngine>(scene.impact_system(), scene.friction, scene.solver);
  if (!scene.friction.empty()) return std::make_unique<FrictionEngine>(scene.system(), scene.friction, scene.solver);
  return std::make_unique<DenseEngine>(scene.impact_system(), scene.solver);
}

const char* to_string(EngineKind engine) {
  switch (engine) {
    case EngineKind::dense: return "dense";
    case EngineKind::modal: return "modal";
    case EngineKind::taylor: return "taylor";
  }
  return "?";
}

const char* to_string(EngineChoice choice) {
  switch (choice) {
    case EngineChoice::automatic: return "auto";
    case EngineChoice::dense: return "dense";
    case EngineChoice::modal: return "modal";
    case EngineChoice::taylor: return "taylor";
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
  std::string restart;  // where initial.from took the state from ("" without it)
};

SceneDocument::SceneDocument() : impl_(std::make_unique<Impl>()) {}
SceneDocument::~SceneDocument() = default;
// A copy re-parses the text and replays the edits: YAML::Clone would lose the source positions
// that every error message needs.
SceneDocument::SceneDocument(const SceneDocument& o) : impl_(std::make_unique<Impl>()) { *this = o; }
SceneDocument& SceneDocument::operator=(const SceneDocument& o) {
  if (this != &o) {
    // The text alone: the edits replay what the original's restart (initial.from) did.
    SceneDocument fresh = parse_text(o.impl_->text, o.impl_->file);
    for (const Impl::Edit& e : o.impl_->edits) e.number ? fresh.set(e.path, *e.number) : fresh.replace(e.path, e.yaml);
    fresh.impl_->restart = o.impl_->restart;
    std::swap(impl_, fresh.impl_);
  }
  return *this;
}

const std::string& SceneDocument::file() const { return impl_->file; }
const std::string& SceneDocument::text() const { return impl_->text; }
const std::string& SceneDocument::restart() const { return impl_->restart; }

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
  SceneDocument doc = parse_text(text, file);
  // initial.from: the scene put on a saved orbit (restart.hpp), as edits a copy replays.
  const YAML::Node& root = doc.impl_->root;
  if (const YAML::Node initial = root["initial"]; initial && initial.IsMap() && initial["from"]) {
    const detail::RestartPoint point = detail::read_restart(initial["from"], file);
    detail::apply_restart(doc, root, point);
    doc.impl_->restart = point.source;
  }
  return doc;
}

SceneDocument SceneDocument::parse_text(const std::string& text, const std::string& file) {
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

/// `run`: its common keys, then the section of its kind (the table of run_kinds.hpp).
void detail::read_run(Reader& r, const YAML::Node& root, SceneParts& p) {
  auto& n = p.n;
  auto& f = p.f;
  auto& run = p.run;
  auto& point_engines = p.point_engines;
  auto& engine_checks = p.engine_checks;
  // --- run: its common keys, then the section of its kind (run_kinds.hpp) ---
  if (const YAML::Node rn = root["run"]) {
    std::vector<std::string> keys{"kind", "transient_periods", "periods"}, names;
    for (const RunKindInfo& k : run_kinds()) {
      names.emplace_back(k.name);
      if (k.section) keys.emplace_back(k.section);
    }
    r.expect_map(rn, "run", keys);
    if (rn["kind"]) run.kind = find_run_kind(r.choice(rn["kind"], "run.kind", names))->kind;
    if (rn["transient_periods"]) run.transient_periods = r.number_in(rn["transient_periods"], "run.transient_periods", 0, 1e9, "a number of periods ≥ 0");
    if (rn["periods"]) run.periods = r.number_in(rn["periods"], "run.periods", 1e-12, 1e9, "a number of periods > 0");
    // Each kind's section: required where the kind says so, refused under any other kind.
    for (const RunKindInfo& k : run_kinds()) {
      if (!k.section) continue;
      const std::string path = std::string("run.") + k.section;
      const YAML::Node node = rn[k.section];
      if (k.kind == run.kind && k.missing && !node) r.fail(rn, path, k.missing);
      if (k.kind != run.kind && node) r.fail(node, path, std::string("only for run.kind: ") + k.name);
    }
    check_sample_times(r, root, p);
    const RunKindInfo& kind = run_kind(run.kind);
    if (kind.parse) {
      RunSection section{r, *p.doc, rn, kind.section ? rn[kind.section] : YAML::Node(), run, n, f.frequency,
                         p.full, point_engines, engine_checks};
      kind.parse(section);
    }
  }
}

Scene SceneDocument::build_checked(bool check_sweep) const {
  Reader r(impl_->file, impl_->overrides);
  const YAML::Node& root = impl_->root;
  r.expect_map(root, "", {"name", "model", "forcing", "base", "stops", "friction", "initial", "solver", "record", "run",
                          "parameters", "forces"});
  SceneParts p;
  p.doc = this;
  p.full = check_sweep;
  read_model(r, root, p);
  read_forcing(r, root, p);
  read_stops(r, root, p);
  read_friction(r, root, p);
  read_initial(r, root, p);
  read_solver(r, root, p);
  check_initial_state(r, root, p);
  read_forces(r, root, p);
  read_record(r, root, p);
  check_result_frame(r, root, p);  // (before the run section, whose checks may build the scene)
  read_run(r, root, p);
  check_sample_times(r, root, p);  // (with the default run.periods when there is no run section)
  resolve_engine(r, root, p);
  check_friction(r, root, p);
  Scene scene{impl_->file, impl_->text, root["name"] ? r.text(root["name"], "name") : std::string(),
              std::move(p.dense), std::move(p.banded), std::move(p.stops), p.t0, p.x0, p.v0, p.opt, p.rec, p.run,
              p.engine_choice, p.engine, p.reason, std::move(p.base), std::move(p.forces), std::move(p.friction),
              impl_->restart};
  return scene;
}

}  // namespace vibro::io
