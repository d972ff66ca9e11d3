// Stops moving with several harmonics (stops.hpp, Stop::harmonics) on the modal chain engine
// (modal.hpp): the engine against the dense Simulator through impacts, chatter, sticking on a
// moving stop and release, on both routes to a contact set's modes; its tangent maps, an orbit's
// multipliers and a parameter derivative along a held stop's harmonic against the dense engine's;
// modes without a slot for a stop's order refused, naming the stop.
#include "support/chains.hpp"
#include "support/engine_agreement.hpp"
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/modal.hpp"
#include "vibro/modal_tangent.hpp"
#include "vibro/observers.hpp"
#include "vibro/shooting.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::BandedChain;
using vibro::ChainModes;
using vibro::ModalChainSimulator;
using vibro::Stop;
using vibro::StopHarmonic;

/// Six masses driven at Ω = 0.45 with a second and a third harmonic in the drive (the chain of
/// test_modal_harmonics.cpp); a stop above mass 0 moving with its first, second and third
/// harmonics, a stop below mass 3 moving with a second and a fourth (an order the drive lacks), a
/// stop between masses 4 and 5 moving with a fifth.
BandedChain six_masses() {
  BandedChain chain = vibro::test::uniform_chain(6, 0.05, 0.6, 0.45);
  vibro::ForcingHarmonic second{2, VectorXd::Zero(6), VectorXd::Zero(6)}, third{3, VectorXd::Zero(6), VectorXd::Zero(6)};
  second.cosine(0) = 0.25;
  second.sine(1) = -0.1;
  third.sine(0) = 0.15;
  third.cosine(1) = 0.05;
  chain.forcing.harmonics = {second, third};
  chain.validate();
  return chain;
}
std::vector<Stop> moving_stops() {
  return {Stop::upper(0, 0.3, 0.6).moving(0.01, 0.4).with_harmonics({{2, 0.005, -0.004}, {3, 0.0, 0.003}}),
          Stop::lower(3, -0.2, 0.8).with_harmonics({{2, 0.004, 0.003}, {4, -0.003, 0.0}}),
          Stop::between(4, 5, 0.2, 0.7).with_harmonics({{5, 0.002, 0.001}})};
}

}  // namespace

TEST_CASE("modal stop harmonics: stops moving with several harmonics, through impacts, chatter, sticking on a "
          "moving stop and release, agree with the dense Simulator on both routes",
          "[modal][harmonics][stops]") {
  // Both engines are exact between events and resolve events by the same rules; they differ by
  // the rounding of their flows. The modal engine's tests with a drive of several harmonics
  // (test_modal_harmonics.cpp) require 1e-8 of T, V and F for the events of a chattering and
  // sticking run (the tail of a chatter sequence amplifies rounding) and 1e-10 for the final
  // state; a stop's harmonics enter both engines as the drive's do (a harmonic part of the
  // guards, of the held sets' offsets and of their reduced forcing), so the same bounds apply,
  // while a wrong term (a missing harmonic in a held set's offsets or forcing, in a gap's rate)
  // moves events by 1e-3 or more.
  const BandedChain chain = six_masses();
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    INFO((route == vibro::TridiagonalSolver::secular ? "secular route" : "tridiagonal route"));
    vibro::ModalSimulatorOptions o;
    o.contact_modes = route;
    const vibro::test::Agreement a = vibro::test::compare_engines(chain, moving_stops(), 30.0, o);
    INFO("events " << a.events << " (impacts " << a.impacts << ", chatters " << a.chatters << ", sticks " << a.sticks
                   << "): times " << a.event_time << " of T, rates " << a.event_rate << " of V, forces "
                   << a.event_force << " of F, final state " << a.state);
    CHECK(a.impacts >= 20);
    CHECK(a.chatters >= 1);
    CHECK(a.sticks >= 1);
    CHECK(a.releases >= 1);
    CHECK(a.event_time <= 1e-8);
    CHECK(a.event_rate <= 1e-8);
    CHECK(a.event_force <= 1e-8);
    CHECK(a.state <= 1e-10);
  }
}

