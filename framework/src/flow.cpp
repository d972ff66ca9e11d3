#include "vibro/flow.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vibro {
namespace {

Eigen::MatrixXd build_generator(const LinearSystem& sys) {
  return augmented_generator(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing());
}

}  // namespace

Eigen::MatrixXd augmented_generator(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C,
                                    const Eigen::MatrixXd& K, const HarmonicForcing& f) {
  const Eigen::Index n = M.rows();
  const Eigen::Index N = 2 * n + 3;
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(N, N);
  if (n > 0) {
    const Eigen::LLT<Eigen::MatrixXd> llt(M);
    g.block(0, n, n, n).setIdentity();
    g.block(n, 0, n, n) = -llt.solve(K);
    g.block(n, n, n, n) = -llt.solve(C);
    g.block(n, 2 * n, n, 1) = llt.solve(f.cosine);
    g.block(n, 2 * n + 1, n, 1) = llt.solve(f.sine);
    g.block(n, 2 * n + 2, n, 1) = llt.solve(f.constant);
  }
  g(2 * n, 2 * n + 1) = -f.frequency;
  g(2 * n + 1, 2 * n) = f.frequency;
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
    }
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
  } else {
    method_ = Method::exponential;
    lambda_.resize(0);
    vectors_.resize(0, 0);
    inverse_.resize(0, 0);
  }
}

Eigen::VectorXd LinearFlow::augment(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                    const Eigen::Ref<const Eigen::VectorXd>& v) const {
  Eigen::VectorXd z(size());
  z.head(n_) = x;
  z.segment(n_, n_) = v;
  z(2 * n_) = std::cos(omega_ * t);
  z(2 * n_ + 1) = std::sin(omega_ * t);
  z(2 * n_ + 2) = 1.0;
  return z;
}

Eigen::MatrixXd LinearFlow::transition_matrix(double tau) const {
  return (generator_ * tau).exp();
}

