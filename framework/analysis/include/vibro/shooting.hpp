#pragma once
/// \file shooting.hpp
/// Periodic orbits by Newton shooting on the stroboscopic map, with their Floquet multipliers.
///
/// With the section at the forcing phase θ (t0 = θ/Ω) the stroboscopic map of period kT is
/// P(z) = φ(t0 + kT; t0, z), and a periodic orbit is a zero of F(z) = P(z) − z. Newton's method
/// uses the exact Jacobian of linearisation.hpp (flows and saltation matrices, to rounding):
///
/// procedure Shoot(t_guess, z_guess):
///     z ← state at the first section time after t_guess (a run from the guess)
///     if a stop is held at the section, or an event falls within 1e-6 T of it, move the section
///        to the middle of the longest stretch of the guess's period in which no stop is held
///     repeat (at most max_iterations):
///         (P(z), J) ← linearise over kT from (t0, z);   F ← P(z) − z
///         r ← max(|F_x|∞ / L, |F_v|∞ / V)
///         if r ≤ tolerance: verify and stop
///         Δ ← −(J − I)⁻¹ F                       # in the scaled variables (x/L, v/V)
///         limit Δ to the trust radius; halve it (up to 12 times) until the trial point is
///         admissible, its run completes and r decreases; grow the radius after full steps
///     report the least k' | k with P^{k'}(z) = z (the minimal period), the multipliers
///
/// While the orbit's event sequence stays fixed, F is smooth and the iteration converges
/// quadratically; where a step changes the sequence (an impact appears, a phase splits) the
/// model is wrong across the step and the trust region keeps it safe. The result is either a
/// converged orbit (residual ≤ tolerance, checked on a final run) or a failure with the
/// residual, the iterations and why — never a false orbit. Unstable orbits converge as well as
/// stable ones: nothing here relies on the dynamics contracting.
///
/// Floquet multipliers are the eigenvalues of J = ∂P/∂z at the orbit. While stops are held the
/// map loses rank (linearisation.hpp): 2n − d of them are exactly zero (d the least tangent
/// dimension along the orbit), reported as structural zeros and not as numbers; the other d are
/// the eigenvalues of the reduced map. The orbit is stable when all of those lie inside the unit
/// circle; a stable orbit is approached like ρ^m after m forcing periods, ρ = (max |μ|)^{1/k}.
///
/// Usage:
///     vibro::ShootingOptions o;                     // period 1, section at phase 0
///     vibro::ShootingResult r = vibro::shoot(system, o, t_guess, x_guess, v_guess);
///     if (r.converged()) … r.x, r.v, r.multipliers.values, r.multipliers.stable …
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"

#include <string>
#include <vector>

namespace vibro {

struct ShootingOptions {
  int period = 1;              ///< k: the orbit repeats after kT (T = 2π/Ω)
  double phase = 0.0;          ///< θ of the section, radians: t0 = θ/Ω (mod T)
  bool free_section = true;    ///< move the section off a held stop or an event (see above)
  /// Converged when max(|Δx|∞/L, |Δv|∞/V) ≤ tolerance (L, V the simulator's scales).
  double tolerance = 1e-11;
  int max_iterations = 40;
  double trust_radius = 0.25;  ///< initial largest step, in units of L and V
  SimulatorOptions solver;
  void validate() const;       ///< throws InvalidInput naming the field
};

/// The Floquet multipliers of an orbit of period kT.
struct FloquetMultipliers {
  /// All 2n: the non-structural ones by decreasing modulus, then the structural zeros (exact 0).
  /// With `leading_only` (Arnoldi, modal engine): only the leading ones, by decreasing modulus.
  Eigen::VectorXcd values;
  int structural_zeros = 0;
  double spectral_radius = 0.0;  ///< max |μ| over the non-structural ones
  bool stable = false;           ///< spectral_radius < 1 (with leading_only: and the first converged)
  double rate = 0.0;             ///< spectral_radius^(1/k): contraction per forcing period
  bool leading_only = false;     ///< values are the leading Ritz values of Arnoldi
  bool converged = true;         ///< Arnoldi: every value's residual ≤ its tolerance
  /// Arnoldi: how many of the leading values (from the first on) have converged. The leading
  /// ones outside the bulk of nearly free modes converge first; the verdict needs only the first.
  int converged_count = 0;
  double ritz_residual = 0.0;    ///< Arnoldi: the first value's residual estimate
  long products = 0;             ///< Arnoldi: J·v products used
};

/// Matrix-free shooting on the modal engine (long chains): GMRES for the Newton steps and
/// Arnoldi for the leading multipliers, both on products with the tangent map
/// (modal_tangent.hpp), so nothing 2N × 2N is formed.
struct KrylovOptions {
  int multipliers = 6;              ///< how many leading multipliers Arnoldi computes
  int max_dimension = 200;          ///< Krylov space size (GMRES restart, Arnoldi's largest)
  int max_products = 2000;          ///< per GMRES solve
  double gmres_tolerance = 1e-10;   ///< relative residual of each Newton step's linear solve
  double arnoldi_tolerance = 1e-10; ///< a Ritz value's residual, relative to max(1, |μ_1|)
  void validate() const;            ///< throws InvalidInput naming the field
};

/// The multipliers of the map `m` over k periods (from its reduced map).
FloquetMultipliers floquet_multipliers(const TangentMap& m, int k);

enum class ShootingStatus { converged, not_converged, map_failed, singular };
const char* to_string(ShootingStatus s);

struct ShootingResult {
  ShootingStatus status = ShootingStatus::not_converged;
  std::string message;             ///< why not converged (residual, iterations, what failed)
  bool converged() const { return status == ShootingStatus::converged; }