TEST_CASE("modal stop harmonics: modes without a slot for a stop's order are refused, naming the stop",
          "[modal][harmonics][stops]") {
  const BandedChain chain = six_masses();  // the drive has orders 2 and 3
  const ChainModes modes(chain);
  CHECK_THROWS_WITH(ModalChainSimulator(modes, moving_stops()),
                    Catch::Contains("stops[1]") && Catch::Contains("order 4") && Catch::Contains("with_stop_orders"));
  const BandedChain with = vibro::with_stop_orders(chain, moving_stops());
  REQUIRE(with.forcing.harmonics.size() == 4);  // 2, 3 (the drive's), then 4, 5 as the stops name them
  CHECK(with.forcing.harmonics[1].cosine(1) == 0.05);
  CHECK(with.forcing.harmonics[2].order == 4);
  CHECK(with.forcing.harmonics[3].order == 5);
  CHECK(with.forcing.harmonics[3].cosine.isZero(0.0));
  const ChainModes with_modes(with);
  CHECK_NOTHROW(ModalChainSimulator(with_modes, moving_stops()));
}

namespace {

/// Both tangent maps over `span` periods from the dense run's state at t0 (free flight there).
struct Maps {
  vibro::TangentMap dense, modal;
};
Maps both_maps(const BandedChain& chain, const std::vector<Stop>& stops, double t0, double t1,
               const vibro::LinearisationOptions& lin = {}) {
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator sim(scene);
  const VectorXd zero = VectorXd::Zero(chain.dof());
  const auto s = sim.run(0.0, zero, zero, t0);
  REQUIRE(s.status == vibro::RunStatus::completed);
  REQUIRE(s.x.size() == chain.dof());
  Maps out;
  out.dense = vibro::linearise(scene, {}, t0, s.x, s.v, t1, lin);
  vibro::ModalEngine engine(chain, stops, {});
  out.modal = vibro::linearise(engine, t0, s.x, s.v, t1, lin);
  REQUIRE(out.dense.summary.status == vibro::RunStatus::completed);
  INFO(out.modal.summary.message);
  REQUIRE(out.modal.summary.status == vibro::RunStatus::completed);
  REQUIRE(out.modal.events.size() == out.dense.events.size());
  for (std::size_t e = 0; e < out.dense.events.size(); ++e) {
    REQUIRE(out.modal.events[e].kind == out.dense.events[e].kind);
    REQUIRE(out.modal.events[e].stop == out.dense.events[e].stop);
  }
  return out;
}

/// The first time after `after` at least `clearance` from every event of the dense run from rest
/// and outside every held phase (a map from a held start is one-sided).
double free_time(const BandedChain& chain, const std::vector<Stop>& stops, double after, double before,
                 double clearance) {
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator sim(scene);
  vibro::EventLog log;
  const VectorXd zero = VectorXd::Zero(chain.dof());
  REQUIRE(sim.run(0.0, zero, zero, before, {&log}).status == vibro::RunStatus::completed);
  std::vector<std::pair<double, double>> busy;
  double held_since = -1.0;
  for (const auto& e : log.events) {
    busy.push_back({e.t, e.t});
    if (e.kind == vibro::EventKind::stick && held_since < 0.0) held_since = e.t;
    if (e.kind == vibro::EventKind::release && held_since >= 0.0) {
      busy.push_back({held_since, e.t});
      held_since = -1.0;
    }
  }
  if (held_since >= 0.0) busy.push_back({held_since, before});
  for (double t = after; t < before; t += 0.01 * clearance) {
    bool ok = true;
    for (const auto& [a, b] : busy) ok = ok && (t < a - clearance || t > b + clearance);
    if (ok) return t;
  }
  FAIL("no free start found");
  return after;
}

}  // namespace

