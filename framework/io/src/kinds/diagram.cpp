#include "vibro/io/kinds/diagram.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"
#include "../progress.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/io/result_file.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <tuple>
#include <utility>
#include <exception>
#include <mutex>
#include <numeric>
#include <optional>

namespace vibro::io {
namespace {

using detail::integers;
using detail::reals;

/// One direction's record, indexed like the sorted grid.
struct Branch {
  std::vector<double> x, v;            ///< m × P × n
  std::vector<std::int64_t> k, reached;
  std::vector<double> impacts;         ///< per period, mean over the P recorded periods
  std::vector<double> residual;        ///< the period test's residual (of k, or the least over k ≤ max_period)
  std::vector<std::int64_t> extra;     ///< periods run beyond the transient before the recorded ones
  std::vector<std::int64_t> verdict;   ///< Verdict
  std::string message;                 ///< why a run stopped early (empty: none did)
  /// record.impact_map: the impacts of the recorded periods, every value in grid order (point:
  /// the value's index in the sorted grid).
  ImpactMap map;
  std::vector<std::int64_t> map_point;
  /// record.section: the crossings of the recorded periods, likewise (section_point: grid index).
  std::vector<double> section_t, section_phase;
  std::vector<std::int64_t> section_direction, section_point;
  std::vector<Eigen::VectorXd> section_x, section_v;
};

/// What the recorded points of a value are.
enum Verdict : std::int64_t {
  periodic = 0,       ///< k > 0: every recorded point repeats within the tolerance
  not_periodic = 1,   ///< no k ≤ max_period, and the residual stopped decreasing (or no extension allowed)
  not_settled = 2,    ///< no k ≤ max_period yet, but the residual was still decreasing at the cap
};

/// max_i max(|x_i − x_{i−k}| / L, |v_i − v_{i−k}| / V): how far the recorded points are from
/// repeating with period k (over the 2k ≤ P points that test it).
double period_residual(const std::vector<Eigen::VectorXd>& z, std::size_t k, double L, double V) {
  const Eigen::Index n = z.front().size() / 2;
  double r = 0.0;
  for (std::size_t i = k; i < z.size(); ++i) {
    const Eigen::VectorXd d = (z[i] - z[i - k]).cwiseAbs();
    r = std::max({r, d.head(n).maxCoeff() / L, d.tail(n).maxCoeff() / V});
  }
  return r;
}

/// The least k ≤ max_period whose residual is within `tolerance` (0 if none), and the residual:
/// of that k, or the least over every k tested when there is none.
std::pair<std::int64_t, double> least_period(const std::vector<Eigen::VectorXd>& z, int max_period,
                                             double tolerance, double L, double V) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 1; k <= static_cast<std::size_t>(max_period) && 2 * k <= z.size(); ++k) {
    const double r = period_residual(z, k, L, V);
    if (r <= tolerance) return {static_cast<std::int64_t>(k), r};
    best = std::min(best, r);
  }
  return {0, best};
}

/// /impact_map of a diagram (record.impact_map; docs/results.md): the impacts of every value's
/// recorded periods, direction after direction, each value's in time order, with the value's
/// grid index (`point`) and the direction.
void write_impact_map(ResultFile& file, const Scene& scene,
                      const std::vector<std::pair<std::string, const std::vector<std::size_t>*>>& directions,
                      const std::vector<Branch>& branches) {
  std::vector<double> t, phase, velocity;
  std::vector<std::int64_t> stop, point, direction;
  std::vector<Eigen::VectorXd> x, v;
  std::vector<std::string> names;
  for (std::size_t d = 0; d < directions.size(); ++d) {
    const Branch& b = branches[d];
    t.insert(t.end(), b.map.t.begin(), b.map.t.end());
    phase.insert(phase.end(), b.map.phase.begin(), b.map.phase.end());
    velocity.insert(velocity.end(), b.map.velocity.begin(), b.map.velocity.end());
    stop.insert(stop.end(), b.map.stop.begin(), b.map.stop.end());
    x.insert(x.end(), b.map.x.begin(), b.map.x.end());
    v.insert(v.end(), b.map.v.begin(), b.map.v.end());
    point.insert(point.end(), b.map_point.begin(), b.map_point.end());
    direction.insert(direction.end(), b.map.t.size(), directions[d].first == "up" ? 0 : 1);
  }
  for (const Stop& s : scene.stops) names.push_back(s.name);
  const std::size_t r = t.size(), n = static_cast<std::size_t>(scene.dof());
  Dataset stops = integers("stop", stop, {r}, Dataset::Type::i32);
  stops.labels.emplace_back("stops", names);
  Dataset dirs = integers("direction", direction);
  dirs.labels.emplace_back("names", std::vector<std::string>{"up", "down"});
  file.write_group("impact_map", {reals("t", t, {r}), std::move(stops), reals("phase", phase, {r}),
                                  reals("velocity", velocity, {r}), detail::table("x", x, n), detail::table("v", v, n),
                                  integers("point", point), std::move(dirs)});
}

