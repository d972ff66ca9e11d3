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
/// A drive with extra harmonics of orders k_h ≥ 2 (system.hpp) appends two components per
/// harmonic, z = [x; v; cos Ωt; sin Ωt; 1; cos k₁Ωt; sin k₁Ωt; …] (N = augmented_size(n, H)
/// = 2n + 3 + 2H): columns M⁻¹Fc_h, M⁻¹Fs_h in the v rows and a rotation block at rate k_h Ω, the
/// layout of H = 0 unchanged. The exponential then holds one particular solution per
/// harmonic (the eigenvalues ±i k_h Ω), exact as above, including resonance with any harmonic.
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
///  * exponential (always right), evaluated in one of two ways:
///     - closed form on the Schur clusters (default where it applies): Â = U T Uᴴ (complex
///       Schur form), the eigenvalues grouped into clusters of nearly equal values (a defective
///       eigenvalue comes out of the Schur form as a cluster spread by rounding, ~ε^{1/m}), the
///       clusters made contiguous by Givens swaps and decoupled by triangular Sylvester
///       equations (Bavely & Stewart 1979; the block diagonalisation of Golub & Van Loan,
///       Matrix Computations, §7.6.3): Â = V diag(T_c) V⁻¹ with T_c = μ_c I + E_c, μ_c the
///       cluster's mean, E_c upper triangular and nearly (or exactly) nilpotent. Then
///           exp(Âτ) = Σ_c V_c e^{μ_c τ} Σ_{p=0}^{P_c} E_c^p τ^p / p! (V⁻¹)_c,
///       the polynomial × exponential form of the Jordan structure, evaluated from the computed
///       T_c itself (never with its diagonal rounded to μ_c, which would perturb Â by ε^{1/m}).
///       The series stops where E_c^p vanishes (a free mass under a constant force: T is Â,
///       nilpotent, and the form is x0 + v0 τ + F τ²/2 exactly) or, for a cluster of distinct
///       but close eigenvalues, after P_c terms chosen so that the next would be below 1e-18 of
///       the leading ones for every τ ≤ horizon() (the simulator splits a longer free flight
///       there). Accepted where cond(V) ≤ max_condition and V diag(T_c) V⁻¹ reproduces Â as the
///       spectral rule asks; so a guard value costs one exponential per cluster and a short
///       polynomial, O(N) per functional as the spectral method, with no Padé approximant.
///     - the Padé exponential exp(Âτ) by scaling and squaring with a [13/13] approximant
///       (Higham 2005, via Eigen's MatrixFunctions), O(N³) per evaluation, where no cluster
///       decomposition is accepted, or when FlowOptions::closed_form is false.
/// Method::automatic takes spectral when the rule accepts it and exponential otherwise; an
/// explicit Method::spectral is refused (InvalidInput) where cond(V) > 1e8.
///
/// Usage:
///     vibro::LinearFlow flow(system);
///     auto s = flow.state(t0, x0, v0, t1);      // s.x, s.v, s.a at t1, exact to rounding
#include "vibro/guard_source.hpp"
#include "vibro/system.hpp"

#include <Eigen/Dense>

