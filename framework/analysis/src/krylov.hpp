#pragma once
/// \file krylov.hpp
/// Krylov methods on an operator given only by its products (private to the analysis layer):
/// GMRES for the Newton steps of matrix-free shooting, Arnoldi for the leading eigenvalues
/// (Floquet multipliers) of a long chain's monodromy map. Both orthogonalise by modified
/// Gram–Schmidt done twice ("twice is enough": Giraud, Langou & Rozložník 2005), so the basis
/// stays orthonormal to rounding even when the operator is far from normal, as a monodromy map
/// with impacts is.
///
///  * gmres (Saad & Schultz 1986): minimises ‖b − A x‖ over the Krylov space, by Givens
///    rotations on the Hessenberg matrix; restarted every `restart` steps.
///  * arnoldi (Saad 2011, ch. 6): the Ritz values of the growing Hessenberg matrix H_m; the
///    residual of a Ritz pair (θ, V y) is h_{m+1,m} |e_mᵀ y| (‖y‖ = 1), and the leading `count`
///    values are accepted when all their residuals are ≤ tol·max(1, |θ_1|), or exactly when the
///    space becomes invariant (h_{m+1,m} = 0).
///
/// Both take an optional stop flag (SimulatorOptions::interrupt), polled before every product:
/// once it is raised they return at once, not converged (a product of a long chain's tangent map
/// takes milliseconds, a basis of hundreds of them seconds).
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <atomic>
#include <functional>
#include <limits>

