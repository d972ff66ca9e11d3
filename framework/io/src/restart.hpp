#pragma once
// Private to vibro_io: `initial.from`, a run started on an orbit saved in a result file
// (docs/scenes.md, "initial"). A long study is a sequence of runs: a continuation's branch point or
// located bifurcation, or an orbit run's orbit, is the start of the next run.
//
// What a saved orbit is: the state (x, v) at its section time t0 (forcing phase θ = Ω t0), its
// period kT, and — for a continuation's point — the value p of the parameter it was continued in
// (the file's /branch attribute `parameter`). The orbit is an orbit only at that value, so a
// restart sets it in the scene as well as the initial state; everything else is the scene's.
// A restarted run starts on the orbit itself: run.transient_periods defaults to 0 (an unstable
// orbit is left by any transient), and the period and phase of `continue` and `orbit` runs
// default to the saved k and θ. Keys the scene gives itself win.
#include "vibro/io/scene.hpp"

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>

#include <optional>
#include <string>

namespace vibro::io::detail {

/// The orbit a restart starts from, and where it came from (for messages and /scene).
struct RestartPoint {
  Eigen::VectorXd x, v;
  double t0 = 0.0, phase = 0.0;
  int k = 1;
  std::string path;  ///< the parameter the orbit was continued in ("" for an orbit run's orbit)
  double p = 0.0;
  std::string source;  ///< "FILE: branch B, point I (row R of /branch)" and the like
  std::string frame;   ///< /meta frame of a base-excited scene's file (record.frame), else ""
};

/// Reads `initial.from` (its node `from`, at `initial.from` of the scene file `scene_file`) from
/// the result file it names. Throws SceneError at the key that is wrong (a missing file, a file
/// without the group asked for, an index out of range, a non-finite or non-converged orbit).
RestartPoint read_restart(const YAML::Node& from, const std::string& scene_file);

/// The edits that put a scene on a restart point, applied to `doc` through set() and replace():
/// initial.{x, v, time}, the parameter, and the defaults above for keys `root` does not give.
/// Throws SceneError if the scene does not set the saved parameter or also gives initial x, v or
/// time.
void apply_restart(SceneDocument& doc, const YAML::Node& root, const RestartPoint& point);

}  // namespace vibro::io::detail
