#pragma once
/// \file friction_tangent.hpp
/// The analysis layer on friction scenes (friction.hpp): the exact tangent map of a run with dry
/// friction and stick-slip, periodic orbits by shooting with their Floquet multipliers, Lyapunov
/// spectra and continuation.
///
/// **Between switches** the motion in a mode (every contact slipping +, slipping − or stuck) is
/// z' = Â z in the augmented coordinates z = [x; v; cos Ωt; sin Ωt; 1; …] (friction.hpp), so the
/// tangent map of a segment of length τ is the state block of exp(Â τ); a parameter p moves Â
/// by dÂ/dp and the sensitivity over the segment is the top right block of the exponential of
/// [[Â, dÂ/dp], [0, Â]] (Van Loan 1978), as in linearisation.hpp.
///
/// **At a switch** at time t where the guard h = ℓᵀz of the old mode reaches zero (ℓ = −σ_j u_j's
/// row while contact j slips in direction σ_j, ±F_j − μ_s N_j's while it is stuck) and the engine
/// resets z⁺ = R(z⁻) = z⁻ − B U_S z⁻ (the relative velocities u_S of the contacts S stuck before or
/// after set to zero in the metric of M: U_S their rows, B = [0; M⁻¹W_S (W_SᵀM⁻¹W_S)⁻¹; 0]), the
/// saltation matrix is (Müller 1995; Leine & Nijmeijer 2004, ch. 7; di Bernardo, Budd, Champneys
/// & Kowalczyk 2008, § 2.5)
///
///     S = R_z + (f⁺ − R_z f⁻) ℓᵀ / (ℓᵀ f⁻),   R_z = I − B U_S,   f∓ = Â∓ z∓,
///
/// in augmented coordinates (time enters through the oscillator's components of z, so R_t = 0),
/// and for a parameter s_p = R_p + (f⁺ − R_z f⁻) (ℓ_pᵀ z⁻) / (ℓᵀ f⁻), R_p = −B (dU_S/dp) z⁻. The
/// three switches of Coulomb friction are its cases:
///  * **slip → stick** (u_j reaches 0, the holding force within μ_s N_j): f⁺ is the stuck mode's
///    field, tangent to u_j = 0 (the Filippov sliding vector field). ℓᵀ S = 0 — the perturbed
///    relative velocity is annihilated: the stuck direction collapses, one structural zero per
///    stuck contact (with R = I the same S is the Filippov sliding-entry saltation
///    I + (f_s − f⁻) ℓᵀ/(ℓᵀf⁻) of di Bernardo et al. 2008, § 2.5 and ch. 8, since ℓᵀ B U = ℓᵀ);
///  * **stick → slip** (|F_j| reaches μ_s N_j): ℓ is the force guard's row and f⁺ − f⁻ = M⁻¹ w_j
///    (F⁺_j − F⁻_j) with F⁺_j = −μ_k N_j σ_j, F⁻_j = μ_s N_j sign F_j = −μ_s N_j σ_j: S = R_z when
///    μ_s = μ_k (the force is continuous), else the jump (μ_s − μ_k) N_j moves S;
///  * **reversal** (u_j passes through 0, slipping on the other way): a Filippov crossing with
///    R = I and f⁺ − f⁻ = (0, 2 μ_k N_j σ⁻_j M⁻¹ w_j, 0): S = I + (f⁺ − f⁻) ∇hᵀ / (∇h · f⁻)
///    (Leine & Nijmeijer 2004, § 7.2; di Bernardo et al. 2008, § 2.5).
/// Several contacts changing at one instant are taken as one switch with the guard that fired
/// (the map is then not smooth: `non_smooth` says so).
///
/// **Structural zeros.** After a stick the tangent map lies in {Wᵀ_S δv = 0} while S is stuck
/// (the stuck flow keeps Wᵀ_S δv constant), so with d = 2n − (most contacts stuck at once after a
/// switch) the 2n × 2n Jacobian has 2n − d zero eigenvalues, exactly; TangentMap::reduced (d × d)
/// carries the others, as in linearisation.hpp. Shooting reports them as structural zero
/// multipliers, the Lyapunov spectrum as exponents −∞ (LyapunovResult::structural). A run that
/// starts stuck keeps the start's relative velocity until its first switch (not a zero: the
/// state's own u is carried), and is one-sided there (`starts_held`).
///
/// **Features** (LinearisationOptions::features, continuation's sliding bifurcations). A contact
/// that reaches u_j = 0 from a slip either reverses or sticks by Coulomb's law: its margin
/// m = |F_j^hold| − μ_s N_j (F_j^hold the force that would hold it there, the mode with j stuck)
/// is > 0 at a reversal and ≤ 0 at a stick, continuous through the crossing-sliding bifurcation
/// where a stick phase is born at a reversal (Kuznetsov, Rinaldi & Gragnani 2003; di Bernardo et
/// al. 2008, ch. 8). Every reversal's margin is a ForceDip (past_release = false), every stick's a
/// ForceDip with past_release = true; and every interior local minimum of σ_j u_j of a slipping
/// contact (→ 0 at a grazing-sliding bifurcation, where a stick phase is born inside a slip) a
/// ForceDip (past_release = false) with the value σ_j u_j F/V (F, V the run's force and velocity
/// scales); and every interior local maximum of |F_j| of a stuck contact, with the value
/// μ_s N_j − |F_j| (→ 0 at an adding-sliding bifurcation, where a slip is born inside a stick
/// phase: the sliding flow touches the boundary of the sliding region), a ForceDip (past_release
/// = false) in force units. Those extrema are found on 64 samples per segment refined by
/// bisection on the derivative (not certified: two within one sample are seen as none). A phase
/// born inside a slip or a stick changes the contact's switch count by two and is located as a
/// `rising` of that contact like the crossing-sliding one. The contact's stuck phases
/// are HeldPhases; the switches are Events (friction_stick, friction_slip, friction_reversal,
/// `stop` the contact), so continuation's event signature counts a contact's switches per orbit
/// as its contact phases, and a stick phase born at a reversal is located as a `rising` of that
/// contact (test_functions.hpp: the least margin, from the side without sticking).
///
/// **Friction with stops** (friction_stops.hpp; the overloads taking an ImpactSystem). A mode is
/// (the held rigid stops, the engaged compliant stops, every contact's state); its generator Â
/// (FrictionStopModeRows) solves one Delassus system over the held stops and the stuck contacts,
/// and a segment's tangent map is again the state block of exp(Â τ), the parameter column the
/// block exponential above. An event is resolved by the engine in two steps, the stops' (Newton's
/// law through the impulse LCP, the chatter rule, the acceleration LCP: z₁ = R₁(z⁻)) and then the
/// frictional contacts' (re-decided, their relative velocities and the held stops' normal rates
/// settled: z⁺ = R₂(z₁) = z₁ − B U z₁, U the rows of u_S and g'_H of the contacts S stuck before or
/// after and the held stops H, B = [0; M⁻¹[W_S N_H] D⁻¹; 0], D = [W_S N_H]ᵀM⁻¹[W_S N_H]). Its
/// saltation matrix is linearisation.hpp's for the composite reset R = R₂ ∘ R₁ and the one guard
/// that fired (a gap for an impact or a compliant engage, −λ for a release, −g for a disengage,
/// friction.hpp's rows for stick, slip and reversal):
///
///     S = R_z + (f⁺ − R_z f⁻ − R_t) h_zᵀ / ḣ⁻,   R_z = P₂ R₁_z,   R_t = P₂ (R₁_t; ω̇),   P₂ = I − B U,
///
/// with R₁'s derivatives those of linearisation.hpp (mechanics.hpp's reset, differentiated exactly;
/// the chatter rule's approach acceleration with the contacts' forces in their states before the
/// event, as the engine reads it) and f∓ the modes' fields. So every event kind of such a run —
/// impact, chatter capture, a stop's stick and release, a compliant engage and disengage, slip →
/// stick, stick → slip, reversal — and every combination one guard causes (an impact that makes a
/// stuck contact slip, a slip that pulls a held stop open) is one formula: each part of it is
/// the same code as for stops alone or friction alone. The parameter column adds
/// R_p = P₂ (R₁_p; ∂ω/∂p) − B (dU/dp) z⁺ and h_p. Several guards firing together (simultaneous
/// impacts among them) are taken as one event with the guard that fired first, and `non_smooth`
/// says so. Held stops and stuck contacts are the structural zeros: the tangent space of a mode is
/// {N_Hᵀδx = 0, [N_H W_S]ᵀδv = 0}. In the map's events, phases and features a frictional contact j
/// is numbered stop_count + j (after the stops), so that a continuation's event signature has both;
/// gap peaks, held stops' force dips, impacts and the sliding margins are the features (the held
/// flow past a release is not continued).
///
/// Usage:
///     vibro::TangentMap m = vibro::linearise(system, contacts, solver, t0, x0, v0, t0 + T);
///     vibro::ShootingResult r = vibro::shoot(system, contacts, options, t_guess, x, v);
#include "vibro/family_engine.hpp"
#include "vibro/friction.hpp"
#include "vibro/friction_stops.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/lyapunov.hpp"
#include "vibro/shooting.hpp"

