#pragma once
/// \file linearisation.hpp
/// The exact linearisation of a hybrid trajectory: the derivative of the state at t1 with
/// respect to the state at t0 (and to a parameter, and to both times), through every impact,
/// stick, release and chatter limit, to rounding.
///
/// **Between events** the motion with the stops S held is z' = Â_S z in the full augmented
/// coordinates z = [x; v; cos Ωt; sin Ωt; 1] (Â_∅ is flow.hpp's generator; Â_S adds the held
/// stops' contact forces, analysis/src/mechanics.hpp), so the tangent map of a segment of length
/// τ is the state block of exp(Â_S τ) — the flow's own propagator, never a finite difference.
/// A parameter p moves the generator by dÂ_S/dp; the sensitivity ζ = ∂z/∂p then obeys
/// ζ' = Â_S ζ + (dÂ_S/dp) z, whose solution over the segment is the top right block of the
/// exponential of the block generator [[Â_S, dÂ_S/dp], [0, Â_S]] applied to z (Van Loan 1978).
///
/// **At an event** at time t where the guard h (a gap g_j = w_jᵀx − s_j(t) for an impact, −λ_j
/// for a release) reaches zero and the state jumps by the reset z⁺ = R(z⁻, t), the perturbed
/// trajectory meets the guard at t + δt, δt = −(h_z δz⁻ + h_p δp)/ḣ⁻ with ḣ⁻ = h_z f⁻ + h_t, and
/// comparing both at time t gives the saltation matrix (Müller 1995; Leine & Nijmeijer 2004,
/// ch. 7; di Bernardo, Budd, Champneys & Kowalczyk 2008, § 2.5)
///
///     δz⁺ = S δz⁻ + s_p δp,   S = R_z + (f⁺ − R_z f⁻ − R_t) h_zᵀ / ḣ⁻,
///                             s_p = R_p + (f⁺ − R_z f⁻ − R_t) h_p / ḣ⁻,
///
/// with f∓ the vector fields of the contact sets before and after, at the states before and
/// after. The reset R is the engine's rule (event_resolution.cpp, written out in
/// analysis/src/mechanics.hpp) with its discrete choices fixed: the generalised Newton law over
/// the held and impacting stops on the LCP's active set (simultaneous and coupled impacts),
/// restitution 0 for held stops and for a chatter the chatter rule ends, the second-order
/// chatter rule's momentum kick (simulator.hpp, ChatterRule: its derivative through the rebound
/// speed w0 and the approach acceleration A is part of R_z, R_t and R_p), and the projection
/// that removes the held stops' residual normal velocity. R_z, R_t and R_p are the exact
/// directional derivatives of that code by forward-mode differentiation (dual numbers): no
/// formula is stated twice. Consequences worth knowing:
///  * Impact, fixed stop: R_z = [[I, 0], [0, I − M⁻¹W_A G_AA⁻¹ (I + R) W_Aᵀ]] (Wagg 2004, eq. 8
///    for one stop), and S adds the term that moves the impact time.
///  * Stick (an impact with r = 0, or a chatter caught by the rule): the held stops' normal
///    position and velocity leave the map: S maps onto the tangent space of the constraint
///    manifold {W_Sᵀ δx = 0, W_Sᵀ δv = 0} (the map loses rank 2|S|).
///  * Release: λ_j = 0 there, so f⁺ = f⁻ and S = I on that tangent space.
///  * Grazing: S grows like 1/ḣ⁻ as an impact's speed falls to zero (least_guard_rate says how
///    close an orbit is).
///  * Compliant stop (stops.hpp) engaging or disengaging: no reset (R = I, up to the
///    projection onto the held rigid stops' manifold), the guard is the stop's gap g = wᵀx − s(t)
///    both ways, and the vector field switches between the modes without and with the stop's
///    spring-dashpot, so (di Bernardo, Budd, Champneys & Kowalczyk 2008, § 2.5 and ch. 4 for
///    the flows with a switching surface)
///        S = I + (f⁺ − f⁻) wᵀ / (wᵀ v − s'(t)),   f⁺ − f⁻ = (0, ∓M⁻¹ w N),
///        N = k_s g + c_s g' + F_p,
///    the sign − on engaging, + on disengaging, all at the switch where g = 0, hence
///    N = c_s g' + F_p there: with c_s = 0 and F_p = 0 the vector field is continuous across
///    g = 0 and S = I exactly; with a dashpot or a preload it is not (the dashpot's part
///    c_s g' M⁻¹ w wᵀ/g' = c_s M⁻¹ w wᵀ does not even vanish as g' → 0, the preload's
///    F_p M⁻¹ w wᵀ/g' grows like 1/g' at grazing). The engine's
///    discrete choice is the same (engage when g rises through 0, disengage when it falls
///    through 0, whatever N), so this is the derivative of its map. The grazing of a compliant
///    stop (the orbit touching g = 0 without engaging) has a discontinuity map of order 3/2 in
///    the distance when the vector field is continuous, not the square root of a rigid impact
///    (Nordmark 1991; di Bernardo et al. 2008, ch. 7): continuation locates it from the side
///    without contact (test_functions.hpp). Several compliant stops switching at one instant
///    are taken in index order before any rigid event of that instant, as the engine does.
///  * Several guards at one instant (simultaneous impacts): the map is differentiable only if
///    the order in which they are perturbed apart does not matter. The impacts are composed one
///    at a time in both orders; `order_spread` gives their relative difference and a spread
///    above 1e-8 marks the map non-smooth there (the index order is returned).
///
/// **Structural zeros.** While S is held the tangent map factors through the tangent space of
/// the constraint manifold, of dimension d_S = 2(n − rank W_S). With d the least d_S along the
/// run, the 2n × 2n Jacobian J has at least 2n − d zero eigenvalues, exactly; the others are the
/// eigenvalues of the d × d map `reduced` = Bᵀ J₁ J₂ B, where J = J₂ J₁ is split at the end of a
/// segment of least d_S and B is an orthonormal basis of that tangent space (eig(J₂J₁) and
/// eig(J₁J₂) share their non-zero values). The Floquet multipliers of shooting.hpp come from it.
///
/// Features (when asked for, for the test functions of continuation.hpp): every interior local
/// maximum of a free stop's gap (grazing from below; for a compliant stop also while engaged:
/// its penetration's maxima), every interior local minimum of a held
/// stop's contact force, and after each release the held flow continued past it to its next
/// local minimum (negative: how far past rising the orbit is), each impact's speed, each contact
/// phase.
///
/// Usage:
///     vibro::LinearisationOptions o;
///     o.parameter = vibro::SystemDerivative::frequency_only();
///     vibro::TangentMap m = vibro::linearise(system, solver, 0.0, x0, v0, 2.0 * pi / omega, o);
///     // m.jacobian (2n × 2n), m.parameter (2n), m.reduced, m.saltations …
#include "vibro/observers.hpp"
#include "vibro/parameter.hpp"
#include "vibro/simulator.hpp"
#include "vibro/taylor_simulator.hpp"

