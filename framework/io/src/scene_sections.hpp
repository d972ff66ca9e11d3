#pragma once
// Private to vibro_io: the sections of a scene file (docs/scenes.md), one function each, in the
// order SceneDocument::build_checked calls them: model, forcing (with base), stops, initial, solver, the
// initial state's check, record, run (scene.cpp: it consults the table of run kinds, whose
// sections kinds/<name>.cpp read), the engine. Each reads its section of the tree into
// SceneParts, given what the sections before it resolved, and reports bad input as SceneError
// (file:line:col: key.path: problem) through the Reader.
#include "run_section.hpp"
#include "scene_reader.hpp"

#include "vibro/base_motion.hpp"
#include "vibro/friction.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/taylor_simulator.hpp"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace vibro::io::detail {

/// What the sections resolve, filled in their order.
struct SceneParts {
  const SceneDocument* doc = nullptr;  ///< the document being built (run sections check grid values on copies)
  bool full = true;                    ///< build() (grids checked value by value) or build_point()
  long n = 0;                          ///< degrees of freedom
  Eigen::MatrixXd M, C, K;             ///< model.matrices
  std::optional<models::Chain> chain_links;  ///< model.chain, assembled only on demand
  HarmonicForcing f;
  std::optional<BaseExcitation> base;  ///< `base`, already added to f (scene_base.cpp)
  LazySystem dense;
  std::optional<BandedChain> banded;
  std::string not_banded;  ///< why a chain is not in banded form (its damping is not proportional)
  std::vector<Stop> stops;
  NonlinearForces forces;  ///< `parameters` and `forces` (scene_forces.cpp); none: a linear scene
  std::vector<FrictionContact> friction;  ///< the `friction` section (scene_friction.cpp)
  double t0 = 0.0;
  Eigen::VectorXd x0, v0;
  SimulatorOptions opt;
  EngineChoice engine_choice = EngineChoice::automatic;
  RecordSpec rec;
  RunSpec run;
  std::vector<PointEngine> point_engines;  ///< each grid value's engine (one run, one engine)
  std::vector<std::function<void(EngineKind, const std::string&)>> engine_checks;
  EngineKind engine = EngineKind::dense;
  std::string reason;  ///< why the engine resolved so
};

void read_model(Reader& r, const YAML::Node& root, SceneParts& p);
void read_forcing(Reader& r, const YAML::Node& root, SceneParts& p);
void read_stops(Reader& r, const YAML::Node& root, SceneParts& p);
/// `base` (scene_base.cpp): reads the base motion and adds its drive to p.f (called by
/// read_forcing before the system is built).
void read_base(Reader& r, const YAML::Node& root, SceneParts& p);
/// `forcing.file` (scene_drive_file.cpp): the drive's mean and harmonics from a CSV file, into f
/// after the inline keys (an order given both ways is refused). scene_file: for relative paths.
void read_drive_file(Reader& r, const YAML::Node& fn, long n, const std::string& scene_file, HarmonicForcing& f);
/// Moves the stops as p.base's frame requires (`stops[j].attached: base`); refuses an attached
/// stop without a base section.
void move_attached_stops(Reader& r, const YAML::Node& root, SceneParts& p, const std::vector<bool>& attached);
/// record.frame other than base.frame for a run kind that writes states but does not map them: refused.
void check_result_frame(Reader& r, const YAML::Node& root, const SceneParts& p);
void read_initial(Reader& r, const YAML::Node& root, SceneParts& p);
void read_solver(Reader& r, const YAML::Node& root, SceneParts& p);
void check_initial_state(Reader& r, const YAML::Node& root, SceneParts& p);
void read_record(Reader& r, const YAML::Node& root, SceneParts& p);
void check_sample_times(Reader& r, const YAML::Node& root, const SceneParts& p);
void read_run(Reader& r, const YAML::Node& root, SceneParts& p);  // scene.cpp: the run kinds' table
void resolve_engine(Reader& r, const YAML::Node& root, SceneParts& p);
// scene_forces.cpp: `parameters` and `forces`; the Taylor engine's share of resolve_engine (true:
// the scene runs on it).
void read_forces(Reader& r, const YAML::Node& root, SceneParts& p);
bool resolve_taylor_engine(Reader& r, const YAML::Node& root, SceneParts& p);
/// scene_friction.cpp: the `friction` section (after stops), and its checks on the resolved scene
/// (after the engine: no stops, run.kind simulate, the dense engine).
void read_friction(Reader& r, const YAML::Node& root, SceneParts& p);
void check_friction(Reader& r, const YAML::Node& root, SceneParts& p);

}  // namespace vibro::io::detail
