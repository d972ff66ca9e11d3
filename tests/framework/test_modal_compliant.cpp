// Compliant stops (stops.hpp, law = compliant) on the modal chain engine (modal.hpp): a soft-impact
// chain (compliant stops on one mass and between neighbours, a preload, c_s = β k_s, a two-stage
// stop: a compliant spring with a rigid stop behind it) against the dense Simulator, on both
// routes to a contact set's modes; a stop that starts engaged; the refusals (c_s ≠ β k_s, a
// compliant stop between masses that are not neighbours).
#include "support/chains.hpp"
#include "support/engine_agreement.hpp"
#include "vibro/engine.hpp"
#include "vibro/modal.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <vector>

namespace {

using Eigen::VectorXd;
using vibro::BandedChain;
using vibro::ChainModes;
using vibro::EventKind;
using vibro::ModalChainSimulator;
using vibro::Stop;

constexpr double kBeta = 0.05;  // the chain's C = βK (uniform_chain)

/// Six masses (m = k = 1, a left wall, C = βK) driven by 1.5 cos 0.45t on mass 0; stops:
///  0: compliant above mass 0 at 0.5 (k_s = 8, c_s = β k_s, preload 0.3),
///  1: rigid above mass 0 behind it at 0.55 (r = 0: the mass comes to rest on it with the spring
///     engaged, and leaves it again): with 0 a two-stage stop,
///  2: compliant between masses 2 and 3 (k_s = 5, c_s = β k_s, no preload),
///  3: rigid below mass 5 at −0.7 (r = 0.7).
BandedChain soft_chain() { return vibro::test::uniform_chain(6, kBeta, 1.5, 0.45); }
std::vector<Stop> soft_stops() {
  return {Stop::upper(0, 0.5, 1.0).compliant(8.0, kBeta * 8.0, 0.3), Stop::upper(0, 0.55, 0.0),
          Stop::between(2, 3, 0.3, 1.0).compliant(5.0, kBeta * 5.0), Stop::lower(5, -0.7, 0.7)};
}

}  // namespace

// Both engines locate the same guards' zeros (the certified search of events.hpp) to a few ulps
// of t, on flows that differ by the rounding of their decompositions (the dense 2N + 3 generator,
// the engaged chains' tridiagonal modes or the secular equation), which the run's ~400 events
// amplify: 1e-8 of T, V, F and 1e-10 of the final state leave room for that (measured over 394
// events: times ≤ 3e-13 of T, rates ≤ 2e-12 of V, forces ≤ 3e-13 of F, state ≤ 2e-13), while a
// wrong term in an engaged set's K, C or f (k_s, c_s Ω s, F_p: O(1e-1) of the forces) moves the
// first switch after it by far more.
TEST_CASE("the modal engine runs compliant stops as the dense engine does", "[modal][compliant]") {
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    INFO((route == vibro::TridiagonalSolver::secular ? "secular route" : "tridiagonal route"));
    vibro::ModalSimulatorOptions o;
    o.contact_modes = route;
    const vibro::test::Agreement a = vibro::test::compare_engines(soft_chain(), soft_stops(), 30.0, o);
    INFO("events " << a.events << " (impacts " << a.impacts << ", switches " << a.switches << ", chatters "
                   << a.chatters << ", sticks " << a.sticks << "): times " << a.event_time << " of T, rates "
                   << a.event_rate << " of V, forces " << a.event_force << " of F, final state " << a.state);
    CHECK(a.switches >= 20);
    CHECK(a.impacts >= 20);
    CHECK(a.sticks >= 3);  // held rigid stop 1 with stop 0 engaged: a mixed contact set
    CHECK(a.releases >= 3);
    CHECK(a.event_time <= 1e-8);
    CHECK(a.event_rate <= 1e-8);
    CHECK(a.event_force <= 1e-8);
    CHECK(a.state <= 1e-10);
  }
}

// A compliant stop penetrated at t0 starts engaged (CompliantStopLaw::engaged_at_start) on both
// engines: the first event is its disengagement, at the same time (tolerances as above).
TEST_CASE("a compliant stop penetrated at the start is engaged on the modal engine too", "[modal][compliant]") {
  const BandedChain chain = soft_chain();
  const std::vector<Stop> stops = soft_stops();
  VectorXd x0 = VectorXd::Zero(6), v0 = VectorXd::Zero(6);
  x0(0) = 0.52;  // 0.02 into stop 0, short of the rigid stop 1 behind it
  const double t_end = 5.0 * 2.0 * std::numbers::pi / 0.45;
  const vibro::ImpactSystem scene(chain.dense(), stops);
  vibro::Simulator dense(scene);
  vibro::EventLog dense_log, modal_log;
  const auto ds = dense.run(0.0, x0, v0, t_end, {&dense_log});
  REQUIRE(ds.status == vibro::RunStatus::completed);
  const ChainModes modes(chain);
  ModalChainSimulator modal(modes, stops);
  const auto ms = modal.run(0.0, x0, v0, t_end, {&modal_log});
  INFO(ms.message);
  REQUIRE(ms.status == vibro::RunStatus::completed);
  REQUIRE(!modal_log.events.empty());
  CHECK(modal_log.events.front().kind == EventKind::disengage);
  CHECK(modal_log.events.front().stop == 0);
  const auto agree = vibro::test::compare_event_logs(dense_log, modal_log, 2.0 * std::numbers::pi / 0.45,
                                                     ms.velocity_scale, ms.force_scale);
  CHECK(agree.time <= 1e-8);
  CHECK(agree.rate <= 1e-8);
  CHECK(agree.force <= 1e-8);
  CHECK((ms.x - ds.x).cwiseAbs().maxCoeff() <= 1e-10);
}

TEST_CASE("the modal engine refuses compliant stops that would leave the banded chain", "[modal][compliant]") {
  const ChainModes modes(soft_chain());
  SECTION("a dashpot that is not β times its spring") {
    const std::vector<Stop> stops{Stop::upper(0, 0.5, 1.0).compliant(8.0, 0.3)};
    REQUIRE_THROWS_WITH(ModalChainSimulator(modes, stops),
                        Catch::Contains("stops[0]") && Catch::Contains("is not β k_s = 0.4"));
  }
  SECTION("a spring between masses that are not neighbours") {
    const std::vector<Stop> stops{Stop::between(1, 3, 0.3, 1.0).compliant(5.0, kBeta * 5.0)};
    REQUIRE_THROWS_WITH(ModalChainSimulator(modes, stops), Catch::Contains("stops[0]") && Catch::Contains("not neighbours"));
  }
}