#include <complex>
#include <limits>
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
  /// Largest accepted condition number of the eigenvector matrix for the spectral method (and
  /// of the cluster basis V for the closed-form exponential).
  double max_condition = 1e4;
  /// The exponential method uses the closed form on the Schur clusters where it is accepted
  /// (see above); false: always the Padé exponential.
  bool closed_form = true;
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
  /// whose augmented state holds only the forcing oscillator); its size tells the number of
  /// extra harmonics.
  LinearFlow(Eigen::MatrixXd generator, Eigen::Index dof, double frequency, FlowOptions options = {});

  Eigen::Index dof() const { return n_; }
  /// N = augmented_size(n, H) = 2n + 3 + 2H, the size of the augmented state.
  Eigen::Index size() const { return augmented_size(n_, rates_.size()); }
  /// The extra harmonics' rates k_h Ω (read from the generator's rotation blocks).
  const std::vector<double>& harmonic_rates() const { return rates_; }
  /// The method in use (never automatic).
  Method method() const { return method_; }
  /// cond₂(V) of Â's eigenvectors; +inf when Â is (numerically) not diagonalisable.
  double eigenvector_condition() const { return condition_; }
  /// The generator Â.
  const Eigen::MatrixXd& generator() const { return generator_; }
  double frequency() const { return omega_; }

  /// Index of the first forcing component (cos Ωt) in the augmented state.
  Eigen::Index forcing_offset() const { return 2 * n_; }

  /// z = [x; v; cos Ωt; sin Ωt; 1; cos k₁Ωt; sin k₁Ωt; …].
  Eigen::VectorXd augment(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v) const;

  /// out = exp(Â τ) z. `out` may not alias `z`. τ may be negative.
  void propagate(const Eigen::Ref<const Eigen::VectorXd>& z, double tau,
                 Eigen::Ref<Eigen::VectorXd> out) const;

  /// State (x, v, a) at time t from (x0, v0) at time t0.
  State state(double t0, const Eigen::Ref<const Eigen::VectorXd>& x0,
              const Eigen::Ref<const Eigen::VectorXd>& v0, double t) const;

  /// exp(Â τ), always by the Padé exponential (the reference the other paths are tested against).
  Eigen::MatrixXd transition_matrix(double tau) const;

  // Spectral data; empty unless method() == spectral.
  const Eigen::VectorXcd& eigenvalues() const { return lambda_; }
  const Eigen::MatrixXcd& eigenvectors() const { return vectors_; }
  const Eigen::MatrixXcd& inverse_eigenvectors() const { return inverse_; }

  /// One eigenvalue of each conjugate pair (and each real one), with weight 2 (pair) or 1
  /// (real): since z is real, Σₖ cₖ e^{λₖτ} = Re Σ_{representatives} weight·cₖ e^{λₖτ}.
  const std::vector<Eigen::Index>& representatives() const { return representatives_; }
  const std::vector<double>& weights() const { return weights_; }

  /// The exponential-polynomial form both fast paths share: z(τ) = Re Σ_r w_r V_r P_r(τ) e^{λ_r τ}
  /// (V⁻¹ z)_r, one term r per representative eigenvalue (spectral: a column of V, P_r = 1) or
  /// per Schur cluster (closed form: m_r columns of V, P_r(τ) = Σ_{p≤degree} E_r^p τ^p / p!).
  struct Term {
    std::complex<double> lambda;  ///< λ_r (a cluster's mean eigenvalue μ_c)
    double weight = 1.0;          ///< 2 for a conjugate pair's representative, else 1
    Eigen::Index column = 0;      ///< first column of V (and row of V⁻¹) of the term
    Eigen::Index size = 1;        ///< columns of V in the term (the cluster's size m_c)
    int degree = 0;               ///< highest power of τ
  };
  /// True when the flow is evaluated in the exponential-polynomial form (spectral, or the closed
  /// form of the exponential method); false for the Padé exponential.
  bool closed_form() const { return !terms_.empty(); }
  const std::vector<Term>& terms() const { return terms_; }
  /// V (N × N) of the form above: the eigenvectors (spectral) or the cluster basis U S.
  const Eigen::MatrixXcd& basis() const { return method_ == Method::spectral ? vectors_ : basis_; }
  const Eigen::MatrixXcd& inverse_basis() const { return method_ == Method::spectral ? inverse_ : inverse_basis_; }
  /// The nilpotent-like parts E_c of the Schur clusters, block diagonal (zero for the spectral method).
  const Eigen::MatrixXcd& cluster_parts() const { return cluster_parts_; }
  /// Longest τ over which the closed form stays within its truncation bound (+∞ unless a cluster
  /// holds distinct eigenvalues); a segment must not be evaluated beyond it.
  double horizon() const { return horizon_; }
  /// ‖V‖_F ‖V⁻¹‖_F of the cluster basis of the closed-form exponential (NaN when not in use).
  double cluster_condition() const { return cluster_condition_; }

  /// Largest |λ| of Â (fastest rate of the system, including Ω). Always available; for the
  /// exponential method with N > 64 an O(N²) upper bound, max(‖D A D⁻¹‖∞, Ω) (flow.cpp).
  double spectral_radius() const { return spectral_radius_; }
  /// Logarithmic 2-norm μ(Â) = λmax((Â + Âᵀ)/2): ‖exp(Âτ)‖₂ ≤ exp(μ τ) for τ ≥ 0.
  double log_norm() const { return log_norm_; }
  /// The same in the scaled norm ‖D z‖₂, D = diag(s I, I, 1, 1, 1), s = position_scale()
  /// = √‖M⁻¹K‖∞ (1 if K = 0): an upper bound (Gershgorin) of λmax of the symmetric part of
  /// D Â D⁻¹, so ‖D exp(Âτ) D⁻¹‖₂ ≤ exp(μ_D τ). For a stiff system μ(Â) ~ ‖M⁻¹K‖/2 (1e8 for a
  /// link of stiffness 1e8) while μ_D ~ √‖M⁻¹K‖, the fastest rate: the Padé path's curvature
  /// bound uses it (see Segment) so that it stays finite over an interval of 1/ρ.
  double scaled_log_norm() const { return scaled_log_norm_; }
  double position_scale() const { return position_scale_; }

 private:
  void build_spectral_terms();
  bool build_schur_clusters(double max_condition);

  Eigen::Index n_;
  double omega_;
  std::vector<double> rates_;  // extra harmonics: k_h Ω
  Method method_;
  double condition_;
  double spectral_radius_ = 0.0;
  double log_norm_ = 0.0;
  double scaled_log_norm_ = 0.0, position_scale_ = 1.0;
  double horizon_ = std::numeric_limits<double>::infinity();
  double cluster_condition_ = std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixXd generator_;
  Eigen::VectorXcd lambda_;
  Eigen::MatrixXcd vectors_, inverse_;
  std::vector<Eigen::Index> representatives_;
  std::vector<double> weights_;
  std::vector<Term> terms_;
  Eigen::MatrixXcd basis_, inverse_basis_, cluster_parts_;
};

