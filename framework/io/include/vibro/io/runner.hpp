#pragma once
/// \file runner.hpp
/// Runs a scene and writes its result file: the engine behind `vibro run`.
///
/// simulate: the transient periods are simulated without recording, then the recorded periods
/// with the observers the scene asks for; one file.
///
/// sweep: the grid of the swept paths (a 2-D grid varies its second parameter fastest; `reverse`
/// walks it backwards). Every point's scene is built and validated before anything is
/// simulated or written, so bad input never leaves a half-written file. Points run in parallel
/// with OpenMP (dynamic schedule: sticking-heavy points cost more) and are written in grid order,
/// so the file's data are identical for any number of threads. With `follow`, each point starts
/// from the state (x, v) the previous point reached, placed at initial.time; the points of a
/// 1-D followed sweep are therefore sequential, and a 2-D followed sweep follows along its second
/// parameter with its rows in parallel. Ctrl-C (SIGINT) or SIGTERM stops taking new points,
/// writes the finished ones and leaves OUT.partial for `--resume`.
#include "vibro/io/scene.hpp"

#include <string>

namespace vibro::io {

struct RunRequest {
  std::string output;      ///< result file path
  int threads = 0;         ///< 0: OpenMP's default
  bool resume = false;     ///< continue OUT.partial of an interrupted sweep
  bool progress = false;   ///< progress bar with ETA on stderr
  /// Behave as if interrupted once this many points are written (0: never). For tests of
  /// interruption and --resume, which must not depend on timing a real signal.
  std::size_t interrupt_after = 0;
};

struct RunReport {
  int exit_code = 0;       ///< 0 all completed, 1 some run stopped early, 130 interrupted
  std::string summary;     ///< one paragraph for the user
};

/// `doc` is the (already --set) scene document, `scene` its build(). Throws SceneError for bad
/// input found while preparing sweep points (before any file is created).
RunReport run_scene(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
