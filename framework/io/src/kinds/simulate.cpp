// run.kind: simulate — one simulation: run.transient_periods simulated without recording, then
// run.periods recorded with the observers the scene's `record` asks for; one file (/events,
// /contacts, /samples, /poincare, /stats: docs/results.md). No section of its own.
#include "kinds.hpp"

#include "../interrupt.hpp"
#include "../progress.hpp"
#include "../simulation.hpp"

#include "vibro/io/result_file.hpp"

#include <fmt/format.h>

#include <optional>
#include <string>

namespace vibro::io::detail {
namespace {

RunReport run_simulation(const Scene& scene, const RunRequest& request) {
  // Ctrl-C ends the run at its next event: `vibro run` writes nothing then; a caller with its own
  // flag (Python) gets the run up to there.
  std::optional<InterruptGuard> guard;
  if (!request.interrupt) guard.emplace();
  ResultFile file = open_result_file(request, scene, current_meta(1));
  Scene interruptible = scene;
  interruptible.solver.interrupt = request.interrupt;  // null: the signal flag (simulate)
  Recording rec;
  {
    SimulationProgress progress(request, "simulate", scene.t0,
                                scene.t0 + (scene.run.transient_periods + scene.run.periods) * scene.period(),
                                scene.period());
    rec = simulate(interruptible, {scene.t0, scene.x0, scene.v0}, progress.reached());
  }
  if (rec.summary.status == RunStatus::interrupted && !request.in_memory) {
    // The frame's message names the time the search reached, which a long segment puts far past
    // the state kept.
    std::string what = rec.summary.message.empty() ? fmt::format("interrupted at t = {:g}", rec.summary.t)
                                                   : rec.summary.message;
    what[0] = 'I';
    return {130, fmt::format("{}: {} was not written (a simulation keeps nothing; only sweeps can be resumed).", what,
                             request.output),
            {}};  // the ResultFile removes its .partial
  }
  file.write_simulation(rec);
  RunMeta meta = current_meta(1);
  meta.wall_seconds = rec.wall_seconds;
  file.finish(meta);
  RunReport report;
  const RunSummary& s = rec.summary;
  report.exit_code = s.status == RunStatus::completed ? 0 : s.status == RunStatus::interrupted ? 130 : 1;
  std::string warnings;
  for (const std::string& w : s.warnings) warnings += "\nwarning: " + w;
  report.summary = fmt::format(
      "Simulated {} with the {} engine from t = {:g} over {:g} transient and {:g} recorded forcing periods in "
      "{:.3f} s: {}; {}.{} Results in {}.{}",
      scene.file, to_string(scene.engine), scene.t0, scene.run.transient_periods, scene.run.periods, rec.wall_seconds,
      to_string(s.status), status_line(s), s.message.empty() ? "" : " " + s.message, file.path(), warnings);
  if (request.in_memory) report.image = file.image();
  return report;
}

}  // namespace

RunKindInfo simulate_kind() {
  RunKindInfo k;
  k.name = "simulate";
  k.kind = RunSpec::Kind::simulate;
  k.summary = "one run: transient periods, then recorded periods with the observers `record` asks for";
  k.groups = {"events", "contacts", "samples", "poincare", "impact_map", "section", "stats"};
  k.run = [](const SceneDocument&, const Scene& scene, const RunRequest& request) { return run_simulation(scene, request); };
  return k;
}

}  // namespace vibro::io::detail
