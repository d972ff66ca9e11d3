#include "vibro/io/kinds/locate.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"
#include "../progress.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/running_locate.hpp"
#include "vibro/io/result_file.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <chrono>
#include <exception>
#include <mutex>

namespace vibro::io {
namespace {

using detail::integers;
using detail::or_none;
using detail::reals;
using detail::table;

std::vector<std::string> kind_names() {
  std::vector<std::string> names;
  for (TransitionKind k : {TransitionKind::rising, TransitionKind::vanishing, TransitionKind::drop,
                           TransitionKind::period, TransitionKind::periodicity, TransitionKind::other})
    names.emplace_back(to_string(k));
  return names;
}

void write_scan(ResultFile& file, const std::vector<ScanPoint>& points, std::size_t n, std::size_t m,
                const std::string& path) {
  std::vector<double> p, residual, t_start;
  std::vector<std::int64_t> periodic, k, periods_run, chatter;
  std::vector<Eigen::VectorXd> sticking, impacts, x, v;
  std::vector<double> ph_phase, ph_duration, ph_force, ph_tforce, ph_start;
  std::vector<std::int64_t> ph_point, ph_stop;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const RunningOrbit& o = points[i].orbit;
    p.push_back(points[i].p);
    periodic.push_back(o.periodic ? 1 : 0);
    k.push_back(o.k);
    residual.push_back(or_none(o.residual));  // none measured: a search stopped before one period
    periods_run.push_back(o.periods_run);
    chatter.push_back(o.chatter_limits);
    t_start.push_back(o.t_start);
    sticking.push_back(o.sticking_fraction(m));
    Eigen::VectorXd imp(static_cast<Eigen::Index>(m));
    for (std::size_t j = 0; j < m; ++j) imp(static_cast<Eigen::Index>(j)) = o.impact_count(static_cast<int>(j));
    impacts.push_back(imp);
    x.push_back(o.x);
    v.push_back(o.v);
    for (const ContactPhase& ph : o.phases) {
      ph_point.push_back(static_cast<std::int64_t>(i));
      ph_stop.push_back(ph.stop);
      ph_start.push_back(ph.t_start);
      ph_phase.push_back(ph.phase / o.period);
      ph_duration.push_back(ph.duration / o.period);
      ph_force.push_back(ph.force_min);
      ph_tforce.push_back(ph.t_force_min);
    }
  }
  const std::size_t rows = points.size();
  file.write_group("scan",
                   {reals("parameter", p, {rows}), integers("periodic", periodic), integers("k", k),
                    reals("residual", residual, {rows}), integers("periods_run", periods_run),
                    table("sticking_fraction", sticking, m), table("impacts", impacts, m),
                    integers("chatter_limits", chatter), reals("t_start", t_start, {rows}),
                    table("x", x, n), table("v", v, n)},
                   {{"parameter", path}});
  const std::size_t r = ph_point.size();
  file.write_group("phases", {integers("point", ph_point), integers("stop", ph_stop),
                              reals("t_start", ph_start, {r}), reals("phase", ph_phase, {r}),
                              reals("duration", ph_duration, {r}), reals("force_min", ph_force, {r}),
                              reals("t_force_min", ph_tforce, {r})});
}

void write_transitions(ResultFile& file, const std::vector<Transition>& found, std::size_t m) {
  std::vector<std::int64_t> kind, stop, evaluations, k_low, k_high;
  std::vector<double> p, lo, hi, force, duration;
  std::vector<Eigen::VectorXd> stick_lo, stick_hi;
  for (const Transition& t : found) {
    kind.push_back(static_cast<std::int64_t>(t.kind));
    stop.push_back(t.stop);
    evaluations.push_back(t.evaluations);
    p.push_back(t.p);
    lo.push_back(t.p_low);
    hi.push_back(t.p_high);
    force.push_back(or_none(t.force_limit));
    duration.push_back(or_none(t.duration_limit));
    k_low.push_back(t.low.orbit.k);
    k_high.push_back(t.high.orbit.k);
    stick_lo.push_back(t.low.orbit.sticking_fraction(m));
    stick_hi.push_back(t.high.orbit.sticking_fraction(m));
  }
  const std::size_t r = found.size();
  Dataset kinds = integers("kind", kind);
  kinds.labels.emplace_back("names", kind_names());
  file.write_group("transitions",
                   {kinds, integers("stop", stop), reals("parameter", p, {r}), reals("parameter_low", lo, {r}),
                    reals("parameter_high", hi, {r}), reals("force_limit", force, {r}),
                    reals("duration_limit", duration, {r}), integers("evaluations", evaluations),
                    integers("k_low", k_low), integers("k_high", k_high),
                    table("sticking_low", stick_lo, m), table("sticking_high", stick_hi, m)});
}

}  // namespace

