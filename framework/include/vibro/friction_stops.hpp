#pragma once
/// \file friction_stops.hpp
/// Dry friction (friction.hpp) and stops (stops.hpp: rigid Newton stops and compliant stops) in
/// one scene, on the dense engine's exact flows.
///
/// Mode. A mode is (the stops' contact set, the frictional contacts' states): the held rigid
/// stops and the engaged compliant stops (a ContactSet, as for the stops alone) and, per
/// frictional contact, slipping +, slipping − or stuck. Its motion is linear: with H the held
/// rigid stops (normals n_h, motions p_h(t)), S the stuck contacts (tangents w_j, surfaces
/// s_j(t)), E the engaged compliant stops and r = f(t) − C v − K x − Σ_E n (k_s g + c_s g' + F_p)
/// − Σ_slipping w_j μ_k N_j σ_j, the constraints n_hᵀx'' = p_h'' and w_jᵀx'' = s_j'' hold with
/// the forces B = [N_H W_S] F,
///
///     F = (BᵀM⁻¹B)⁻¹ ([p_H''; s_S''] − BᵀM⁻¹ r),     x'' = M⁻¹ (r + B F),
///
/// one Delassus system over the held stops and the stuck contacts together (friction.hpp's
/// holding forces, with the stops' columns first). A held stop's contact force is λ_h = −F_h.
/// The mode's exact flow is built on first use, in the full augmented state z of flow.hpp (the
/// dense engine writes a held set in reduced coordinates; here the stuck contacts need the full
/// state anyway, and the flow keeps n_hᵀx − p_h(t) at the value it starts with, 0).
///
/// Guards (one certified search over all of them, events.hpp): the open stops' gaps g_j, the
/// held rigid stops' pulls −λ_h, the engaged compliant stops' −g_j (contact_law.hpp's rows),
/// then the friction guards of friction.hpp (−σ_j u_j slipping, ±F_j − μ_s N_j stuck).
///
/// Events. The run is the event loop shared with the stop engines (event_loop.hpp: scales,
/// tolerances, simultaneity, initial contacts, Zeno guard), and the stops' events are resolved by
/// the same code (event_resolution.hpp's resolve_event: Newton's law through the impulse LCP,
/// the chatter rule, the acceleration LCP) on an algebra of this engine: impulses use M⁻¹ (a
/// frictional force is bounded, μ_s N, so it takes no part in an impulse); the acceleration LCP
/// of the held stops uses the mode's acceleration with the frictional contacts in their
/// current states (stuck ones as constraints, whose Delassus complement reduces the stops'
/// G: G − N ᵀM⁻¹W_S (W_SᵀM⁻¹W_S)⁻¹ W_SᵀM⁻¹N). After it the frictional contacts are decided
/// again with the held stops as constraints (friction.hpp's resolution, the static limit
/// μ_s N): an impact changes the velocities, so a contact stuck before it whose relative
/// velocity the impulse moved beyond the trigger slips in that velocity's direction. The two
/// decisions are repeated until the held set no longer changes (a friction state that pulls a
/// held stop open releases it; at most one round per stop), and the run ends with
/// RunStatus::numerical_failure if they do not agree. Then the relative velocities of the stuck
/// contacts and the normal rates of the held stops are set to 0 together (the smallest change
/// of v in the metric of M). A compliant stop's engage and disengage change only the mode, and
/// are followed by the same re-decision.
///
/// Where this differs from the stop engine: the chatter rule's local coefficients (α, β and the
/// state correction) are the free system's, as in the dense engine, with the friction forces of
/// the current states in the acceleration it reads; the force slope and curvature along the held
/// flow are exact (this engine's mode). The segments' force_local_minima are not computed
/// (ContactLog then records each held interval's least force at segment starts).
///
/// Scales (run_scales): the friction limits Σ μ_s N_j join the forcing amplitudes (fmax).
/// The analysis layer's tangent maps (friction_tangent.hpp) are built from the modes and events
/// this simulator reports to its FrictionStopObservers.
/// Limits: one harmonic surface motion per contact, at the fundamental.
#include "vibro/engine.hpp"
#include "vibro/friction.hpp"
#include "vibro/stops.hpp"

#include <map>
#include <memory>
#include <utility>
#include <vector>

