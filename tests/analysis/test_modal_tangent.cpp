/// Tests of the modal engine's matrix-free tangent map (analysis/modal_tangent.hpp):
///  * against the dense engine's tangent map (linearisation.hpp, itself tested against long-double
///    finite differences and closed forms) on the same chains, through impacts, chatter, sticking
///    and release, on both routes to a contact set's modes (tridiagonal and secular), the
///    parameter derivatives ∂z1/∂p (Ω, forcing, stop offsets and motion, restitution) included;
///  * against central finite differences of the modal engine's own map;
///  * the reduced map (structural zeros) and the record's validity.
#include "support/chains.hpp"
#include "support/analysis_helpers.hpp"
#include "vibro/bounded_wait.hpp"
#include "vibro/lyapunov.hpp"
#include "vibro/modal_tangent.hpp"
#include "vibro/shooting.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <atomic>
#include <ios>
#include <cmath>
#include <complex>
#include <numbers>
#include <set>
#include <string>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::BandedChain;
using vibro::Stop;
using vibro::test::stack;

using vibro::test::uniform_chain;

/// A state of the run from rest at a time t0 ≥ `after` in free flight, at least `clearance` from
/// every event and outside every held phase (a map from a held start is one-sided; see the header).
struct FreeStart {
  double t0 = 0.0;
  VectorXd x, v;
};
FreeStart free_start(const vibro::ImpactSystem& scene, double after, double before, double clearance) {
  const auto n = scene.dof();
  vibro::LinearisationOptions o;
  o.jacobian = false;
  const VectorXd zero = VectorXd::Zero(n);
  const vibro::TangentMap m = vibro::linearise(scene, {}, 0.0, zero, zero, before, o);
  REQUIRE(m.summary.status == vibro::RunStatus::completed);
  std::vector<std::pair<double, double>> busy;
  for (const auto& e : m.events) busy.push_back({e.t, e.t});
  // Held phases from the saltations' held sets (the features' phases, without their costly scan).
  double held_since = m.starts_held ? 0.0 : -1.0;
  for (const auto& r : m.saltations) {
    if (held_since < 0.0 && !r.held_after.empty()) held_since = r.t;
    if (held_since >= 0.0 && r.held_after.empty()) {
      busy.push_back({held_since, r.t});
      held_since = -1.0;
    }
  }
  if (held_since >= 0.0) busy.push_back({held_since, before});
  for (double t = after; t < before; t += 0.01 * clearance) {
    bool ok = true;
    for (const auto& [a, b] : busy) ok = ok && (t < a - clearance || t > b + clearance);
    if (!ok) continue;
    vibro::Simulator sim(scene);
    const auto s = sim.run(0.0, zero, zero, t);
    return {t, s.x, s.v};
  }
  FAIL("no free start found");
  return {};
}

struct Compared {
  double jacobian = 0.0;     // max |J_modal − J_dense| / max |J_dense|
  double end_state = 0.0;    // relative
  long impacts = 0, sticks = 0, releases = 0;
  vibro::TangentMap dense, modal;
};

/// Both runs completed, with the same events (kind and stop) in the same order.
void require_same_events(const vibro::TangentMap& dense, const vibro::TangentMap& modal) {
  REQUIRE(dense.summary.status == vibro::RunStatus::completed);
  INFO(modal.summary.message);
  REQUIRE(modal.summary.status == vibro::RunStatus::completed);
  REQUIRE(modal.events.size() == dense.events.size());
  for (std::size_t e = 0; e < dense.events.size(); ++e) {
    REQUIRE(modal.events[e].kind == dense.events[e].kind);
    REQUIRE(modal.events[e].stop == dense.events[e].stop);
  }
}

Compared compare(const BandedChain& chain, const std::vector<Stop>& stops, double periods, double span,
                 const vibro::ModalSimulatorOptions& options = {}) {
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const vibro::ImpactSystem scene(chain.dense(), stops);
  const FreeStart s = free_start(scene, periods * T, (periods + 2.0) * T, 0.02 * T);
  Compared out;
  out.dense = vibro::linearise(scene, {}, s.t0, s.x, s.v, s.t0 + span * T);
  vibro::ModalEngine engine(chain, stops, options);
  out.modal = vibro::linearise(engine, s.t0, s.x, s.v, s.t0 + span * T);
  require_same_events(out.dense, out.modal);
  out.jacobian = (out.modal.jacobian - out.dense.jacobian).cwiseAbs().maxCoeff() /
                 out.dense.jacobian.cwiseAbs().maxCoeff();
  out.end_state = (stack(out.modal.x1, out.modal.v1) - stack(out.dense.x1, out.dense.v1)).cwiseAbs().maxCoeff() /
                  std::max(1.0, stack(out.dense.x1, out.dense.v1).cwiseAbs().maxCoeff());
  out.impacts = out.dense.summary.impacts;
  out.sticks = out.dense.summary.sticks;
  out.releases = out.dense.summary.releases;
  return out;
}