  int iterations = 0;
  std::vector<double> residuals;   ///< r of every accepted iterate, the first is the guess's
  double residual = 0.0;           ///< r at the returned state
  int k = 1;                       ///< the period asked for
  int minimal_k = 1;               ///< the least k' dividing k with P^{k'}(z) = z (converged)
  double phase = 0.0;              ///< θ of the section used
  double t0 = 0.0;                 ///< its time, in [0, T)
  Eigen::VectorXd x, v;            ///< state on the orbit at t0 (the last iterate if not converged)
  TangentMap map;                  ///< over kT from (t0, x, v): Jacobian, events, features
  FloquetMultipliers multipliers;  ///< valid when converged
  double length_scale = 0.0, velocity_scale = 0.0;
  long krylov_products = 0;        ///< J·v products of GMRES (modal engine; Arnoldi's: multipliers.products)
};

/// Newton shooting from the guess (t_guess, x, v) (see the file comment). `options_map` says what
/// the returned map also carries (a parameter derivative, features); its `jacobian` is always on.
/// Throws InvalidInput for bad options, sizes or an inadmissible guess; Ω must be > 0.
ShootingResult shoot(const ImpactSystem& system, const ShootingOptions& options, double t_guess,
                     const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                     const LinearisationOptions& options_map = {});

/// Newton shooting on the Taylor engine: `system` with the nonlinear forces F(x, v, t), maps and
/// Jacobians from linearise(system, forces, …) (linearisation.hpp). The same procedure, section
/// choice, trust region and multipliers as above. Orbits with impacts in free flight only: a
/// stop held along an iterate's period makes that map fail (InvalidInput, reported as the
/// iterate's failure). `options_map` may not ask for a parameter derivative or features.
ShootingResult shoot(const ImpactSystem& system, const NonlinearForces& forces, const ShootingOptions& options,
                     double t_guess, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                     const LinearisationOptions& options_map = {});
/// Newton–Krylov shooting on the modal engine (long chains; see KrylovOptions): the same
/// procedure, section choice, trust region and reports as above, with the Newton steps solved by
/// GMRES (a step whose solve does not reach its tolerance ends the shooting as `singular`, with
/// GMRES's residual in the message) and the leading multipliers by Arnoldi (`leading_only`;
/// the result's map has no Jacobian). options.solver is not used: the engine has its own settings.
ShootingResult shoot(ModalEngine& engine, const ShootingOptions& options, double t_guess,
                     const Eigen::VectorXd& x, const Eigen::VectorXd& v, const KrylovOptions& krylov = {});

/// Newton shooting on the modal engine with the full Jacobian (ModalTangent::fill_jacobian: 2N
/// products per map, O(N²) memory): the linear algebra of shoot(ImpactSystem, …) — LU Newton
/// steps, all 2N multipliers from the reduced map — on the modal engine's exact maps, so both
/// engines take the same steps up to the maps' rounding. For chains of up to a few thousand masses
/// (continuation.hpp uses it; longer chains: the Newton–Krylov shoot above). `options_map` as
/// for the dense shoot (its `directions` are ignored); options.solver is not used.
ShootingResult shoot_full_jacobian(ModalEngine& engine, const ShootingOptions& options, double t_guess,
                                  const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                  const LinearisationOptions& options_map = {});

/// max(|Δx|∞/L, |Δv|∞/V) of the map's end state against its start.
double periodicity_residual(const TangentMap& m);

}  // namespace vibro
