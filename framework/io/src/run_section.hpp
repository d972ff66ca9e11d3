#pragma once
// Private to vibro_io: what the parser of a run kind's own section (`run.<section>`, kinds/) is
// given — the reader, the document, its place in the tree, the RunSpec to fill, what the scene's
// other sections resolved — and the pieces such sections share: a parameter grid (`path` with
// linspace, logspace or values), the check that every grid value makes a valid scene, and checks
// to make once the scene's engine is known.
#include "scene_reader.hpp"

#include <functional>
#include <string>
#include <vector>

namespace vibro::io::detail {

/// A grid value's scene and the engine it resolves to (a run uses one engine: checked once the
/// base scene's engine is known).
struct PointEngine {
  YAML::Node at;
  std::string path, what;
  EngineKind engine;
};

struct RunSection {
  Reader& r;
  const SceneDocument& doc;
  YAML::Node run_node;  ///< `run`
  YAML::Node node;      ///< `run.<section>` of this kind, or an undefined node if absent
  RunSpec& run;         ///< kind, transient_periods and periods are read; the rest is this kind's
  long dof = 0;
  double frequency = 0.0;  ///< forcing.frequency
  /// build(): read the whole section (grids included, every value checked); build_point(): only
  /// what a point of such a run needs (the grid was checked once by build()).
  bool full = true;
  std::vector<PointEngine>& point_engines;
  /// Checks to make once the scene's engine is resolved (its kind, the reason it resolved so).
  std::vector<std::function<void(EngineKind, const std::string&)>>& engine_checks;

  /// One varied value at `p` (named `path`): `path` and exactly one of linspace, logspace,
  /// values; `keys` are the other keys the mapping may hold; no path twice among `others`.
  SweepAxis axis(const YAML::Node& p, const std::string& path, const std::vector<SweepAxis>& others,
                 std::vector<std::string> keys);
  /// Every value must make a valid scene: found out now, at the value, not mid-run. With
  /// `starts_may_be_inadmissible` a value whose only fault is a start outside a stop passes (a
  /// basin labels such a start; inadmissible_start below).
  void check_values(const SweepAxis& axis, const YAML::Node& p, const std::string& path,
                    bool starts_may_be_inadmissible = false);
  /// A grid along which a run follows its attractor (run.axes[0]): at least two values, strictly
  /// monotonic.
  void monotonic(const YAML::Node& node, const std::string& path);
};

/// Whether a scene was refused only because its initial state lies outside a stop (by more than
/// the trigger tolerance: check_admissible, stops.hpp).
bool inadmissible_start(const SceneError& e);

}  // namespace vibro::io::detail
