#pragma once
/// \file taylor_step.hpp
/// One step of the Taylor method: the solution over [t₀, t₀ + h] as a polynomial in τ = t − t₀,
/// its order and step size from the coefficients' decay, dense output, guard polynomials with a
/// bound on their remainder, and (optionally) the step's state-transition matrix polynomial.
///
/// ## Taylor coefficients (automatic differentiation)
/// With z' = f(z, t) and the normalised derivatives z_[k] = z⁽ᵏ⁾(t₀)/k!, the solution is
/// z(t₀ + τ) = Σ_k z_[k] τ^k and z_[k+1] = f_[k] / (k + 1), where f_[k] is the k-th coefficient of
/// f(z(t₀ + τ), t₀ + τ). The Dag (dag.hpp) gives f as elementary operations; each node's k-th
/// coefficient follows from the operands' coefficients 0…k (Jorba & Zou 2005, §2.1; Moore 1966;
/// Griewank & Walther 2008, ch. 13), one order at a time over the whole Dag:
///
///     c = a ± b    c_k = a_k ± b_k
///     c = a·b      c_k = Σ_{j=0}^{k} a_j b_{k−j}
///     c = a/b      c_k = (a_k − Σ_{j=1}^{k} b_j c_{k−j}) / b_0
///     c = a²       c_k = Σ_{j=0}^{k} a_j a_{k−j}               (half the terms, by symmetry)
///     c = a^α      c_k = Σ_{j=0}^{k−1} (α(k−j) − j) a_{k−j} c_j / (k a_0)      (a_0 ≠ 0)
///     c = √a       c_k = (a_k − Σ_{j=1}^{k−1} c_j c_{k−j}) / (2 c_0)
///     c = exp a    c_k = Σ_{j=1}^{k} j a_j c_{k−j} / k
///     c = log a    c_k = (a_k − Σ_{j=1}^{k−1} j c_j a_{k−j} / k) / a_0
///     s = sin a, q = cos a (a pair):  s_k = Σ j a_j q_{k−j} / k,   q_k = −Σ j a_j s_{k−j} / k
///     c = tan a,  u = 1 + c²:  c_k = Σ j a_j u_{k−j} / k,  then u_k = Σ c_j c_{k−j}
///     c = tanh a, u = 1 − c²:  c_k = Σ j a_j u_{k−j} / k,  then u_k = −Σ c_j c_{k−j}
///     c = atan a, u = 1 + a²:  u_k = Σ a_j a_{k−j},  c_k = (a_k − Σ_{j=1}^{k−1} (k−j) u_j c_{k−j} / k) / u_0
///
/// (sums over j = 1…k unless written otherwise): O(k) work per node and order, O(p²) per node
/// and step. The linear part (A_x, A_v, M⁻¹ of taylor_system.hpp) is applied to each order's
/// coefficients directly.
///
/// ## Order and step size (Jorba & Zou 2005, §3.2–3.3)
/// With tolerance ε (a setting, default 2⁻⁵² ≈ 2.2e-16, the unit roundoff of double) and the
/// mixed absolute-relative scale S = max(1, ‖z_[0]‖∞) — absolute below 1, relative above — the
/// order is p = min(20, ⌈−0.7 ln ε + 1⌉) (20 at the default, 18 at 1e-10, 14 at 1e-8) and the step
///
///     h = min_{k ∈ {p−1, p}} (ε S / ‖z_[k]‖∞)^{1/k} · exp(−0.7 / (p − 1)),
///
/// which makes the last two terms of the series ≈ ε S at τ = h and, for a solution analytic in a
/// disc of radius ρ ≈ min_k (S/‖z_[k]‖)^{1/k}, h ≈ ρ ε^{1/p} · 0.97 (≈ 0.23 ρ below the cap,
/// ≈ 0.16 ρ at the default): the terms then decay by a factor r = h/ρ per order, so the truncated
/// tail is ≈ ε S r/(1 − r). With variational
/// equations on, the norms are taken over [z; Φ] (the tangent map is as accurate as the state);
/// with a held set (StepTerms) over the contact forces λ too (in the norms and in S): λ is a
/// guard of the step, and when every coordinate is held z is constant while λ carries the drive.
/// Order: with a cost per step of a p² (the products' convolutions) the work per unit time
/// p² ε^{−1/p} is least at p = −½ ln ε (Jorba & Zou's order); with a cost linear in p (each
/// order's pass over the tape, the linear part, Horner, the guard's passes) at p = −ln ε. For
/// the small systems an impact oscillator has the linear part weighs as much as the products:
/// the Taylor engine's instruction count on tools/bench/bench_taylor_odeint's Duffing and pendulum
/// oscillators (200 periods, valgrind's callgrind) is least at p = 27 for ε = 2⁻⁵² (of 20, 24,
/// 27, 30), 18 for 1e-10 (of 13, 14, 18, 20, 27) and 14 for 1e-8 (of 14, 18, 20, 24, 27, 30), and
/// within 3 % from 20 to 30 at 1e-12 — the factor 0.7 (at 1e-10 21 % fewer instructions than
/// Jorba & Zou's 13). The cap at 20: near the unit roundoff the longer step of a higher order
/// puts the guard's remainder bound (its evaluation rounding 4(p + 1) u Σ|g_k| h^k) above the
/// event search's trigger level of 1e-13 of the scale (at order 27, 3.8e-13 against 3.6e-13 for
/// the guard 3 x0 − 2 v0 of tests/taylor/test_taylor_step.cpp), although it would take 20 % fewer
/// instructions there. TaylorSettings::order overrides the rule.
/// A step whose coefficients k ≥ 1 all vanish (a polynomial solution) has h = ∞; the caller caps
/// it (advance() stops at its end time).
///
/// ## Dense output and accuracy
/// z(t₀ + τ) for any τ ∈ [0, h] is the polynomial evaluated by compensated Horner (Graillat,
/// Langlois & Louvet 2005): as if in twice the working precision, so a state carries only the
/// rounding of the coefficients themselves. Round-off still makes conserved quantities random-walk
/// (≈ ε per step), and for a nonlinear oscillator, whose frequency depends on its energy, the
/// phase error then grows like t^{3/2} (Brouwer's law): measured for x'' + x + x³ = 0 (A = 1),
/// 5e-14 after 20 periods and 2.5e-13 after 100 (tests/taylor/test_taylor_step.cpp).
///
/// ## Guards and their remainder
/// A guard g(z, t) (taylor_system.hpp) is a Dag output: its coefficients g_[0…p] come from the
/// same pass. The polynomial G(τ) = Σ_{k≤p} g_[k] τ^k differs from g(z(t₀ + τ), t₀ + τ) by the
/// tail R(τ) = Σ_{k>p} g_[k] τ^k. Bound used (guard_remainder): a Cauchy estimate fitted to the
/// computed coefficients. If g is analytic with |g| ≤ B on the disc |τ| ≤ ρ, then |g_[k]| ≤ B/ρ^k
/// (Cauchy) and, with r = h/ρ < 1,
///
///     |R(τ)| ≤ Σ_{k>p} B r^k = B r^{p+1} / (1 − r)    for 0 ≤ τ ≤ h.
///
/// ρ is the state's radius estimate above and B = 2 max_{k ∈ {p−1, p}} |g_[k]| ρ^k (the constant
/// fitted to the last two orders, doubled; two consecutive orders, so that a series with only
/// even or only odd terms is still seen). This is rigorous under the hypothesis that the decay
/// seen at orders p − 1 and p continues — the hypothesis that sets the step size — not an
/// interval-arithmetic proof. Its size is ~ε of the guard's scale: for x'' = −x and the guard
/// x0 = cos τ, 2e-16 against a true tail of 7e-17 (tests/taylor/test_taylor_step.cpp checks the
/// bound against the exact tail at tolerances 1e-16, 1e-12 and 1e-8). To it is added the rounding of the
/// polynomial's evaluation, 4(p + 1) u Σ_k |g_[k]| h^k (Higham 2002, §5.1, with a margin).
/// guard_roots.hpp isolates G's first crossing with both bounds folded in.
///
/// ## Variational equations
/// With `variational` on, the tangent map Φ(τ) = ∂z(t₀ + τ)/∂z(t₀) solves Φ' = J(z, t) Φ,
/// Φ(0) = I. Its coefficients come from forward-mode differentiation of the same recurrences:
/// each Dag node carries, besides its series c, the series ċ_d = ∂c/∂z₀·e_d for the 2n
/// directions d, whose recurrences are the linearised ones (ċ = ȧ b + a ḃ for a product,
/// ċ = c ȧ for exp, ċ b = ȧ − c ḃ for a quotient, …), and Φ_[k+1] = (J Φ)_[k] / (k + 1). So Φ is
/// the exact derivative of the computed polynomial map, to rounding: O(p² · 2n) per node.
///
/// Usage:
///     vibro::taylor::TaylorStep step(system, {.variational = true});
///     if (step.expand(t0, z0) != vibro::taylor::StepStatus::ok) ... step.trouble() ...
///     step.state(0.5 * step.step_size(), z_mid);    // dense output (Horner)
///     step.transition(step.step_size(), phi);       // tangent map over the step
#include "vibro/taylor/taylor_system.hpp"

