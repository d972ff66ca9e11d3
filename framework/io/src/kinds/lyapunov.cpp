#include "vibro/io/kinds/lyapunov.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"
#include "../progress.hpp"

#include "vibro/io/result_file.hpp"
#include "vibro/bounded_wait.hpp"
#include "vibro/engine.hpp"
#include "vibro/friction_tangent.hpp"
#include "vibro/lyapunov.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <exception>
#include <mutex>
#include <optional>

namespace vibro::io {

RunReport run_lyapunov(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  using detail::integers;
  using detail::reals;
  const auto wall_start = std::chrono::steady_clock::now();
  const LyapunovSpec& spec = scene.run.lyapunov;
  const std::string path = spec.along ? scene.run.axes.at(0).path : std::string();
  const std::vector<double> grid = spec.along ? scene.run.axes.at(0).values : std::vector<double>{0.0};
  const std::size_t m = grid.size();
  const std::size_t p = static_cast<std::size_t>(spec.count > 0 ? spec.count : 2 * scene.dof());

  ResultFile file = open_result_file(request, scene, current_meta(1));
  std::vector<double> exponents(m * p, 0.0), sums(m, 0.0);
  std::vector<std::int64_t> finite(m * p, 0), structural(m, 0), reached(m, 0), dimension(m, 0);
  std::vector<std::string> messages(m);
  const long first_transient = static_cast<long>(std::ceil(scene.run.transient_periods));
  // Progress: the grid's points, or the forcing periods of the one point's run.
  detail::Progress points(request, "lyapunov", "points", spec.along ? static_cast<double>(m) : 0.0);
  std::optional<detail::SimulationProgress> periods;
  if (!spec.along)
    periods.emplace(request, "lyapunov", scene.t0,
                    scene.t0 + static_cast<double>(first_transient + spec.transient + spec.align + spec.periods) *
                                   scene.period(),
                    scene.period());
  // One grid point from (x, v): its spectrum into row g; false if its run stopped early.
  auto compute = [&](SceneDocument& point, std::size_t g, bool first, Eigen::VectorXd& x, Eigen::VectorXd& v) {
    if (spec.along) point.set(path, grid[g]);
    Scene built = spec.along ? point.build_point() : scene;
    built.solver.interrupt = request.interrupt;
    if (periods) built.solver.reached = periods->reached();
    LyapunovOptions options;
    options.count = spec.count;
    options.transient = spec.transient + (first ? first_transient : 0);
    options.align = spec.align;
    options.periods = spec.periods;
    LyapunovResult r;
    if (built.engine == EngineKind::modal) {  // matrix-free frames on the modal engine
      std::unique_ptr<Engine> engine;
      try {
        engine = make_engine(built);
      } catch (const Interrupted&) {  // in the set-up of the point's engine (bounded_wait.hpp): not reached
        const std::string what = "interrupted while its engine was set up";
        messages[g] = spec.along ? fmt::format("at {} = {:.12g}: {}", path, grid[g], what) : what;
        return false;
      }
      r = lyapunov_spectrum(dynamic_cast<ModalEngine&>(*engine), built.t0, x, v, options);
    } else if (!built.friction.empty() && !built.stops.empty()) {  // friction with stops (friction_tangent.hpp)
      r = lyapunov_spectrum(built.impact_system(), built.friction, built.solver, built.t0, x, v, options);
    } else if (!built.friction.empty()) {  // dry friction (friction_tangent.hpp)
      r = lyapunov_spectrum(built.system(), built.friction, built.solver, built.t0, x, v, options);
    } else if (built.engine == EngineKind::taylor) {  // nonlinear forces
      r = lyapunov_spectrum(built.impact_system(), built.forces, built.solver, built.t0, x, v, options);
    } else {
      r = lyapunov_spectrum(built.impact_system(), built.solver, built.t0, x, v, options);
    }
    if (r.status != RunStatus::completed) {
      messages[g] = spec.along ? fmt::format("at {} = {:.12g}: {}", path, grid[g], r.message) : r.message;
      return false;
    }
    for (std::size_t i = 0; i < p; ++i) {
      const double e = r.exponents(static_cast<Eigen::Index>(i));
      finite[g * p + i] = std::isfinite(e) ? 1 : 0;
      exponents[g * p + i] = std::isfinite(e) ? e : 0.0;
      if (std::isfinite(e)) sums[g] += e;
    }
    structural[g] = r.structural;
    dimension[g] = static_cast<std::int64_t>(r.least_free_dimension);
    reached[g] = 1;
    x = r.x_end;
    v = r.v_end;
    if (spec.along) points.add();
    return true;
  };
  int threads = 1;
  if (spec.follow || !spec.along) {
    SceneDocument point(doc);
    Eigen::VectorXd x = scene.x0, v = scene.v0;
    for (std::size_t g = 0; g < m; ++g)
      if (!compute(point, g, g == 0, x, v)) break;
  } else {
    // Independent points (each from the scene's initial state): in parallel, written in grid order.
    std::exception_ptr failure;
    std::mutex lock;
#ifdef _OPENMP
    if (request.threads > 0) omp_set_num_threads(request.threads);
    threads = omp_get_max_threads();
#pragma omp parallel
#endif
    {
      SceneDocument point(doc);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
      for (std::size_t g = 0; g < m; ++g) {
        try {
          Eigen::VectorXd x = scene.x0, v = scene.v0;
          (void)compute(point, g, true, x, v);
        } catch (...) {
          const std::lock_guard<std::mutex> hold(lock);
          if (!failure) failure = std::current_exception();
        }
      }
    }
    if (failure) std::rethrow_exception(failure);
  }
  std::string message;
  for (const std::string& text : messages)
    if (message.empty()) message = text;

  std::vector<Dataset> datasets{reals("exponents", exponents, {m, p}), integers("finite", finite),
                                integers("structural", structural), integers("free_dimension", dimension),
                                reals("sum", sums, {m}), integers("reached", reached)};
  datasets[1].shape = {m, p};
  if (spec.along) datasets.insert(datasets.begin(), reals("parameter", grid, {m}));
  file.write_group("lyapunov", datasets,
                   {{"parameter", path}, {"period", fmt::format("{:.17g}", scene.period())},
                    {"units", "per unit time (divide by Omega / (2 pi) for per forcing period)"}});
  long not_reached = 0;
  for (std::int64_t r : reached) not_reached += r ? 0 : 1;
  const bool interrupted = request.interrupt && request.interrupt->load();
  file.set_outcome(interrupted ? "interrupted" : not_reached ? "points_stopped_early" : "completed",
                   interrupted ? "interrupted: the points after it were not reached" : message,
                   {{"points", static_cast<std::int64_t>(m)}, {"points_not_reached", not_reached}});
  const double wall = detail::finish_run(file, threads, wall_start);

  std::string text;
  if (spec.along) {
    text = fmt::format("Lyapunov spectra ({} exponents) along {} over {} points in {:.2f} s.", p, path, m, wall);
  } else {
    text = fmt::format("Lyapunov spectrum ({} periods averaged, {:.2f} s):", spec.periods, wall);
    for (std::size_t i = 0; i < p; ++i)
      text += finite[i] ? fmt::format(" {:.6g}", exponents[i]) : std::string(" -inf");
  }
  if (not_reached > 0) text += fmt::format(" {} points not reached ({}).", not_reached, message);
  text += fmt::format("\nResults in {}.", file.path());
  return {interrupted ? 130 : not_reached ? 1 : 0, text, request.in_memory ? file.image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.lyapunov (docs/scenes.md).
void parse_lyapunov_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  const YAML::Node ly = s.node;
  if (s.full) {
    LyapunovSpec& l = run.lyapunov;
    if (!(s.frequency > 0.0))
      r.fail(s.run_node["kind"], "run.kind", "Lyapunov exponents are averaged over forcing periods: they need a forcing frequency > 0 (forcing.frequency)");
    if (ly) {
      r.expect_map(ly, "run.lyapunov", {"count", "transient", "align", "periods", "follow", "path", "linspace", "logspace", "values"});
      if (ly["count"]) l.count = static_cast<int>(r.integer(ly["count"], "run.lyapunov.count", 0, 2 * s.dof));
      if (ly["transient"]) l.transient = r.integer(ly["transient"], "run.lyapunov.transient", 0, 100000000);
      if (ly["align"]) l.align = r.integer(ly["align"], "run.lyapunov.align", 0, 100000000);
      if (ly["periods"]) l.periods = r.integer(ly["periods"], "run.lyapunov.periods", 1, 100000000);
      if (ly["path"] || ly["linspace"] || ly["logspace"] || ly["values"]) {
        run.axes.push_back(s.axis(ly, "run.lyapunov", {}, {"count", "transient", "align", "periods", "follow"}));
        s.monotonic(ly, "run.lyapunov");
        s.check_values(run.axes[0], ly, "run.lyapunov");
        l.along = true;
      }
      if (ly["follow"]) {
        l.follow = r.boolean(ly["follow"], "run.lyapunov.follow");
        if (!l.along) r.fail(ly["follow"], "run.lyapunov.follow", "only with a grid (run.lyapunov.path and its values)");
      }
    }
  }
}

}  // namespace

RunKindInfo lyapunov_kind() {
  RunKindInfo k;
  k.name = "lyapunov";
  k.kind = RunSpec::Kind::lyapunov;
  k.summary = "the Lyapunov spectrum at the scene's values or along one parameter";
  k.section = "lyapunov";
  k.missing = nullptr;
  k.groups = {"lyapunov"};
  k.every_process = false;
  k.stoppable = true;
  k.parse = parse_lyapunov_section;
  k.run = run_lyapunov;
  return k;
}

}  // namespace vibro::io::detail