void LinearFlow::propagate(const Eigen::Ref<const Eigen::VectorXd>& z, double tau,
                           Eigen::Ref<Eigen::VectorXd> out) const {
  if (method_ == Method::spectral) {
    Eigen::VectorXcd c = inverse_ * z.cast<std::complex<double>>();
    for (Eigen::Index k = 0; k < c.size(); ++k) c(k) *= std::exp(lambda_(k) * tau);
    out = (vectors_ * c).real();
  } else {
    out = transition_matrix(tau) * z;
  }
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

// ---------------------------------------------------------------------------------------------

Functionals::Functionals(const LinearFlow& flow, Eigen::MatrixXd rows) : flow_(&flow) {
  rows_[0] = std::move(rows);
  for (int d = 1; d < 4; ++d) rows_[d] = rows_[d - 1] * flow.generator();
  if (flow.method() == LinearFlow::Method::spectral)
    modal_rows_ = rows_[0].cast<std::complex<double>>() * flow.eigenvectors();
}

Segment::Segment(const Functionals& functionals, double t0,
                 const Eigen::Ref<const Eigen::VectorXd>& z0)
    : functionals_(&functionals), t0_(t0), cached_tau_(std::numeric_limits<double>::quiet_NaN()) {
  reset(t0, z0);
}

void Segment::reset(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0) {
  const Functionals& functionals = *functionals_;
  t0_ = t0;
  z0_ = z0;  // same size: no allocation
  cached_tau_ = std::numeric_limits<double>::quiet_NaN();
  for (double& tau : cache_tau_) tau = std::numeric_limits<double>::quiet_NaN();
  cache_next_ = 0;
  const LinearFlow& flow = functionals.flow();
  if (flow.method() == LinearFlow::Method::spectral) {
    const Eigen::Index N = flow.size();
    modal_.resize(N);
    modal_.noalias() = flow.inverse_eigenvectors() * z0_.cast<std::complex<double>>();
    const auto& reps = flow.representatives();
    const auto K = static_cast<Eigen::Index>(reps.size());
    const Eigen::Index rows = functionals.count();
    lambda_.resize(K);
    modulus_.resize(K);
    coefficients_.resize(rows, K);
    curvature_.resize(rows, K);
    cache_e_.resize(K, cache_slots);
    cache_growth_.resize(K, cache_slots);
    for (Eigen::Index r = 0; r < K; ++r) {
      const Eigen::Index k = reps[static_cast<std::size_t>(r)];
      lambda_(r) = flow.eigenvalues()(k);
      modulus_(r) = std::abs(lambda_(r));
      const double w = flow.weights()[static_cast<std::size_t>(r)];
      for (Eigen::Index i = 0; i < rows; ++i) {
        coefficients_(i, r) = w * functionals.modal_rows()(i, k) * modal_(k);
        curvature_(i, r) = std::abs(coefficients_(i, r)) * std::norm(lambda_(r));
      }
    }
  }
}

const Eigen::VectorXd& Segment::exponential_state(double tau) const {
  if (!(tau == cached_tau_)) {
    cached_z_ = functionals_->flow().transition_matrix(tau) * z0_;
    cached_tau_ = tau;
  }
  return cached_z_;
}

const std::complex<double>* Segment::exponentials(double tau) const {
  for (int c = 0; c < cache_slots; ++c)
    if (cache_tau_[c] == tau) return &cache_e_(0, c);
  const int c = cache_next_;
  cache_next_ = (cache_next_ + 1) % cache_slots;
  cache_tau_[c] = tau;
  // e^{λτ} = e^{Re λ τ} (cos Im λ τ + i sin Im λ τ), with the real (damped modes without
  // oscillation, the constant) and the purely imaginary (the forcing) cases taking one call.
  for (Eigen::Index r = 0; r < lambda_.size(); ++r) {
    const double re = lambda_(r).real() * tau, im = lambda_(r).imag() * tau;
    const double growth = re == 0.0 ? 1.0 : std::exp(re);
    cache_growth_(r, c) = growth;
    if (im == 0.0) {
      cache_e_(r, c) = {growth, 0.0};
    } else {
      const double cs = std::cos(im), sn = std::sin(im);
      cache_e_(r, c) = {growth * cs, growth * sn};
    }
  }
  return &cache_e_(0, c);
}

const double* Segment::cached_growth(double tau) const {
  for (int c = 0; c < cache_slots; ++c)
    if (cache_tau_[c] == tau) return &cache_growth_(0, c);
  return nullptr;
}

double Segment::value(Eigen::Index i, double tau, int derivative) const {
  const LinearFlow& flow = functionals_->flow();
  if (flow.method() == LinearFlow::Method::spectral) {
    const std::complex<double>* e = exponentials(tau);
    double sum = 0.0;
    for (Eigen::Index r = 0; r < lambda_.size(); ++r) {
      std::complex<double> term = coefficients_(i, r) * e[r];
      for (int d = 0; d < derivative; ++d) term *= lambda_(r);
      sum += term.real();
    }
    return sum;
  }
  return functionals_->rows(derivative).row(i).dot(exponential_state(tau));
}

std::pair<double, double> Segment::value_and_slope(Eigen::Index i, double tau) const {
  const LinearFlow& flow = functionals_->flow();
  if (flow.method() == LinearFlow::Method::spectral) {
    const std::complex<double>* e = exponentials(tau);
    double h = 0.0, dh = 0.0;
    for (Eigen::Index r = 0; r < lambda_.size(); ++r) {
      const std::complex<double> term = coefficients_(i, r) * e[r];
      h += term.real();
      dh += (term * lambda_(r)).real();
    }
    return {h, dh};
  }
  const Eigen::VectorXd& z = exponential_state(tau);
  return {functionals_->rows(0).row(i).dot(z), functionals_->rows(1).row(i).dot(z)};
}

double Segment::second_derivative_bound(Eigen::Index i, double a, double b) const {
  const LinearFlow& flow = functionals_->flow();
  if (flow.method() == LinearFlow::Method::spectral) {
    // max over [a, b] of e^{Re λ τ} is at a (Re λ < 0) or b (Re λ > 0); the values at the
    // interval ends are usually in the exponentials' cache already (the search evaluated h there).
    const double* ga = cached_growth(a);
    const double* gb = cached_growth(b);
    double bound = 0.0;
    for (Eigen::Index r = 0; r < lambda_.size(); ++r) {
      const double re = lambda_(r).real();
      double growth = 1.0;
      if (re < 0.0) growth = ga ? ga[r] : std::exp(re * a);
      else if (re > 0.0) growth = gb ? gb[r] : std::exp(re * b);
      bound += curvature_(i, r) * growth;
    }
    return bound * (1.0 + 1e-12);
  }
  // Two rigorous bounds, in the 2-norm and in the scaled norm ‖D·‖ (flow.hpp); the scaled one
  // stays finite for stiff systems, whose 2-norm log norm ~ ‖M⁻¹K‖ overflows e^{μ (b - a)}.
  const Eigen::VectorXd& z = exponential_state(a);
  const auto& row = functionals_->rows(2).row(i);
  const Eigen::Index n = flow.dof();
  const double s = flow.position_scale();
  auto bound = [&](double row_norm, double z_norm, double mu) {  // 0 · ∞ is 0 here
    return row_norm == 0.0 || z_norm == 0.0 ? 0.0
                                            : row_norm * z_norm * std::exp(std::max(0.0, mu * (b - a)));
  };
  const double plain = bound(row.norm(), z.norm(), flow.log_norm());
  const double scaled = bound(
      std::sqrt(row.head(n).squaredNorm() / (s * s) + row.tail(row.size() - n).squaredNorm()),
      std::sqrt(s * s * z.head(n).squaredNorm() + z.tail(z.size() - n).squaredNorm()),
      flow.scaled_log_norm());
  return std::fmin(plain, scaled) * (1.0 + 1e-12);
}

double Segment::third_derivative_bound(Eigen::Index i, double a, double b) const {
  const LinearFlow& flow = functionals_->flow();
  if (flow.method() != LinearFlow::Method::spectral) return std::numeric_limits<double>::infinity();
  const double* ga = cached_growth(a);
  const double* gb = cached_growth(b);
  double bound = 0.0;
  for (Eigen::Index r = 0; r < lambda_.size(); ++r) {
    const double re = lambda_(r).real();
    double growth = 1.0;
    if (re < 0.0) growth = ga ? ga[r] : std::exp(re * a);
    else if (re > 0.0) growth = gb ? gb[r] : std::exp(re * b);
    bound += curvature_(i, r) * modulus_(r) * growth;
  }
  return bound * (1.0 + 1e-12);
}

void Segment::state(double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  const LinearFlow& flow = functionals_->flow();
  if (flow.method() == LinearFlow::Method::spectral) {
    // Σₖ V(:, k) (V⁻¹z0)ₖ e^{λₖτ}, written out so that nothing is allocated.
    scratch_.resize(modal_.size());
    for (Eigen::Index k = 0; k < modal_.size(); ++k) scratch_(k) = modal_(k) * std::exp(flow.eigenvalues()(k) * tau);
    const Eigen::MatrixXcd& V = flow.eigenvectors();
    for (Eigen::Index i = 0; i < out.size(); ++i) {
      double sum = 0.0;
      for (Eigen::Index k = 0; k < V.cols(); ++k) sum += (V(i, k) * scratch_(k)).real();
      out(i) = sum;
    }
  } else {
    out = exponential_state(tau);
  }
}

}  // namespace vibro