#include <Eigen/Dense>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace vibro::taylor {

struct TaylorSettings {
  double tolerance = std::numeric_limits<double>::epsilon();  ///< ε (mixed absolute-relative)
  bool variational = false;   ///< also the state-transition matrix polynomial
  int order = 0;              ///< the series' order p (3 … 60); 0: from the tolerance (see above)
  /// Throws std::invalid_argument naming the field, the value and the rule.
  void validate() const;
};

/// Terms of z' that an event loop supplies per step besides the system's (taylor_simulator.hpp):
///
///   - `acceleration` (n × (p + 1), optional): a series a_t(τ) that depends on time only, added
///     to v' (a harmonic drive M⁻¹ f(t), whose coefficients are known in closed form);
///   - a held set of k stops (all four optional together): v' is the constrained acceleration
///
///         a = a_free − M⁻¹W λ,   λ = G⁻¹ (Wᵀ a_free − p̈(t)),   G = Wᵀ M⁻¹ W,
///
///     the Gauss principle of a bilateral constraint Wᵀx = p(t) (Wᵀa = p̈ exactly), applied
///     order by order: a_free's k-th coefficient is linear in the k-th coefficients of z and of
///     the forces, so λ's k-th coefficient follows from it with the same constant matrices. λ
///     (the contact forces, whose sign change is a release) is kept as a series too;
///   - `position_matrix` and `velocity_matrix` (n × n, optional): A_x and A_v in place of the
///     system's (taylor_system.hpp), for linear terms that hold over a step only (the springs
///     and dashpots of engaged compliant stops: −M⁻¹(K + Σ k_s w wᵀ), −M⁻¹(C + Σ c_s w wᵀ)).
///     The variational equations take them too (the linear part's Jacobian is the matrices).
struct StepTerms {
  const Eigen::MatrixXd* acceleration = nullptr;       ///< n × (p + 1)
  const Eigen::MatrixXd* normals = nullptr;            ///< W, n × k
  const Eigen::MatrixXd* minv_normals = nullptr;       ///< M⁻¹W, n × k
  const Eigen::MatrixXd* delassus_inverse = nullptr;   ///< G⁻¹, k × k
  const Eigen::MatrixXd* stop_acceleration = nullptr;  ///< p̈'s series, k × (p + 1)
  const Eigen::MatrixXd* position_matrix = nullptr;    ///< A_x, n × n (none: the system's)
  const Eigen::MatrixXd* velocity_matrix = nullptr;    ///< A_v, n × n (none: the system's)
};

