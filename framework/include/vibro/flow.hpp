#pragma once
/// \file flow.hpp
/// Exact propagation of a LinearSystem between events.
///
/// The forcing is folded into the state (Van Loan 1978, "Computing integrals involving the matrix
/// exponential", IEEE TAC 23(3); the same trick as in ../shared/DESIGN.md). With
///
///     z = [x; v; cos Ωt; sin Ωt; 1]      (size N = 2n + 3)
///
/// the forced second-order system is the autonomous linear system z' = Â z,
///
///         ⎡  0       I       0        0       0    ⎤
///     Â = ⎢ -M⁻¹K  -M⁻¹C   M⁻¹Fc   M⁻¹Fs   M⁻¹F0  ⎥
///         ⎢  0       0       0       -Ω       0    ⎥
///         ⎢  0       0       Ω        0       0    ⎥
///         ⎣  0       0       0        0       0    ⎦
///
/// so that z(t0 + τ) = exp(Â τ) z(t0) exactly, for every damping regime (under-, critically,
/// over-damped, C = 0, non-proportional C), for singular K (rigid-body modes: a constant force
/// grows the displacement quadratically, the τ²-term comes out of the Jordan block) and at exact
/// resonance (the secular τ·sin term likewise). Nothing divides by a frequency difference, so
/// nothing can become NaN.
///
/// Two evaluation methods, chosen once per flow:
///  * spectral (fast): Â = V Λ V⁻¹ with V the eigenvectors of Â, so z(τ) = V e^{Λτ} V⁻¹ z0.
///    Cost: one O(N³) decomposition per flow; then O(N²) per state, and O(N) per scalar
///    functional ℓᵀz(τ) once a segment has its N coefficients (see Segment). Its rounding error is
///    about cond(V)·ε, so it is used only where cond(V) ≤ Options::max_condition (default 1e4,
///    i.e. error ≲ 2e-12) and the decomposition reproduces Â to 1e-13·max(1, cond(V)/100) relative. Near a defective
///    case (critical damping, resonance, rigid-body modes) cond(V) → ∞ and this rule rejects it.
///  * exponential (always right): exp(Âτ) by scaling and squaring with a [13/13] Padé
///    approximant (Higham 2005, via Eigen's MatrixFunctions), O(N³) per evaluation.
/// Method::automatic takes spectral when the rule accepts it and exponential otherwise; an
/// explicit Method::spectral is refused (InvalidInput) where cond(V) > 1e8.
///
/// Usage:
///     vibro::LinearFlow flow(system);
///     auto s = flow.state(t0, x0, v0, t1);      // s.x, s.v, s.a at t1, exact to rounding
#include "vibro/system.hpp"

#include <Eigen/Dense>

#include <complex>
#include <utility>
#include <vector>

namespace vibro {

/// The generator Â above for M x'' + C x' + K x = f(t); M must be positive definite (not checked
/// here: LinearSystem checks it). n = 0 is allowed and gives the 3×3 forcing oscillator.
Eigen::MatrixXd augmented_generator(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C,
                                    const Eigen::MatrixXd& K, const HarmonicForcing& forcing);

enum class FlowMethod { automatic, spectral, exponential };

struct FlowOptions {
  FlowMethod method = FlowMethod::automatic;
  /// Largest accepted condition number of the eigenvector matrix for the spectral method.
  double max_condition = 1e4;
};

class LinearFlow {
 public:
  using Method = FlowMethod;
  using Options = FlowOptions;

  struct State {
    Eigen::VectorXd x, v, a;
  };

  explicit LinearFlow(const LinearSystem& system, FlowOptions options = {});
  /// From a generator Â already in the layout above (n may be 0: a fully constrained subsystem
  /// whose augmented state holds only the forcing oscillator).
  LinearFlow(Eigen::MatrixXd generator, Eigen::Index dof, double frequency, FlowOptions options = {});

  Eigen::Index dof() const { return n_; }
  /// N = 2n + 3, the size of the augmented state.
  Eigen::Index size() const { return 2 * n_ + 3; }
  /// The method in use (never automatic).
  Method method() const { return method_; }
  /// cond₂(V) of Â's eigenvectors; +inf when Â is (numerically) not diagonalisable.
  double eigenvector_condition() const { return condition_; }
  /// The generator Â.
  const Eigen::MatrixXd& generator() const { return generator_; }
  double frequency() const { return omega_; }

