#pragma once
// Private to vibro_core: the modes of a symmetric eigenproblem restricted by one linear
// constraint, from the modes of the unrestricted one, by the secular equation (modal.hpp,
// "Sticking"). Used by ChainModes for the contact sets of long chains.
//
// The problem. In an orthonormal eigenbasis of the parent, diag(d) with d ascending (m values),
// restrict to the subspace {y : zᵀy = 0}. Its eigenpairs (μ, v) satisfy (d - μ) v = γ z with
// zᵀv = 0, hence v ∝ (d - μ)⁻¹ z and the secular equation
//     f(μ) = Σᵢ zᵢ² / (dᵢ - μ) = 0,
// whose m - 1 roots interlace the poles: μ_l ∈ (d_l, d_{l+1}) (f rises from -∞ to +∞ on each
// interval). This is the limit ρ → ∞ of the rank-one update diag(d) + ρ zzᵀ of Cuppen's divide
// and conquer (Golub 1973, "Some modified matrix eigenvalue problems", SIAM Rev. 15).
//
// How, with the safeguards of LAPACK's dlaed2/dlaed3/dlaed4 (Gu & Eisenstat 1995, "A
// divide-and-conquer algorithm for the symmetric tridiagonal eigenproblem", SIAM J. Matrix
// Anal. Appl. 16; Li 1994, "Solving secular equations stably and efficiently"):
//  * z is scaled to unit length. Deflation: a component |zᵢ| ≤ 8ε leaves parent mode i an
//    eigenvector of the restricted problem (eigenvalue dᵢ; residual ≤ 8ε‖d‖); two poles closer
//    than 8ε‖d‖ / |cs| are rotated (Givens, c = zᵢ/r, s = zⱼ/r) so that one of them has z = 0
//    and is deflated the same way.
//  * Each root is found from the pole it is closer to as μ = d_o + τ (first guess: where the
//    previous roots sat in their intervals, extrapolated; the origin moves if the root proves
//    nearer the other pole), with every difference dᵢ - μ formed as (dᵢ - d_o) - τ, so
//    that τ and the vectors are accurate even where poles cluster. Iteration: the "middle way"
//    of dlaed4 (the sums over the poles below and above the root each replaced by a constant
//    plus one pole, matching value and slope), safeguarded by bisection on the bracket, to
//    |f| ≤ 8ε Σ|terms| or a step below 1e-9 |τ| (the step is kept: the iteration converges
//    quadratically, so the next would be below rounding).
//  * The weights are recomputed from the roots (Löwner's formula, the residues of f):
//        ẑ_p² = Π_{l<p} (μ_l - d_p)/(d_l - d_p) · Π_{l≥p} (μ_l - d_p)/(d_{l+1} - d_p),
//    every factor in (0, 1], so that the computed μ are the exact eigenvalues of the problem
//    with ẑ for z, and the vectors v_l = (d - μ_l)⁻¹ ẑ / ‖·‖ are orthogonal to working
//    precision (Gu & Eisenstat's argument).
//
// Storage O(m) (the vectors are never formed); each product with the child basis V (m × (m-1))
// or its transpose is O(m²) per vector, and several vectors share each pass. Cost of a level:
// passes over the q poles, one division per pole each, for every root: the root (one pass for
// most when the weights vary smoothly, else ~3), Löwner's weights (one), the norms (one, which
// also carries any columns given to the constructor into the child basis).
#include <Eigen/Dense>

#include <vector>

namespace vibro::detail {

class SecularLevel {
 public:
  /// d: the parent's eigenvalues, ascending (size m ≥ 1); z: the constraint in the parent's basis.
  /// carry (optional, m × k): columns in the parent's basis, replaced by Vᵀ carry ((m-1) × k),
  /// computed in the pass that normalises the vectors (so they cost no pass of their own).
  /// Throws std::runtime_error if z is zero to rounding (the constraint adds nothing).
  SecularLevel(const Eigen::VectorXd& d, const Eigen::VectorXd& z, Eigen::MatrixXd* carry = nullptr);

  Eigen::Index parent_size() const { return m_; }
  Eigen::Index child_size() const { return m_ - 1; }
  /// The restricted problem's eigenvalues, ascending (size m - 1).
  const Eigen::VectorXd& eigenvalues() const { return mu_; }

  /// child = Vᵀ parent (each column a vector), parent (m × k), child ((m-1) × k). `scratch`
  /// (≥ (m + q) k doubles, q ≤ m the poles kept) is used and not allocated; the other overload
  /// allocates it.
  void to_child(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child,
                double* scratch) const;
  void to_child(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child) const;
  /// parent = V child (same scratch).
  void to_parent(const Eigen::Ref<const Eigen::MatrixXd>& child, Eigen::Ref<Eigen::MatrixXd> parent,
                 double* scratch) const;
  /// Doubles of scratch a product with k vectors needs.
  Eigen::Index scratch_size(Eigen::Index k) const { return (m_ + d_.size()) * k; }

  /// Bytes held.
  std::size_t bytes() const;

 private:
  struct Rotation {
    Eigen::Index i, j;
    double c, s;  // (xᵢ, xⱼ) ← (c xᵢ + s xⱼ, -s xᵢ + c xⱼ)
  };
  void rotate(Eigen::Map<Eigen::MatrixXd>& x, bool forward) const;
  /// to_child; with zhat2 (ẑ²) and inv_norm given, also each root's 1/‖(d - μ_l)⁻¹ ẑ‖ into
  /// inv_norm, read from the same divisions and used for this product (the constructor's pass).
  void child_pass(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child, double* scratch,
                  const Eigen::VectorXd* zhat2, Eigen::VectorXd* inv_norm) const;

  Eigen::Index m_ = 0;
  std::vector<Rotation> rotations_;
  std::vector<Eigen::Index> poles_;   // parent indices (after rotation) kept in the equation
  Eigen::VectorXd d_, zhat_;          // their d and recomputed weights
  std::vector<Eigen::Index> origin_;  // per root: position in poles_ of its origin
  Eigen::VectorXd tau_, inv_norm_;    // per root: μ = d[origin] + τ, 1/‖(d - μ)⁻¹ ẑ‖
  // Per child (ascending eigenvalue): ≥ 0 a root index, < 0 the deflated parent index -1-i.
  std::vector<Eigen::Index> child_;
  Eigen::VectorXd mu_;
};

}  // namespace vibro::detail
