#pragma once
/// \file simulator.hpp
/// The hybrid event loop: exact flows between events, certified event location, Newton impacts,
/// chatter resolved into sticking, sticking ended where a contact force crosses zero.
///
/// procedure Run(t0, x0, v0, t_end):
///     S ← Settle(stops touching with zero approach speed)      # acceleration LCP, contact.hpp
///     loop
///         mode ← contact set S (reduced flow built on first use)
///         segment ← exact flow of mode from (t, x, v); guards: g_j for j ∉ S, -λ_j for j ∈ S
///         τ* ← earliest guard rising above its trigger ε in (t, t_end]   # events.hpp guarantee
///         report the segment [t, t + τ*] to the observers
///         if none: stop at t_end
///         t ← t + τ*;  (x, v) ← exact state there
///         I ← gap guards at zero and closing within the simultaneity window  (impacts)
///         L ← force guards at zero and decreasing                          (releases)
///         if I ≠ ∅:
///             slow ← {j ∈ I : r_j < 1, j would be held (LCP), next bounce below chatter_height}
///             Λ ← impulse LCP over S ∪ I with r_j := 0 for j ∈ slow       # generalised Newton
///             v ← v - M⁻¹ W Λ;   log impacts; log chatter limit of j ∈ slow at the
///                 Budd–Dux accumulation time t + 2 r_j g'_j / (a_j (1 - r_j))
///         S ← Settle(candidates: S \ L ∪ {j ∈ I : |g'_j⁺| ≤ v_contact})   # acceleration LCP
///         log sticks (S grew) and releases (S shrank)
///         if more than max_events events within one event window: stop (Zeno guard)
///
/// Both engines run this loop (framework/src/event_loop.hpp; the dense engine here, the modal
/// chain engine of modal.hpp) and locate crossings with the same certified search (events.hpp,
/// on their guards as a GuardSource); they differ only in how a mode's segment is built and
/// evaluated, and in their stops' algebra. What each guard's crossing means, and where a contact
/// law other than the rigid stop would plug in, is contact_law.hpp.
///
/// Tolerances are relative to scales of the problem: length L (stops, initial state, static and
/// forced response), velocity V = L·ω_ref, force F = (largest stiffness or mass·ω²)·L, time
/// T = 2π/ω_ref with ω_ref the forcing frequency (or the fastest natural frequency if unforced).
#include "vibro/contact.hpp"
#include "vibro/observers.hpp"

#include <atomic>
#include <string>
#include <vector>