namespace vibro {

/// A mode's rows for the data (M, C, K, f, the stops, the frictional contacts), computed as the
/// simulator computes them (the law above), for the analysis layer (friction_tangent.hpp): the
/// mode of the stops `key` (held rigid and engaged compliant) and the frictional contacts'
/// `states`. All rows act on the augmented state z (N = augmented_size(n, f)).
struct FrictionStopModeRows {
  ContactSet held;             ///< the key's held rigid stops, in order
  Eigen::MatrixXd generator;   ///< Â (N × N)
  /// The guards (rows ℓᵀ): the open stops' gaps (the first `opening_rows`), the held rigid stops'
  /// −λ and the engaged compliant stops' −g in stop order (up to `stop_rows`), then the friction
  /// guards of friction.hpp; FrictionStopSwitch::guard_row indexes them.
  Eigen::MatrixXd guards;
  Eigen::Index opening_rows = 0, stop_rows = 0;
  Eigen::MatrixXd force;       ///< the contacts' friction forces F_j (m × N)
  Eigen::MatrixXd held_force;  ///< the held stops' forces along their normals, F = −λ (h × N)
  Eigen::MatrixXd relative;    ///< the contacts' relative velocities u_j (m × N)
  Eigen::MatrixXd held_rates;  ///< the held stops' normal rates g' = nᵀv − p'(t) (h × N)
  /// Per contact: its tangent lies in the span of the held stops' normals (a stuck contact is
  /// then no constraint of its own, and the settling of the relative velocities skips it).
  std::vector<char> locked;
};
FrictionStopModeRows friction_stop_mode_rows(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C,
                                             const Eigen::MatrixXd& K, const HarmonicForcing& forcing,
                                             const std::vector<Stop>& stops,
                                             const std::vector<FrictionContact>& contacts, const ContactSet& key,
                                             const std::vector<FrictionState>& states);

/// One event of a run as a whole (every stop and contact that changed at that instant), with
/// what its saltation matrix needs (friction_tangent.hpp): the guard that fired (a row of the
/// old mode's FrictionStopModeRows::guards), the modes before and after, and the augmented
/// state before the event and after its whole resolution.
struct FrictionStopSwitch {
  double t = 0.0;
  Eigen::Index guard_row = -1;
  int guards_fired = 1;              ///< guards that fired together (> 1: a simultaneous event)
  ContactSet key_before, key_after;  ///< held rigid ∪ engaged compliant stops
  /// The held rigid stops as the stops' resolution (Newton's law, the chatter rule, the
  /// acceleration LCP) left them, before the frictional contacts' re-decision released any.
  ContactSet held_by_stops;
  std::vector<FrictionState> before, after;
  Eigen::VectorXd z_before, z_after;
};

/// Observes a run's modes: every segment's mode and start state and every event (called, when
/// given to run(), after the Observer calls of the same segment or event).
class FrictionStopObserver {
 public:
  virtual ~FrictionStopObserver() = default;
  virtual void mode_segment(double /*t_begin*/, double /*t_end*/, const ContactSet& /*key*/,
                            const std::vector<FrictionState>& /*states*/, const Eigen::VectorXd& /*z_begin*/) {}
  virtual void mode_switch(const FrictionStopSwitch& /*s*/) {}
};

class FrictionStopSimulator {
 public:
  /// The scene (its stops may be rigid or compliant), the frictional contacts (validated here)
  /// and the solver options. The scene must outlive the simulator.
  FrictionStopSimulator(const ImpactSystem& scene, std::vector<FrictionContact> contacts, SimulatorOptions options = {});
  FrictionStopSimulator(ImpactSystem&& scene, std::vector<FrictionContact> contacts, SimulatorOptions options = {}) = delete;
  ~FrictionStopSimulator();

  /// Runs from (t0, x0, v0) to t_end: the stops' events as the dense engine reports them, the
  /// friction events as Events of kinds friction_stick, friction_slip, friction_reversal (`stop`
  /// = the contact's index, v_before = v_after = its relative velocity, force = F_j). The summary
  /// counts impacts and chatters as the stop engines do; sticks and releases count both the
  /// stops' and the frictional contacts' (a slip or a reversal as a release).
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {},
                 const std::vector<FrictionStopObserver*>& mode_observers = {});

  const ImpactSystem& scene() const { return *scene_; }
  const std::vector<FrictionContact>& contacts() const { return contacts_; }
  /// The frictional contacts' states at the end of the last run.
  const std::vector<FrictionState>& states() const { return states_; }
  /// Friction events of the last run, by kind.
  long friction_sticks() const { return sticks_; }
  long friction_slips() const { return slips_; }
  long friction_reversals() const { return reversals_; }
  /// Modes (contact set, friction states) whose flows were built.
  std::size_t modes_built() const { return modes_.size(); }

  class Mode;  // friction_stops.cpp
  class Loop;  // friction_stops.cpp

 private:
  const ImpactSystem* scene_;
  std::vector<FrictionContact> contacts_;
  SimulatorOptions options_;
  std::map<std::pair<ContactSet, std::vector<FrictionState>>, std::unique_ptr<Mode>> modes_;
  std::vector<FrictionState> states_;
  long sticks_ = 0, slips_ = 0, reversals_ = 0;
};

/// The FrictionStopSimulator behind the Engine interface (engine.hpp), for the runner.
class FrictionStopEngine final : public Engine {
 public:
  FrictionStopEngine(ImpactSystem scene, std::vector<FrictionContact> contacts, const SimulatorOptions& options)
      : scene_(std::make_unique<ImpactSystem>(std::move(scene))),
        sim_(std::make_unique<FrictionStopSimulator>(*scene_, std::move(contacts), options)) {}
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {}) override {
    return sim_->run(t0, x0, v0, t_end, observers);
  }
  double frequency() const override { return scene_->system().forcing().frequency; }
  std::size_t stop_count() const override { return scene_->stop_count(); }
  FrictionStopSimulator& simulator() { return *sim_; }

 private:
  std::unique_ptr<ImpactSystem> scene_;  // stable address for sim_
  std::unique_ptr<FrictionStopSimulator> sim_;
};

}  // namespace vibro