/// Seven masses' stops visiting several contact sets: a moving plastic stop, a plastic stop between
/// neighbours, a bouncing stop.
std::vector<Stop> several_sets_stops() {
  return {Stop::upper(1, 0.25, 0.0).moving(0.05, 0.4), Stop::between(3, 4, 0.15, 0.0), Stop::lower(6, -0.4, 0.7)};
}

/// f(options) on both routes to a contact set's modes (the reduced chain's tridiagonal
/// eigenproblem, the secular equation).
template <class F>
void on_both_routes(F&& f) {
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    vibro::ModalSimulatorOptions o;
    o.contact_modes = route;
    f(o);
  }
}

/// The parameter directions compared below, by name: d/dΩ, a forcing amplitude (the cosine on mass
/// 0, which carries the drive), every stop's offset and restitution (where r > 0: at r = 0 the
/// stop sticks and r's derivative is one-sided), and a moving stop's two harmonic amplitudes.
std::vector<std::pair<std::string, vibro::SystemDerivative>> parameter_directions(const std::vector<Stop>& stops,
                                                                                  Eigen::Index n) {
  std::vector<std::pair<std::string, vibro::SystemDerivative>> out;
  out.emplace_back("frequency", vibro::SystemDerivative::frequency_only());
  vibro::SystemDerivative drive;
  drive.cosine = VectorXd::Unit(n, 0);
  out.emplace_back("forcing cosine on mass 0", drive);
  vibro::SystemDerivative steady;
  steady.constant = VectorXd::Constant(n, 0.1);
  steady.sine = VectorXd::Unit(n, n - 1);
  out.emplace_back("forcing constant and sine", steady);
  for (std::size_t j = 0; j < stops.size(); ++j) {
    auto stop = [&](const std::string& what, auto set) {
      vibro::SystemDerivative d;
      d.stops.resize(stops.size());
      set(d.stops[j]);
      out.emplace_back("stop " + std::to_string(j) + " " + what, d);
    };
    stop("offset", [](vibro::StopDerivative& s) { s.offset = 1.0; });
    if (stops[j].restitution > 0.0) stop("restitution", [](vibro::StopDerivative& s) { s.restitution = 1.0; });
    if (stops[j].amplitude != 0.0) {
      stop("cosine", [](vibro::StopDerivative& s) { s.cosine = 1.0; });
      stop("sine", [](vibro::StopDerivative& s) { s.sine = 1.0; });
    }
  }
  return out;
}

/// Non-zero eigenvalues of a reduced map by decreasing modulus.
Eigen::VectorXcd sorted_eigenvalues(const MatrixXd& reduced) {
  Eigen::VectorXcd mu = reduced.eigenvalues();
  std::sort(mu.data(), mu.data() + mu.size(), [](auto a, auto b) { return std::abs(a) > std::abs(b); });
  return mu;
}

}  // namespace

// Both maps are exact to rounding: the engines' trajectories agree to ~1e-13 per event
// (tests/framework/test_modal.cpp), and each map is a product of flow propagators (exact on both,
// ~1e-14) and saltation matrices whose entries carry 1/ḣ⁻ (impact speeds here ≥ 1e-2 V, so an
// event-time difference of 1e-13 moves them by ≤ 1e-11 relative). Over a few dozen events with
// |J| up to ~10², 1e-8 of max |J| is a bound with two orders of margin over what rounding gives,
// while a wrong saltation term (a missing time-shift term, the wrong vector field, the wrong
// projection) changes entries at the 1e-2 level or more.
TEST_CASE("modal tangent map: equals the dense engine's through impacts, chatter, sticking and release",
          "[modal_tangent]") {
  const double tol = 1e-8;
  SECTION("6 masses, a chattering stop into sticking and a second stop (tridiagonal route)") {
    const BandedChain chain = uniform_chain(6, 0.05, 0.6, 0.35);
    const Compared c = compare(chain, {Stop::upper(0, 0.3, 0.6), Stop::lower(3, -0.2, 0.8)}, 3.0, 1.0);
    CHECK(c.impacts > 5);
    CHECK(c.sticks >= 1);
    CHECK(c.releases >= 1);
    CHECK(c.end_state <= tol);
    CHECK(c.jacobian <= tol);
    // The map loses rank while the stop holds: the same structural zeros, the same multipliers.
    CHECK(c.modal.free_dimension == c.dense.free_dimension);
    REQUIRE(c.modal.free_dimension < 12);
    const Eigen::VectorXcd a = sorted_eigenvalues(c.modal.reduced), b = sorted_eigenvalues(c.dense.reduced);
    REQUIRE(a.size() == b.size());
    CHECK((a - b).cwiseAbs().maxCoeff() <= tol * std::max(1.0, std::abs(b(0))));
  }
  SECTION("7 masses, plastic stops on a moving stop and between neighbours, the secular route") {
    const BandedChain chain = uniform_chain(7, 0.05, 0.7, 0.4);
    vibro::ModalSimulatorOptions o;
    o.contact_modes = vibro::TridiagonalSolver::secular;
    const Compared c = compare(chain, {Stop::upper(1, 0.25, 0.0), Stop::between(3, 4, 0.15, 0.0)}, 3.0, 1.5, o);
    CHECK(c.impacts > 0);
    CHECK(c.sticks >= 1);
    CHECK(c.end_state <= tol);
    CHECK(c.jacobian <= tol);
  }
}

