// Stops along general normals (Stop::general, nᵀx ≤ p) on the modal chain engine (modal.hpp,
// "General normals"): free flight, impacts and chatter against the dense Simulator, on both
// routes to a contact set's modes, with another stop held in between (the general stop's guard
// row searched in a reduced chain's modes); a run in which a general stop would stick ends unsupported, naming
// it; a bad normal and a compliant stop along a general normal are refused.
#include "support/chains.hpp"
#include "support/engine_agreement.hpp"
#include "vibro/modal.hpp"
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

/// Eight unit masses (C = 0.05 K, a left wall) driven by 0.8 cos 0.5t on mass 0.
BandedChain chain8() { return vibro::test::uniform_chain(8, 0.05, 0.8, 0.5); }

/// n = (1, 0.5, 0, −0.3, 0, 0, 0, 0.2): a stop on a combination of four masses, none neighbours
/// of all the others.
VectorXd combination() {
  VectorXd n = VectorXd::Zero(8);
  n(0) = 1.0;
  n(1) = 0.5;
  n(3) = -0.3;
  n(7) = 0.2;
  return n;
}

/// The same with mass 1 of 2 (the impulse along M⁻¹n is then not along n).
BandedChain heavy_chain() {
  return BandedChain::from_links({1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0}, std::vector<double>(7, 1.0),
                                 std::vector<double>(7, 0.05), 1.0, 0.05, 0.0, 0.0, chain8().forcing);
}

/// 0: the general stop (r = 0.8); 1: a plastic stop above mass 5 that holds it for a while (the
/// general stop's guard then is searched in the held set's modes); 2: a bouncing stop below mass 3.
std::vector<Stop> general_stops() {
  return {Stop::general(combination(), 0.35, 0.8), Stop::upper(5, 0.25, 0.0), Stop::lower(3, -0.3, 0.8)};
}

}  // namespace

// Tolerances as tests/framework/test_modal_compliant.cpp justifies them (the same certified search
// on flows that differ by their decompositions' rounding, amplified over the run's events): 1e-8
// of T, V, F for the events and 1e-10 of the final state, while a wrong guard row (a missing
// mass of n, the offsets of a held set left out of nᵀo) or an impulse along the wrong direction
// (w instead of M⁻¹w) moves the first event after it by far more.
TEST_CASE("the modal engine runs a stop along a general normal as the dense engine does", "[modal][general-stops]") {
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    INFO((route == vibro::TridiagonalSolver::secular ? "secular route" : "tridiagonal route"));
    vibro::ModalSimulatorOptions o;
    o.contact_modes = route;
    const vibro::test::Agreement a = vibro::test::compare_engines(heavy_chain(), general_stops(), 12.0, o);
    INFO("events " << a.events << " (impacts " << a.impacts << ", sticks " << a.sticks << ", releases "
                   << a.releases << ", chatters " << a.chatters << "): times " << a.event_time << " of T, rates "
                   << a.event_rate << " of V, forces " << a.event_force << " of F, final state " << a.state);
    CHECK(a.impacts >= 10);
    CHECK(a.sticks >= 2);
    CHECK(a.releases >= 2);
    CHECK(a.event_time <= 1e-8);
    CHECK(a.event_rate <= 1e-8);
    CHECK(a.event_force <= 1e-8);
    CHECK(a.state <= 1e-10);
  }
}

TEST_CASE("a general stop that would stick ends the modal run unsupported, naming it", "[modal][general-stops]") {
  // A plastic general stop (r = 0): the first impact that leaves the mass pressed on it would hold it.
  const ChainModes modes(chain8());
  ModalChainSimulator modal(modes, {Stop::upper(6, 0.5, 0.8), Stop::general(combination(), 0.3, 0.0)});
  const VectorXd zero = VectorXd::Zero(8);
  const vibro::ModalRunSummary s = modal.run(0.0, zero, zero, 20.0 * 2.0 * std::numbers::pi / 0.5);
  CHECK(s.status == vibro::RunStatus::unsupported);
  CHECK_THAT(s.message, Catch::Contains("stops[1] (normal 1·x0 + 0.5·x1") &&
                            Catch::Contains("general normal") && Catch::Contains("solver.engine: dense"));
  // The dense engine holds it.
  const vibro::ImpactSystem scene(chain8().dense(), {Stop::upper(6, 0.5, 0.8), Stop::general(combination(), 0.3, 0.0)});
  vibro::Simulator dense(scene);
  const vibro::RunSummary d = dense.run(0.0, zero, zero, 20.0 * 2.0 * std::numbers::pi / 0.5);
  CHECK(d.status == vibro::RunStatus::completed);
  CHECK(d.sticks >= 1);
}

TEST_CASE("the modal engine refuses bad general normals and compliant ones", "[modal][general-stops]") {
  const ChainModes modes(chain8());
  CHECK_THROWS_WITH(ModalChainSimulator(modes, {Stop::upper(0, 0.5, 0.8), Stop::general(VectorXd::Ones(3), 0.2, 0.5)}),
                    Catch::Contains("stops[1]") && Catch::Contains("8 finite entries"));
  CHECK_THROWS_WITH(ModalChainSimulator(modes, {Stop::general(VectorXd::Zero(8), 0.2, 0.5)}),
                    Catch::Contains("stops[0]") && Catch::Contains("not all zero"));
  CHECK_THROWS_WITH(ModalChainSimulator(modes, {Stop::general(combination(), 0.3, 1.0).compliant(4.0, 0.2)}),
                    Catch::Contains("stops[0]") && Catch::Contains("compliant stop along a general normal"));
}
