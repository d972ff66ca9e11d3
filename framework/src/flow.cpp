#include "vibro/flow.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vibro {
namespace {

/// Closed-form exponential (flow.hpp): largest augmented size for which the Schur clusters are
/// computed (an O(N³) set-up, minutes beyond a few hundred), and the longest series kept.
constexpr Eigen::Index kClosedFormMaxSize = 400;
constexpr int kMaxDegree = 24;

Eigen::MatrixXd build_generator(const LinearSystem& sys) {
  return augmented_generator(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing());
}

}  // namespace

Eigen::MatrixXd augmented_generator(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C,
                                    const Eigen::MatrixXd& K, const HarmonicForcing& f) {
  const Eigen::Index n = M.rows();
  const Eigen::Index N = augmented_size(n, f);
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(N, N);
  if (n > 0) {
    const Eigen::LLT<Eigen::MatrixXd> llt(M);
    g.block(0, n, n, n).setIdentity();
    g.block(n, 0, n, n) = -llt.solve(K);
    g.block(n, n, n, n) = -llt.solve(C);
    g.block(n, 2 * n, n, 1) = llt.solve(f.cosine);
    g.block(n, 2 * n + 1, n, 1) = llt.solve(f.sine);
    g.block(n, 2 * n + 2, n, 1) = llt.solve(f.constant);
    for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
      const Eigen::Index c = augmented_size(n, h);  // cos k_h Ωt, then sin k_h Ωt
      g.block(n, c, n, 1) = llt.solve(f.harmonics[h].cosine);
      g.block(n, c + 1, n, 1) = llt.solve(f.harmonics[h].sine);
    }
  }
  g(2 * n, 2 * n + 1) = -f.frequency;
  g(2 * n + 1, 2 * n) = f.frequency;
  for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
    const Eigen::Index c = augmented_size(n, h);
    const double w = f.harmonics[h].rate(f.frequency);
    g(c, c + 1) = -w;
    g(c + 1, c) = w;
  }
  return g;
}

LinearFlow::LinearFlow(const LinearSystem& system, Options options)
    : LinearFlow(build_generator(system), system.dof(), system.forcing().frequency, options) {}