// ∂z1/∂p on both engines, for every kind of parameter the modal map takes. Both are exact to
// rounding: the dense one from the block exponential of [[Â, dÂ/dp], [0, Â]] (Van Loan) and
// dual-number saltations, the modal one from the particular solution's derivative at each
// segment's ends and the same dual-number resets on the banded form; their trajectories agree to
// ~1e-13 per event (see the tolerance above). Measured: ≤ 7e-13 of max |∂z1/∂p| on these runs
// (the Jacobians: 2e-13); 1e-10 leaves a factor 100 for other platforms' rounding, while leaving
// out any one term (an event's h_p, the general path's R_p, the free-flight impact's h_p or κ, a
// flight's particular part at its start) makes the directions it enters differ by O(1) of
// max |∂z1/∂p| (0.25 to 20; checked by removing each in turn). R_p of an impact into sticking only moves the
// normal velocity, which the next held flight projects away, so the general path (modal_events
// false) is what tests R_p of a rebound.
TEST_CASE("modal tangent map: parameter derivatives equal the dense engine's (frequency, forcing, stop "
          "offsets, moving stops, restitution)",
          "[modal_tangent]") {
  const double tol = 1e-10;
  // One modal record serves every direction (ModalTangent::parameter); the dense map is run per
  // direction. `check_run` checks what the run goes through.
  // One modal record serves every direction (ModalTangent::parameter), on each path for
  // free-flight impacts (modal coordinates, or the general one: R_p by dual numbers); the dense map
  // is run per direction. `check_run` checks what the run goes through.
  auto check_all = [&](const BandedChain& chain, const std::vector<Stop>& stops, double span,
                       const vibro::ModalSimulatorOptions& options, auto&& check_run) {
    const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
    const vibro::ImpactSystem scene(chain.dense(), stops);
    const FreeStart s = free_start(scene, 3.0 * T, 5.0 * T, 0.02 * T);
    const auto directions = parameter_directions(stops, chain.dof());
    std::vector<vibro::TangentMap> dense;
    for (const auto& direction : directions) {
      vibro::LinearisationOptions lin;
      lin.jacobian = false;
      lin.parameter = direction.second;
      dense.push_back(vibro::linearise(scene, {}, s.t0, s.x, s.v, s.t0 + span * T, lin));
    }
    vibro::ModalEngine engine(chain, stops, options);
    for (const bool modal_events : {true, false}) {
      const vibro::ModalTangent tangent(engine, s.t0, s.x, s.v, s.t0 + span * T, modal_events);
      std::set<vibro::ContactSet> sets{{}};
      for (const auto& r : tangent.map().saltations) sets.insert(r.held_after);
      check_run(tangent.map().summary, sets.size());
      for (std::size_t k = 0; k < directions.size(); ++k) {
        INFO("d/dp: " << directions[k].first << (modal_events ? "" : " (general path)"));
        require_same_events(dense[k], tangent.map());
        const VectorXd modal = tangent.parameter(directions[k].second);
        const double size = dense[k].parameter.cwiseAbs().maxCoeff();
        const double relative = (modal - dense[k].parameter).cwiseAbs().maxCoeff() / size;
        INFO("max |dz1/dp| " << std::scientific << size << ", relative difference " << relative);
        CHECK(size > 0.0);
        CHECK(relative <= tol);
      }
    }
  };
  SECTION("8 masses, free-flight impacts only") {
    check_all(uniform_chain(8, 0.05, 0.6, 0.35), {Stop::upper(0, 0.3, 0.8), Stop::lower(5, -0.15, 0.7)}, 1.0, {},
              [](const vibro::RunSummary& r, std::size_t sets) {
                CHECK(r.impacts >= 2);
                CHECK(r.sticks == 0);
                CHECK(sets == 1);
              });
  }
  SECTION("6 masses, chatter into sticking and release") {
    check_all(uniform_chain(6, 0.05, 0.6, 0.35), {Stop::upper(0, 0.3, 0.6), Stop::lower(3, -0.2, 0.8)}, 1.0, {},
              [](const vibro::RunSummary& r, std::size_t) {
                CHECK(r.impacts > 5);
                CHECK(r.chatters >= 1);
                CHECK(r.sticks >= 1);
                CHECK(r.releases >= 1);
              });
  }
  SECTION("7 masses, a moving stop and a stop between neighbours: several contact sets, both routes") {
    on_both_routes([&](const vibro::ModalSimulatorOptions& o) {
      check_all(uniform_chain(7, 0.05, 0.7, 0.4), several_sets_stops(), 1.5, o,
                [](const vibro::RunSummary& r, std::size_t sets) {
                  CHECK(r.sticks >= 2);
                  CHECK(sets >= 3);
                });
    });
  }
}