  /// Index of the first forcing component (cos Ωt) in the augmented state.
  Eigen::Index forcing_offset() const { return 2 * n_; }

  /// z = [x; v; cos Ωt; sin Ωt; 1].
  Eigen::VectorXd augment(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v) const;

  /// out = exp(Â τ) z. `out` may not alias `z`. τ may be negative.
  void propagate(const Eigen::Ref<const Eigen::VectorXd>& z, double tau,
                 Eigen::Ref<Eigen::VectorXd> out) const;

  /// State (x, v, a) at time t from (x0, v0) at time t0.
  State state(double t0, const Eigen::Ref<const Eigen::VectorXd>& x0,
              const Eigen::Ref<const Eigen::VectorXd>& v0, double t) const;

  /// exp(Â τ), always by the exponential method (the reference the spectral path is tested against).
  Eigen::MatrixXd transition_matrix(double tau) const;

  // Spectral data; empty unless method() == spectral.
  const Eigen::VectorXcd& eigenvalues() const { return lambda_; }
  const Eigen::MatrixXcd& eigenvectors() const { return vectors_; }
  const Eigen::MatrixXcd& inverse_eigenvectors() const { return inverse_; }

  /// One eigenvalue of each conjugate pair (and each real one), with weight 2 (pair) or 1
  /// (real): since z is real, Σₖ cₖ e^{λₖτ} = Re Σ_{representatives} weight·cₖ e^{λₖτ}.
  const std::vector<Eigen::Index>& representatives() const { return representatives_; }
  const std::vector<double>& weights() const { return weights_; }

  /// Largest |λ| of Â (fastest rate of the system, including Ω). Always available; for the
  /// exponential method with N > 64 an O(N²) upper bound, max(‖D A D⁻¹‖∞, Ω) (flow.cpp).
  double spectral_radius() const { return spectral_radius_; }
  /// Logarithmic 2-norm μ(Â) = λmax((Â + Âᵀ)/2): ‖exp(Âτ)‖₂ ≤ exp(μ τ) for τ ≥ 0.
  double log_norm() const { return log_norm_; }
  /// The same in the scaled norm ‖D z‖₂, D = diag(s I, I, 1, 1, 1), s = position_scale()
  /// = √‖M⁻¹K‖∞ (1 if K = 0): an upper bound (Gershgorin) of λmax of the symmetric part of
  /// D Â D⁻¹, so ‖D exp(Âτ) D⁻¹‖₂ ≤ exp(μ_D τ). For a stiff system μ(Â) ~ ‖M⁻¹K‖/2 (1e8 for a
  /// link of stiffness 1e8) while μ_D ~ √‖M⁻¹K‖, the fastest rate: the exponential method's
  /// curvature bound uses it (see Segment) so that it stays finite over an interval of 1/ρ.
  double scaled_log_norm() const { return scaled_log_norm_; }
  double position_scale() const { return position_scale_; }

 private:
  Eigen::Index n_;
  double omega_;
  Method method_;
  double condition_;
  double spectral_radius_ = 0.0;
  double log_norm_ = 0.0;
  double scaled_log_norm_ = 0.0, position_scale_ = 1.0;
  Eigen::MatrixXd generator_;
  Eigen::VectorXcd lambda_;
  Eigen::MatrixXcd vectors_, inverse_;
  std::vector<Eigen::Index> representatives_;
  std::vector<double> weights_;
};

/// A piece of trajectory z(t0 + τ) = exp(Âτ) z0 seen through a fixed set of linear functionals
/// ℓᵢᵀ z (gap functions, contact forces, a chosen coordinate). The event loop needs only these
/// scalars, their derivatives dᵏ/dτᵏ ℓᵢᵀ z = ℓᵢᵀ Âᵏ z, and bounds on their second derivative over
/// an interval, so a segment precomputes exactly that:
///  * spectral: αᵢₖ = (ℓᵢᵀ V)ₖ (V⁻¹ z0)ₖ, then ℓᵢᵀ Âᵈ z(τ) = Re Σₖ αᵢₖ λₖᵈ e^{λₖτ}: O(N) per value;
///    |second derivative| on [a, b] ≤ Σₖ |αᵢₖ| |λₖ|² max(e^{Re λₖ a}, e^{Re λₖ b}).
///  * exponential: z(τ) by the Padé exponential (cached for the last τ), values by dot products;
///    the bound is ‖ℓᵢᵀ Â²‖ ‖z(a)‖ e^{μ (b - a)} with μ the logarithmic norm, or the same in the
///    scaled norm, ‖ℓᵢᵀ Â² D⁻¹‖ ‖D z(a)‖ e^{μ_D (b - a)}, whichever is smaller.
class Functionals {
 public:
  /// Rows of `rows` are the ℓᵢᵀ (each of length flow.size()).
  Functionals(const LinearFlow& flow, Eigen::MatrixXd rows);
  const LinearFlow& flow() const { return *flow_; }
  Eigen::Index count() const { return rows_[0].rows(); }
  /// ℓᵢᵀ Âᵈ for d = 0, 1, 2, 3.
  const Eigen::MatrixXd& rows(int derivative) const { return rows_[derivative]; }
  /// (ℓᵢᵀ Âᵈ V) for the spectral method.
  const Eigen::MatrixXcd& modal_rows() const { return modal_rows_; }