/// /section of a diagram (record.section; docs/results.md): the crossings of every value's
/// recorded periods, direction after direction, each value's in time order, with the value's grid
/// index (`point`), the parameter's value (`parameter`) and the diagram's direction (`sweep`).
void write_section(ResultFile& file, const Scene& scene, const std::vector<double>& grid,
                   const std::vector<std::pair<std::string, const std::vector<std::size_t>*>>& directions,
                   const std::vector<Branch>& branches) {
  std::vector<double> t, phase, parameter;
  std::vector<std::int64_t> crossing, point, sweep;
  std::vector<Eigen::VectorXd> x, v;
  for (std::size_t d = 0; d < directions.size(); ++d) {
    const Branch& b = branches[d];
    t.insert(t.end(), b.section_t.begin(), b.section_t.end());
    phase.insert(phase.end(), b.section_phase.begin(), b.section_phase.end());
    crossing.insert(crossing.end(), b.section_direction.begin(), b.section_direction.end());
    x.insert(x.end(), b.section_x.begin(), b.section_x.end());
    v.insert(v.end(), b.section_v.begin(), b.section_v.end());
    point.insert(point.end(), b.section_point.begin(), b.section_point.end());
    for (const std::int64_t g : b.section_point) parameter.push_back(grid[static_cast<std::size_t>(g)]);
    sweep.insert(sweep.end(), b.section_t.size(), directions[d].first == "up" ? 0 : 1);
  }
  const std::size_t r = t.size(), n = static_cast<std::size_t>(scene.dof());
  Dataset sweeps = integers("sweep", sweep);
  sweeps.labels.emplace_back("names", std::vector<std::string>{"up", "down"});
  file.write_group("section", {reals("t", t, {r}), reals("phase", phase, {r}), integers("direction", crossing),
                               detail::table("x", x, n), detail::table("v", v, n), integers("point", point),
                               reals("parameter", parameter, {r}), std::move(sweeps)});
}