/// A piece of trajectory z(t0 + τ) = exp(Âτ) z0 seen through a fixed set of linear functionals
/// ℓᵢᵀ z (gap functions, contact forces, a chosen coordinate). The event loop needs only these
/// scalars, their derivatives dᵏ/dτᵏ ℓᵢᵀ z = ℓᵢᵀ Âᵏ z, and bounds on their derivatives over
/// an interval, so a segment precomputes exactly that:
///  * exponential-polynomial form (spectral, closed-form exponential): per term r and power p,
///    αᵢᵣₚ = w_r (ℓᵢᵀ V_r) E_r^p (V⁻¹ z0)_r / p!, so ℓᵢᵀ z(τ) = Re Σᵣ e^{λᵣτ} Σₚ αᵢᵣₚ τ^p and
///    each derivative is of the same form with αᵈ⁺¹ᵢᵣₚ = λᵣ αᵈᵢᵣₚ + (p + 1) αᵈᵢᵣ₍ₚ₊₁₎: O(N) per
///    value. On [a, b] ⊂ [0, ∞), |dᵈ/dτᵈ ℓᵢᵀz| ≤ Σᵣ max(e^{Re λᵣ a}, e^{Re λᵣ b}) Σₚ |αᵈᵢᵣₚ| b^p
///    (spectral: Σₖ |αᵢₖ| |λₖ|ᵈ max(e^{Re λₖ a}, e^{Re λₖ b})).
///  * Padé: z(τ) by the Padé exponential (cached for the last τ), values by dot products;
///    the bound is ‖ℓᵢᵀ Âᵈ‖ ‖z(a)‖ e^{μ (b - a)} with μ the logarithmic norm, or the same in the
///    scaled norm, ‖ℓᵢᵀ Âᵈ D⁻¹‖ ‖D z(a)‖ e^{μ_D (b - a)}, whichever is smaller.
class Functionals {
 public:
  /// Rows of `rows` are the ℓᵢᵀ (each of length flow.size()).
  Functionals(const LinearFlow& flow, Eigen::MatrixXd rows);
  const LinearFlow& flow() const { return *flow_; }
  Eigen::Index count() const { return rows_[0].rows(); }
  /// ℓᵢᵀ Âᵈ for d = 0, 1, 2, 3.
  const Eigen::MatrixXd& rows(int derivative) const { return rows_[derivative]; }
  /// ℓᵢᵀ V for the exponential-polynomial form (spectral: the eigenvectors).
  const Eigen::MatrixXcd& modal_rows() const { return modal_rows_; }
  /// Padé path: the 2-norms of ℓᵢᵀÂᵈ and of ℓᵢᵀÂᵈD⁻¹ (d = 2, 3; see above).
  const Eigen::MatrixXd& row_norms() const { return row_norms_; }

 private:
  const LinearFlow* flow_;
  Eigen::MatrixXd rows_[4];
  Eigen::MatrixXcd modal_rows_;
  Eigen::MatrixXd row_norms_;  // rows × 4: plain d=2, scaled d=2, plain d=3, scaled d=3
};