 private:
  const LinearFlow* flow_;
  Eigen::MatrixXd rows_[4];
  Eigen::MatrixXcd modal_rows_;
};

class Segment {
 public:
  Segment(const Functionals& functionals, double t0, const Eigen::Ref<const Eigen::VectorXd>& z0);

  /// Re-targets the segment to a new start (same functionals): no allocation when the
  /// functionals' sizes are those of the last call (the event loop reuses one Segment per mode).
  void reset(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0);

  double t0() const { return t0_; }
  const Eigen::VectorXd& initial_state() const { return z0_; }
  const Functionals& functionals() const { return *functionals_; }

  /// dᵈ/dτᵈ ℓᵢᵀ z(τ), d ∈ {0, 1, 2, 3}.
  double value(Eigen::Index i, double tau, int derivative = 0) const;
  /// Value and first derivative together (one evaluation of the exponentials).
  std::pair<double, double> value_and_slope(Eigen::Index i, double tau) const;
  /// An upper bound of |d²/dτ² ℓᵢᵀ z(τ)| over τ ∈ [a, b] (a ≤ b).
  double second_derivative_bound(Eigen::Index i, double a, double b) const;
  /// An upper bound of |d³/dτ³ ℓᵢᵀ z(τ)| over [a, b] (spectral: Σₖ |αᵢₖ| |λₖ|³ max(e^{Re λₖ a},
  /// e^{Re λₖ b})); +∞ for the exponential method (no such bound is kept there).
  double third_derivative_bound(Eigen::Index i, double a, double b) const;
  /// Full augmented state at τ.
  void state(double tau, Eigen::Ref<Eigen::VectorXd> out) const;

 private:
  const Eigen::VectorXd& exponential_state(double tau) const;
  /// e^{λₖ τ} of the representatives (spectral method), from a small cache of recent τ: the
  /// event search evaluates every row at the same few points (interval ends, trial roots), so
  /// one set of exponentials serves all rows and both derivatives.
  const std::complex<double>* exponentials(double tau) const;
  /// e^{Re λₖ τ} if τ is in the cache, else nullptr.
  const double* cached_growth(double tau) const;

  const Functionals* functionals_;
  double t0_;
  Eigen::VectorXd z0_;

  Eigen::VectorXcd modal_;        // V⁻¹ z0 (spectral)
  // Spectral: per representative eigenvalue λₖ (see LinearFlow::representatives), the weighted
  // coefficients weight·αᵢₖ and their moduli times |λₖ|² (for the second-derivative bound).
  Eigen::VectorXcd lambda_;
  Eigen::VectorXd modulus_;  // |λₖ|
  Eigen::MatrixXcd coefficients_;
  Eigen::MatrixXd curvature_;
  mutable double cached_tau_;
  mutable Eigen::VectorXd cached_z_;   // exponential method: z(cached_tau_)
  // Spectral method: e^{λₖ τ} (column c) and e^{Re λₖ τ} for the τ in cache_tau_[c], replaced
  // round-robin.
  static constexpr int cache_slots = 4;
  mutable double cache_tau_[cache_slots];
  mutable int cache_next_ = 0;
  mutable Eigen::MatrixXcd cache_e_;
  mutable Eigen::MatrixXd cache_growth_;
  mutable Eigen::VectorXcd scratch_;  // state(): modal coordinates at τ
};

}  // namespace vibro