// The tangent maps on both engines are exact to rounding (tests/analysis/test_modal_tangent.cpp:
// 1e-8 of max |J|, measured ~1e-12): each is a product of exact flow propagators and saltation
// matrices whose entries carry the stop's s'(t) and s''(t) (the relative normal velocity and the
// gap's acceleration) — with a stop's higher harmonics left out of either, entries differ at the
// 1e-2 level. The parameter derivative along a held stop's harmonic amplitude enters through the
// held set's particular solution (its offsets' harmonic of that order): the bound of the modal
// parameter derivatives' tests, 1e-10 of max |∂z1/∂p| (measured ≤ 7e-13 there).
TEST_CASE("modal stop harmonics: tangent maps through sticking on a stop moving with several harmonics, and a "
          "derivative along a held stop's harmonic, equal the dense engine's",
          "[modal][harmonics][stops][modal_tangent]") {
  const BandedChain chain = six_masses();
  const std::vector<Stop> stops = moving_stops();
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const double t0 = free_time(chain, stops, 3.0 * T, 6.0 * T, 0.02 * T);
  const Maps m = both_maps(chain, stops, t0, t0 + 3.0 * T);
  INFO("impacts " << m.dense.summary.impacts << ", sticks " << m.dense.summary.sticks << ", releases "
                  << m.dense.summary.releases);
  CHECK(m.dense.summary.impacts >= 3);
  CHECK(m.dense.summary.sticks >= 1);
  const double jacobian =
      (m.modal.jacobian - m.dense.jacobian).cwiseAbs().maxCoeff() / m.dense.jacobian.cwiseAbs().maxCoeff();
  INFO("jacobians differ by " << jacobian << " of max |J| over " << m.dense.events.size() << " events");
  CHECK(jacobian <= 1e-8);

  vibro::LinearisationOptions lin;
  lin.jacobian = false;
  for (std::size_t j : {std::size_t{0}, std::size_t{1}}) {
    for (int part = 0; part < 2; ++part) {
      vibro::SystemDerivative d;
      d.stop_harmonic_cosine.assign(stops.size(), {});
      d.stop_harmonic_sine.assign(stops.size(), {});
      auto& list = part == 0 ? d.stop_harmonic_cosine[j] : d.stop_harmonic_sine[j];
      list.assign(stops[j].harmonics.size(), 0.0);
      list[0] = 1.0;  // the stop's second harmonic
      lin.parameter = d;
      const Maps p = both_maps(chain, stops, 0.0, 6.0 * T, lin);
      INFO("sticks " << p.dense.summary.sticks);
      CHECK(p.dense.summary.sticks >= 1);
      const double size = p.dense.parameter.cwiseAbs().maxCoeff();
      const double difference = (p.modal.parameter - p.dense.parameter).cwiseAbs().maxCoeff() / size;
      INFO("stops[" << j << "] second harmonic's " << (part == 0 ? "cosine" : "sine") << ": max |dz1/dp| " << size
                    << ", relative difference " << difference);
      CHECK(size > 0.0);
      CHECK(difference <= 1e-10);
    }
  }
}

// Newton–Krylov shooting on the modal engine and dense shooting from the same guess: the same
// orbit and the same leading multipliers, to the bounds of the modal engine's shooting tests
// (tests/analysis/test_modal_tangent.cpp): states within 1e-8 of L and V (the periodicity
// tolerance 1e-11 times the conditioning of J − I), multipliers within 1e-8.
TEST_CASE("modal stop harmonics: an orbit with impacts on stops moving with several harmonics has the dense "
          "engine's multipliers",
          "[modal][harmonics][stops][modal_tangent]") {
  BandedChain chain = vibro::test::uniform_chain(10, 0.02, 0.6, 0.5);
  chain.rayleigh_mass = 0.05;
  const std::vector<Stop> stops{Stop::upper(0, 0.5, 0.8).moving(0.02, 0.3).with_harmonics({{2, 0.01, 0.005}, {3, 0.0, -0.005}}),
                                Stop::lower(4, -0.12, 0.7).with_harmonics({{2, -0.005, 0.005}})};
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency;
  const VectorXd zero = VectorXd::Zero(chain.dof());
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator sim(scene);
  const auto g = sim.run(0.0, zero, zero, 6.0 * T);
  REQUIRE(g.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  const vibro::ShootingResult dense = vibro::shoot(scene, o, 6.0 * T, g.x, g.v);
  vibro::ModalEngine engine(chain, stops, {});
  const vibro::ShootingResult modal = vibro::shoot(engine, o, 6.0 * T, g.x, g.v);
  INFO(dense.message << " / " << modal.message);
  REQUIRE(dense.converged());
  REQUIRE(modal.converged());
  CHECK(modal.map.summary.impacts > 0);
  CHECK((modal.x - dense.x).cwiseAbs().maxCoeff() <= 1e-8 * dense.length_scale);
  CHECK((modal.v - dense.v).cwiseAbs().maxCoeff() <= 1e-8 * dense.velocity_scale);
  const auto& md = modal.multipliers;
  const auto& dd = dense.multipliers;
  REQUIRE(md.converged);
  REQUIRE(md.values.size() >= 2);
  for (Eigen::Index i = 0; i < md.values.size(); ++i) {
    INFO("multiplier " << i << ": " << md.values(i) << " vs " << dd.values(i));
    CHECK(std::min(std::abs(md.values(i) - dd.values(i)), std::abs(md.values(i) - std::conj(dd.values(i)))) <= 1e-8);
  }
  CHECK(md.stable == dd.stable);
}