namespace vibro::detail {

using Product = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;

inline bool stop_raised(const std::atomic<bool>* stop) { return stop && stop->load(std::memory_order_relaxed); }

/// Orthogonalises w against the first k columns of V (twice) and stores the coefficients in h.
inline void orthogonalise(const Eigen::MatrixXd& V, Eigen::Index k, Eigen::VectorXd& w, Eigen::Ref<Eigen::VectorXd> h) {
  h.setZero();
  for (int pass = 0; pass < 2; ++pass)
    for (Eigen::Index i = 0; i < k; ++i) {
      const double c = V.col(i).dot(w);
      h(i) += c;
      w -= c * V.col(i);
    }
}

struct GmresResult {
  Eigen::VectorXd x;
  double relative_residual = 1.0;  ///< ‖b − A x‖ / ‖b‖
  int products = 0;
  bool converged = false;
};

inline GmresResult gmres(const Product& A, const Eigen::VectorXd& b, double tol, int restart, int max_products,
                         const std::atomic<bool>* stop = nullptr) {
  const Eigen::Index n = b.size();
  GmresResult out;
  out.x = Eigen::VectorXd::Zero(n);
  const double bnorm = b.norm();
  if (bnorm == 0.0) {
    out.relative_residual = 0.0;
    out.converged = true;
    return out;
  }
  const Eigen::Index m = std::max<Eigen::Index>(1, std::min<Eigen::Index>(restart, n));
  Eigen::VectorXd r = b;
  while (out.products < max_products && !stop_raised(stop)) {
    const double beta = r.norm();
    out.relative_residual = beta / bnorm;
    if (out.relative_residual <= tol) break;
    Eigen::MatrixXd V(n, m + 1), H = Eigen::MatrixXd::Zero(m + 1, m);
    Eigen::VectorXd cs = Eigen::VectorXd::Zero(m), sn = Eigen::VectorXd::Zero(m), g = Eigen::VectorXd::Zero(m + 1);
    V.col(0) = r / beta;
    g(0) = beta;
    Eigen::Index j = 0;
    for (; j < m && out.products < max_products && !stop_raised(stop); ++j) {
      Eigen::VectorXd w = A(V.col(j));
      ++out.products;
      orthogonalise(V, j + 1, w, H.col(j).head(j + 1));
      H(j + 1, j) = w.norm();
      if (H(j + 1, j) > 0.0) V.col(j + 1) = w / H(j + 1, j);
      for (Eigen::Index i = 0; i < j; ++i) {  // earlier rotations on the new column
        const double a = H(i, j), c = H(i + 1, j);
        H(i, j) = cs(i) * a + sn(i) * c;
        H(i + 1, j) = -sn(i) * a + cs(i) * c;
      }
      const double a = H(j, j), c = H(j + 1, j), d = std::hypot(a, c);
      cs(j) = d > 0.0 ? a / d : 1.0;
      sn(j) = d > 0.0 ? c / d : 0.0;
      H(j, j) = d;
      H(j + 1, j) = 0.0;
      g(j + 1) = -sn(j) * g(j);
      g(j) = cs(j) * g(j);
      if (std::abs(g(j + 1)) / bnorm <= tol || !(H(j, j) != 0.0)) {
        ++j;
        break;
      }
    }
    if (stop_raised(stop)) break;  // not converged: no more products
    const Eigen::VectorXd y = H.topLeftCorner(j, j).triangularView<Eigen::Upper>().solve(g.head(j));
    out.x += V.leftCols(j) * y;
    r = b - A(out.x);  // the true residual (not the recurrence's) decides
    ++out.products;
  }
  out.relative_residual = r.norm() / bnorm;
  out.converged = out.relative_residual <= tol;
  return out;
}

struct ArnoldiResult {
  Eigen::VectorXcd values;   ///< the leading Ritz values by decreasing modulus
  Eigen::VectorXd residuals; ///< their residual estimates (absolute)
  int products = 0;
  bool converged = false;
  bool invariant = false;    ///< the space became invariant: the values are exact eigenvalues
};

inline ArnoldiResult arnoldi(const Product& A, Eigen::Index n, int count, int max_dimension, double tol,
                             const std::atomic<bool>* stop = nullptr) {
  ArnoldiResult out;
  const Eigen::Index m = std::min<Eigen::Index>(max_dimension, n);
  Eigen::MatrixXd V(n, m + 1), H = Eigen::MatrixXd::Zero(m + 1, m);
  Eigen::VectorXd v0(n);  // a fixed start with every component present
  for (Eigen::Index i = 0; i < n; ++i) v0(i) = 1.0 + 0.5 * std::sin(0.37 * static_cast<double>(i) + 0.11);
  V.col(0) = v0.normalized();
  for (Eigen::Index j = 0; j < m; ++j) {
    if (stop_raised(stop)) return out;  // not converged
    Eigen::VectorXd w = A(V.col(j));
    ++out.products;
    orthogonalise(V, j + 1, w, H.col(j).head(j + 1));
    H(j + 1, j) = w.norm();
    const Eigen::Index k = j + 1;
    out.invariant = H(j + 1, j) <= 1e-14 * H.topLeftCorner(k, k).norm();
    if (H(j + 1, j) > 0.0) V.col(j + 1) = w / H(j + 1, j);
    // The Ritz values cost O(k³): looked at every ⌈k/8⌉ steps (and at the end), which keeps
    // their total cost at a few times the last one's.
    const bool last = out.invariant || k == m;
    if (!last && (k < count || k % std::max<Eigen::Index>(1, (k + 7) / 8) != 0)) continue;
    Eigen::EigenSolver<Eigen::MatrixXd> es(H.topLeftCorner(k, k));
    std::vector<Eigen::Index> order(static_cast<std::size_t>(k));
    for (Eigen::Index i = 0; i < k; ++i) order[static_cast<std::size_t>(i)] = i;
    std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
      return std::abs(es.eigenvalues()(a)) > std::abs(es.eigenvalues()(b));
    });
    const Eigen::Index c = std::min<Eigen::Index>(count, k);
    out.values.resize(c);
    out.residuals.resize(c);
    bool all = true;
    const double scale = std::max(1.0, std::abs(es.eigenvalues()(order[0])));
    for (Eigen::Index i = 0; i < c; ++i) {
      const Eigen::Index e = order[static_cast<std::size_t>(i)];
      out.values(i) = es.eigenvalues()(e);
      const Eigen::VectorXcd y = es.eigenvectors().col(e).normalized();
      out.residuals(i) = out.invariant ? 0.0 : H(j + 1, j) * std::abs(y(k - 1));
      all = all && out.residuals(i) <= tol * scale;
    }
    if (all || out.invariant) {
      out.converged = true;
      break;
    }
  }
  return out;
}

}  // namespace vibro::detail