TEST_CASE("modal tangent map: a parameter derivative that moves M, C or K is refused, saying so", "[modal_tangent]") {
  const BandedChain chain = uniform_chain(4, 0.05, 0.6, 0.35);
  vibro::ModalEngine engine(chain, {Stop::upper(0, 0.3, 0.8)}, {});
  const VectorXd zero = VectorXd::Zero(4);
  vibro::SystemDerivative stiffness;
  stiffness.stiffness = MatrixXd::Zero(4, 4);
  stiffness.stiffness(1, 1) = 1.0;
  vibro::SystemDerivative mass;
  mass.mass = MatrixXd::Identity(4, 4);
  for (const vibro::SystemDerivative& d : {stiffness, mass}) {
    vibro::LinearisationOptions o;
    o.parameter = d;
    CHECK_THROWS_WITH(vibro::linearise(engine, 0.0, zero, zero, 5.0, o),
                      Catch::Contains("derivatives of the mass, damping or stiffness matrices are not available on "
                                      "the modal engine") &&
                          Catch::Contains("use the dense engine"));
    const vibro::ModalTangent tangent(engine, 0.0, zero, zero, 5.0);
    CHECK_THROWS_AS(tangent.parameter(d), vibro::InvalidInput);
  }
  // Matrices that do not move (zero) are no obstacle, and a wrong size is named.
  vibro::SystemDerivative still = vibro::SystemDerivative::frequency_only();
  still.damping = MatrixXd::Zero(4, 4);
  vibro::LinearisationOptions o;
  o.parameter = still;
  CHECK(vibro::linearise(engine, 0.0, zero, zero, 5.0, o).parameter.size() == 8);
  o.parameter->constant = VectorXd::Ones(3);
  CHECK_THROWS_WITH(vibro::linearise(engine, 0.0, zero, zero, 5.0, o), Catch::Contains("dF0/dp"));
}

namespace {

/// The largest differences between the features of two maps of the same run, each in its scale
/// (times in T, gaps in L, forces in F, speeds in V, accelerations relative to the largest one);
/// counts must agree.
struct FeatureDifferences {
  double time = 0.0, gap = 0.0, force = 0.0, speed = 0.0, acceleration = 0.0;
  std::size_t peaks = 0, dips = 0, past_release = 0, impacts = 0, phases = 0;
};

FeatureDifferences feature_differences(const vibro::TangentMap& dense, const vibro::TangentMap& modal) {
  const vibro::RunSummary& r = dense.summary;
  const double T = r.time_scale, L = r.length_scale, F = r.force_scale, V = r.velocity_scale;
  FeatureDifferences out;
  auto time = [&](double a, double b) { out.time = std::max(out.time, std::abs(a - b) / T); };
  REQUIRE(modal.gap_peaks.size() == dense.gap_peaks.size());
  for (std::size_t k = 0; k < dense.gap_peaks.size(); ++k) {
    CHECK(modal.gap_peaks[k].stop == dense.gap_peaks[k].stop);
    time(modal.gap_peaks[k].t, dense.gap_peaks[k].t);
    out.gap = std::max(out.gap, std::abs(modal.gap_peaks[k].value - dense.gap_peaks[k].value) / L);
  }
  REQUIRE(modal.force_dips.size() == dense.force_dips.size());
  for (std::size_t k = 0; k < dense.force_dips.size(); ++k) {
    CHECK(modal.force_dips[k].stop == dense.force_dips[k].stop);
    CHECK(modal.force_dips[k].past_release == dense.force_dips[k].past_release);
    out.past_release += dense.force_dips[k].past_release;
    time(modal.force_dips[k].t, dense.force_dips[k].t);
    out.force = std::max(out.force, std::abs(modal.force_dips[k].value - dense.force_dips[k].value) / F);
  }
  REQUIRE(modal.impacts.size() == dense.impacts.size());
  double A = V / T;
  for (const auto& i : dense.impacts) A = std::max(A, std::abs(i.acceleration));
  for (std::size_t k = 0; k < dense.impacts.size(); ++k) {
    CHECK(modal.impacts[k].stop == dense.impacts[k].stop);
    time(modal.impacts[k].t, dense.impacts[k].t);
    out.speed = std::max(out.speed, std::abs(modal.impacts[k].speed - dense.impacts[k].speed) / V);
    out.acceleration =
        std::max(out.acceleration, std::abs(modal.impacts[k].acceleration - dense.impacts[k].acceleration) / A);
  }
  REQUIRE(modal.phases.size() == dense.phases.size());
  for (std::size_t k = 0; k < dense.phases.size(); ++k) {
    CHECK(modal.phases[k].stop == dense.phases[k].stop);
    CHECK(modal.phases[k].closed == dense.phases[k].closed);
    time(modal.phases[k].t_start, dense.phases[k].t_start);
    time(modal.phases[k].t_end, dense.phases[k].t_end);
  }
  out.peaks = dense.gap_peaks.size();
  out.dips = dense.force_dips.size();
  out.impacts = dense.impacts.size();
  out.phases = dense.phases.size();
  return out;
}

}  // namespace