LinearFlow::LinearFlow(Eigen::MatrixXd generator, Eigen::Index dof, double frequency,
                       Options options)
    : n_(dof),
      omega_(frequency),
      method_(Method::exponential),
      condition_(std::numeric_limits<double>::infinity()),
      generator_(std::move(generator)) {
  // Extra harmonics (flow.hpp): the generator's size gives their number, its rotation blocks
  // their rates k_h Ω.
  if (generator_.rows() > augmented_size(dof) && (generator_.rows() - augmented_size(dof)) % 2 == 0)
    for (Eigen::Index c = augmented_size(dof); c + 1 < generator_.rows(); c += 2)
      rates_.push_back(generator_(c + 1, c));
  const Eigen::Index N = size();
  if (generator_.rows() != N || generator_.cols() != N)
    throw InvalidInput("flow: generator is " + std::to_string(generator_.rows()) + "x" +
                       std::to_string(generator_.cols()) + ", expected " + std::to_string(N) +
                       "x" + std::to_string(N) + " for " + std::to_string(dof) + " DOF");
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> sym(0.5 * (generator_ + generator_.transpose()),
                                                    Eigen::EigenvaluesOnly);
  log_norm_ = sym.eigenvalues()(N - 1);
  // Scaled logarithmic norm (see flow.hpp): Gershgorin bound of λmax(sym(D Â D⁻¹)), O(N²).
  if (n_ > 0) {
    const double kscale = generator_.block(n_, 0, n_, n_).cwiseAbs().rowwise().sum().maxCoeff();
    position_scale_ = kscale > 0.0 ? std::sqrt(kscale) : 1.0;
  }
  auto scale_of = [&](Eigen::Index i) { return i < n_ ? position_scale_ : 1.0; };
  scaled_log_norm_ = -std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < N; ++i) {
    double row = generator_(i, i);
    for (Eigen::Index j = 0; j < N; ++j)
      if (j != i)
        row += 0.5 * std::abs(scale_of(i) * generator_(i, j) / scale_of(j) +
                              scale_of(j) * generator_(j, i) / scale_of(i));
    scaled_log_norm_ = std::max(scaled_log_norm_, row);
  }

  if (options.method == Method::exponential) {
    // Only the spectral radius is needed (it sets the event search's step). Beyond N = 64 a
    // dense non-symmetric eigenvalue solve costs minutes (N = 2003: > 300 s on a loaded 2-core
    // machine), so there it is bounded in O(N²): Â is block triangular (mechanical block A,
    // forcing rotation Ω), so ρ(Â) = max(ρ(A), Ω), and ρ(A) ≤ ‖D A D⁻¹‖∞ for the scaling D above.
    if (N <= 64) {
      Eigen::EigenSolver<Eigen::MatrixXd> values(generator_, false);
      spectral_radius_ = values.info() == Eigen::Success
                             ? values.eigenvalues().cwiseAbs().maxCoeff()
                             : generator_.cwiseAbs().rowwise().sum().maxCoeff();  // ∞-norm bounds |λ|
    } else {
      double rows = position_scale_;  // the x rows of D A D⁻¹: s on the diagonal of the I block
      for (Eigen::Index i = n_; i < 2 * n_; ++i)
        rows = std::max(rows, generator_.row(i).head(n_).cwiseAbs().sum() / position_scale_ +
                                  generator_.row(i).segment(n_, n_).cwiseAbs().sum());
      spectral_radius_ = std::max(rows, std::abs(omega_));
      for (const double w : rates_) spectral_radius_ = std::max(spectral_radius_, std::abs(w));
    }
    if (options.closed_form && N <= kClosedFormMaxSize) build_schur_clusters(options.max_condition);
    return;
  }
  // A strictly upper triangular Â (a free mass under a constant force, Ω = 0) is nilpotent:
  // every eigenvalue 0, defective unless Â = 0, so the spectral attempt below can only fail
  // (its eigenvectors and their SVD cost a third of such a run's set-up): go to the closed form.
  bool strictly_upper = !generator_.isZero(0.0);
  for (Eigen::Index j = 0; j < N && strictly_upper; ++j)
    for (Eigen::Index i = j; i < N && strictly_upper; ++i) strictly_upper = generator_(i, j) == 0.0;
  if (options.method == Method::automatic && strictly_upper) {
    spectral_radius_ = 0.0;
    if (options.closed_form && N <= kClosedFormMaxSize) build_schur_clusters(options.max_condition);
    return;
  }
  Eigen::EigenSolver<Eigen::MatrixXd> eig(generator_, true);
  if (eig.info() == Eigen::Success) {
    lambda_ = eig.eigenvalues();
    vectors_ = eig.eigenvectors();
    spectral_radius_ = lambda_.cwiseAbs().maxCoeff();
    // Divide-and-conquer SVD: the same cond₂(V) as Jacobi's to ~3 digits, 30x faster at N = 400.
    Eigen::BDCSVD<Eigen::MatrixXcd> svd(vectors_);
    const auto& s = svd.singularValues();
    condition_ = s(N - 1) > 0 ? s(0) / s(N - 1) : std::numeric_limits<double>::infinity();
  } else {
    spectral_radius_ = generator_.cwiseAbs().rowwise().sum().maxCoeff();  // ∞-norm bounds |λ|
  }

  bool spectral_ok = std::isfinite(condition_) && condition_ <= options.max_condition;
  if (spectral_ok) {
    inverse_ = vectors_.partialPivLu().inverse();
    // The decomposition must reproduce Â: ‖V Λ V⁻¹ - Â‖ ≤ 1e-13 max(1, cond(V)/100) ‖Â‖ (max-norm).
    const Eigen::MatrixXcd rebuilt = vectors_ * lambda_.asDiagonal() * inverse_;
    const double scale = std::max(generator_.cwiseAbs().maxCoeff(), 1e-300);
    const double err = (rebuilt - generator_.cast<std::complex<double>>()).cwiseAbs().maxCoeff();
    spectral_ok = err <= 1e-13 * scale * std::max(1.0, condition_ / 100.0);
  }
  const bool use_spectral = options.method == Method::spectral ||
                            (options.method == Method::automatic && spectral_ok);
  // Forcing the spectral method on a (nearly) defective generator would silently return wrong
  // states; refuse where its error bound cond(V)·ε exceeds 1e-8.
  if (options.method == Method::spectral && (eig.info() != Eigen::Success || !(condition_ <= 1e8)))
    throw InvalidInput("flow: the spectral method was requested but the eigenvector matrix has "
                       "condition number " + std::to_string(condition_) +
                       " (> 1e8: Â is defective or nearly so); use the automatic or exponential method");
  if (use_spectral) {
    if (inverse_.size() == 0) inverse_ = vectors_.partialPivLu().inverse();
    method_ = Method::spectral;
    // Eigen lists a complex pair as (λ, conj λ) in consecutive places.
    for (Eigen::Index k = 0; k < N; ++k) {
      if (lambda_(k).imag() != 0.0 && k + 1 < N && lambda_(k + 1) == std::conj(lambda_(k))) {
        representatives_.push_back(k);
        weights_.push_back(2.0);
        ++k;
      } else {
        representatives_.push_back(k);
        weights_.push_back(lambda_(k).imag() == 0.0 ? 1.0 : 0.0);
      }
    }
    // An unpaired complex eigenvalue (not expected for a real Â) falls back to the full sum.
    if (std::find(weights_.begin(), weights_.end(), 0.0) != weights_.end()) {
      representatives_.clear();
      weights_.clear();
      for (Eigen::Index k = 0; k < N; ++k) {
        representatives_.push_back(k);
        weights_.push_back(1.0);
      }
    }
    build_spectral_terms();
  } else {
    method_ = Method::exponential;
    lambda_.resize(0);
    vectors_.resize(0, 0);
    inverse_.resize(0, 0);
    if (options.closed_form && N <= kClosedFormMaxSize) build_schur_clusters(options.max_condition);
  }
}

