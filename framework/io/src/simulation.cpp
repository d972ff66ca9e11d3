#include "simulation.hpp"

#include "interrupt.hpp"

#include "vibro/engine.hpp"
#include "vibro/io/recorded_gaps.hpp"

#include <algorithm>
#include <chrono>
#include <memory>
#include <string>

namespace vibro::io::detail {

Recording simulate(const Scene& base, const StartState& start, std::atomic<double>* reached) {
  const auto clock = std::chrono::steady_clock::now();
  Scene scene = base;  // shares the built system; only the options change
  if (!scene.solver.interrupt) scene.solver.interrupt = &g_interrupted;  // the caller's flag, or signals
  scene.solver.reached = reached;
  // One engine per run (a simulation, or a sweep point): everything else in this file (transient
  // then recorded run, observers, files, threads, processes) is the same for both engines.
  const std::unique_ptr<vibro::Engine> engine = make_engine(scene);
  vibro::Engine& sim = *engine;
  const double T = scene.period();
  const double t1 = start.t + scene.run.transient_periods * T;
  RunSummary transient;
  transient.status = RunStatus::completed;
  transient.t = start.t;
  transient.x = start.x;
  transient.v = start.v;
  if (scene.run.transient_periods > 0.0) transient = sim.run(start.t, start.x, start.v, t1, {});
  // An interrupted transient records nothing: no sample times laid out for the recorded periods
  // (millions of them take seconds to allocate, after the signal).
  Scene shape = scene;
  if (transient.status == RunStatus::interrupted) shape.run.periods = 0.0;
  Recording rec = Recording::for_scene(shape, t1);
  if (transient.status != RunStatus::completed) {
    rec.summary = transient;
    rec.summary.message = "during the transient: " + transient.message;
  } else {
    // Counts are the recorded run's (docs/results.md), as the recorded events are.
    rec.summary = sim.run(t1, transient.x, transient.v, t1 + scene.run.periods * T, rec.observers());
  }
  check_recorded_gaps(scene, rec);  // no state past a stop is stored as a result
  rec.map_to_result_frame();        // (the gaps are checked in the frame the engine computed in)
  for (const std::string& w : transient.warnings)
    if (std::find(rec.summary.warnings.begin(), rec.summary.warnings.end(), w) == rec.summary.warnings.end())
      rec.summary.warnings.insert(rec.summary.warnings.begin(), "during the transient: " + w);
  rec.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
  return rec;
}

}  // namespace vibro::io::detail
