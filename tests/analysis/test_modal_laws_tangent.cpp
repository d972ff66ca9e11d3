/// The modal engine's tangent map (analysis/modal_tangent.hpp) beyond rigid stops on one mass or
/// two: impacts on a stop along a general normal (modal.hpp, "General normals") against the dense
/// engine's map; and compliant stops' switches
/// (stops.hpp, law = compliant; modal.hpp, "Compliant stops"): a soft-impact chain whose dashpots
/// are c_s = β k_s > 0, so that every engagement and disengagement has a saltation that is not
/// the identity (f⁺ − f⁻ = ∓(0, M⁻¹w c_s ġ)), against
///  * the dense engine's tangent map (linearisation.hpp, tested there against closed forms and
///    finite differences): J, the parameter column ∂z1/∂p and the features, over runs with
///    engaged sets, a two-stage stop (a rigid stop held while its spring is engaged) and impacts;
///  * a periodic orbit found by shooting on both engines: the orbit and its Floquet multipliers;
///  * central differences of the modal engine's own period map.
#include "support/analysis_helpers.hpp"
#include "support/chains.hpp"
#include "vibro/modal_tangent.hpp"
#include "vibro/shooting.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <ios>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::BandedChain;
using vibro::EventKind;
using vibro::Stop;
using vibro::test::stack;

constexpr double kBeta = 0.05;

/// Six unit masses on unit springs (a left wall), C = αM + βK, driven by 1.5 cos 0.45t on mass 0.
BandedChain soft_chain(double alpha) {
  BandedChain c = vibro::test::uniform_chain(6, kBeta, 1.5, 0.45);
  c.rayleigh_mass = alpha;
  return c;
}

/// 0: compliant above mass 0 (k_s = 8, c_s = β k_s, preload 0.3); 1: compliant between masses 2
/// and 3 (k_s = 5, c_s = β k_s); 2: rigid below mass 5 (r = 0.7); with `two_stage`, 3: rigid above
/// mass 0 behind stop 0 (r = 0: the mass comes to rest on it with the spring engaged).
std::vector<Stop> soft_stops(bool two_stage) {
  std::vector<Stop> s{Stop::upper(0, 0.5, 1.0).compliant(8.0, kBeta * 8.0, 0.3),
                      Stop::between(2, 3, 0.3, 1.0).compliant(5.0, kBeta * 5.0), Stop::lower(5, -0.7, 0.7)};
  if (two_stage) s.push_back(Stop::upper(0, 0.55, 0.0));
  return s;
}

long count(const std::vector<vibro::Event>& events, EventKind kind) {
  return static_cast<long>(std::count_if(events.begin(), events.end(), [&](const auto& e) { return e.kind == kind; }));
}

/// A state of the run from rest at t ≥ `after` at least `clearance` from every event, with no
/// stop held or engaged (so that both engines start it in the same contact set).
struct Start {
  double t0 = 0.0;
  VectorXd x, v;
};
Start quiet_start(const BandedChain& chain, const std::vector<Stop>& stops, double after, double before,
                  double clearance) {
  const vibro::ImpactSystem scene(chain.dense(), stops);
  const VectorXd zero = VectorXd::Zero(chain.dof());
  vibro::Simulator sim(scene);
  vibro::EventLog log;
  REQUIRE(sim.run(0.0, zero, zero, before, {&log}).status == vibro::RunStatus::completed);
  // Closed intervals where some stop is held or engaged, and the events themselves.
  std::vector<std::pair<double, double>> busy;
  std::vector<double> since(stops.size(), -1.0);
  for (const vibro::Event& e : log.events) {
    busy.push_back({e.t, e.t});
    const auto j = static_cast<std::size_t>(e.stop);
    if (e.kind == EventKind::engage || e.kind == EventKind::stick) since[j] = e.t;
    if ((e.kind == EventKind::disengage || e.kind == EventKind::release) && since[j] >= 0.0) {
      busy.push_back({since[j], e.t});
      since[j] = -1.0;
    }
  }
  for (double s : since)
    if (s >= 0.0) busy.push_back({s, before});
  for (double t = after; t < before; t += 0.01 * clearance) {
    bool ok = true;
    for (const auto& [a, b] : busy) ok = ok && (t < a - clearance || t > b + clearance);
    if (!ok) continue;
    vibro::Simulator again(scene);
    const auto s = again.run(0.0, zero, zero, t);
    return {t, s.x, s.v};
  }
  FAIL("no quiet start found");
  return {};
}