/// Follows the attractor through the grid values `order` (indices into the sorted grid).
void follow(const SceneDocument& doc, const Scene& scene, const std::vector<double>& grid,
            const std::vector<std::size_t>& order, const RunRequest& request, detail::Progress& progress,
            Branch& out) {
  const DiagramSpec& spec = scene.run.diagram;
  const std::string& path = scene.run.axes[0].path;
  const std::size_t m = grid.size(), P = static_cast<std::size_t>(spec.points);
  const Eigen::Index n = scene.dof();
  out.x.assign(m * P * static_cast<std::size_t>(n), 0.0);
  out.v.assign(out.x.size(), 0.0);
  out.k.assign(m, 0);
  out.reached.assign(m, 0);
  out.impacts.assign(m, 0.0);
  out.residual.assign(m, std::numeric_limits<double>::quiet_NaN());
  out.extra.assign(m, 0);
  out.verdict.assign(m, Verdict::not_periodic);
  SceneDocument point(doc);
  Eigen::VectorXd x = scene.x0, v = scene.v0;
  long transient = static_cast<long>(std::ceil(scene.run.transient_periods));
  for (const std::size_t g : order) {
    point.set(path, grid[g]);
    Scene built = point.build_point();
    built.solver.interrupt = request.interrupt;
    std::unique_ptr<Engine> engine;
    try {
      engine = make_engine(built);
    } catch (const Interrupted&) {  // in the set-up of the value's engine (bounded_wait.hpp): not reached
      out.message = fmt::format("at {} = {:.12g}: interrupted while its engine was set up", path, grid[g]);
      return;
    }
    const double T = built.period(), t0 = built.t0;
    RunSummary s;
    s.status = RunStatus::completed;
    if (transient > 0) {
      s = engine->run(t0, x, v, t0 + static_cast<double>(transient) * T);
      x = s.x;
      v = s.v;
    }
    std::vector<Eigen::VectorXd> z;
    long impacts = 0;
    double L = 1.0, V = 1.0;
    // The impact map of the recorded periods (record.impact_map), one block's at a time.
    std::optional<ImpactMap> map;
    std::optional<Section> section;  // record.section, likewise
    std::vector<Observer*> observers;
    // P stroboscopic points from period `first` after t0 on (each block replaces the last).
    const auto record = [&](long first) {
      z.clear();
      impacts = 0;
      observers.clear();
      if (scene.record.impact_map) {
        map.emplace();
        observers.push_back(&*map);
      }
      if (scene.record.section) {
        section.emplace(scene.record.section->plane, scene.record.section->direction);
        observers.push_back(&*section);
      }
      const double t1 = t0 + static_cast<double>(first) * T;
      for (std::size_t i = 1; i <= P && s.status == RunStatus::completed; ++i) {
        s = engine->run(t1 + static_cast<double>(i - 1) * T, x, v, t1 + static_cast<double>(i) * T, observers);
        x = s.x;
        v = s.v;
        impacts += s.impacts;
        L = s.length_scale;
        V = s.velocity_scale;
        Eigen::VectorXd zi(2 * n);
        zi << x, v;
        z.push_back(zi);
      }
    };
    record(transient);
    // Not periodic yet: the recorded periods become transient and P more are recorded, up to
    // `settle` periods, while the motion still approaches an orbit of period ≤ max_period. The
    // residual of an approached orbit falls (geometrically, once near it); a transient (transient
    // chaos above all) may keep it high for a while first, so only `patience` periods (a quarter
    // of `settle`, at least 4 blocks) without a new least residual say it does not (chaos, a
    // torus, a longer period, or a transient longer than that) and end the extension early.
    const long patience = std::max<long>(4 * static_cast<long>(P), spec.settle / 4);
    auto [k, residual] = s.status == RunStatus::completed
                             ? least_period(z, spec.max_period, spec.tolerance, L, V)
                             : std::pair<std::int64_t, double>{0, 0.0};
    long extra = 0;
    double least = residual;
    long stalled = patience;  // (no extension run: nothing says it is still approaching)
    if (k == 0 && static_cast<long>(P) <= spec.settle) stalled = 0;
    while (s.status == RunStatus::completed && k == 0 && stalled < patience &&
           extra + static_cast<long>(P) <= spec.settle) {
      extra += static_cast<long>(P);
      record(transient + extra);
      if (s.status != RunStatus::completed) break;
      std::tie(k, residual) = least_period(z, spec.max_period, spec.tolerance, L, V);
      if (residual < least) {
        least = residual;
        stalled = 0;
      } else {
        stalled += static_cast<long>(P);
      }
    }
    const bool converging = stalled < patience;
    if (s.status != RunStatus::completed) {
      out.message = fmt::format("at {} = {:.12g}: {}", path, grid[g], s.message);
      return;
    }
    // Written in the result's frame (record.frame): z[i] is the state at t0 + (first + i + 1) T,
    // first = transient + extra the last block's first period (the map's states carry their times).
    const ResultFrame frame = ResultFrame::of(built);
    for (std::size_t i = 0; i < P; ++i) {
      Eigen::VectorXd xi = z[i].head(n), vi = z[i].tail(n);
      frame.to_result(t0 + static_cast<double>(transient + extra + static_cast<long>(i) + 1) * T, xi, vi);
      for (Eigen::Index j = 0; j < n; ++j) {
        const std::size_t at = (g * P + i) * static_cast<std::size_t>(n) + static_cast<std::size_t>(j);
        out.x[at] = xi(j);
        out.v[at] = vi(j);
      }
    }
    if (map)
      for (std::size_t i = 0; i < map->t.size(); ++i) frame.to_result(map->t[i], map->x[i], map->v[i]);
    if (section)  // the crossings of the scene's own coordinates, their states written in the result's frame
      for (std::size_t i = 0; i < section->t.size(); ++i) frame.to_result(section->t[i], section->x[i], section->v[i]);
    out.k[g] = k;
    out.residual[g] = residual;
    out.extra[g] = extra;
    out.verdict[g] = k > 0 ? Verdict::periodic : converging ? Verdict::not_settled : Verdict::not_periodic;
    out.impacts[g] = static_cast<double>(impacts) / static_cast<double>(P);
    out.reached[g] = 1;
    if (map) {
      ImpactMap& to = out.map;
      to.t.insert(to.t.end(), map->t.begin(), map->t.end());
      to.phase.insert(to.phase.end(), map->phase.begin(), map->phase.end());
      to.velocity.insert(to.velocity.end(), map->velocity.begin(), map->velocity.end());
      to.stop.insert(to.stop.end(), map->stop.begin(), map->stop.end());
      to.x.insert(to.x.end(), map->x.begin(), map->x.end());
      to.v.insert(to.v.end(), map->v.begin(), map->v.end());
      out.map_point.insert(out.map_point.end(), map->t.size(), static_cast<std::int64_t>(g));
    }
    if (section) {
      out.section_t.insert(out.section_t.end(), section->t.begin(), section->t.end());
      out.section_phase.insert(out.section_phase.end(), section->phase.begin(), section->phase.end());
      out.section_direction.insert(out.section_direction.end(), section->crossing.begin(), section->crossing.end());
      out.section_x.insert(out.section_x.end(), section->x.begin(), section->x.end());
      out.section_v.insert(out.section_v.end(), section->v.begin(), section->v.end());
      out.section_point.insert(out.section_point.end(), section->t.size(), static_cast<std::int64_t>(g));
    }
    transient = spec.transient;
    progress.add();
  }
}