#include <optional>
#include <string>
#include <vector>

namespace vibro {

/// One event's part in a tangent map.
struct SaltationRecord {
  double t = 0.0;
  ContactSet held_before, impacting, caught, released, held_after;
  int guard_stop = -1;       ///< the stop whose guard fired (the first, for simultaneous events)
  bool impact = false;       ///< the guard is a gap (else a contact force)
  double guard_rate = 0.0;   ///< ḣ⁻: the approach speed of an impact, −λ̇ of a release (> 0)
  bool simultaneous = false; ///< more than one impact at this instant
  double order_spread = 0.0; ///< ‖S(index order) − S(reverse order)‖ / ‖S‖ (simultaneous)
};

/// An interior local maximum of the gap of a stop that is not held (g < 0 unless it grazes).
struct GapPeak {
  int stop = -1;
  double t = 0.0, value = 0.0;
};

/// An interior local minimum of a held stop's contact force. `past_release`: the held flow
/// continued beyond a release of this stop (the value is then ≤ 0: the force the stop would need).
struct ForceDip {
  int stop = -1;
  double t = 0.0, value = 0.0;
  bool past_release = false;
};

/// An impact: its stop, time, approach speed u = g'⁻ > 0 and the gap's acceleration g''⁻ just
/// before it (< 0 where the free trajectory would turn back: u²/(2|g''|) is then how far past the
/// stop its parabola would rise, → 0 at grazing).
struct ImpactRecord {
  int stop = -1;
  double t = 0.0, speed = 0.0, acceleration = 0.0;
};

/// A contact phase: stop `stop` held over [t_start, t_end] (closed: ended by a release).
struct HeldPhase {
  int stop = -1;
  double t_start = 0.0, t_end = 0.0;
  bool closed = false;
};

struct LinearisationOptions {
  bool jacobian = true;                      ///< the full 2n × 2n ∂z(t1)/∂z(t0)
  /// Instead of J, only the products J·D for these columns (2n × p): tangent vectors carried
  /// through the run (Lyapunov exponents, matrix-free Newton). Empty: J itself.
  Eigen::MatrixXd directions;
  std::optional<SystemDerivative> parameter; ///< and ∂z(t1)/∂p at fixed t0, t1
  bool features = false;                     ///< gap peaks, force dips, phases (continuation)
  /// How far past a release the held flow is continued to find its next force minimum, in
  /// units of the time scale T (0 switches that off).
  double past_release_window = 0.5;
};

struct TangentMap {
  RunSummary summary;        ///< of the run (status not completed: the map is not valid)
  double t0 = 0.0, t1 = 0.0;
  Eigen::VectorXd x0, v0, x1, v1;
  Eigen::MatrixXd jacobian;  ///< ∂(x1, v1)/∂(x0, v0)
  Eigen::MatrixXd products;  ///< J·directions (when directions were given; jacobian is then empty)
  Eigen::VectorXd parameter; ///< ∂(x1, v1)/∂p (empty unless asked)
  /// The vector fields f(z, t) = (v, a) at the start and the end: ∂z1/∂t1 = rate_end,
  /// ∂z1/∂t0 = −J rate_start.
  Eigen::VectorXd rate_start, rate_end;