// The features (gap peaks, force dips with those past a release, impacts, phases) on both engines.
// Both locate an extremum as the root of the guard's slope, certified, to a few ulps of t, on
// trajectories that agree to ~1e-13 (to ~1e-11 late in a chatter sequence, whose impacts amplify
// differences): the values (stationary there) agree as the trajectories do, the times as well
// divided by the slope's rate of change. Measured: ≤ 3.6e-12 (times, in T), 9e-14 (gaps, in L),
// 3e-14 (forces, in F), 1.8e-11 (impact speeds, in V), 2.1e-11 (impact accelerations, relative);
// 1e-9 leaves a factor 50 or more; a missing or extra feature, or one of another stop, fails.
TEST_CASE("modal tangent map: features equal the dense engine's (gap peaks, force dips, impacts, phases)",
          "[modal_tangent]") {
  const double tol = 1e-9;
  auto check = [&](const BandedChain& chain, const std::vector<Stop>& stops, double span,
                   const vibro::ModalSimulatorOptions& options) {
    const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
    const vibro::ImpactSystem scene(chain.dense(), stops);
    const FreeStart s = free_start(scene, 3.0 * T, 5.0 * T, 0.02 * T);
    vibro::LinearisationOptions lin;
    lin.jacobian = false;
    lin.features = true;
    const vibro::TangentMap dense = vibro::linearise(scene, {}, s.t0, s.x, s.v, s.t0 + span * T, lin);
    vibro::ModalEngine engine(chain, stops, options);
    const vibro::TangentMap modal = vibro::linearise(engine, s.t0, s.x, s.v, s.t0 + span * T, lin);
    require_same_events(dense, modal);
    const FeatureDifferences d = feature_differences(dense, modal);
    INFO("peaks " << d.peaks << ", dips " << d.dips << " (" << d.past_release << " past a release), impacts "
                  << d.impacts << ", phases " << d.phases);
    INFO(std::scientific << "time " << d.time << ", gap " << d.gap << ", force " << d.force << ", speed " << d.speed
                         << ", acceleration " << d.acceleration);
    CHECK(d.time <= tol);
    CHECK(d.gap <= tol);
    CHECK(d.force <= tol);
    CHECK(d.speed <= tol);
    CHECK(d.acceleration <= tol);
    return d;
  };
  SECTION("8 masses, free-flight impacts only") {
    const FeatureDifferences d =
        check(uniform_chain(8, 0.05, 0.6, 0.35), {Stop::upper(0, 0.4, 0.8), Stop::lower(5, -0.15, 0.7)}, 1.0, {});
    CHECK(d.peaks >= 3);
    CHECK(d.impacts >= 5);
    CHECK(d.phases == 0);
  }
  SECTION("6 masses, chatter into sticking and release") {
    const FeatureDifferences d =
        check(uniform_chain(6, 0.05, 0.6, 0.35), {Stop::upper(0, 0.3, 0.6), Stop::lower(3, -0.2, 0.8)}, 2.0, {});
    CHECK(d.impacts > 5);
    CHECK(d.phases >= 2);
    CHECK(d.past_release >= 2);
  }
  SECTION("6 masses pressed onto a plastic stop: held phases with interior force minima") {
    BandedChain chain = uniform_chain(6, 0.05, 0.8, 0.35);
    chain.forcing.constant(0) = 0.3;
    const FeatureDifferences d = check(chain, {Stop::upper(0, 0.2, 0.0), Stop::lower(3, -0.2, 0.8)}, 2.0, {});
    CHECK(d.peaks >= 3);
    CHECK(d.dips - d.past_release >= 2);
    CHECK(d.past_release >= 2);
    CHECK(d.phases >= 2);
  }
  SECTION("7 masses, a moving stop and a stop between neighbours, both routes") {
    on_both_routes([&](const vibro::ModalSimulatorOptions& o) {
      const FeatureDifferences d = check(uniform_chain(7, 0.05, 0.7, 0.4), several_sets_stops(), 2.0, o);
      CHECK(d.peaks >= 3);
      CHECK(d.phases >= 2);
      CHECK(d.dips >= 1);
    });
  }
}

