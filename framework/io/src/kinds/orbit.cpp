#include "vibro/io/kinds/orbit.hpp"

#include "kinds.hpp"
#include "../run_section.hpp"

#include "../datasets.hpp"
#include "../progress.hpp"

#include "vibro/engine.hpp"
#include "vibro/friction_tangent.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/shooting.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <vector>

namespace vibro::io {

RunReport run_orbit(const SceneDocument& /*doc*/, const Scene& scene, const RunRequest& request) {
  using detail::integers;
  using detail::reals;
  const auto wall_start = std::chrono::steady_clock::now();
  const OrbitSpec& spec = scene.run.orbit;
  // The guess: where run.transient_periods from `initial` lead, the long part of the run, shown
  // in periods (the engine lives on for the shooting, so the progress outlives it).
  const double T = 2.0 * std::numbers::pi / scene.forcing().frequency;
  const double t_guess = scene.t0 + scene.run.transient_periods * T;
  detail::SimulationProgress progress(request, "orbit", scene.t0, t_guess, T);
  Scene built = scene;
  built.solver.interrupt = request.interrupt;
  built.solver.reached = progress.reached();
  const std::unique_ptr<Engine> engine = make_engine(built);
  ResultFile file = open_result_file(request, scene, current_meta(1));
  const RunSummary guess = engine->run(scene.t0, scene.x0, scene.v0, t_guess);
  progress.stop();
  ShootingOptions o;
  o.period = spec.period;
  o.phase = spec.phase;
  o.tolerance = spec.tolerance;
  o.max_iterations = spec.max_iterations;
  o.solver = built.solver;
  o.solver.reached = nullptr;
  ShootingResult r;
  const bool interrupted_guess = guess.status == RunStatus::interrupted;
  if (guess.status != RunStatus::completed) {
    r.status = ShootingStatus::map_failed;
    r.message = std::string("the guess's run stopped early (") + to_string(guess.status) + "): " + guess.message;
    r.x = guess.x;
    r.v = guess.v;
  } else {
    try {
      if (auto* modal = dynamic_cast<ModalEngine*>(engine.get())) {
        KrylovOptions k;
        k.multipliers = spec.multipliers;
        r = shoot(*modal, o, guess.t, guess.x, guess.v, k);
      } else if (!scene.friction.empty() && !scene.stops.empty()) {  // friction with stops
        r = shoot(scene.impact_system(), scene.friction, o, guess.t, guess.x, guess.v);
      } else if (!scene.friction.empty()) {
        r = shoot(scene.system(), scene.friction, o, guess.t, guess.x, guess.v);
      } else if (scene.engine == EngineKind::taylor) {
        r = shoot(scene.impact_system(), scene.forces, o, guess.t, guess.x, guess.v);
      } else {
        r = shoot(scene.impact_system(), o, guess.t, guess.x, guess.v);
      }
    } catch (const InvalidInput&) {
      // Shooting's own runs (the section's) stopped by the interrupt: not bad input.
      if (!(request.interrupt && request.interrupt->load())) throw;
      r.status = ShootingStatus::map_failed;
      r.message = "interrupted";
      r.x = guess.x;
      r.v = guess.v;
    }
  }
  const bool interrupted = interrupted_guess || (request.interrupt && request.interrupt->load());

  const FloquetMultipliers& f = r.multipliers;
  std::vector<double> re, im;
  if (r.converged())
    for (Eigen::Index i = 0; i < f.values.size(); ++i) {
      re.push_back(f.values(i).real());
      im.push_back(f.values(i).imag());
    }
  auto values = [](const Eigen::VectorXd& a) { return std::vector<double>(a.data(), a.data() + a.size()); };
  // The state (at t0, or where the guess's run stopped) in the result's frame (record.frame).
  ResultFrame::of(scene).to_result(guess.status != RunStatus::completed ? guess.t : r.t0, r.x, r.v);
  std::vector<Dataset> datasets{reals("x", values(r.x), {static_cast<std::size_t>(r.x.size())}),
                                reals("v", values(r.v), {static_cast<std::size_t>(r.v.size())}),
                                reals("residuals", r.residuals, {r.residuals.size()}),
                                reals("multipliers_real", re, {re.size()}),
                                reals("multipliers_imag", im, {im.size()})};
  auto number = [](double v) { return fmt::format("{:.17g}", v); };
  // Arnoldi's leading value may not converge (a long chain's nearly free modes crowd the unit
  // circle): the verdict is then undetermined, not "unstable".
  const std::string stability = !r.converged() ? "none"
                                : f.leading_only && f.converged_count == 0 ? "undetermined"
                                : f.stable ? "stable" : "unstable";
  file.write_group("orbit", datasets,
                   {{"status", to_string(r.status)},
                    {"message", r.message},
                    {"t0", number(r.t0)},
                    {"phase", number(r.phase)},
                    {"period", std::to_string(spec.period)},
                    {"minimal_period", std::to_string(r.converged() ? r.minimal_k : 0)},
                    {"residual", number(r.residual)},
                    {"iterations", std::to_string(r.iterations)},
                    {"stable", r.converged() && f.stable ? "true" : "false"},
                    {"stability", stability},
                    {"spectral_radius", number(f.spectral_radius)},
                    {"structural_zeros", std::to_string(f.structural_zeros)},
                    {"leading_only", f.leading_only ? "true" : "false"},
                    {"converged_multipliers", std::to_string(f.leading_only ? f.converged_count : static_cast<int>(f.values.size()))},
                    {"krylov_products", std::to_string(r.krylov_products + f.products)}});
  const std::string status = interrupted ? "interrupted" : r.converged() ? "completed" : "not_converged";
  file.set_outcome(status, r.converged() ? std::string() : r.message,
                   {{"iterations", static_cast<std::int64_t>(r.iterations)}});
  const double wall = detail::finish_run(file, 1, wall_start);

  std::string text;
  if (r.converged()) {
    text = fmt::format("Periodic orbit of period {}T (least period {}T) in {} Newton iterations, residual {:.2g}, "
                       "{:.2f} s; largest |multiplier| {:.10g}: {}.",
                       spec.period, r.minimal_k, r.iterations, r.residual, wall, f.spectral_radius,
                       stability == "undetermined"
                           ? "stability undetermined (Arnoldi's leading value did not converge)"
                           : stability);
    if (f.leading_only)
      text += fmt::format(" (modal engine: {} leading multipliers by Arnoldi, {} converged; {} J·v products.)",
                          f.values.size(), f.converged_count, r.krylov_products + f.products);
  } else {
    text = fmt::format("No periodic orbit: {} ({:.2f} s).", r.message, wall);
  }
  text += fmt::format("\nResults in {}.", file.path());
  return {interrupted ? 130 : r.converged() ? 0 : 1, text, request.in_memory ? file.image() : std::vector<char>{}};
}

}  // namespace vibro::io