enum class StepStatus {
  ok,
  domain_error,  ///< an operation left its domain at the step's start (log of ≤ 0, division by 0, …)
  not_finite     ///< a coefficient or the step size is not finite (overflow)
};

class TaylorStep {
 public:
  /// Allocates everything once (order p from the tolerance); expand() allocates nothing.
  TaylorStep(const TaylorSystem& system, TaylorSettings settings = {});

  /// Computes the series at (t0, z0) and chooses the step size.
  StepStatus expand(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0);
  /// The terms of StepTerms (pointers kept: the matrices must outlive the expand() calls that
  /// use them). Default: none.
  void set_terms(const StepTerms& terms);
  /// z'(t₀) only (the series' order 0): cheaper than expand() where a rate is all that is needed
  /// (the accelerations at an event). `out` has size 2n.
  StepStatus rate(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0, Eigen::Ref<Eigen::VectorXd> out);
  /// The a-th held stop's contact force λ_a's coefficients λ_[0…p] (StepTerms).
  const double* force_coefficients(int a) const { return &lambda_[static_cast<std::size_t>(a) * (p_ + 1)]; }
  /// Bound on the remainder of any series of the step (its coefficients, p + 1 of them) over
  /// [0, min(h, tau_max)], as guard_remainder.
  double remainder(const double* coefficients, double tau_max = std::numeric_limits<double>::infinity()) const;
  /// The same bound in its two parts over [0, T], T = min(h, tau_max): the evaluation's rounding
  /// (`rounding`) and the truncated tail (`truncation`), which over [0, τ] ⊂ [0, T] is at most
  /// truncation · (τ/T)^{p+1} (each term of the tail Σ_{k>p} g_k τ^k, and 1/(1 − τ/ρ), grow with τ).
  void remainder_parts(const double* coefficients, double tau_max, double* rounding, double* truncation) const;
  /// Why the last expand() failed ("log(x0): argument 0 at t = 1.5").
  const std::string& trouble() const { return trouble_; }

  int order() const { return p_; }
  double start_time() const { return t0_; }
  double step_size() const { return h_; }
  /// Radius-of-convergence estimate ρ (see the header): h ≈ ρ ε^{1/p} · 0.97.
  double radius() const { return rho_; }

  /// z(t₀ + τ) and z'(t₀ + τ) from the step's polynomial (Horner).
  void state(double tau, Eigen::Ref<Eigen::VectorXd> out) const;
  void derivative(double tau, Eigen::Ref<Eigen::VectorXd> out) const;
  /// Φ(τ) (2n × 2n); needs `variational`.
  void transition(double tau, Eigen::Ref<Eigen::MatrixXd> out) const;