// Central differences of the modal engine's own map along random directions: error
// O(h² |∂³φ|) + O(ε |φ| / h); with h = 1e-6 (relative to the state's scales) both are ~1e-10 to
// 1e-9 of |J d| here, so 1e-6 is a wide bound that still catches any wrong term (≥ 1e-3).
TEST_CASE("modal tangent map: products equal central differences of the modal engine's map", "[modal_tangent]") {
  const BandedChain chain = uniform_chain(8, 0.05, 0.6, 0.35);
  const std::vector<Stop> stops{Stop::upper(0, 0.3, 0.8), Stop::lower(5, -0.15, 0.7)};
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const vibro::ImpactSystem scene(chain.dense(), stops);
  const FreeStart s = free_start(scene, 3.0 * T, 5.0 * T, 0.02 * T);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::ModalTangent tangent(engine, s.t0, s.x, s.v, s.t0 + T);
  REQUIRE(tangent.map().summary.status == vibro::RunStatus::completed);
  const long impacts = tangent.map().summary.impacts;
  REQUIRE(impacts > 0);
  const MatrixXd D = MatrixXd::Random(16, 3);
  const VectorXd scale = vibro::test::state_scale(8, tangent.map().summary.length_scale, tangent.map().summary.velocity_scale);
  const double h = 1e-6;
  for (int c = 0; c < 3; ++c) {
    const VectorXd d = D.col(c).cwiseProduct(scale);
    const VectorXd z = stack(s.x, s.v);
    auto map = [&](const VectorXd& z0) {
      vibro::ModalEngine e(chain, stops, {});
      const auto r = e.run(s.t0, z0.head(8), z0.tail(8), s.t0 + T);
      REQUIRE(r.status == vibro::RunStatus::completed);
      REQUIRE(r.impacts == impacts);
      return stack(r.x, r.v);
    };
    const VectorXd fd = (map(z + h * d) - map(z - h * d)) / (2.0 * h);
    const VectorXd exact = tangent.apply(d);
    INFO("direction " << c);
    CHECK((fd - exact).cwiseAbs().maxCoeff() <= 1e-6 * exact.cwiseAbs().maxCoeff());
  }
}

// The free-flight fast path (impacts applied in modal coordinates, ModalTangent's FreeImpact) and
// the general path (every event in physical coordinates, by dual numbers) are two derivations of
// the same map: they agree to rounding of the O(N²) basis changes, ~1e-14 of |J d|; 1e-11 leaves
// margin and catches any wrong term of the fast path's formula (each is O(1) of |J d|).
TEST_CASE("modal tangent map: free-flight impacts in modal coordinates equal the general path", "[modal_tangent]") {
  const BandedChain chain = uniform_chain(40, 0.05, 0.6, 0.35);
  const std::vector<Stop> stops{Stop::upper(0, 0.3, 0.8), Stop::lower(5, -0.15, 0.7), Stop::upper(30, 0.1, 0.5)};
  const VectorXd zero = VectorXd::Zero(40);
  vibro::ModalEngine engine(chain, stops, {});
  const auto warm = engine.run(0.0, zero, zero, 40.0);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  const MatrixXd D = MatrixXd::Random(80, 4);
  MatrixXd fast, general;
  long impacts = 0;
  {
    const vibro::ModalTangent t(engine, 40.0, warm.x, warm.v, 60.0, true);
    fast = t.apply(D);
    impacts = t.map().summary.impacts;
    CHECK((t.physical_coordinates(t.apply_modal(t.modal_coordinates(D))) - fast).cwiseAbs().maxCoeff() <=
          1e-11 * fast.cwiseAbs().maxCoeff());
  }
  {
    const vibro::ModalTangent t(engine, 40.0, warm.x, warm.v, 60.0, false);
    general = t.apply(D);
  }
  CHECK(impacts >= 3);
  CHECK((fast - general).cwiseAbs().maxCoeff() <= 1e-11 * general.cwiseAbs().maxCoeff());
}

TEST_CASE("modal tangent map: a record refuses to be used after the engine ran again", "[modal_tangent]") {
  const BandedChain chain = uniform_chain(4, 0.05, 0.6, 0.35);
  vibro::ModalEngine engine(chain, {Stop::upper(0, 0.3, 0.8)}, {});
  const VectorXd zero = VectorXd::Zero(4);
  const vibro::ModalTangent tangent(engine, 0.0, zero, zero, 5.0);
  CHECK(tangent.apply(MatrixXd::Identity(8, 1)).size() == 8);
  engine.run(0.0, zero, zero, 1.0);
  CHECK_THROWS_AS(tangent.apply(MatrixXd::Identity(8, 1)), std::logic_error);
  // A cache too small for the run's contact sets: no map, and why.
  {
    const BandedChain c6 = uniform_chain(6, 0.05, 0.7, 0.4);
    vibro::ModalSimulatorOptions tiny;
    tiny.mode_cache_bytes = 1.0;  // every new set drops the one before
    vibro::ModalEngine e(c6, {Stop::upper(1, 0.25, 0.0), Stop::between(3, 4, 0.15, 0.0)}, tiny);
    const VectorXd z6 = VectorXd::Zero(6);
    const vibro::ModalTangent t(e, 0.0, z6, z6, 60.0);
    CHECK(t.map().summary.status == vibro::RunStatus::unsupported);
    CHECK_THAT(t.map().summary.message, Catch::Contains("mode_cache_bytes"));
    CHECK_THROWS_AS(t.apply(MatrixXd::Identity(12, 1)), std::logic_error);
  }
  CHECK_THROWS_AS(vibro::linearise(engine, 0.0, zero, zero, 1.0, [] {
                    vibro::LinearisationOptions o;
                    o.directions = MatrixXd::Identity(7, 1);
                    return o;
                  }()),
                  vibro::InvalidInput);
}

