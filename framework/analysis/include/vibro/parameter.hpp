#pragma once
/// \file parameter.hpp
/// How a system moves with one scalar parameter: the derivative dD/dp of the scene data D.
///
/// Everything the analysis layer differentiates with respect to a parameter p (a frequency, a
/// forcing amplitude, a stop position, a restitution coefficient, a damper, a mass …) enters
/// through the data of an ImpactSystem:
///
///     D = (M, C, K, F0, Fc, Fs, Fc_h, Fs_h of each extra harmonic, Ω, and per stop j: s0_j, sc_j, ss_j, r_j,
///          and a compliant stop's k_j, c_j, F_p,j),
///
/// with the stop in canonical form g_j = w_jᵀx − s_j(t), s_j(t) = s0_j + sc_j cos Ωt + ss_j sin Ωt
/// (stops.hpp; the normals w_j are topology and never move). A SystemDerivative is dD/dp at one
/// point. The tangent maps of linearisation.hpp use it exactly: the generator's derivative
/// dÂ/dp, the guards' ∂g/∂p and the resets' ∂R/∂p are the directional derivatives of the same
/// code along dD (forward-mode differentiation), so no step size enters anywhere.
///
/// A compliant stop's law (stops.hpp) enters only the modes in which it is engaged: there its
/// Kelvin–Voigt force −w N, N = k g + c ġ + F_p, adds k w wᵀ to K, c w wᵀ to C and
/// w (k s + c s' − F_p) to the forcing, so dk, dc, dF_p move those modes' generators and nothing
/// else. Its switch surface g = wᵀx − s(t) does not depend on them: the switch time moves with p
/// only through the flow that reaches it (the saltation's parameter column, linearisation.hpp).
///
/// Where the scene comes from a file, the io layer turns a `--set` path into a SystemDerivative
/// (vibro::io::parameter_derivative): model, forcing and stop values enter D affinely (a mass,
/// a spring, a damper, an amplitude, a position, r) except Ω and a stop's phase, whose
/// derivatives it writes in closed form.
///
/// Usage:
///     vibro::SystemDerivative d = vibro::SystemDerivative::frequency_only();   // d/dΩ
///     vibro::SystemDerivative e;                                               // d/dA1
///     e.cosine = Eigen::Vector2d(1.0, 0.0);
#include <Eigen/Dense>

#include <vector>

namespace vibro {

/// d/dp of one stop's canonical data.
struct StopDerivative {
  double offset = 0.0;       ///< ds0/dp
  double cosine = 0.0;       ///< dsc/dp
  double sine = 0.0;         ///< dss/dp
  double restitution = 0.0;  ///< dr/dp
  /// dk_s/dp, dc_s/dp, dF_p/dp of a compliant stop (stops.hpp); non-zero only on a compliant stop.
  double stiffness = 0.0;
  double damping = 0.0;
  double preload = 0.0;

  /// True when every entry is zero.
  bool is_zero() const {
    return offset == 0.0 && cosine == 0.0 && sine == 0.0 && restitution == 0.0 && stiffness == 0.0 && damping == 0.0 &&
           preload == 0.0;
  }
  /// True when the compliant law moves (stiffness, damping or preload).
  bool moves_law() const { return stiffness != 0.0 || damping != 0.0 || preload != 0.0; }
};

/// d/dp of one frictional contact's data (friction.hpp): its normal load N and coefficients μ_s,
/// μ_k. A slip moves with N and μ_k through its constant force −μ_k N sign u (the mode's
/// forcing); a stuck contact's slip starts where its holding force reaches μ_s N, a guard that
/// moves with N and μ_s directly.
struct FrictionDerivative {
  double normal_load = 0.0;          ///< dN/dp
  double static_coefficient = 0.0;   ///< dμ_s/dp
  double kinetic_coefficient = 0.0;  ///< dμ_k/dp
  bool is_zero() const { return normal_load == 0.0 && static_coefficient == 0.0 && kinetic_coefficient == 0.0; }
};

struct SystemDerivative {
  /// dM/dp, dC/dp, dK/dp (n × n, symmetric), dF0/dp, dFc/dp, dFs/dp (n); empty means zero.
  Eigen::MatrixXd mass, damping, stiffness;
  Eigen::VectorXd constant, cosine, sine;
  /// dFc_h/dp, dFs_h/dp of the extra harmonics (system.hpp), one per harmonic in the forcing's
  /// order (n each); a short list or an empty entry means zero.
  std::vector<Eigen::VectorXd> harmonic_cosine, harmonic_sine;
  double frequency = 0.0;  ///< dΩ/dp
  /// One per stop, in the system's order; empty means zero for every stop.
  std::vector<StopDerivative> stops;
  /// d/dp of the canonical coefficients (Stop::h_cos, Stop::h_sin) of each stop's higher
  /// harmonics: [j][i] for stop j's harmonic i (Stop::harmonics' order); a short list means zero.
  std::vector<std::vector<double>> stop_harmonic_cosine, stop_harmonic_sine;
  /// d/dp of the named parameters of the nonlinear forces (the Taylor engine's
  /// NonlinearForces::parameters, in their order); empty means zero. Linear scenes have none.
  Eigen::VectorXd force_parameters;
  /// One per frictional contact of the friction engine (friction.hpp), in their order; empty
  /// means zero. Only the friction engine's tangent maps read it (friction_tangent.hpp).
  std::vector<FrictionDerivative> friction;

  /// d/dΩ: only the frequency moves (the forcing period, moving stops' motion, the oscillator).
  static SystemDerivative frequency_only();

  /// True when nothing moves.
  bool is_zero() const;
  /// Throws InvalidInput when a non-empty entry has the wrong size for n DOF and m stops, is
  /// not finite, or a matrix is not symmetric (relative 1e-12). (A law derivative on a rigid
  /// stop is refused where the stops are known: linearise and the family engines.)
  void validate(Eigen::Index n, std::size_t m) const;

  /// a·this + b·other (for a direction in a plane of two parameters).
  SystemDerivative combined(double a, const SystemDerivative& other, double b) const;
};

}  // namespace vibro