/// The residuals with 0 where a value was not reached (nothing non-finite is written).
std::vector<double> unreached_as_zero(std::vector<double> residual, const std::vector<std::int64_t>& reached) {
  for (std::size_t g = 0; g < residual.size(); ++g)
    if (!reached[g]) residual[g] = 0.0;
  return residual;
}

}  // namespace

RunReport run_diagram(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const auto wall_start = std::chrono::steady_clock::now();
  const SweepAxis& axis = scene.run.axes.at(0);
  const DiagramSpec& spec = scene.run.diagram;
  std::vector<double> grid = axis.values;
  std::sort(grid.begin(), grid.end());
  const std::size_t m = grid.size(), P = static_cast<std::size_t>(spec.points), n = static_cast<std::size_t>(scene.dof());
  std::vector<std::size_t> up(m);
  std::iota(up.begin(), up.end(), std::size_t{0});
  std::vector<std::size_t> down(up.rbegin(), up.rend());
  std::vector<std::pair<std::string, const std::vector<std::size_t>*>> directions;
  if (spec.up) directions.emplace_back("up", &up);
  if (spec.down) directions.emplace_back("down", &down);

  ResultFile file = open_result_file(request, scene, current_meta(request.threads));
  std::vector<Branch> branches(directions.size());
  detail::Progress progress(request, "diagram", "points", static_cast<double>(m * directions.size()));
  std::exception_ptr failure;
  std::mutex lock;
  int threads = 1;
#ifdef _OPENMP
  if (request.threads > 0) omp_set_num_threads(request.threads);
  threads = std::min<int>(omp_get_max_threads(), static_cast<int>(directions.size()));
#pragma omp parallel for schedule(static, 1) num_threads(threads)
#endif
  for (std::size_t d = 0; d < directions.size(); ++d) {
    try {
      follow(doc, scene, grid, *directions[d].second, request, progress, branches[d]);
    } catch (...) {
      const std::lock_guard<std::mutex> hold(lock);
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);

  std::vector<Dataset> datasets{reals("parameter", grid, {m})};
  std::string message, names;
  long not_periodic = 0, not_settled = 0, not_reached = 0;
  for (std::size_t d = 0; d < directions.size(); ++d) {
    const std::string& dir = directions[d].first;
    const Branch& b = branches[d];
    datasets.push_back(reals("x_" + dir, b.x, {m, P, n}));
    datasets.push_back(reals("v_" + dir, b.v, {m, P, n}));
    datasets.push_back(integers("k_" + dir, b.k));
    datasets.push_back(reals("impacts_" + dir, b.impacts, {m}));
    datasets.push_back(integers("reached_" + dir, b.reached));
    datasets.push_back(reals("residual_" + dir, unreached_as_zero(b.residual, b.reached), {m}));
    datasets.push_back(integers("extra_periods_" + dir, b.extra));
    Dataset verdict = integers("verdict_" + dir, b.verdict);
    verdict.labels.emplace_back("names", std::vector<std::string>{"periodic", "not_periodic", "not_settled"});
    datasets.push_back(std::move(verdict));
    names += (names.empty() ? "" : " ") + dir;
    for (std::size_t g = 0; g < m; ++g) {
      if (!b.reached[g]) ++not_reached;
      else if (b.verdict[g] == Verdict::not_periodic) ++not_periodic;
      else if (b.verdict[g] == Verdict::not_settled) ++not_settled;
    }
    if (message.empty() && !b.message.empty()) message = dir + ": " + b.message;
  }
  file.write_group("diagram", datasets, {{"parameter", axis.path}, {"directions", names}});
  if (scene.record.impact_map) write_impact_map(file, scene, directions, branches);
  if (scene.record.section) write_section(file, scene, grid, directions, branches);
  const bool interrupted = request.interrupt && request.interrupt->load();
  file.set_outcome(interrupted ? "interrupted" : not_reached ? "points_stopped_early" : "completed",
                   interrupted ? "interrupted: the points after it were not reached" : message,
                   {{"points", static_cast<std::int64_t>(m * directions.size())},
                    {"points_not_periodic", not_periodic},
                    {"points_not_settled", not_settled},
                    {"points_not_reached", not_reached}});
  const double wall = detail::finish_run(file, threads, wall_start);

  std::string text = fmt::format("Diagram of {} over {} .. {} ({} values, {} directions: {}; {} points recorded "
                                 "each) on {} threads in {:.2f} s: {} points not periodic (k ≤ {})",
                                 axis.path, grid.front(), grid.back(), m, directions.size(), names, P, threads, wall,
                                 not_periodic, spec.max_period);
  if (not_settled > 0)
    text += fmt::format(", {} not settled within {} extra periods (raise run.diagram.settle)", not_settled, spec.settle);
  if (not_reached > 0) text += fmt::format(", {} not reached ({})", not_reached, message);
  text += fmt::format(".\nResults in {}.", file.path());
  return {interrupted ? 130 : not_reached ? 1 : 0, text, request.in_memory ? file.image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.diagram (docs/scenes.md).
void parse_diagram_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  const YAML::Node dg = s.node;
  if (dg && s.full) {
    DiagramSpec& d = run.diagram;
    run.axes.push_back(s.axis(dg, "run.diagram", {}, {"transient", "points", "directions", "max_period", "tolerance", "settle"}));
    s.monotonic(dg, "run.diagram");
    if (dg["transient"]) d.transient = r.integer(dg["transient"], "run.diagram.transient", 0, 100000000);
    if (dg["settle"]) d.settle = r.integer(dg["settle"], "run.diagram.settle", 0, 100000000);
    if (dg["points"]) d.points = static_cast<int>(r.integer(dg["points"], "run.diagram.points", 1, 100000));
    if (dg["directions"]) {
      const std::string dir = r.choice(dg["directions"], "run.diagram.directions", {"both", "up", "down"});
      d.up = dir != "down";
      d.down = dir != "up";
    }
    if (dg["max_period"]) d.max_period = static_cast<int>(r.integer(dg["max_period"], "run.diagram.max_period", 1, 50000));
    if (2 * d.max_period > d.points)
      r.fail(dg["max_period"] ? dg["max_period"] : dg, "run.diagram.max_period",
             "expected at most points / 2 = " + std::to_string(d.points / 2) +
                 " (a period k is recognised on 2k recorded points)");
    if (dg["tolerance"]) d.tolerance = r.number_in(dg["tolerance"], "run.diagram.tolerance", 1e-15, 0.1, "a relative tolerance in [1e-15, 0.1]");
    s.check_values(run.axes[0], dg, "run.diagram");
    if (!(s.frequency > 0.0))
      r.fail(s.run_node["kind"], "run.kind", "a diagram records stroboscopic points: it needs a forcing frequency > 0 (forcing.frequency)");
  }
}

}  // namespace

RunKindInfo diagram_kind() {
  RunKindInfo k;
  k.name = "diagram";
  k.kind = RunSpec::Kind::diagram;
  k.summary = "a brute-force bifurcation diagram along one parameter, up and down";
  k.section = "diagram";
  k.missing = "missing: run.kind: diagram needs run.diagram (path and grid)";
  k.groups = {"diagram", "impact_map", "section"};
  k.every_process = false;
  k.stoppable = true;
  k.parse = parse_diagram_section;
  k.run = run_diagram;
  return k;
}

}  // namespace vibro::io::detail