// fill_jacobian carries J's 2N columns in blocks (of 64 to 127) so that it can look at the
// interrupt flag between them: each column's products do not depend on the block that holds it,
// so J is bit for bit the one pass J·I (no tolerance), here through free flights, impacts,
// sticking, release and a held set's own modes (both routes), with 2N = 160 (blocks of 64 and 96).
// Raised before fill_jacobian, the flag makes it throw Interrupted (and linearise report the map
// as interrupted: tests/io/test_signals.py); so it does for products along given directions.
TEST_CASE("modal tangent map: the full J in column blocks is the one-pass J bit for bit, and an interrupt ends it",
          "[modal_tangent]") {
  const int n = 80;
  on_both_routes([&](vibro::ModalSimulatorOptions o) {
    std::atomic<bool> stop{false};
    o.interrupt = &stop;
    const BandedChain chain = uniform_chain(n, 0.05, 0.6, 0.35);
    vibro::ModalEngine engine(chain, {Stop::upper(0, 0.3, 0.0), Stop::lower(40, -0.1, 0.7)}, o);
    const VectorXd zero = VectorXd::Zero(n);
    const vibro::ModalTangent t(engine, 0.0, zero, zero, 60.0);
    REQUIRE(t.map().summary.status == vibro::RunStatus::completed);
    CHECK(t.map().summary.sticks >= 1);
    CHECK(t.map().summary.impacts >= 3);
    vibro::TangentMap blocked;
    t.fill_jacobian(blocked);
    const MatrixXd whole = t.apply(MatrixXd::Identity(2 * n, 2 * n));
    REQUIRE(blocked.jacobian.rows() == 2 * n);
    REQUIRE(blocked.jacobian.cols() == 2 * n);
    CHECK(blocked.jacobian.cwiseAbs().maxCoeff() > 0.0);
    CHECK((blocked.jacobian.array() == whole.array()).all());
    stop = true;
    vibro::TangentMap cut;
    CHECK_THROWS_AS(t.fill_jacobian(cut), vibro::Interrupted);
    CHECK_THROWS_AS(t.apply(MatrixXd::Identity(2 * n, 3)), vibro::Interrupted);
  });
}

