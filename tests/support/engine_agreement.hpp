#pragma once
/// \file engine_agreement.hpp
/// The modal chain engine against the dense Simulator on one chain with stops, from rest (tests only).
#include "vibro/modal.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace vibro::test {

struct Agreement {
  double event_time = 0.0, event_rate = 0.0, event_force = 0.0, state = 0.0;
  long impacts = 0, sticks = 0, chatters = 0, releases = 0;
  long switches = 0;  ///< compliant stops' engagements and disengagements
  std::size_t events = 0;
};

/// The largest differences of two engines' event logs, event by event (same kinds and stops
/// required): times of T, rates (before and after) of V, forces of F.
struct EventAgreement {
  double time = 0.0, rate = 0.0, force = 0.0;
};

inline EventAgreement compare_event_logs(const EventLog& dense, const EventLog& modal, double T, double V, double F) {
  REQUIRE(modal.events.size() == dense.events.size());
  EventAgreement out;
  for (std::size_t e = 0; e < dense.events.size(); ++e) {
    const auto& a = dense.events[e];
    const auto& b = modal.events[e];
    INFO("event " << e << " at t = " << a.t);
    REQUIRE(a.kind == b.kind);
    REQUIRE(a.stop == b.stop);
    out.time = std::max(out.time, std::abs(a.t - b.t) / T);
    out.rate = std::max({out.rate, std::abs(a.v_before - b.v_before) / V, std::abs(a.v_after - b.v_after) / V});
    out.force = std::max(out.force, std::abs(a.force - b.force) / F);
  }
  return out;
}

/// Both engines from rest over `periods`: events one to one (kind, stop; time of T, rates of V,
/// forces of F), the final state relative. The modal engine's modes come from
/// with_stop_orders(chain, stops), whose harmonics are those ImpactSystem gives the dense system.
inline Agreement compare_engines(const BandedChain& chain, const std::vector<Stop>& stops, double periods,
                                 const ModalSimulatorOptions& options = {}) {
  const double T = 2.0 * std::numbers::pi / chain.forcing.frequency, t_end = periods * T;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(chain.dof());
  const ImpactSystem scene(chain.dense(), stops);
  const BandedChain slots = with_stop_orders(chain, stops);
  REQUIRE(scene.system().forcing().harmonics.size() == slots.forcing.harmonics.size());
  Simulator dense(scene);
  EventLog dense_log;
  const auto ds = dense.run(0.0, zero, zero, t_end, {&dense_log});
  REQUIRE(ds.status == RunStatus::completed);
  const ChainModes modes(slots);
  ModalChainSimulator modal(modes, stops, options);
  EventLog modal_log;
  const auto ms = modal.run(0.0, zero, zero, t_end, {&modal_log});
  INFO(ms.message);
  REQUIRE(ms.status == RunStatus::completed);
  CHECK(ms.impacts == ds.impacts);
  CHECK(ms.sticks == ds.sticks);
  CHECK(ms.releases == ds.releases);
  CHECK(ms.chatters == ds.chatters);
  Agreement out;
  const EventAgreement events = compare_event_logs(dense_log, modal_log, T, ms.velocity_scale, ms.force_scale);
  out.event_time = events.time;
  out.event_rate = events.rate;
  out.event_force = events.force;
  auto relative = [](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
  };
  out.state = std::max(relative(ms.x, ds.x), relative(ms.v, ds.v));
  out.impacts = ds.impacts;
  out.sticks = ds.sticks;
  out.chatters = ds.chatters;
  out.releases = ds.releases;
  out.events = dense_log.events.size();
  for (const Event& e : dense_log.events)
    out.switches += e.kind == EventKind::engage || e.kind == EventKind::disengage ? 1 : 0;
  return out;
}

}  // namespace vibro::test