RunReport run_locate(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const auto wall_start = std::chrono::steady_clock::now();
  const SweepAxis& axis = scene.run.axes.at(0);
  const LocateSpec& spec = scene.run.locate;
  // Grid values were validated at load; a bisection point between two valid values that is not
  // valid itself surfaces as SceneError from here, before anything is written.
  const EngineFamily family = [&doc, &axis, &request](double value) {
    SceneDocument point(doc);
    point.set(axis.path, value);
    Scene built = point.build_point();
    built.solver.interrupt = request.interrupt;
    return make_engine(built);  // the scene's engine, dense or modal
  };
  ScanOptions options;
  options.orbit.solver = scene.solver;
  options.orbit.solver.interrupt = request.interrupt;
  options.orbit.tolerance = spec.periodicity;
  options.orbit.max_period = spec.max_period;
  options.orbit.max_periods = spec.max_periods;
  options.first_transient = static_cast<long>(std::ceil(scene.run.transient_periods));
  options.tolerance = spec.tolerance;
  options.jump = spec.jump;
  const std::size_t n = static_cast<std::size_t>(scene.dof());
  const std::size_t m = scene.stops.size();

  ResultFile file = open_result_file(request, scene, current_meta(request.threads));
  // Progress in steps: the grid's points one after the other, then the brackets between
  // neighbours (each a bisection, however many transitions it holds).
  detail::Progress progress(request, "locate", "steps", static_cast<double>(2 * axis.values.size() - 1));
  options.on_point = [&progress](std::size_t) { progress.add(); };
  // An interrupted scan ends early: only its points are bracketed (none once interrupted).
  const std::vector<ScanPoint> points = scan(family, axis.values, scene.t0, scene.x0, scene.v0, options);
  const std::size_t steps = points.size() - 1;

  // Bisections between neighbouring grid points are independent: in parallel, gathered in order.
  std::vector<std::vector<Transition>> found(steps);
  long orbits = static_cast<long>(points.size());
  std::exception_ptr failure;
  std::mutex lock;
  int threads = 1;
#ifdef _OPENMP
  if (request.threads > 0) omp_set_num_threads(request.threads);
  threads = omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : orbits)