  Eigen::Index free_dimension = 0;  ///< d: least tangent dimension along the run (2n: none held)
  Eigen::MatrixXd reduced;          ///< d × d, shares J's non-zero eigenvalues (see above)
  /// 2n × d: an eigenvector e of `reduced` for μ ≠ 0 lifts to the eigenvector lift·e of J.
  Eigen::MatrixXd lift;
  bool starts_held = false;  ///< the run starts with a stop held (J is then one-sided there)
  bool ends_at_event = false;  ///< an event falls on t1 exactly (J is one-sided there)

  std::vector<SaltationRecord> saltations;
  std::vector<Event> events;   ///< every event of the run, as the engine reported them
  double least_guard_rate = 0.0;  ///< min ḣ⁻ over impacts, in units of the velocity scale V
  bool non_smooth = false;        ///< simultaneous impacts whose order matters (see above)
  std::string non_smooth_reason;

  std::vector<GapPeak> gap_peaks;
  std::vector<ForceDip> force_dips;
  std::vector<ImpactRecord> impacts;
  std::vector<HeldPhase> phases;
};

/// Runs the dense engine (Simulator with `solver`) from (t0, x0, v0) to t1 and returns the
/// tangent map. Throws InvalidInput as Simulator::run does (bad sizes, an inadmissible start)
/// and for a parameter derivative of the wrong size. Compliant stops (stops.hpp) are taken
/// as above: each mode's generator carries the engaged stops' k_s and c_s along their normals
/// and their preloads, each switch its saltation. A parameter derivative moves the data D of
/// parameter.hpp (the compliant stops' positions and motion with it, through k_s s(t) + c_s s'(t)
/// in the engaged forcing); k_s, c_s and F_p are not among D.
TangentMap linearise(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                     const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
                     const LinearisationOptions& options = {});

/// The same map on the Taylor engine (taylor_simulator.hpp): `system` with the nonlinear forces
/// F(x, v, t) added. Between events the tangent map of a segment comes from the variational
/// equations Φ' = (∂f/∂z) Φ, integrated by the Taylor core's forward-mode differentiation of the
/// same series (taylor_step.hpp) from the engine's state at the segment's start to its end, so it
/// is the derivative of the flow to the series' tolerance (rounding by default). At an impact the
/// saltation matrix is the one above, S = R_z + (f⁺ − R_z f⁻ − R_t) h_zᵀ / ḣ⁻, with the reset R
/// of the linear engines (the Newton law depends on M, the normals and the restitutions, not on
/// the forces) and the vector fields f∓ = (v, a_lin + M⁻¹F) of the nonlinear system. With stops
/// held (sticking, a chatter caught by its rule) the segment's flow is the held one, a = a_free −
/// M⁻¹W λ, λ = G⁻¹(Wᵀa_free − s̈) with the forces in a_free, written on the whole state space as
/// the linear engines' Â_S is; its variational equations give the segment's map, f∓ carry the
/// projected forces (I − M⁻¹W G⁻¹Wᵀ) M⁻¹F, and a release's guard −λ_a its gradient, rate and
/// parameter derivative from the same series. A parameter derivative (`options.parameter`) is a
/// variational equation of a lifted system (taylor_tangent.cpp); `options.features` come from the
/// Taylor steps (the gaps' peaks, the held forces' minima).
///
/// Compliant stops are handled (their switches' saltation (f⁺ − f⁻) wᵀ/ġ). Refused with
/// InvalidInput: a parameter that moves M. Throws as TaylorSimulator does for bad forces.
TangentMap linearise(const ImpactSystem& system, const NonlinearForces& forces, const SimulatorOptions& solver,
                     double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
                     const LinearisationOptions& options = {});

}  // namespace vibro
