#pragma once
/// \file scene.hpp
/// Scene files: YAML in, a validated plain description out. This is the io layer: the core
/// (framework/include/vibro) knows nothing of YAML.
///
/// A scene holds the model (a chain builder or explicit M, C, K), the forcing, the stops, the
/// initial state, the solver settings, what to record, and the run (simulate or sweep). Every key
/// is documented in docs/scenes.md. Every numeric value is addressable by a path into the YAML
/// tree — `forcing.frequency`, `stops[1].position`, `model.chain.masses[3]` — which is how
/// `--set PATH=VALUE` and sweeps change a scene: they edit the tree and the scene is rebuilt from
/// it, so nothing can be changed that the file could not have said.
///
/// Errors: every malformed scene raises SceneError with `file:line:column: key.path: expected
/// …, found …` (unknown keys add "did you mean …"); the command turns it into exit code 2.
///
/// Usage:
///     vibro::io::SceneDocument doc = vibro::io::SceneDocument::load("experiments/x.yaml");
///     doc.set("forcing.frequency", 0.26);          // --set
///     vibro::io::Scene scene = doc.build();         // validated; throws SceneError
///     vibro::ImpactSystem system = scene.impact_system();   // dense engine
///     if (scene.engine == vibro::io::EngineKind::modal) vibro::ChainModes modes(*scene.chain);
///
/// Long chains. A `model.chain` scene keeps its chain in banded form (Scene::chain, O(n)) and
/// builds the dense n × n system only when something asks for it (Scene::system(), cached):
/// a scene that resolves to the modal engine (solver.engine, docs/scenes.md) is loaded, checked
/// and run without any n × n matrix. Its stops and initial state are checked in O(n + m log m).
#include "vibro/base_motion.hpp"
#include "vibro/engine.hpp"
#include "vibro/taylor_simulator.hpp"
#include "vibro/friction.hpp"
#include "vibro/modal.hpp"
#include "vibro/section.hpp"
#include "vibro/simulator.hpp"

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro::io {

/// A malformed scene. what() is the full message: "file:line:col: path: problem".
class SceneError : public std::runtime_error {
 public:
  SceneError(std::string file, int line, int column, std::string path, std::string problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  int column() const { return column_; }
  const std::string& path() const { return path_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string file_;
  int line_, column_;
  std::string path_, problem_;
};

/// record.section: a hyperplane nᵀx = c in the positions and the direction of the crossings
/// recorded (vibro/section.hpp).
struct SectionSpec {
  Hyperplane plane;
  Section::Direction direction = Section::Direction::both;
};

/// What a run records (each observer exists only if asked for).
struct RecordSpec {
  bool events = false;
  bool contacts = false;
  bool statistics = false;
  bool poincare = false;
  bool impact_map = false;             ///< the state before every impact (ImpactMap)
  std::optional<SectionSpec> section;  ///< crossings of a hyperplane (Section)
  int samples_per_period = 0;          ///< exact samples, evenly spaced in each recorded period
  std::vector<double> sample_times;    ///< or explicit times (relative to the recording start)
  /// `record.frame`: the frame a base-excited scene's states are written in (result_frame.hpp);
  /// defaults to base.frame (and is absolute, and unused, without a base).
  BaseFrame frame = BaseFrame::absolute;
};

/// One swept parameter: a path into the scene and its values.
struct SweepAxis {
  std::string path;
  std::vector<double> values;
};

/// run.kind: locate — bifurcations of periodic orbits along one parameter (vibro/running_locate.hpp).
struct LocateSpec {
  double tolerance = 1e-8;     ///< final bracket width of each located transition
  double periodicity = 1e-10;  ///< |z(t + kT) − z(t)| relative to L and V
  int max_period = 8;          ///< k looked for
  long max_periods = 2000;     ///< forcing periods per orbit search, at most
  double jump = 0.02;          ///< sticking-fraction change searched for a jump (0: none)
};

/// run.kind: continue — branches of periodic orbits followed in one parameter by pseudo-arclength
/// continuation, their stability and bifurcations (vibro/continuation.hpp), and optionally the
/// located grazing and rising points followed in a second parameter.
struct ContinueSpec {
  std::string path;                   ///< the parameter (a --set path)
  double p_min = 0.0, p_max = 0.0;    ///< `range`
  int direction = 1;                  ///< first direction: +1 up, −1 down
  int period = 1;                     ///< k
  double phase = 0.0;                 ///< section phase θ, radians
  double step = 0.01, min_step = 1e-7, max_step = 0.05;
  double parameter_scale = 0.0;       ///< P, the parameter's scale in the steps (0: p_max − p_min)
  int max_points = 400;
  double tolerance = 1e-11;
  bool locate = true;
  double locate_tolerance = 1e-10;
  int max_doublings = 3;
  int max_branches = 64;           ///< the run's budget: branches
  long max_total_points = 40000;   ///< the run's budget: points over all branches
  bool switch_at_start = false;    ///< `switch: period_doubling`: only the doubled branch from the start
  /// run.continue.curve: a second parameter for the located grazing and rising points.
  std::string curve_path;             ///< empty: no curves
  double curve_min = 0.0, curve_max = 0.0;
  double curve_step = 0.02;
  int curve_max_points = 50;
  std::vector<std::string> curve_kinds{"grazing", "rising"};
};

/// run.kind: basin — basins of attraction over a 2-D grid of two scene values (usually initial
/// state components), each run stopped as soon as it has converged (vibro/io/kinds/basin.hpp).
struct BasinSpec {
  int max_period = 8;        ///< periods kT looked for: k = 1 … max_period
  long max_periods = 1000;   ///< forcing periods per grid point, at most ("not converged" after)
  double tolerance = 1e-8;   ///< |z_n − z_{n−k}| (relative to L and V) that makes a new attractor
  double match = 1e-5;       ///< |z_n − a_j| that puts a run on a known attractor's point a_j
  int seed_stride = 16;      ///< every seed_stride-th point of both axes runs first (the seeds)
};

/// run.kind: diagram — a brute-force bifurcation diagram: the attractor followed along one
/// parameter up and/or down, its stroboscopic points, period and impacts (vibro/io/kinds/diagram.hpp).
struct DiagramSpec {
  long transient = 100;        ///< periods run at every point after the first (from the previous end)
  int points = 32;             ///< P: stroboscopic points recorded per grid point
  bool up = true, down = true; ///< directions: increasing, decreasing parameter
  int max_period = 16;         ///< least period k looked for among the P points (2k ≤ P)
  double tolerance = 1e-6;     ///< |z_i − z_{i−k}| relative to L, V for every recorded i
  long settle = 1000;          ///< extra periods at most, in blocks of P, while not periodic and converging
};

/// run.kind: lyapunov — the Lyapunov spectrum (vibro/lyapunov.hpp) at the scene's values or
/// along a parameter, each point from the previous one's end (vibro/io/kinds/lyapunov.hpp).
struct LyapunovSpec {
  int count = 0;           ///< the p largest exponents; 0: all 2n
  long transient = 100;    ///< periods before each point's frame starts (first point: also run.transient_periods)
  long align = 50;         ///< periods the frame turns onto the leading directions
  long periods = 1000;     ///< periods averaged
  bool along = false;      ///< a parameter grid is given (run.axes[0])
  bool follow = true;      ///< along a grid: each point from the previous one's end (else from initial, in parallel)
};

/// run.kind: orbit — one periodic orbit by Newton shooting from the state after
/// run.transient_periods (vibro/shooting.hpp), with its Floquet multipliers; on the modal engine
/// by Newton–Krylov with the leading multipliers by Arnoldi.
struct OrbitSpec {
  int period = 1;              ///< k: the orbit repeats after kT
  double phase = 0.0;          ///< section phase θ, radians
  double tolerance = 1e-11;    ///< max(|Δx|∞/L, |Δv|∞/V)
  int max_iterations = 40;
  int multipliers = 6;         ///< modal engine: the leading ones (dense: all 2n)
};

struct RunSpec {
  enum class Kind { simulate, sweep, locate, continuation, basin, diagram, lyapunov, orbit };
  Kind kind = Kind::simulate;
  double transient_periods = 0.0;  ///< simulated, not recorded
  double periods = 1.0;            ///< recorded forcing periods (or time units when Ω = 0)
  /// Sweep: one axis (1-D) or two (2-D grid, the second varying fastest). Locate: one axis.
  std::vector<SweepAxis> axes;
  LocateSpec locate;
  ContinueSpec continuation;  ///< run.kind: continue
  BasinSpec basin;            ///< run.kind: basin (its two axes are `axes`)
  DiagramSpec diagram;        ///< run.kind: diagram (its axis is axes[0])
  LyapunovSpec lyapunov;      ///< run.kind: lyapunov (a grid, if any, is axes[0])
  OrbitSpec orbit;            ///< run.kind: orbit
  bool follow = false;   ///< each point starts from the previous point's final state
  bool reverse = false;  ///< walk the grid from its last point to its first
};

/// The run kind as the scene file spells it ("simulate", "sweep", "locate", "continue", "basin", "orbit",
/// "diagram", "lyapunov").
const char* to_string(RunSpec::Kind kind);

/// The engine that runs a scene: the dense Simulator (any M, C, K) or the modal chain engine
/// (vibro/modal.hpp: M diagonal, K tridiagonal, C = αM + βK; O(n) per event), or the Taylor
/// engine (vibro/taylor_simulator.hpp) for a scene with nonlinear forces.
enum class EngineKind { dense, modal, taylor };
/// What `solver.engine` asks for; `automatic` resolves as docs/scenes.md says (Scene::engine).
enum class EngineChoice { automatic, dense, modal, taylor };
const char* to_string(EngineKind engine);
const char* to_string(EngineChoice choice);

/// The dense system of a scene, built on first use and cached; copies share the cache, and the
/// first use is thread-safe. Built from a LinearSystem (already there) or from a function
/// (a chain's assembly: n × n matrices and their O(n³) checks, paid only if the dense engine or
/// a dense-only tool needs them). dof() and forcing() never build it.
class LazySystem {
 public:
  LazySystem() = default;
  LazySystem(LinearSystem system);  // NOLINT(google-explicit-constructor): a built system is one
  LazySystem(Eigen::Index dof, HarmonicForcing forcing, std::function<LinearSystem()> build);

  /// The system; the first call builds it (may throw InvalidInput from its validation).
  const LinearSystem& get() const;
  bool built() const;
  Eigen::Index dof() const { return dof_; }
  const HarmonicForcing& forcing() const { return forcing_; }

 private:
  struct Cache {
    std::once_flag once;
    std::function<LinearSystem()> build;
    std::optional<LinearSystem> system;
  };
  Eigen::Index dof_ = 0;
  HarmonicForcing forcing_;
  std::shared_ptr<Cache> cache_;
};

/// The resolved, validated scene.
struct Scene {
  std::string file;       ///< path it was read from ("<string>" if none)
  std::string yaml_text;  ///< the file's text, verbatim
  std::string name;       ///< optional `name:`
  LazySystem dense;       ///< M, C, K (n × n), built on first use: see system()
  /// `model.chain` whose damping is proportional (BandedChain::from_links accepted it), in
  /// banded form (O(n)); empty for `model.matrices` and for chains with other damping.
  std::optional<BandedChain> chain;
  std::vector<Stop> stops;  ///< validated, unnamed stops named ("upper x3")
  double t0 = 0.0;
  Eigen::VectorXd x0, v0;
  SimulatorOptions solver;
  RecordSpec record;
  RunSpec run;
  EngineChoice engine_choice = EngineChoice::automatic;  ///< solver.engine as given
  EngineKind engine = EngineKind::dense;                         ///< as resolved
  std::string engine_reason;  ///< why it resolved so (for `vibro check` and `vibro info`)
  /// `base`: the support motion, already in the forcing and the stops (base_motion.hpp); the
  /// state x0, v0 and every result are in its frame.
  std::optional<BaseExcitation> base;
  /// `parameters` and `forces` (docs/scenes.md): nonlinear forces, run by the Taylor engine
  /// (taylor_simulator.hpp); empty forces for a linear scene.
  NonlinearForces forces;
  /// The frictional contacts (friction.hpp), validated; empty: none. A scene with friction runs on
  /// the dense engine's FrictionSimulator (with stops: FrictionStopSimulator, friction_stops.hpp),
  /// in every run kind (the analysis kinds through friction_tangent.hpp).
  std::vector<FrictionContact> friction;
  /// `initial.from`: the saved orbit the scene was put on ("FILE: branch B, point I …"), else "".
  std::string restart;

  /// The dense system: built (O(n²) memory, O(n³) checks) and cached on the first call.
  const LinearSystem& system() const { return dense.get(); }
  Eigen::Index dof() const { return dense.dof(); }
  const HarmonicForcing& forcing() const { return dense.forcing(); }
  /// The dense ImpactSystem (builds system()).
  ImpactSystem impact_system() const { return ImpactSystem(system(), stops); }
  /// Forcing period 2π/Ω, or 1 when Ω = 0 (periods then count time units).
  double period() const;
};

/// The scene's engine (engine.hpp), set up: the dense Simulator on scene.impact_system() or the
/// modal chain engine on scene.chain, with the scene's solver settings. For runs, orbits and
/// bifurcation location alike.
std::unique_ptr<vibro::Engine> make_engine(const Scene& scene);

/// The smallest chain that `solver.engine: automatic` runs with the modal engine: below it the
/// dense engine's O(n³) set-up is cheap and it handles every contact set (the modal engine not all).
inline constexpr Eigen::Index kModalAutomaticMinimumDof = 64;

/// The YAML tree of a scene with the source positions of its nodes; editable by path.
class SceneDocument {
 public:
  static SceneDocument load(const std::string& path);
  /// Parses a scene; a scene with `initial.from` is put on the saved orbit it names (its state, the
  /// parameter value it was computed at, and the restart's defaults: docs/scenes.md "initial"),
  /// as edits that set() and replace() would make.
  static SceneDocument parse(const std::string& text, const std::string& file = "<string>");
  SceneDocument(const SceneDocument&);
  SceneDocument& operator=(const SceneDocument&);
  ~SceneDocument();

  /// Sets the numeric value at `path` (e.g. "stops[1].position"). Throws SceneError if the path
  /// does not name an existing numeric value (message names the path and what is there).
  void set(const std::string& path, double value);
  /// Parses "PATH=VALUE" (for --set) and applies it. Errors read "--set:K:C: PATH: problem":
  /// the `ordinal`-th --set (from 1), column C of the assignment (1: the path, after '=': the value).
  void set_assignment(const std::string& assignment, int ordinal = 1);
  /// The numeric value at `path`.
  double get(const std::string& path) const;
  /// Replaces the value at `path` (keys only, e.g. "record" or "run.sweep") by the YAML text
  /// `yaml` (a scalar, list or mapping), adding missing keys; an empty `yaml` removes the key.
  /// For what a program chooses per run (the Python module's record and run keywords): build()
  /// checks it as if the file said it. Like set(), it leaves text() as loaded. Throws SceneError
  /// if a step of the path is not a mapping or `yaml` does not parse.
  void replace(const std::string& path, const std::string& yaml);

  /// Builds and validates the scene. Throws SceneError.
  Scene build() const;
  /// Builds and validates the scene but not the values of its sweep or locate grid (for the
  /// points of such a run, whose grid build() has checked once).
  Scene build_point() const { return build_checked(false); }
  const std::string& file() const;
  const std::string& text() const;
  /// Where `initial.from` took the initial state from ("FILE: branch B, point I …"), or "".
  const std::string& restart() const;

 private:
  SceneDocument();
  Scene build_checked(bool check_sweep) const;
  /// The YAML tree of the text, nothing applied (copies replay the edits on it).
  static SceneDocument parse_text(const std::string& text, const std::string& file);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vibro::io