#endif
  for (std::size_t i = 0; i < steps; ++i) {
    try {
      if (request.interrupt && request.interrupt->load()) continue;
      found[i] = locate_between(family, points[i], points[i + 1], options, &orbits);
      progress.add();
    } catch (const Interrupted&) {  // an engine's set-up (bounded_wait.hpp): the bracket is left unexplored
    } catch (...) {
      const std::lock_guard<std::mutex> hold(lock);
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);
  std::vector<Transition> transitions;
  for (auto& f : found) transitions.insert(transitions.end(), f.begin(), f.end());
  std::sort(transitions.begin(), transitions.end(),
            [](const Transition& a, const Transition& b) { return a.p < b.p; });
  merge_doublings(transitions);

  write_scan(file, points, n, m, axis.path);
  write_transitions(file, transitions, m);

  long not_periodic = 0, failed = 0;
  std::string failure_message;
  for (const ScanPoint& s : points) {
    if (!s.orbit.periodic) ++not_periodic;
    if (s.orbit.status != RunStatus::completed) {
      ++failed;
      if (failure_message.empty()) failure_message = fmt::format("at {} = {:.12g}: {}", axis.path, s.p, s.orbit.message);
    }
  }
  // Stopped by the caller (RunRequest::interrupt): the orbits after that point stopped at once,
  // so neither they nor the transitions found between them mean anything.
  const bool interrupted = request.interrupt && request.interrupt->load();
  file.set_outcome(interrupted ? "interrupted" : failed ? "points_stopped_early" : "completed",
                   interrupted ? "interrupted: orbits computed after it are cut short and the transitions found "
                                 "are not reliable"
                               : failure_message,
                   {{"orbits_computed", orbits}, {"transitions", static_cast<std::int64_t>(transitions.size())},
                    {"points_not_periodic", not_periodic}});
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  RunMeta meta = current_meta(threads);
  meta.wall_seconds = wall;
  file.finish(meta);

  std::string text = fmt::format("Located {} transitions of {} over {} .. {} ({} grid points, {} orbits, "
                                 "{} threads, {:.2f} s):\n",
                                 transitions.size(), axis.path, axis.values.front(), axis.values.back(),
                                 points.size(), orbits, threads, wall);
  text += fmt::format("  {:<12} {:>5} {:>18} {:>11} {:>12} {:>12}\n", "kind", "stop", axis.path, "bracket",
                      "force_limit", "dur_limit");
  for (const Transition& t : transitions)
    text += fmt::format("  {:<12} {:>5} {:>18.10f} {:>11.1e} {:>12.3e} {:>12.3e}\n", to_string(t.kind),
                        t.stop >= 0 ? scene.stops[static_cast<std::size_t>(t.stop)].name : std::string("-"),
                        t.p, t.p_high - t.p_low, or_none(t.force_limit), or_none(t.duration_limit));
  if (not_periodic > 0)
    text += fmt::format("  {} of {} grid points are not periodic within {} periods (see /scan/periodic).\n",
                        not_periodic, points.size(), spec.max_periods);
  text += fmt::format("Results in {}.", file.path());
  return {interrupted ? 130 : failed ? 1 : 0, text, request.in_memory ? file.image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.locate (docs/scenes.md).
void parse_locate_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  const YAML::Node lc = s.node;
  if (lc && s.full) {
    LocateSpec& l = run.locate;
    run.axes.push_back(s.axis(lc, "run.locate", {}, {"tolerance", "periodicity", "max_period", "max_periods", "jump"}));
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
    // a budget below that would have to be raised behind the user's back (running_locate.cpp).
    const long needed = static_cast<long>(std::ceil(run.transient_periods)) + l.max_period + 1;
    if (l.max_periods < needed)
      r.fail(lc["max_periods"] ? lc["max_periods"] : lc, "run.locate.max_periods",
             "expected at least " + std::to_string(needed) + " periods (run.transient_periods " +
                 number_text(run.transient_periods) + " + max_period " + std::to_string(l.max_period) +
                 " + 1: the first orbit is tested after the transient), found " + std::to_string(l.max_periods));
    if (lc["jump"]) l.jump = r.number_in(lc["jump"], "run.locate.jump", 0, 1, "a fraction of the period in [0, 1] (0: no jump search)");
    s.check_values(run.axes[0], lc, "run.locate");
  }
}

}  // namespace

RunKindInfo locate_kind() {
  RunKindInfo k;
  k.name = "locate";
  k.kind = RunSpec::Kind::locate;
  k.summary = "periodic orbits followed along one parameter, their bifurcations located";
  k.section = "locate";
  k.missing = "missing: run.kind: locate needs run.locate (path and grid)";
  k.groups = {"scan", "phases", "transitions"};
  k.every_process = false;
  k.stoppable = true;
  k.parse = parse_locate_section;
  k.run = run_locate;
  return k;
}

}  // namespace vibro::io::detail