void LinearFlow::build_spectral_terms() {
  terms_.clear();
  for (std::size_t r = 0; r < representatives_.size(); ++r)
    terms_.push_back({lambda_(representatives_[r]), weights_[r], representatives_[r], 1, 0});
  horizon_ = std::numeric_limits<double>::infinity();
}

namespace {

/// Swaps the adjacent diagonal entries k, k+1 of the complex Schur form T (Â = U T Uᴴ) by a
/// unitary rotation G whose first column is the eigenvector (t_{k,k+1}, t_{k+1,k+1} - t_kk) of
/// the 2×2 block for t_{k+1,k+1}: T ← Gᴴ T G, U ← U G (Golub & Van Loan, Matrix Computations,
/// 4th ed., §7.6.2).
void swap_schur(Eigen::MatrixXcd& T, Eigen::MatrixXcd& U, Eigen::Index k) {
  using C = std::complex<double>;
  const Eigen::Index N = T.rows();
  const C a = T(k, k), b = T(k + 1, k + 1), x = T(k, k + 1);
  const double r = std::hypot(std::abs(x), std::abs(b - a));
  if (r == 0.0) return;
  const C g1 = x / r, g2 = (b - a) / r;
  for (Eigen::Index j = k; j < N; ++j) {
    const C u = T(k, j), v = T(k + 1, j);
    T(k, j) = std::conj(g1) * u + std::conj(g2) * v;
    T(k + 1, j) = -g2 * u + g1 * v;
  }
  for (Eigen::Index i = 0; i <= k + 1; ++i) {
    const C u = T(i, k), v = T(i, k + 1);
    T(i, k) = u * g1 + v * g2;
    T(i, k + 1) = -u * std::conj(g2) + v * std::conj(g1);
  }
  for (Eigen::Index i = 0; i < N; ++i) {
    const C u = U(i, k), v = U(i, k + 1);
    U(i, k) = u * g1 + v * g2;
    U(i, k + 1) = -u * std::conj(g2) + v * std::conj(g1);
  }
  T(k + 1, k) = 0.0;
  T(k, k) = b;
  T(k + 1, k + 1) = a;
}

/// Solves A X - X B = C for upper triangular A (m × m) and B (k × k) with disjoint spectra,
/// column by column: (A - b_jj I) X_j = C_j + Σ_{l<j} X_l b_lj (back substitution).
Eigen::MatrixXcd triangular_sylvester(const Eigen::MatrixXcd& A, const Eigen::MatrixXcd& B,
                                      const Eigen::MatrixXcd& C) {
  const Eigen::Index m = A.rows(), k = B.rows();
  Eigen::MatrixXcd X(m, k);
  for (Eigen::Index j = 0; j < k; ++j) {
    Eigen::VectorXcd rhs = C.col(j);
    for (Eigen::Index l = 0; l < j; ++l) rhs += X.col(l) * B(l, j);
    for (Eigen::Index i = m - 1; i >= 0; --i) {
      std::complex<double> sum = rhs(i);
      for (Eigen::Index l = i + 1; l < m; ++l) sum -= A(i, l) * X(l, j);
      X(i, j) = sum / (A(i, i) - B(j, j));
    }
  }
  return X;
}

}  // namespace

