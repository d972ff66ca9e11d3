#pragma once
/// \file friction.hpp
/// Dry (Coulomb) friction with stick-slip on the dense engine: exact linear flows between
/// events, certified location of every switch.
///
/// A frictional contact j acts along a tangent w_j on a LinearSystem M x'' + C x' + K x = f(t):
///   * on one mass i against a surface that moves as s_j(t) = a_j cos(Ω t + φ_j) (w_j = e_i), or
///   * between two masses i, k (w_j = e_i − e_k, s_j = 0),
/// with normal load N_j ≥ 0, static and kinetic coefficients μ_s ≥ μ_k ≥ 0. Its relative velocity
/// is u_j = w_jᵀv − s_j'(t), and it exerts the force w_j F_j on the masses:
///
///     M x'' + C x' + K x = f(t) + Σ_j w_j F_j.
///
/// Slipping (u_j ≠ 0, or u_j = 0 with the relative acceleration moving away): F_j = −μ_k N_j σ_j,
/// σ_j = sign(u_j): a constant, added to the constant part of f, so the motion stays linear.
/// Stuck (u_j ≡ 0): F_j is whatever holds w_jᵀx'' = s_j''(t). For the stuck set S (tangents W,
/// columns w_j) and the right-hand side r = f(t) + Σ_{slipping} w_j F_j − C v − K x,
///
///     F_S = G⁻¹ (s_S''(t) − Wᵀ M⁻¹ r),     G = Wᵀ M⁻¹ W        (the holding forces),
///     x'' = M⁻¹ (r + W F_S) = P M⁻¹ r + M⁻¹ W G⁻¹ s_S''(t),   P = I − M⁻¹ W G⁻¹ Wᵀ,
///
/// a linear system again in the augmented state z = [x; v; cos Ωt; sin Ωt; 1] of flow.hpp
/// (s'' = −a Ω² cos(Ωt + φ) is a combination of the forcing oscillator's components), whose
/// exact flow keeps Wᵀx − s_S(t) constant: the constant c at which the contact stuck is carried by
/// the state itself, so one flow serves every stick of the same mode. A mode is the state of
/// every contact (slipping +, slipping −, stuck); its flow is built on first use (FrictionModes).
///
/// Guards (rows ℓᵀz of the mode's flow, located by the certified search of events.hpp):
///   slipping σ_j:  −σ_j u_j            (it fires when u_j reaches 0)
///   stuck:          F_j − μ_s N_j  and  −F_j − μ_s N_j   (it fires when |F_j| reaches μ_s N_j)
/// Both are linear in z, so the search's guarantee holds unchanged.
///
/// Resolution (at t0 and at every event). Contacts with |u_j| within the trigger (and the
/// contacts already stuck) are candidates; the others slip in the direction of u_j. Every
/// assignment of the candidates to {stuck, slipping +, slipping −} is tried (3^c of them, c ≤ 10)
/// and accepted when consistent: every stuck contact's holding force within μ_s N_j, every
/// candidate slipping in direction σ_j has σ_j u_j' > 0 (its relative acceleration in that mode
/// carries it that way). The contact whose guard fired is not kept in its old state (a
/// slip that reached u = 0 sticks or reverses; a stick whose force reached μ_s N slips, in the
/// direction opposite to F: the way the other forces push it). Among consistent assignments the
/// one with the most stuck contacts is taken (ties: the first in the enumeration, which counts
/// the candidates' options stuck, +, − like the digits of a base-3 number, the first candidate
/// the lowest digit); if none is consistent with the fired contact changing state, it may keep
/// its state. Tolerances: forces within ε·F, relative accelerations within ε·V·ω (ε the solver's
/// trigger; F, V, ω the run's scales). For one contact
/// this is exactly Coulomb's law: stick iff |F| ≤ μ_s N, else slip against F (and with
/// μ_s ≥ μ_k the slip is consistent, since σ u' = G(|F| − μ_k N) > 0). For several coupled
/// contacts the consistent set need not be unique (as with the contact LCP of stops); the rule
/// above picks one, and a run where none is consistent ends with RunStatus::numerical_failure.
///
/// Limits: FrictionSimulator runs scenes without stops; friction together with stops runs on
/// FrictionStopSimulator (friction_stops.hpp), which shares these modes' algebra. The modal and
/// Taylor engines have no friction. The analysis layer's tangent
/// maps of friction runs (saltation matrices of stick, slip and reversal; friction_tangent.hpp)
/// are built from the switches this simulator reports to its FrictionObservers. The forcing may
/// have extra harmonics; the surfaces move at the fundamental Ω.
///
/// References: J. P. Den Hartog, "Forced vibrations with combined Coulomb and viscous friction",
/// Trans. ASME 53 (1931) APM-53-9, 107–115 (the steady state without stops, tests); S. W. Shaw,
/// "On the dynamic response of a system with dry friction", J. Sound Vib. 108 (1986) 305–325.
#include "vibro/engine.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace vibro {