namespace vibro {

/// The chatter rule: what replaces the bounces left after the impact that ends a chatter.
///
/// Local model (the gap g ≤ 0 of the chattering stop j, τ from an impact with rebound speed w):
/// g'' = A(t) + α g' + O(g), where A(t) = G λ_j(t) is the approach acceleration the held stop
/// resists (G = w_jᵀ M⁻¹ w_j, λ_j its holding force along the sticking flow) and
/// α = -w_jᵀ M⁻¹ C M⁻¹ w_j / G the damping felt by the gap's own rate (the impulses and the
/// missing contact force both act along M⁻¹ w_j).
///  * first_order (Budd & Dux 1994, "Chattering and related behaviour in impact oscillators",
///    Phil. Trans. R. Soc. A 347): A constant, α = 0. The rebounds are r^k w0 (w0 = r u), the
///    flights 2 r^k w0 / A, so the bounces accumulate at t + T0, T0 = 2 w0 / (A (1 - r)); the
///    error of the accumulation time is O(T0²) (O(w0²)), and the motion of the other degrees of
///    freedom misses the bounces' mean displacement, O(w0³).
///  * second_order: the same expansion carried one order further, in the spirit of the
///    chatter map of Nordmark & Piiroinen (2009, "Simulation and stability analysis of impacting
///    systems with complete chattering", Nonlinear Dyn. 58): with A(t_k) = A + A'(t_k - t),
///    one flight lasts τ_k = 2w_k/A_k - (4/3) A' w_k²/A³ + (2/3) α w_k²/A² and ends at the speed
///    u_{k+1} = w_k + (2/3)(A'/A² + α/A) w_k², so that, summed over the geometric series to first
///    order in w0 (derivation in event_resolution.cpp),
///        T = T0 + T0² (α/6 - A'/(3A)),   error O(T0³) = O(w0³);
///    and the bounces' displacement δg (∫ δg dt = -(2/3) w0³ / (A² (1 - r³)) over the whole tail)
///    acts on the rest of the system. Derivation: the true motion minus the sticking motion
///    started at the impact, e(t), obeys M e'' + C e' + K e = w_j μ(t), μ the impulses minus the
///    holding force; with the impulse response H(τ) = M⁻¹τ − ½M⁻¹CM⁻¹τ² + ⅙(M⁻¹CM⁻¹CM⁻¹ −
///    M⁻¹KM⁻¹)τ³ + … and the moments m_k = ∫ (t∞ − s)ᵏ μ ds (m_k = O(w0^{k+1})), the state
///    difference at the accumulation point t∞ is e = Σ H_k w_j m_k, e' = Σ k H_k w_j m_{k−1}.
///    The gap's own end conditions δg = δg' = 0 fix m_1, m_0 from m_2 = 2 ∫δg dt / G, and what
///    is left, with q = M⁻¹ w_j and d = P M⁻¹ C q (P removing the held stops' normal components,
///    M-orthogonally), is the correction applied at the impact:
///        Δx = −(∫δg dt / G) d,   Δv = (∫δg dt / G) (M⁻¹ C d − M⁻¹ K q)   (then v's normal part
///    is taken by the held stops), so that the state errs by O(w0⁴) instead of O(w0³). On the
///    paper's system (damped), state error outside the chatter tails against chatter_height
///    = 1e-13: 9.6e-11 → 9.5e-12 L at chatter_height 1e-7, 2.3e-9 → 9.4e-11 at 1e-6 (bench_engine;
///    the former value with Δv's K term alone: without damping d = 0 and that is the whole
///    correction; tests/framework/test_chatter.cpp).
///    A' = G λ_j' comes exactly from
///    the reduced sticking flow (ℓ Â z of the force row). Where the expansion does not hold
///    (|T - T0| > T0/2: the holding force changes by O(1) within the tail) T0 is kept.
///  * third_order (default): the state as second_order, the accumulation time
///    one order further, O(w0⁴). The same moment expansion, carried to the gap itself
///    (h = −g ≥ 0, s from the impact), closes at this order into a local equation without memory:
///        h'' = −A(s) + α h' + β h + O(w0³),   A(s) = A + A' s + ½ A'' s²,
///        β = (w_jᵀM⁻¹CM⁻¹CM⁻¹w_j − w_jᵀM⁻¹KM⁻¹w_j) / G − α²
///    (the impulses' history enters through Σ P_k φ''(t − t_k), φ = w_jᵀ H w_j the gap's own
///    impulse response, whose terms are α h' and β h to this order). Its bounces are not summed
///    in closed form but one by one (each flight the root of its Taylor polynomial, event_resolution.cpp,
///    local_tail): no series to get wrong, and a few hundred flops per chatter. A'' = G λ_j'' from
///    the reduced sticking flow like A'. Same fallback (to T0) where the model has no accumulation.
/// All are exact for a ball under constant gravity (A' = α = 0, K = 0). For several held stops
/// the rules use the diagonal G_jj and the free system's α, β: exact when the held stops' normals
/// are M⁻¹-orthogonal and the damping does not couple them (Wagg 2004: stops on different masses,
/// diagonal M — the damping does couple them there, at O(w0⁴) in the times).
enum class ChatterRule { first_order, second_order, third_order };
/// Its name in scenes and results ("first_order", "second_order", "third_order").
const char* to_string(ChatterRule rule);

struct SimulatorOptions {
  /// Guards trigger when they exceed this fraction of L (gaps) or F (forces): no penetration
  /// beyond it, and any excursion beyond it is detected.
  double trigger = 1e-13;
  /// Impacts closer in time than this fraction of T are treated as simultaneous.
  double simultaneity = 1e-12;
  /// Chatter is ended by jumping to its accumulation point (chatter_rule) at an impact on a
  /// stop that would hold (acceleration LCP) when the next bounce would rise less than
  /// chatter_height·L, i.e. (r u)² / (2 a) ≤ chatter_height·L for approach speed u and approach
  /// acceleration a, or when u ≤ chatter_velocity·V. Errors: see ChatterRule (with the default
  /// third-order rule the accumulation time errs by O(u⁴), the state by O(u⁴)).
  double chatter_height = 1e-9;
  double chatter_velocity = 0.0;
  /// How the skipped bounces are accounted for (see ChatterRule).
  ChatterRule chatter_rule = ChatterRule::third_order;
  /// Post-impact normal speeds below this fraction of V count as resting contact.
  double contact_velocity = 1e-11;
  /// Zeno guard: at most this many events within one event window (default one period T).
  long max_events = 100000;
  double event_window = 0.0;  ///< 0: T
  /// Length scale L; 0 = automatic.
  double length_scale = 0.0;
  FlowOptions flow;
  /// Cancellation: when set, both engines read it once per event and once per step of the event
  /// search, and end the run with RunStatus::interrupted (state and time where they stopped) as
  /// soon as it is true. For Ctrl-C in sweeps and in Python; the flag must outlive the run.
  const std::atomic<bool>* interrupt = nullptr;
  /// Progress: when set, both engines store the time reached there (relaxed) wherever they poll
  /// `interrupt`, so that another thread can report a long run's progress. Costs one store.
  std::atomic<double>* reached = nullptr;