#include <memory>
#include <vector>

namespace vibro {

/// The tangent map of the friction run (FrictionSimulator with `solver`) from (t0, x0, v0) to t1:
/// Jacobian, products with `options.directions`, the parameter column (options.parameter: Ω, the
/// forcing, C and K; a derivative that moves M is refused with InvalidInput), the reduced map,
/// the events, stuck phases and (options.features) the sliding margins above. Throws InvalidInput
/// as FrictionSimulator does.
TangentMap linearise(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                     const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                     double t1, const LinearisationOptions& options = {});

/// Newton shooting on a friction scene (shooting.hpp's procedure, section choice, trust region
/// and multipliers), the maps from linearise above. Stuck directions are structural zeros.
ShootingResult shoot(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                     const ShootingOptions& options, double t_guess, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& v, const LinearisationOptions& options_map = {});

/// The Lyapunov spectrum of a friction run (lyapunov.hpp's QR method, re-orthonormalised once per
/// forcing period). The directions collapsed by sticking are exponents −∞ (`structural`).
LyapunovResult lyapunov_spectrum(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                                 const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options = {});

/// The friction engine for continuation (family_engine.hpp): its "stops" are the frictional
/// contacts (stop_count() = their number; their switches make the event signature). Throws
/// InvalidInput for a derivative that moves M (or has the wrong size) or bad contacts.
std::unique_ptr<FamilyEngine> friction_family_engine(LinearSystem system, std::vector<FrictionContact> contacts,
                                                     SystemDerivative derivative, const SimulatorOptions& solver);

/// Friction with stops (friction_stops.hpp, FrictionStopSimulator): the tangent map, shooting,
/// the Lyapunov spectrum and the continuation engine of the scene `scene` (rigid and compliant
/// stops) with the frictional contacts `contacts`, as above. A parameter derivative may move C,
/// K, the forcing, Ω, the stops' data (parameter.hpp) and the contacts' N, μ_s, μ_k (not M). The
/// family engine's "stops" are the stops then the contacts (stop_count() = their sum).
TangentMap linearise(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                     const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                     double t1, const LinearisationOptions& options = {});
ShootingResult shoot(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                     const ShootingOptions& options, double t_guess, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& v, const LinearisationOptions& options_map = {});
LyapunovResult lyapunov_spectrum(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                                 const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options = {});
std::unique_ptr<FamilyEngine> friction_stop_family_engine(ImpactSystem scene, std::vector<FrictionContact> contacts,
                                                          SystemDerivative derivative, const SimulatorOptions& solver);

}  // namespace vibro