  /// z_i's coefficients z_[0…p] (p + 1 values, contiguous).
  const double* state_coefficients(int i) const { return &z_[static_cast<std::size_t>(i) * (p_ + 1)]; }
  /// Guard g's coefficients g_[0…p].
  const double* guard_coefficients(int g) const;
  /// Bound on |g(z(t₀ + τ)) − G(τ)| over [0, min(h, tau_max)] (truncation and rounding).
  double guard_remainder(int g, double tau_max = std::numeric_limits<double>::infinity()) const;
  /// ∂g/∂z_d at the step's start (z_d the state's d-th entry): guard g's gradient, from the
  /// forward-mode tangents (needs `variational`).
  double guard_gradient(int g, int d) const;

  /// Ω and the named parameters (initially the system's values).
  void set_parameter(int j, double value) { parameters_[j] = value; }
  const Eigen::VectorXd& parameters() const { return parameters_; }
  const TaylorSystem& system() const { return *system_; }

 private:
  bool compute_order(int k);
  bool node_order(int k);   // every node by the Dag (order 0, and the tangents)
  void tape_order(int k);   // order k ≥ 1 of the tape below
  void tape_orders();       // orders 1 … p without tangents: the tape and the linear part
  bool linear_order(int k); // the linear part and the StepTerms: z_[k+1] from the forces' f_[k]
  /// A_x and A_v in force: the StepTerms' or the system's.
  const Eigen::MatrixXd& position_matrix() const {
    return terms_.position_matrix ? *terms_.position_matrix : system_->position_matrix();
  }
  const Eigen::MatrixXd& velocity_matrix() const {
    return terms_.velocity_matrix ? *terms_.velocity_matrix : system_->velocity_matrix();
  }
  double* c(int node) { return &c_[static_cast<std::size_t>(node) * (p_ + 1)]; }
  double* aux(int node) { return &aux_[static_cast<std::size_t>(node) * (p_ + 1)]; }
  double* dc(int node, int d) { return &dc_[(static_cast<std::size_t>(node) * dim_ + d) * (p_ + 1)]; }
  double* zc(int i) { return &z_[static_cast<std::size_t>(i) * (p_ + 1)]; }
  double* yc(int i, int d) { return &y_[(static_cast<std::size_t>(i) * dim_ + d) * (p_ + 1)]; }

  const TaylorSystem* system_;
  TaylorSettings settings_;
  int p_;
  int dim_;  // 2n
  double t0_ = 0.0, h_ = 0.0, rho_ = 0.0;
  double safety_ = 1.0;                  // exp(−0.7 / (p − 1))
  double inverse_root_[2] = {1.0, 1.0};  // ε^{−1/(p−1)}, ε^{−1/p}
  Eigen::VectorXd parameters_;
  std::vector<double> c_, aux_, dc_, z_, y_;
  /// The recurrences of orders ≥ 1 as a flat tape: the Dag's nodes that vary in time, in
  /// topological order, each with its operation specialised (a product or quotient with a
  /// time-constant operand as a scaling) and its operands' offsets in c_, aux_ and z_ precomputed.
  enum class Code : std::uint8_t {
    Time, State, Add, Subtract, Negate, ScaleLeft, ScaleRight, Multiply, Square, DivideByConstant, Divide,
    PowerReal, Sqrt, Exp, Log, Sin, Cos, Tan, Tanh, Atan
  };
  struct Instruction {
    Code code;
    std::size_t out, a, b;  // offsets of the node's series and its operands' (State: in z_; Cos: the Sin's aux)
    double value;           // PowerReal: α
  };
  std::vector<Instruction> tape_;
  Eigen::VectorXd force_k_;   // M⁻¹ F_[k] scratch
  Eigen::MatrixXd dforce_k_;  // n × 2n scratch
  std::string trouble_;
  StepTerms terms_;
  std::vector<double> lambda_;                  // k × (p + 1), the held stops' forces
  Eigen::VectorXd acc_k_, residual_k_, lambda_k_;  // scratch
  Eigen::MatrixXd dacc_k_, dresidual_k_;
};

/// Integrates from (t0, z0) to t1 ≥ t0 by successive steps (the last one shortened to end at t1;
/// the elapsed time kept with compensated summation, so the end is t1 to rounding). Writes z(t1)
/// and, if `phi` is given and the step is variational, ∂z(t1)/∂z(t0). Returns the status of the
/// first failing step; `steps` counts the steps taken.
StepStatus advance(TaylorStep& step, double t0, const Eigen::Ref<const Eigen::VectorXd>& z0, double t1,
                   Eigen::Ref<Eigen::VectorXd> z1, Eigen::MatrixXd* phi = nullptr, long* steps = nullptr);

}  // namespace vibro::taylor