/// The dense engine's guard source (guard_source.hpp): its samples hold e^{λᵣτ} (e) and
/// |e^{λᵣτ}| (growth) per term, or on the Padé path ‖z(τ)‖₂ and ‖D z(τ)‖₂ (growth).
class Segment final : public GuardSource {
 public:
  Segment(const Functionals& functionals, double t0, const Eigen::Ref<const Eigen::VectorXd>& z0);

  /// Re-targets the segment to a new start (same functionals): no allocation when the
  /// functionals' sizes are those of the last call (the event loop reuses one Segment per mode).
  void reset(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0);

  double t0() const override { return t0_; }
  const Eigen::VectorXd& initial_state() const { return z0_; }
  const Functionals& functionals() const { return *functionals_; }

  /// dᵈ/dτᵈ ℓᵢᵀ z(τ), d ∈ {0, 1, 2, 3}.
  double value(Eigen::Index i, double tau, int derivative = 0) const override;
  /// Value and first derivative together (one evaluation of the exponentials).
  std::pair<double, double> value_and_slope(Eigen::Index i, double tau) const;
  /// An upper bound of |d²/dτ² ℓᵢᵀ z(τ)| over τ ∈ [a, b] (0 ≤ a ≤ b).
  double second_derivative_bound(Eigen::Index i, double a, double b) const override;
  /// An upper bound of |d³/dτ³ ℓᵢᵀ z(τ)| over [a, b] (0 ≤ a ≤ b).
  double third_derivative_bound(Eigen::Index i, double a, double b) const;
  /// Full augmented state at τ.
  void state(double tau, Eigen::Ref<Eigen::VectorXd> out) const;
  /// The same, bit for bit, without storing e^{λτ} in the cache of recent τ: for observers. The
  /// search takes its series from the cached points (fill_exponentials), so a τ stored by an
  /// observer (which evicts another) would change the rounding of the run's later states: a run
  /// must not depend on what observes it.
  void state_unstored(double tau, Eigen::Ref<Eigen::VectorXd> out) const;

  // --- the certified search's interface (events.hpp): all rows at once ---
  /// Values, slopes and curvatures of every row at τ, with what the bounds need. One
  /// evaluation of the exponentials; no allocation once `out` has been sized by a first call.
  void sample(double tau, SegmentSample& out) const override;
  /// Value, slope and curvature of row i at τ (one evaluation of the exponentials).
  void row_jet(Eigen::Index i, double tau, double* h, double* d, double* c) const override;
  /// An upper bound of |dᵈ/dτᵈ ℓᵢᵀz| over [a.tau, b.tau] (d = 2 or 3) from two samples.
  double derivative_bound(int derivative, Eigen::Index i, const SegmentSample& a,
                          const SegmentSample& b) const override;
  /// The magnitude of row i's terms at the start, Σ |αᵢᵣₚ| (Padé: ‖ℓᵢ‖ ‖z0‖): its values carry
  /// rounding errors of a few ulps of this, which no root can be located below.
  double magnitude(Eigen::Index i) const;
  /// Full augmented state at s.tau, from the sample's exponentials.
  void state(const SegmentSample& s, Eigen::Ref<Eigen::VectorXd> out) const;
  /// out = (ℓᵢᵀ z(τ))ᵢ for the rows of `other`, functionals of the same flow that are not the
  /// segment's own (e.g. a contact mode's positions and velocities of the full system, which
  /// observers ask for at many τ). Exponential-polynomial form: their coefficients αᵢᵣₚ (as in
  /// the class comment) are tabulated on the first call after a reset, O(rows · N · m), as real
  /// numbers Re α and, for a complex λᵣ, -Im α; each call then costs one exponential per term
  /// and, per row, Σᵣ Re(e^{λᵣτ} Σₚ αᵢᵣₚ τ^p) in real arithmetic: the same exact form as
  /// state(), rounded in another order, without forming z. Padé path: the rows times the Padé
  /// state. Allocates only on a Segment's first call (or a first call with
  /// rows of a new size); touches neither the exponentials' cache nor evaluations().
  void evaluate(const Functionals& other, double tau, Eigen::Ref<Eigen::VectorXd> out) const;
  /// The same at many times in one call (an observer's dense samples): column k at
  /// τ = t[k] - origin, its first top.rows() rows in top and the others in bottom
  /// (top.rows() + bottom.rows() = other.count(); e.g. x and v, n × count each, from a mode's
  /// state rows). The method and the table are settled once per call, then each column costs
  /// the exponentials and the row sums: bit for bit what evaluate() gives at that τ (which is
  /// this call with count = 1). Allocates as evaluate() does (Padé path: its product's vector,
  /// once per Segment).
  void evaluate(const Functionals& other, const double* t, Eigen::Index count, double origin,
                Eigen::Ref<Eigen::MatrixXd> top, Eigen::Ref<Eigen::MatrixXd> bottom) const;
  /// Evaluations of the exponentials since construction (one per sample or uncached τ; one
  /// matrix exponential on the Padé path): the unit of work of the event search.
  long evaluations() const { return evaluations_; }
  /// Guard evaluations since construction: one per row evaluated at one τ (its value, with or
  /// without its derivatives from the same exponentials); a sample counts every row.
  long guard_evaluations() const { return guard_evaluations_; }