namespace vibro::io::detail {
namespace {

/// run.orbit (docs/scenes.md).
void parse_orbit_section(RunSection& s) {
  Reader& r = s.r;
  RunSpec& run = s.run;
  if (const YAML::Node ob = s.node) {
    r.expect_map(ob, "run.orbit", {"period", "phase", "tolerance", "max_iterations", "multipliers"});
    OrbitSpec& o = run.orbit;
    if (ob["period"]) o.period = static_cast<int>(r.integer(ob["period"], "run.orbit.period", 1, 1024));
    if (ob["phase"]) o.phase = r.number_in(ob["phase"], "run.orbit.phase", -1e3, 1e3, "a phase in radians");
    if (ob["tolerance"]) o.tolerance = r.number_in(ob["tolerance"], "run.orbit.tolerance", 1e-15, 1e-4, "a relative tolerance in [1e-15, 1e-4]");
    if (ob["max_iterations"]) o.max_iterations = static_cast<int>(r.integer(ob["max_iterations"], "run.orbit.max_iterations", 1, 1000));
    if (ob["multipliers"]) o.multipliers = static_cast<int>(r.integer(ob["multipliers"], "run.orbit.multipliers", 1, 100));
  }
  if (!(s.frequency > 0.0))
    r.fail(s.run_node["kind"], "run.kind", "a periodic orbit's period is 2π/Ω: it needs a forcing frequency > 0 (forcing.frequency)");
}

}  // namespace

RunKindInfo orbit_kind() {
  RunKindInfo k;
  k.name = "orbit";
  k.kind = RunSpec::Kind::orbit;
  k.summary = "one periodic orbit by Newton shooting, with its Floquet multipliers";
  k.section = "orbit";
  k.missing = nullptr;
  k.groups = {"orbit"};
  k.every_process = false;
  k.stoppable = true;
  k.parse = parse_orbit_section;
  k.run = run_orbit;
  return k;
}

}  // namespace vibro::io::detail