/// Both maps completed over the same events (kind and stop, in order).
void require_same_events(const vibro::TangentMap& dense, const vibro::TangentMap& modal) {
  INFO(dense.summary.message << " / " << modal.summary.message);
  REQUIRE(dense.summary.status == vibro::RunStatus::completed);
  REQUIRE(modal.summary.status == vibro::RunStatus::completed);
  REQUIRE(modal.events.size() == dense.events.size());
  for (std::size_t e = 0; e < dense.events.size(); ++e) {
    REQUIRE(modal.events[e].kind == dense.events[e].kind);
    REQUIRE(modal.events[e].stop == dense.events[e].stop);
  }
}

double relative(const MatrixXd& a, const MatrixXd& b) { return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff(); }

}  // namespace

// Both maps are exact to rounding: products of exact flow propagators and saltation matrices whose
// entries carry 1/ġ⁻ at each switch and impact. The engines locate the same events to ~1e-13 of T
// (tests/framework/test_modal_compliant.cpp: ≤ 3e-13 over ~400 events), each set's flow differs by
// the rounding of its own decomposition (the dense 2N + 3 generator, the engaged chain's
// tridiagonal modes or the secular equation), and the slowest switch here has |ġ| ≥ 1e-2 V, so
// the saltations agree to ~1e-11 relative. Over two periods' few dozen switches, with |J| up to
// ~10², 1e-8 of max |J| bounds that with two orders of margin, while a missing or wrong saltation
// term (c_s ġ M⁻¹w at a switch, f of the wrong set) moves J by ≥ 1e-3 of max |J| (the dashpot's
// jump is c_s ġ = 0.4 × O(0.1–1)). The parameter column takes 1e-10 as in test_modal_tangent.cpp
// (measured there ≤ 7e-13); the features 1e-9 as there.
TEST_CASE("modal tangent map through compliant switches equals the dense engine's (J, ∂z/∂p, features)",
          "[modal_tangent][compliant]") {
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    INFO((route == vibro::TridiagonalSolver::secular ? "secular route" : "tridiagonal route"));
    const BandedChain chain = soft_chain(0.0);
    const std::vector<Stop> stops = soft_stops(true);
    const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
    const Start s = quiet_start(chain, stops, 3.0 * T, 5.0 * T, 0.02 * T);
    const double t1 = s.t0 + 2.0 * T;
    const vibro::ImpactSystem scene(chain.dense(), stops);
    vibro::LinearisationOptions lin;
    lin.features = true;
    const vibro::TangentMap dense = vibro::linearise(scene, {}, s.t0, s.x, s.v, t1, lin);
    vibro::ModalSimulatorOptions o;
    o.contact_modes = route;
    vibro::ModalEngine engine(chain, stops, o);
    const vibro::TangentMap modal = vibro::linearise(engine, s.t0, s.x, s.v, t1, lin);
    require_same_events(dense, modal);
    const long switches = count(dense.events, EventKind::engage) + count(dense.events, EventKind::disengage);
    INFO("events " << dense.events.size() << ", switches " << switches << ", impacts " << dense.summary.impacts
                   << ", sticks " << dense.summary.sticks);
    CHECK(switches >= 6);
    CHECK(dense.summary.impacts >= 2);
    CHECK(dense.summary.sticks >= 1);  // the two-stage stop: rigid stop 3 held while spring 0 is engaged
    const double j_diff = relative(modal.jacobian, dense.jacobian);
    INFO(std::scientific << "J: " << j_diff << " of max |J| = " << dense.jacobian.cwiseAbs().maxCoeff());
    CHECK(j_diff <= 1e-8);
    CHECK(relative(stack(modal.x1, modal.v1), stack(dense.x1, dense.v1)) <= 1e-10);
    // The features: gap peaks (engaged stops' penetration maxima included), force dips, impacts.
    // (Within a segment the dense map lists them by stop, the modal one by guard row: by stop and
    // time here; the two-stage stops 0 and 3 on one mass peak at the same instants.)
    auto by_stop = [](std::vector<vibro::GapPeak> p) {
      std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) { return a.stop != b.stop ? a.stop < b.stop : a.t < b.t; });
      return p;
    };
    const std::vector<vibro::GapPeak> dp = by_stop(dense.gap_peaks), mp = by_stop(modal.gap_peaks);
    REQUIRE(mp.size() == dp.size());
    long penetration = 0;
    const double L = dense.summary.length_scale, F = dense.summary.force_scale;
    for (std::size_t i = 0; i < dp.size(); ++i) {
      CHECK(mp[i].stop == dp[i].stop);
      CHECK(std::abs(mp[i].t - dp[i].t) <= 1e-9 * T);
      CHECK(std::abs(mp[i].value - dp[i].value) <= 1e-9 * L);
      penetration += dp[i].value > 0.0 ? 1 : 0;
    }
    CHECK(penetration >= 2);
    REQUIRE(modal.force_dips.size() == dense.force_dips.size());
    for (std::size_t i = 0; i < dense.force_dips.size(); ++i)
      CHECK(std::abs(modal.force_dips[i].value - dense.force_dips[i].value) <= 1e-9 * F);
    // ∂z1/∂p along Ω, the drive, the compliant stops' positions and preload, the rigid one's offset.
    std::vector<std::pair<std::string, vibro::SystemDerivative>> directions;
    directions.emplace_back("frequency", vibro::SystemDerivative::frequency_only());
    vibro::SystemDerivative drive;
    drive.cosine = VectorXd::Unit(6, 0);
    directions.emplace_back("drive", drive);
    for (std::size_t j = 0; j < stops.size(); ++j) {
      vibro::SystemDerivative d;
      d.stops.resize(stops.size());
      d.stops[j].offset = 1.0;
      directions.emplace_back("stop " + std::to_string(j) + " offset", d);
    }
    vibro::SystemDerivative preload;
    preload.stops.resize(stops.size());
    preload.stops[0].preload = 1.0;
    directions.emplace_back("stop 0 preload", preload);
    const vibro::ModalTangent tangent(engine, s.t0, s.x, s.v, t1);
    for (const auto& [name, d] : directions) {
      INFO("d/dp: " << name);
      vibro::LinearisationOptions with;
      with.jacobian = false;
      with.parameter = d;
      const vibro::TangentMap reference = vibro::linearise(scene, {}, s.t0, s.x, s.v, t1, with);
      require_same_events(reference, tangent.map());
      const VectorXd mine = tangent.parameter(d);
      CHECK(reference.parameter.cwiseAbs().maxCoeff() > 0.0);
      CHECK(relative(mine, reference.parameter) <= 1e-10);
    }
  }
}