struct FrictionContact {
  enum class Kind { surface, between };
  Kind kind = Kind::surface;
  Eigen::Index mass = 0;     ///< i
  Eigen::Index other = -1;   ///< k, for Kind::between
  double normal_load = 0.0;  ///< N ≥ 0
  double static_coefficient = 0.0;   ///< μ_s ≥ μ_k
  double kinetic_coefficient = 0.0;  ///< μ_k ≥ 0
  double amplitude = 0.0;    ///< a of the surface's motion a cos(Ωt + φ) (surface contacts only)
  double phase = 0.0;        ///< φ, radians
  std::string name;          ///< for messages; defaulted by validated_friction ("mass x0", "between x0-x1")

  static FrictionContact on_surface(Eigen::Index mass, double load, double mu_s, double mu_k,
                                    double amplitude = 0.0, double phase = 0.0);
  static FrictionContact between(Eigen::Index mass, Eigen::Index other, double load, double mu_s, double mu_k);
  /// Tangent w (length n).
  Eigen::VectorXd tangent(Eigen::Index n) const;
};

/// Checks every contact (index in range and distinct for between, N ≥ 0, μ_k ≥ 0, μ_s ≥ μ_k,
/// all finite, no amplitude on a between contact) and names them; throws InvalidInput naming
/// friction[j] and the key.
std::vector<FrictionContact> validated_friction(std::vector<FrictionContact> contacts, Eigen::Index n);

/// The state of one frictional contact between events.
enum class FrictionState : std::int8_t { slip_negative = -1, stuck = 0, slip_positive = 1 };

/// Friction events: stick (a slip reached u = 0 and the contact holds), slip (a stuck contact's
/// holding force reached μ_s N, or a contact at u = 0 at the start slips), reversal (a slip
/// reached u = 0 and slips on the other way).
enum class FrictionEventKind { stick, slip, reversal };
const char* to_string(FrictionEventKind kind);

struct FrictionEvent {
  double t = 0.0;
  int contact = -1;
  FrictionEventKind kind = FrictionEventKind::stick;
  double force = 0.0;  ///< F_j after the event (the holding force when stuck, −μ_k N σ when slipping)
};

/// The friction force F_j of every contact at a state, in a given mode (for observers and tests).
struct FrictionSnapshot {
  double t = 0.0;
  std::vector<FrictionState> states;
  Eigen::VectorXd forces;  ///< F_j
};

struct FrictionSummary {
  RunStatus status = RunStatus::completed;
  std::string message;
  double t = 0.0;
  Eigen::VectorXd x, v;
  std::vector<FrictionState> states;  ///< at the end
  long sticks = 0, slips = 0, reversals = 0, segments = 0;
  std::size_t modes_built = 0;
  double length_scale = 0.0, velocity_scale = 0.0, force_scale = 0.0;
};

/// One switch of a friction run as a whole (every contact that changed at that instant), with
/// what its saltation matrix needs (friction_tangent.hpp): the guard that fired, h = ℓᵀz with ℓ
/// the `guard_index`-th row of the old mode's guards (friction_mode_rows), and the augmented
/// state z = [x; v; cos Ωt; sin Ωt; 1; …] at the switch before and after the settling of the
/// relative velocities (the reset z⁺ = z⁻ − B U_S z⁻ of settle_relative_velocities, S the
/// contacts stuck before or after).
struct FrictionSwitch {
  double t = 0.0;
  int fired = -1;            ///< the contact whose guard fired
  Eigen::Index guard_index = -1;
  std::vector<FrictionState> before, after;
  Eigen::VectorXd z_before, z_after;
};