 private:
  const Eigen::VectorXd& pade_state(double tau) const;
  /// e^{λᵣτ} of the terms, from a small cache of recent τ.
  const std::complex<double>* exponentials(double tau) const;
  /// e^{λᵣτ} and |e^{λᵣτ}| of the terms; `direct`: computed from τ alone (not from a cached base).
  void fill_exponentials(double tau, std::complex<double>* e, double* growth, bool* direct) const;
  /// The cache slot holding τ's exponentials, filled if missing.
  int store_exponentials(double tau) const;
  /// Σᵣ Re(e_r Σₚ αᵈᵢᵣₚ τ^p) for derivative d.
  double row_value(Eigen::Index i, int derivative, double tau, const std::complex<double>* e) const;
  double pade_bound(int derivative, Eigen::Index i, double z_norm, double dz_norm, double length) const;
  double closed_form_bound(int derivative, Eigen::Index i, double a, double b, const double* ga,
                           const double* gb) const;
  double bound_between(int derivative, Eigen::Index i, double a, double b) const;
  void closed_form_state(double tau, const std::complex<double>* e, Eigen::Ref<Eigen::VectorXd> out) const;

  const Functionals* functionals_;
  double t0_;
  Eigen::VectorXd z0_;
  bool polynomial_ = false;  // some term has degree > 0 (closed-form exponential)
  Eigen::Index width_ = 0;   // Σᵣ (degree_r + 1): coefficient columns per row
  double rate_ = 0.0;        // maxᵣ |λᵣ|: where |λᵣτ| is small the exponentials are series
  std::vector<Eigen::Index> offset_;  // per term: first coefficient column

  Eigen::VectorXcd modal_;   // V⁻¹ z0
  // Per derivative d = 0…3: rows × width_ complex coefficients αᵈ; moduli for d = 2, 3.
  Eigen::MatrixXcd coefficients_[4];
  Eigen::MatrixXd moduli_[2];
  Eigen::VectorXd magnitude_;
  // The state's own coefficients: per term r and power p, w_r E_r^p (V⁻¹ z0)_r / p! (columns).
  Eigen::MatrixXcd powers_;
  mutable long evaluations_ = 0, guard_evaluations_ = 0;
  mutable double cached_tau_;
  mutable Eigen::VectorXd cached_z_;   // Padé: z(cached_tau_)
  static constexpr int cache_slots = 4;
  mutable double cache_tau_[cache_slots];
  mutable bool cache_direct_[cache_slots] = {};
  mutable int cache_next_ = 0, pinned_ = -1;
  mutable Eigen::MatrixXcd cache_e_;
  mutable Eigen::MatrixXd cache_growth_;
  mutable Eigen::VectorXcd scratch_;  // state(): the terms' vectors at τ
  mutable Eigen::VectorXcd unstored_e_;  // state_unstored(): e^{λᵣτ}, |e^{λᵣτ}| of a τ not cached
  mutable Eigen::VectorXd unstored_growth_;
  // evaluate(): the table of the rows it was last asked for (null: none since the last reset),
  // one column per row, and e^{λᵣτ} per term for each of the times evaluated together.
  void tabulate(const Functionals& other) const;
  mutable const Functionals* tabulated_ = nullptr;
  mutable Eigen::MatrixXd table_;
  mutable Eigen::VectorXcd table_e_;
  mutable Eigen::VectorXd rows_out_;  // evaluate() on the Padé path: all rows at one τ
};

}  // namespace vibro