  /// Throws InvalidInput naming the field, the value and the rule.
  void validate() const;
};

/// unsupported: the engine cannot represent what the run reached (the modal chain engine of
/// modal.hpp, e.g. sticking on a stop between non-neighbouring masses); the message says what.
/// interrupted: SimulatorOptions::interrupt was raised; the summary holds the state reached.
enum class RunStatus { completed, event_cap, numerical_failure, unsupported, interrupted };
const char* to_string(RunStatus s);

struct RunSummary {
  RunStatus status = RunStatus::completed;
  std::string message;   ///< why the run stopped early (empty when completed)
  double t = 0.0;        ///< time reached
  Eigen::VectorXd x, v;  ///< state reached
  ContactSet stuck;      ///< stops held at the end
  long impacts = 0, sticks = 0, releases = 0, chatters = 0, segments = 0;
  /// Work of the event search (events.hpp): guard evaluations (one guard at one time) and
  /// evaluation points (one evaluation of the exponentials, shared by all guards at that time).
  long guard_evaluations = 0, evaluation_points = 0;
  std::size_t contact_sets_built = 0;    ///< restitution data built (distinct sets visited)
  std::size_t sticking_flows_built = 0;  ///< reduced sticking subsystems built
  /// What the run could not do as well as the tolerances ask, found before it started (see
  /// Simulator::run): e.g. the spacing of doubles near t coarser than the trigger allows.
  std::vector<std::string> warnings;
  double length_scale = 0.0, velocity_scale = 0.0, force_scale = 0.0, time_scale = 0.0;
};

/// The length scale L a run uses (RunSummary::length_scale; SimulatorOptions' tolerances are
/// relative to it) for a system of forcing frequency `omega` (> 0), max |K_ij| = kmax,
/// max |M_ij| = mmax, forcing amplitudes summing to fmax, started from (x0, v0). For an unforced
/// system (the engines use the fastest mode's frequency) give omega = 1, fmax = 0 and v0 = 0:
/// the result is then a lower bound of the L the run will use.
double run_length_scale(const SimulatorOptions& options, double omega, double kmax, double mmax, double fmax,
                        const std::vector<Stop>& stops, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0);

class Simulator {
 public:
  /// Validates options. The scene must outlive the simulator.
  explicit Simulator(const ImpactSystem& scene, SimulatorOptions options = {});
  /// The simulator keeps a reference to its scene: a temporary one would dangle.
  explicit Simulator(ImpactSystem&& scene, SimulatorOptions options = {}) = delete;

  /// Runs from (t0, x0, v0) to t_end, reporting to `observers`. Throws InvalidInput if x0
  /// violates a stop by more than the trigger tolerance or sizes are wrong, and if the run
  /// cannot be resolved in doubles at all: near t the spacing of doubles moves a stop by more
  /// than 1e-6 L (|ω|·ulp(t) > 1e-6: e.g. t0 = 1e15), the forcing is so large against the
  /// stiffness that the exact flow's rounding exceeds 1e-6 of the motion (fmax/k > 3.8e8 length
  /// units: the flow carries the forcing as a unit oscillator, so its rounding grows like
  /// 12 ε fmax/k), or solver.length_scale puts the trigger outside [10 ulp, 1e-3] of the scene's
  /// own length scale. Where those errors only exceed the trigger tolerance, the run goes on and
  /// says so in RunSummary::warnings. Numerical trouble and the Zeno guard end the run with a
  /// status and a message, never with NaN.
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {});

  const ContactModes& modes() const { return modes_; }
  const ImpactSystem& scene() const { return *scene_; }
  /// Guard evaluations of the current (or last) run so far, updated after each search, before
  /// the segment is reported: an observer reads the work of each search from its differences.
  long guard_evaluations() const { return guard_evaluations_; }

  /// The acceleration LCP (contact.hpp) at (t, x, v): which of `candidates` (sorted stop
  /// indices) hold, and the contact forces of all candidates in `forces` (0 for those released).
  ContactSet settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                    const ContactSet& candidates, Eigen::VectorXd* forces) const;

 private:
  class Loop;  // the engine's side of the event loop (simulator.cpp)
  /// ω for the run's scales: the forcing frequency, or the fastest mode's when unforced.
  double scale_frequency() const;

  const ImpactSystem* scene_;
  SimulatorOptions options_;
  ContactModes modes_;
  long guard_evaluations_ = 0;
};

}  // namespace vibro