/// Observes a friction run: the usual observers (segments: states from the exact flow; no stops,
/// so active() is empty) plus the friction events; and, for observers that ask for them
/// (wants_modes), every segment's mode and every switch.
class FrictionObserver {
 public:
  virtual ~FrictionObserver() = default;
  virtual void friction_event(const FrictionEvent& /*event*/, const Eigen::VectorXd& /*x*/,
                              const Eigen::VectorXd& /*v*/) {}
  /// True: friction_segment and friction_switch are called (else they cost nothing).
  virtual bool wants_modes() const { return false; }
  /// A segment [t_begin, t_end] in the mode `states`, from the augmented state z_begin (before the
  /// Observer::segment call of the same segment).
  virtual void friction_segment(double /*t_begin*/, double /*t_end*/, const std::vector<FrictionState>& /*states*/,
                                const Eigen::VectorXd& /*z_begin*/) {}
  /// A switch (before the friction_event calls of its contacts).
  virtual void friction_switch(const FrictionSwitch& /*s*/) {}
};

/// A mode's rows for the data (M, C, K, f) and the contacts, computed as the simulator computes
/// them (friction.hpp's law): the augmented generator Â (N × N), the friction forces F = force z
/// (m × N), the guards h = guards z (the mode's guard order: per contact, −σ_j u_j while slipping,
/// F_j − μ_s N_j and −F_j − μ_s N_j while stuck) and the relative velocities u = relative z
/// (m × N). The analysis layer takes its parameter derivatives from these (M must be positive
/// definite; C, K, f are used as given, unchecked).
struct FrictionModeRows {
  Eigen::MatrixXd generator, force, guards, relative;
};
FrictionModeRows friction_mode_rows(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K,
                                    const HarmonicForcing& forcing, const std::vector<FrictionContact>& contacts,
                                    const std::vector<FrictionState>& states);

class FrictionSimulator {
 public:
  /// The system, its contacts (validated here) and the solver options (trigger, max_events,
  /// event_window and flow are used). Throws InvalidInput on bad contacts.
  FrictionSimulator(const LinearSystem& system, std::vector<FrictionContact> contacts, SimulatorOptions options = {});
  /// The simulator keeps a reference to its system: a temporary one would dangle.
  FrictionSimulator(LinearSystem&& system, std::vector<FrictionContact> contacts, SimulatorOptions options = {}) = delete;
  ~FrictionSimulator();

  /// Runs from (t0, x0, v0) to t_end. The initial contact states are decided by the resolution
  /// above. Segments go to `observers` (Observer::segment, ::begin, ::end; Observer::event is not
  /// called: friction events go to `friction_observers`).
  FrictionSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                      const std::vector<Observer*>& observers = {},
                      const std::vector<FrictionObserver*>& friction_observers = {});

  const std::vector<FrictionContact>& contacts() const { return contacts_; }
  const LinearSystem& system() const { return *system_; }
  /// The relative velocities u_j at (t, v).
  Eigen::VectorXd relative_velocities(double t, const Eigen::VectorXd& v) const;
  /// The friction forces F_j at (t, x, v) in the given contact states.
  Eigen::VectorXd forces(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                         const std::vector<FrictionState>& states) const;

  class Mode;  // a mode's exact flow and guard rows (friction.cpp)

 private:
  const Mode& mode(const std::vector<FrictionState>& states);

  const LinearSystem* system_;
  std::vector<FrictionContact> contacts_;
  SimulatorOptions options_;
  std::map<std::vector<FrictionState>, std::unique_ptr<Mode>> modes_;
};

/// The FrictionSimulator behind the Engine interface (engine.hpp), for the runner: friction events
/// reach the observers as Events of kinds friction_stick, friction_slip and friction_reversal
/// (`stop` = the contact's index, v_before = v_after = its relative velocity, force = F_j);
/// RunSummary counts them as sticks (friction_stick) and releases (friction_slip and
/// friction_reversal).
/// A friction run's summary as the engines' RunSummary (as FrictionEngine::run reports it).
RunSummary run_summary(const FrictionSummary& f);

class FrictionEngine final : public Engine {
 public:
  FrictionEngine(LinearSystem system, std::vector<FrictionContact> contacts, const SimulatorOptions& options);
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {}) override;
  double frequency() const override { return system_->forcing().frequency; }
  std::size_t stop_count() const override { return 0; }
  FrictionSimulator& simulator() { return *sim_; }

 private:
  std::unique_ptr<LinearSystem> system_;  // stable address for sim_
  std::unique_ptr<FrictionSimulator> sim_;
};

}  // namespace vibro