bool LinearFlow::build_schur_clusters(double max_condition) {
  using C = std::complex<double>;
  const Eigen::Index N = size();
  const Eigen::MatrixXcd A = generator_.cast<C>();
  const Eigen::ComplexSchur<Eigen::MatrixXcd> schur(A);
  if (schur.info() != Eigen::Success) return false;
  const double scale = std::max(generator_.cwiseAbs().rowwise().sum().maxCoeff(), 1e-300);
  const double a_max = std::max(generator_.cwiseAbs().maxCoeff(), 1e-300);
  // Tighter clusters first: a defective eigenvalue of multiplicity m is spread by ~ε^{1/m}
  // (1.5e-8 for m = 2, 6e-6 for m = 3, 1.2e-4 for m = 4), which the first threshold gathers;
  // wider ones merge nearly defective groups until the cluster basis is well conditioned.
  for (const double eta : {1e-4, 1e-3, 1e-2, 1e-1, 1.0}) {
    Eigen::MatrixXcd T = schur.matrixT(), U = schur.matrixU();
    // Clusters: connected components of |t_ii - t_jj| ≤ η‖Â‖∞, numbered by first appearance.
    std::vector<int> cluster(static_cast<std::size_t>(N), -1);
    int clusters = 0;
    for (Eigen::Index i = 0; i < N; ++i) {
      if (cluster[static_cast<std::size_t>(i)] >= 0) continue;
      std::vector<Eigen::Index> todo{i};
      cluster[static_cast<std::size_t>(i)] = clusters;
      while (!todo.empty()) {
        const Eigen::Index p = todo.back();
        todo.pop_back();
        for (Eigen::Index j = 0; j < N; ++j)
          if (cluster[static_cast<std::size_t>(j)] < 0 && std::abs(T(p, p) - T(j, j)) <= eta * scale) {
            cluster[static_cast<std::size_t>(j)] = clusters;
            todo.push_back(j);
          }
      }
      ++clusters;
    }
    // Make each cluster contiguous (insertion sort by adjacent swaps).
    for (Eigen::Index i = 1; i < N; ++i)
      for (Eigen::Index k = i; k > 0 && cluster[static_cast<std::size_t>(k - 1)] > cluster[static_cast<std::size_t>(k)]; --k) {
        swap_schur(T, U, k - 1);
        std::swap(cluster[static_cast<std::size_t>(k - 1)], cluster[static_cast<std::size_t>(k)]);
      }
    std::vector<Eigen::Index> offset, sizes;
    for (Eigen::Index i = 0; i < N; ++i)
      if (i == 0 || cluster[static_cast<std::size_t>(i)] != cluster[static_cast<std::size_t>(i - 1)]) {
        offset.push_back(i);
        sizes.push_back(1);
      } else {
        ++sizes.back();
      }
    // Decouple the clusters: T = S diag(T_c) S⁻¹ with S unit upper triangular.
    Eigen::MatrixXcd S = Eigen::MatrixXcd::Identity(N, N), Sinv = Eigen::MatrixXcd::Identity(N, N);
    bool finite = true;
    for (std::size_t c = 0; c + 1 < offset.size(); ++c) {
      const Eigen::Index o = offset[c], m = sizes[c], rest = N - o - m;
      const Eigen::MatrixXcd X =
          triangular_sylvester(T.block(o, o, m, m), T.block(o + m, o + m, rest, rest), -T.block(o, o + m, m, rest));
      if (!X.allFinite()) {
        finite = false;
        break;
      }
      T.block(o, o + m, m, rest).setZero();
      S.rightCols(rest) += S.block(0, o, N, m) * X;
      Sinv.middleRows(o, m) -= X * Sinv.bottomRows(rest);
    }
    if (!finite) continue;
    Eigen::MatrixXcd V = U * S, Vinv = Sinv * U.adjoint();
    const double cond = V.norm() * Vinv.norm();  // Frobenius: ≥ cond₂
    if (!(cond <= max_condition)) continue;
    const double err = (V * T * Vinv - A).cwiseAbs().maxCoeff();
    if (!(err <= 1e-13 * a_max * std::max(1.0, cond / 100.0))) continue;

    // Per cluster: μ_c, E_c = T_c - μ_c I, and the degree of its series.
    std::vector<Term> terms;
    Eigen::MatrixXcd parts = Eigen::MatrixXcd::Zero(N, N);
    double horizon = std::numeric_limits<double>::infinity();
    for (std::size_t c = 0; c < offset.size(); ++c) {
      const Eigen::Index o = offset[c], m = sizes[c];
      const C mu = T.block(o, o, m, m).diagonal().mean();
      Eigen::MatrixXcd E = T.block(o, o, m, m);
      E.diagonal().array() -= mu;
      parts.block(o, o, m, m) = E;
      // Norms n_p = ‖E^p‖ (max-abs row sum); the series stops at the first exactly zero power,
      // else after kMaxDegree terms, with the horizon where the next term falls below 1e-18 of
      // the largest kept one (for τ ≤ horizon the neglected tail is below rounding).
      std::vector<double> norms{1.0};
      Eigen::MatrixXcd power = Eigen::MatrixXcd::Identity(m, m);
      int degree = -1;
      for (int p = 1; p <= kMaxDegree + 1; ++p) {
        power = power * E;
        const double np = power.cwiseAbs().rowwise().sum().maxCoeff();
        if (np == 0.0) {
          degree = p - 1;
          break;
        }
        norms.push_back(np);
      }
      if (degree < 0) {
        degree = kMaxDegree;
        // Largest τ with n_{P+1} τ^{P+1}/(P+1)! ≤ 1e-18 · max(1, max_p n_p τ^p / p!), in log τ.
        auto ok = [&](double tau) {
          double lead = 1.0, term = 1.0;
          for (int p = 1; p <= kMaxDegree; ++p) {
            term *= tau / p;
            lead = std::max(lead, norms[static_cast<std::size_t>(p)] * term);
          }
          return norms[static_cast<std::size_t>(kMaxDegree + 1)] * term * tau / (kMaxDegree + 1) <= 1e-18 * lead;
        };
        double lo = 0.0, hi = 1.0;
        while (ok(hi) && hi < 1e300) hi *= 2.0;
        for (int it = 0; it < 200 && hi - lo > 1e-6 * hi; ++it) {
          const double mid = 0.5 * (lo + hi);
          (ok(mid) ? lo : hi) = mid;
        }
        horizon = std::min(horizon, lo);
      }
      terms.push_back({mu, 1.0, o, m, degree});
    }
    if (!(horizon > 0.0)) continue;
    terms_ = std::move(terms);
    basis_ = std::move(V);
    inverse_basis_ = std::move(Vinv);
    cluster_parts_ = std::move(parts);
    horizon_ = horizon;
    cluster_condition_ = cond;
    return true;
  }
  return false;
}

