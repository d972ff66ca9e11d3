// run.kind: sweep — one simulation per point of a grid of one or two scene values (run.sweep),
// on OpenMP threads and, under MPI, on several processes (mpi_sweep.cpp), written in grid order
// (/sweep and the recorded groups with a leading point axis: docs/results.md). The plan, the
// writer and the units of work are in sweep_plan.hpp.
#include "kinds.hpp"

#include "../interrupt.hpp"
#include "../mpi_world.hpp"
#include "../run_section.hpp"
#include "../sweep_plan.hpp"

#include "vibro/io/resources.hpp"

#include <fmt/format.h>

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>

namespace vibro::io::detail {

SweepPlan plan_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  SweepPlan plan;
  plan.interrupted = request.interrupt ? request.interrupt : &g_interrupted;
  const auto& axes = scene.run.axes;
  if (axes.size() == 1) {
    for (double a : axes[0].values) plan.grid.push_back({a});
  } else {
    for (double a : axes[0].values)
      for (double b : axes[1].values) plan.grid.push_back({a, b});
  }
  if (scene.run.reverse) std::reverse(plan.grid.begin(), plan.grid.end());
  plan.total = plan.grid.size();
  const std::size_t row_length = axes.size() == 1 ? plan.total : axes[1].values.size();

  // Build and validate every point's scene first: bad input never starts a file.
  plan.scenes.reserve(plan.total);
  SceneDocument point = doc;  // one working copy: set() replaces the swept values per point
  for (std::size_t p = 0; p < plan.total; ++p) {
    for (std::size_t a = 0; a < axes.size(); ++a) point.set(axes[a].path, plan.grid[p][a]);
    try {
      plan.scenes.push_back(point.build_point());  // build() checks the whole grid: once, in main
      plan.scenes.back().solver.interrupt = plan.interrupted;
    } catch (const SceneError& e) {
      std::string where;
      for (std::size_t a = 0; a < axes.size(); ++a) where += fmt::format("{}{} = {:.12g}", a ? ", " : "", axes[a].path, plan.grid[p][a]);
      throw SceneError(e.file(), e.line(), e.column(), e.path(), e.problem() + " (at sweep point " + std::to_string(p) + ": " + where + ")");
    }
  }
  for (const auto& a : axes) plan.names.push_back(a.path);
  plan.follow = scene.run.follow;
  plan.chain_length = plan.follow ? row_length : 1;
  plan.chains = (plan.total + plan.chain_length - 1) / plan.chain_length;
  return plan;
}

/// Opens (or resumes) the result file; throws before creating anything if a stale .partial
/// is in the way.
ResultFile open_sweep_file(const SweepPlan& plan, const Scene& scene, const RunRequest& request,
                           int threads, SweepStart& start) {
  if (request.in_memory && request.resume) throw std::logic_error("runner: a sweep in memory cannot be resumed");
  ResultFile file = request.resume ? ResultFile::open_partial(request.output, scene, request.force)
                                   : open_result_file(request, scene, current_meta(threads));
  file.begin_sweep(plan.names, plan.total);
  start.first = file.completed_points();
  start.resumed.reset();
  if (plan.follow && start.first > 0 && start.first % plan.chain_length != 0) {
    StartState s{scene.t0, {}, {}};
    if (file.last_state(s.t, s.x, s.v)) {
      // x_end, v_end are written in the result's frame: back to the one the last point computed in
      ResultFrame::of(plan.scenes[start.first - 1]).to_scene(s.t, s.x, s.v);
      start.resumed = s;
    }
  }
  return file;
}

namespace {

Recording unstarted_point(const Scene& sc, const StartState& start, std::string message) {
  Recording rec = Recording::for_scene(sc, start.t);
  rec.summary.status = RunStatus::numerical_failure;
  rec.summary.message = std::move(message);
  rec.summary.t = start.t;
  rec.summary.x = start.x;
  rec.summary.v = start.v;
  return rec;
}

}  // namespace

/// One point; a point that cannot start (its initial state violates a stop) or would run for
/// days (resources.hpp, work_refusal: the scene's check covers only the unswept values) is
/// recorded as a numerical failure with the reason, like any point that stops early.
Recording run_point(const Scene& sc, const StartState& start) {
  if (std::string why = work_refusal(sc); !why.empty())
    return unstarted_point(sc, start, "not run: " + why);
  try {
    return simulate(sc, start);
  } catch (const InvalidInput& e) {
    return unstarted_point(sc, start, std::string("cannot start this point: ") + e.what());
  }
}

/// Threads for a sweep: as requested (0: all cores), at most one per unit of work (resources.hpp).
int thread_count(const RunRequest& request, const SweepPlan& plan) {
  return checked_threads(request.threads, plan.chains);
}

namespace {

RunReport run_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const SweepPlan plan = plan_sweep(doc, scene, request);
  const int threads = thread_count(request, plan);
#ifdef VIBRO_WITH_MPI
  if (const auto [rank, size] = world(); size > 1) return run_sweep_mpi(plan, scene, request, threads, rank, size);
#endif
  SweepStart from;
  ResultFile file = open_sweep_file(plan, scene, request, threads, from);
  SweepWriter writer(file, plan, from.first, request);
  ChainDispenser dispenser(plan, from.first / plan.chain_length);
  const auto wall_start = std::chrono::steady_clock::now();
  std::optional<InterruptGuard> guard;  // signals are the caller's when it gives its own flag
  if (!request.interrupt) guard.emplace();
  run_chains(threads, plan, from, dispenser, writer);
  RunReport report = writer.report(scene, threads, seconds_since(wall_start), fmt::format("{} threads", threads));
  if (request.in_memory) report.image = file.image();
  return report;
}

/// run.sweep (docs/scenes.md).
void parse_sweep_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  const YAML::Node sw = s.node;
  if (sw && s.full) {
    r.expect_map(sw, "run.sweep", {"parameters", "follow", "reverse"});
    if (sw["follow"]) run.follow = r.boolean(sw["follow"], "run.sweep.follow");
    if (sw["reverse"]) run.reverse = r.boolean(sw["reverse"], "run.sweep.reverse");
    const YAML::Node ps = sw["parameters"];
    if (!ps || !ps.IsSequence() || ps.size() == 0 || ps.size() > 2)
      r.fail(ps ? ps : sw, "run.sweep.parameters", "expected a list of one or two parameters, found " + (ps ? describe(ps) : std::string("nothing")));
    for (std::size_t a = 0; a < ps.size(); ++a)
      run.axes.push_back(s.axis(ps[a], "run.sweep.parameters[" + std::to_string(a) + "]", run.axes, {}));
    for (std::size_t a = 0; a < run.axes.size(); ++a)
      s.check_values(run.axes[a], ps[a], "run.sweep.parameters[" + std::to_string(a) + "]");
  }
}

}  // namespace

RunKindInfo sweep_kind() {
  RunKindInfo k;
  k.name = "sweep";
  k.kind = RunSpec::Kind::sweep;
  k.summary = "one run per point of a grid of one or two scene values (OpenMP threads, MPI processes), resumable";
  k.section = "sweep";
  k.missing = "missing: a sweep needs run.sweep.parameters";
  k.groups = {"sweep", "events", "contacts", "samples", "poincare", "impact_map", "section", "stats"};
  k.resumable = true;
  k.every_process = true;
  k.parse = parse_sweep_section;
  k.run = run_sweep;
  return k;
}

}  // namespace vibro::io::detail