namespace {

/// The chain of `n` masses above with mass-proportional damping α added (C = αM + βK), so that
/// every mode decays at least like e^{−αt/2} and periodic orbits are reached in a few periods.
BandedChain damped_chain(int n, double alpha, double beta, double amplitude, double frequency) {
  BandedChain c = uniform_chain(n, beta, amplitude, frequency);
  c.rayleigh_mass = alpha;
  return c;
}

struct ShotPair {
  vibro::ShootingResult dense, modal;
};

/// Both shootings from the same guess (a run of `periods` from rest).
ShotPair shoot_both(const BandedChain& chain, const std::vector<Stop>& stops, double periods, int k = 1) {
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const auto n = chain.dof();
  const VectorXd zero = VectorXd::Zero(n);
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator sim(scene);
  const auto g = sim.run(0.0, zero, zero, periods * T);
  REQUIRE(g.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  o.period = k;
  ShotPair out;
  out.dense = vibro::shoot(scene, o, periods * T, g.x, g.v);
  vibro::ModalEngine engine(chain, stops, {});
  out.modal = vibro::shoot(engine, o, periods * T, g.x, g.v);
  return out;
}

/// Both shootings converged, to the same orbit within 1e-8 of L and V (see the test below).
void require_same_orbit(const ShotPair& p) {
  INFO(p.dense.message << " / " << p.modal.message);
  REQUIRE(p.dense.converged());
  REQUIRE(p.modal.converged());
  const double L = p.dense.length_scale, V = p.dense.velocity_scale;
  CHECK((p.modal.x - p.dense.x).cwiseAbs().maxCoeff() <= 1e-8 * L);
  CHECK((p.modal.v - p.dense.v).cwiseAbs().maxCoeff() <= 1e-8 * V);
}

}  // namespace

// Newton–Krylov shooting on the modal engine finds the orbit dense shooting finds, and Arnoldi's
// leading multipliers are the dense Jacobian's leading eigenvalues. Both orbits satisfy the same
// periodicity tolerance 1e-11 (of L, V) on maps that agree to ~1e-13, so the states agree to the
// tolerance times the conditioning of J − I (≤ 10² here): 1e-8 of L and V. The multipliers are
// eigenvalues of matrices equal to 1e-8 relative (above), well separated from each other
// (the real ones checked below: gaps ≥ 1e-3), so they agree to 1e-8 as well; Arnoldi's own tolerance is 1e-10.
TEST_CASE("modal engine: Newton–Krylov shooting and Arnoldi multipliers equal dense shooting", "[modal_tangent]") {
  SECTION("10 masses, two impacting stops, period 1") {
    const BandedChain chain = damped_chain(10, 0.05, 0.02, 0.6, 0.5);
    const ShotPair p = shoot_both(chain, {Stop::upper(0, 0.5, 0.8), Stop::lower(4, -0.12, 0.7)}, 6.0);
    require_same_orbit(p);
    CHECK(p.modal.map.summary.impacts > 0);
    const auto& md = p.modal.multipliers;
    const auto& dd = p.dense.multipliers;
    CHECK(md.leading_only);
    CHECK(md.converged);
    REQUIRE(md.values.size() == 6);
    for (Eigen::Index i = 0; i < md.values.size(); ++i) {
      INFO("multiplier " << i << ": " << md.values(i) << " vs " << dd.values(i));
      // A complex pair may come in either order.
      CHECK(std::min(std::abs(md.values(i) - dd.values(i)), std::abs(md.values(i) - std::conj(dd.values(i)))) <= 1e-8);
      if (i > 0 && std::abs(dd.values(i).imag()) < 1e-12) {  // the gaps the tolerance relies on
        CHECK(std::abs(std::abs(dd.values(i)) - std::abs(dd.values(i - 1))) >= 1e-3);
      }
    }
    CHECK(md.stable == dd.stable);
    CHECK(p.modal.krylov_products > 0);
  }
  SECTION("6 masses, an orbit that chatters into sticking and releases every period") {
    const BandedChain chain = damped_chain(6, 0.05, 0.05, 0.6, 0.35);
    const ShotPair p = shoot_both(chain, {Stop::upper(0, 0.3, 0.6), Stop::lower(3, -0.2, 0.8)}, 8.0);
    require_same_orbit(p);
    CHECK(p.modal.map.summary.sticks >= 1);
    CHECK(p.modal.map.summary.chatters >= 1);
    const auto& md = p.modal.multipliers;
    const auto& dd = p.dense.multipliers;
    REQUIRE(md.converged_count >= 1);
    CHECK(std::abs(md.spectral_radius - dd.spectral_radius) <= 1e-8);
    CHECK(md.stable == dd.stable);
  }
}

// Lyapunov spectra on both engines. For unit masses the modal coordinates are an orthogonal change
// of basis (Φ̃⁻¹ = Φ̃ᵀ), the modal frame starts as the dense one's image, and QR is invariant under
// an orthogonal change of basis, so every R_ii — hence every exponent — is the same number on both
// engines up to the maps' own difference (~1e-13, above) amplified by the frame's conditioning;
// 1e-9 per unit time bounds that with margin, while any error in the carried frame (a wrong
// saltation, a dropped direction) moves exponents by ≥ 1e-3.
TEST_CASE("modal engine: Lyapunov spectrum through impacts, chatter and sticking equals the dense engine's",
          "[modal_tangent]") {
  const BandedChain chain = uniform_chain(6, 0.05, 0.6, 0.35);
  const std::vector<Stop> stops{Stop::upper(0, 0.3, 0.6), Stop::lower(3, -0.2, 0.8)};
  const VectorXd zero = VectorXd::Zero(6);
  vibro::LyapunovOptions o;
  o.transient = 3;
  o.align = 2;
  o.periods = 6;
  const vibro::ImpactSystem scene(chain.dense(), stops);
  const vibro::LyapunovResult dense = vibro::lyapunov_spectrum(scene, {}, 0.0, zero, zero, o);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::LyapunovResult modal = vibro::lyapunov_spectrum(engine, 0.0, zero, zero, o);
  REQUIRE(dense.status == vibro::RunStatus::completed);
  REQUIRE(modal.status == vibro::RunStatus::completed);
  CHECK(modal.structural == dense.structural);
  CHECK(dense.structural > 0);  // the run sticks: exponents of held directions are −∞
  REQUIRE(modal.exponents.size() == 12);
  for (Eigen::Index i = 0; i < 12; ++i) {
    INFO("exponent " << i << ": " << modal.exponents(i) << " vs " << dense.exponents(i));
    if (std::isinf(dense.exponents(i))) CHECK(std::isinf(modal.exponents(i)));
    else CHECK(std::abs(modal.exponents(i) - dense.exponents(i)) <= 1e-9);
  }
}