Eigen::VectorXd LinearFlow::augment(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                    const Eigen::Ref<const Eigen::VectorXd>& v) const {
  Eigen::VectorXd z(size());
  z.head(n_) = x;
  z.segment(n_, n_) = v;
  z(2 * n_) = std::cos(omega_ * t);
  z(2 * n_ + 1) = std::sin(omega_ * t);
  z(2 * n_ + 2) = 1.0;
  for (std::size_t h = 0; h < rates_.size(); ++h) {
    const Eigen::Index c = augmented_size(n_, h);
    z(c) = std::cos(rates_[h] * t);
    z(c + 1) = std::sin(rates_[h] * t);
  }
  return z;
}

Eigen::MatrixXd LinearFlow::transition_matrix(double tau) const {
  return (generator_ * tau).exp();
}

void LinearFlow::propagate(const Eigen::Ref<const Eigen::VectorXd>& z, double tau,
                           Eigen::Ref<Eigen::VectorXd> out) const {
  if (!closed_form() || !(std::abs(tau) <= horizon_)) {
    out = transition_matrix(tau) * z;
    return;
  }
  // Re Σ_r w_r V_r e^{λ_r τ} Σ_p (τ E_r)^p / p! (V⁻¹ z)_r (flow.hpp).
  const Eigen::MatrixXcd& V = basis();
  const Eigen::MatrixXcd& Vinv = inverse_basis();
  Eigen::VectorXcd w = Eigen::VectorXcd::Zero(size());
  for (const Term& term : terms_) {
    const Eigen::Index o = term.column, m = term.size;
    Eigen::VectorXcd y = Vinv.middleRows(o, m) * z.cast<std::complex<double>>();
    Eigen::VectorXcd sum = y;
    for (int p = 1; p <= term.degree; ++p) {
      y = cluster_parts_.block(o, o, m, m) * y * (tau / p);
      sum += y;
    }
    w.segment(o, m) = term.weight * std::exp(term.lambda * tau) * sum;
  }
  out = (V * w).real();
}

LinearFlow::State LinearFlow::state(double t0, const Eigen::Ref<const Eigen::VectorXd>& x0,
                                    const Eigen::Ref<const Eigen::VectorXd>& v0, double t) const {
  Eigen::VectorXd z(size());
  propagate(augment(t0, x0, v0), t - t0, z);
  // The forcing components are known exactly; only x and v come from the flow.
  const Eigen::VectorXd exact = augment(t, z.head(n_), z.segment(n_, n_));
  const Eigen::VectorXd dz = generator_ * exact;
  return {exact.head(n_), exact.segment(n_, n_), dz.segment(n_, n_)};
}
}  // namespace vibro