// A compliant stop's spring or dashpot moves the modes of the sets where it is engaged, which the
// modal map keeps fixed: their derivatives are refused, saying what to do.
TEST_CASE("modal tangent map: a derivative of a compliant stop's stiffness or damping is refused",
          "[modal_tangent][compliant]") {
  vibro::ModalEngine engine(soft_chain(0.0), soft_stops(false), {});
  const VectorXd zero = VectorXd::Zero(6);
  const vibro::ModalTangent tangent(engine, 0.0, zero, zero, 5.0);
  for (const bool stiffness : {true, false}) {
    vibro::SystemDerivative d;
    d.stops.resize(3);
    (stiffness ? d.stops[1].stiffness : d.stops[1].damping) = 1.0;
    CHECK_THROWS_WITH(tangent.parameter(d), Catch::Contains("stops[1]") && Catch::Contains("use the dense engine"));
  }
}

// A periodic orbit of the soft-impact chain (α = 0.05 so that transients die within a few
// periods) found by shooting on both engines from the same guess: the two orbits satisfy the same
// periodicity tolerance on maps that agree to ~1e-12 (above), so they agree to that tolerance
// times the conditioning of J − I: 1e-8 of L and V. The multipliers are eigenvalues of Jacobians
// equal to ~1e-11 relative; those compared are separated by ≥ 1e-3 (checked), so they agree to
// 1e-8, while the saltations' dashpot term moves them by far more (the mutation check in the
// report: dropping it moves the leading multiplier by ~1e-2).
TEST_CASE("modal engine: a soft-impact orbit and its Floquet multipliers equal the dense engine's",
          "[modal_tangent][compliant]") {
  const BandedChain chain = soft_chain(0.05);
  const std::vector<Stop> stops = soft_stops(false);
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const VectorXd zero = VectorXd::Zero(6);
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator sim(scene);
  const double guess = 12.0 * T;
  const auto g = sim.run(0.0, zero, zero, guess);
  REQUIRE(g.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  const vibro::ShootingResult dense = vibro::shoot(scene, o, guess, g.x, g.v);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::ShootingResult modal = vibro::shoot(engine, o, guess, g.x, g.v);
  INFO(dense.message << " / " << modal.message);
  REQUIRE(dense.converged());
  REQUIRE(modal.converged());
  const long switches = count(dense.map.events, EventKind::engage) + count(dense.map.events, EventKind::disengage);
  CHECK(switches >= 2);
  CHECK((modal.x - dense.x).cwiseAbs().maxCoeff() <= 1e-8 * dense.length_scale);
  CHECK((modal.v - dense.v).cwiseAbs().maxCoeff() <= 1e-8 * dense.velocity_scale);
  // The modal map's full J at the modal orbit, against the dense J at the dense one (1e-8: above).
  const vibro::TangentMap J = vibro::linearise(engine, modal.t0, modal.x, modal.v, modal.t0 + T);
  require_same_events(dense.map, J);
  CHECK(relative(J.jacobian, dense.map.jacobian) <= 1e-8);
  // All 2n multipliers from it, and Arnoldi's leading ones (shooting's), against the dense ones.
  const vibro::FloquetMultipliers all = vibro::floquet_multipliers(J, 1);
  const Eigen::VectorXcd& b = dense.multipliers.values;
  for (const Eigen::VectorXcd* a : {&all.values, &modal.multipliers.values}) {
    REQUIRE(a->size() >= 2);
    REQUIRE(a->size() <= b.size());
    for (Eigen::Index i = 0; i < a->size(); ++i) {
      INFO("multiplier " << i << ": " << (*a)(i) << " vs " << b(i));
      // A complex pair may come in either order.
      CHECK(std::min(std::abs((*a)(i) - b(i)), std::abs((*a)(i) - std::conj(b(i)))) <= 1e-8);
    }
  }
  CHECK(all.values.size() == b.size());
  for (Eigen::Index i = 1; i < b.size(); ++i)  // the gaps the tolerance relies on (real neighbours)
    if (std::abs(b(i).imag()) < 1e-12 && std::abs(b(i - 1).imag()) < 1e-12)
      CHECK(std::abs(std::abs(b(i)) - std::abs(b(i - 1))) >= 1e-3);
  CHECK(modal.multipliers.stable == dense.multipliers.stable);
  CHECK(all.stable == dense.multipliers.stable);
}

// Central differences of the modal engine's own map over one period through switches:
// error O(h² |∂³φ|) + O(ε |φ| / h); with h = 1e-6 of the state's scales both are ~1e-10 to 1e-9 of
// |J d|, so 1e-6 is a wide bound that still catches any wrong term (the dashpot's saltation term
// is ≥ 1e-3 of |J d| here).
TEST_CASE("modal tangent map through compliant switches equals central differences of the modal map",
          "[modal_tangent][compliant]") {
  const BandedChain chain = soft_chain(0.0);
  const std::vector<Stop> stops = soft_stops(false);
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const Start s = quiet_start(chain, stops, 3.0 * T, 5.0 * T, 0.02 * T);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::ModalTangent tangent(engine, s.t0, s.x, s.v, s.t0 + T);
  REQUIRE(tangent.map().summary.status == vibro::RunStatus::completed);
  const std::vector<vibro::Event> events = tangent.map().events;
  CHECK(count(events, EventKind::engage) >= 2);
  const VectorXd scale =
      vibro::test::state_scale(6, tangent.map().summary.length_scale, tangent.map().summary.velocity_scale);
  const MatrixXd D = MatrixXd::Random(12, 3);
  const double h = 1e-6;
  for (int c = 0; c < 3; ++c) {
    const VectorXd d = D.col(c).cwiseProduct(scale);
    const VectorXd z = stack(s.x, s.v);
    auto map = [&](const VectorXd& z0) {
      vibro::ModalEngine e(chain, stops, {});
      vibro::EventLog log;
      const auto r = e.run(s.t0, z0.head(6), z0.tail(6), s.t0 + T, {&log});
      REQUIRE(r.status == vibro::RunStatus::completed);
      REQUIRE(log.events.size() == events.size());
      return stack(r.x, r.v);
    };
    const VectorXd fd = (map(z + h * d) - map(z - h * d)) / (2.0 * h);
    const VectorXd exact = tangent.apply(d);
    INFO("direction " << c);
    CHECK((fd - exact).cwiseAbs().maxCoeff() <= 1e-6 * exact.cwiseAbs().maxCoeff());
  }
}

// Impacts on a stop along a general normal (n on four masses, unequal masses so that the impulse
// along M⁻¹n is not along n), in free flight and while another stop is held: J and ∂z1/∂Ω against
// the dense map. Tolerances as the compliant case above (1e-8 of max |J|, 1e-10 for the parameter
// column), for the same reasons; a guard derivative along the wrong normal or an impulse along n
// rather than M⁻¹n changes J at the 1e-2 level.
TEST_CASE("modal tangent map through impacts on a general normal equals the dense engine's",
          "[modal_tangent][general-stops]") {
  VectorXd normal = VectorXd::Zero(8);
  normal(0) = 1.0;
  normal(1) = 0.5;
  normal(3) = -0.3;
  normal(7) = 0.2;
  BandedChain chain = BandedChain::from_links({1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0}, std::vector<double>(7, 1.0),
                                              std::vector<double>(7, 0.05), 1.0, 0.05, 0.0, 0.0,
                                              vibro::test::uniform_chain(8, 0.05, 0.8, 0.5).forcing);
  const std::vector<Stop> stops{Stop::general(normal, 0.35, 0.8), Stop::upper(5, 0.25, 0.0), Stop::lower(3, -0.3, 0.8)};
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const Start s = quiet_start(chain, stops, 3.0 * T, 5.0 * T, 0.02 * T);
  const double t1 = s.t0 + 2.0 * T;
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::LinearisationOptions lin;
  lin.parameter = vibro::SystemDerivative::frequency_only();
  const vibro::TangentMap dense = vibro::linearise(scene, {}, s.t0, s.x, s.v, t1, lin);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::TangentMap modal = vibro::linearise(engine, s.t0, s.x, s.v, t1, lin);
  require_same_events(dense, modal);
  long general = 0;
  for (const vibro::Event& e : dense.events) general += e.stop == 0 && e.kind == EventKind::impact ? 1 : 0;
  INFO("impacts on the general stop " << general << ", sticks " << dense.summary.sticks);
  CHECK(general >= 2);
  CHECK(relative(modal.jacobian, dense.jacobian) <= 1e-8);
  CHECK(relative(modal.parameter, dense.parameter) <= 1e-10);
}
