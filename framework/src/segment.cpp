// Functionals and Segment (flow.hpp): rows of one LinearFlow evaluated along one segment of its
// motion, for the certified event search (values, slopes, derivative bounds) and the observers'
// states. The flow itself (generator, spectral terms, Schur clusters, transition matrices) is
// flow.cpp.
#include "vibro/flow.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace vibro {

Functionals::Functionals(const LinearFlow& flow, Eigen::MatrixXd rows) : flow_(&flow) {
  rows_[0] = std::move(rows);
  for (int d = 1; d < 4; ++d) rows_[d] = rows_[d - 1] * flow.generator();
  if (flow.closed_form()) {
    modal_rows_ = rows_[0].cast<std::complex<double>>() * flow.basis();
  } else {
    // Padé path's bounds (flow.hpp): ‖ℓᵢᵀÂᵈ‖₂ and ‖ℓᵢᵀÂᵈD⁻¹‖₂ for d = 2, 3.
    const Eigen::Index n = flow.dof();
    const double s = flow.position_scale();
    row_norms_.resize(count(), 4);
    for (Eigen::Index i = 0; i < count(); ++i)
      for (int k = 0; k < 2; ++k) {
        const auto& row = rows_[2 + k].row(i);
        row_norms_(i, 2 * k) = row.norm();
        row_norms_(i, 2 * k + 1) =
            std::sqrt(row.head(n).squaredNorm() / (s * s) + row.tail(row.size() - n).squaredNorm());
      }
  }
}

Segment::Segment(const Functionals& functionals, double t0,
                 const Eigen::Ref<const Eigen::VectorXd>& z0)
    : functionals_(&functionals), t0_(t0), cached_tau_(std::numeric_limits<double>::quiet_NaN()) {
  reset(t0, z0);
}

void Segment::reset(double t0, const Eigen::Ref<const Eigen::VectorXd>& z0) {
  using C = std::complex<double>;
  const Functionals& functionals = *functionals_;
  t0_ = t0;
  z0_ = z0;  // same size: no allocation
  tabulated_ = nullptr;  // evaluate()'s table is of the previous start
  cached_tau_ = std::numeric_limits<double>::quiet_NaN();
  for (double& tau : cache_tau_) tau = std::numeric_limits<double>::quiet_NaN();
  for (bool& direct : cache_direct_) direct = false;
  cache_next_ = 0;
  const LinearFlow& flow = functionals.flow();
  if (!flow.closed_form()) return;
  const auto& terms = flow.terms();
  const auto K = static_cast<Eigen::Index>(terms.size());
  const Eigen::Index rows = functionals.count();
  const Eigen::MatrixXcd& Vinv = flow.inverse_basis();
  const Eigen::MatrixXcd& modal_rows = functionals.modal_rows();
  if (offset_.size() != static_cast<std::size_t>(K)) {
    // Layout (once per Segment): per term r, degree_r + 1 coefficient columns (powers of τ).
    offset_.resize(static_cast<std::size_t>(K));
    width_ = 0;
    Eigen::Index state_width = 0;
    polynomial_ = false;
    for (Eigen::Index r = 0; r < K; ++r) {
      const auto& term = terms[static_cast<std::size_t>(r)];
      offset_[static_cast<std::size_t>(r)] = width_;
      width_ += term.degree + 1;
      state_width += term.size * (term.degree + 1);
      polynomial_ = polynomial_ || term.degree > 0;
    }
    modal_.resize(flow.size());
    powers_.resize(state_width, 1);
    for (int d = 0; d < 4; ++d) coefficients_[d].resize(rows, width_);
    for (auto& m : moduli_) m.resize(rows, width_);
    rate_ = 0.0;
    for (const auto& term : terms) rate_ = std::max(rate_, std::abs(term.lambda));
    cache_e_.resize(K, cache_slots);
    cache_growth_.resize(K, cache_slots);
    unstored_e_.resize(K);
    unstored_growth_.resize(K);
    scratch_.resize(flow.size());
  }
  magnitude_.setZero(rows);
  if (!polynomial_) {
    // Spectral (every term a single eigenvalue): αᵢᵣ = w_r (ℓᵢᵀV)_k (V⁻¹z0)_k, αᵈ = α λᵈ,
    // the moduli |α| |λ|², |α| |λ|³; complex products written out (no library call per term).
    for (Eigen::Index r = 0; r < K; ++r) {
      const auto& term = terms[static_cast<std::size_t>(r)];
      const Eigen::Index k = term.column;
      double yr = 0.0, yi = 0.0;
      for (Eigen::Index j = 0; j < z0_.size(); ++j) {
        yr += Vinv(k, j).real() * z0_(j);
        yi += Vinv(k, j).imag() * z0_(j);
      }
      modal_(k) = {yr, yi};
      yr *= term.weight;
      yi *= term.weight;
      powers_(r) = {yr, yi};
      const double lr = term.lambda.real(), li = term.lambda.imag();
      const double l2 = lr * lr + li * li, l1 = std::sqrt(l2);
      for (Eigen::Index i = 0; i < rows; ++i) {
        const double mr = modal_rows(i, k).real(), mi = modal_rows(i, k).imag();
        double ar = mr * yr - mi * yi, ai = mr * yi + mi * yr;
        const double modulus = std::sqrt(ar * ar + ai * ai);
        coefficients_[0](i, r) = {ar, ai};
        for (int d = 1; d < 4; ++d) {
          const double br = ar * lr - ai * li, bi = ar * li + ai * lr;
          ar = br;
          ai = bi;
          coefficients_[d](i, r) = {ar, ai};
        }
        moduli_[0](i, r) = modulus * l2;
        moduli_[1](i, r) = modulus * l2 * l1;
        magnitude_(i) += modulus;
      }
    }
    return;
  }
  Eigen::Index at = 0;  // position in powers_
  for (Eigen::Index r = 0; r < K; ++r) {
    const auto& term = terms[static_cast<std::size_t>(r)];
    const Eigen::Index o = term.column, m = term.size, w = offset_[static_cast<std::size_t>(r)];
    for (Eigen::Index j = o; j < o + m; ++j) {
      C sum = 0.0;
      for (Eigen::Index k = 0; k < z0_.size(); ++k) sum += Vinv(j, k) * z0_(k);
      modal_(j) = sum;
    }
    // y_p = w_r E_r^p y / p! (the state's coefficients), α_{i,p} = (ℓᵢᵀV)_r y_p.
    for (Eigen::Index q = 0; q < m; ++q) powers_(at + q) = term.weight * modal_(o + q);
    for (int p = 0; p <= term.degree; ++p) {
      const Eigen::Index here = at + p * m;
      if (p > 0) {
        const auto& E = flow.cluster_parts();
        for (Eigen::Index q = 0; q < m; ++q) {
          C sum = 0.0;
          for (Eigen::Index l = q; l < m; ++l) sum += E(o + q, o + l) * powers_(here - m + l);
          powers_(here + q) = sum / static_cast<double>(p);
        }
      }
      for (Eigen::Index i = 0; i < rows; ++i) {
        C sum = 0.0;
        for (Eigen::Index q = 0; q < m; ++q) sum += modal_rows(i, o + q) * powers_(here + q);
        coefficients_[0](i, w + p) = sum;
      }
    }
    // αᵈ⁺¹_p = λ αᵈ_p + (p + 1) αᵈ_{p+1}.
    for (int d = 1; d < 4; ++d)
      for (Eigen::Index i = 0; i < rows; ++i)
        for (int p = 0; p <= term.degree; ++p) {
          C next = term.lambda * coefficients_[d - 1](i, w + p);
          if (p < term.degree) next += static_cast<double>(p + 1) * coefficients_[d - 1](i, w + p + 1);
          coefficients_[d](i, w + p) = next;
        }
    at += m * (term.degree + 1);
  }
  for (int k = 0; k < 2; ++k)
    for (Eigen::Index i = 0; i < rows; ++i)
      for (Eigen::Index c = 0; c < width_; ++c) {
        const C a = coefficients_[2 + k](i, c);
        moduli_[k](i, c) = std::sqrt(a.real() * a.real() + a.imag() * a.imag());
      }
  for (Eigen::Index i = 0; i < rows; ++i) magnitude_(i) = coefficients_[0].row(i).cwiseAbs().sum();
}

double Segment::magnitude(Eigen::Index i) const {
  if (functionals_->flow().closed_form()) return magnitude_(i);
  return functionals_->rows(0).row(i).norm() * z0_.norm();
}

const Eigen::VectorXd& Segment::pade_state(double tau) const {
  if (!(tau == cached_tau_)) {
    ++evaluations_;
    cached_z_ = functionals_->flow().transition_matrix(tau) * z0_;
    cached_tau_ = tau;
  }
  return cached_z_;
}

namespace {

/// Short steps (Segment::fill_exponentials): e^z for |z| ≤ 2⁻⁵ by its Taylor polynomial of
/// degree 8, whose tail is below 1.04 |z|⁹/9! ≤ 8e-20 (and |e^z| ≥ e^{-1/32}): the value right
/// to about an ulp, as exp and sincos give it.
constexpr double kSeriesReach = 0x1p-5;
/// 1/k!, k = 0…8.
constexpr double kFactorial[9] = {1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320};

/// e^{λᵣτ} = e^{Re λᵣτ} (cos Im λᵣτ + i sin Im λᵣτ) for every term by exp and sincos, with the
/// real (damped modes without oscillation, the constant) and the purely imaginary (the forcing)
/// cases taking one call; growth (if not null) |e^{λᵣτ}|. The one direct formula of the segment's
/// exponentials, for the search (fill_exponentials) and the observers' states (evaluate). At
/// `count` times tau[j] at once (term by term, so that each term's case is settled once), into
/// e[r + j·K] and growth[r + j·K], K the number of terms: each value as at one time alone.
void direct_exponentials(const std::vector<LinearFlow::Term>& terms, const double* tau, Eigen::Index count,
                         std::complex<double>* e, double* growth) {
  const auto K = static_cast<Eigen::Index>(terms.size());
  for (Eigen::Index r = 0; r < K; ++r) {
    const std::complex<double> lambda = terms[static_cast<std::size_t>(r)].lambda;
    for (Eigen::Index j = 0; j < count; ++j) {
      const double re = lambda.real() * tau[j], im = lambda.imag() * tau[j];
      const double g = re == 0.0 ? 1.0 : std::exp(re);
      if (growth) growth[r + j * K] = g;
      if (im == 0.0) {
        e[r + j * K] = {g, 0.0};
      } else {
        const double cs = std::cos(im), sn = std::sin(im);
        e[r + j * K] = {g * cs, g * sn};
      }
    }
  }
}

}  // namespace

void Segment::fill_exponentials(double tau, std::complex<double>* e, double* growth, bool* direct) const {
  ++evaluations_;
  const auto& terms = functionals_->flow().terms();
  // The event search evaluates mostly near points it has just evaluated (the root refinement's
  // iterates converge on a point already sampled) or near the start (the flights of a chatter
  // sequence): from the nearest such base b — τ = 0, where e = 1 exactly, or a cached τ whose
  // exponentials were computed directly — e^{λτ} = e^{λb} e^{λ(τ - b)} with the second factor
  // a short series (above) when |λ(τ - b)| ≤ 2⁻⁵ for every term: a few complex products
  // instead of one exp and one sincos per term. Only directly computed values serve as bases,
  // so no chain of products builds up: each value is within a few ulps.
  double delta = tau;
  int base = -1;
  for (int c = 0; c < cache_slots; ++c)
    if (cache_direct_[c] && std::abs(tau - cache_tau_[c]) < std::abs(delta)) {
      delta = tau - cache_tau_[c];
      base = c;
    }
  const double reach = rate_ * std::abs(delta);
  if (reach <= kSeriesReach) {
    for (std::size_t r = 0; r < terms.size(); ++r) {
      const double zr = terms[r].lambda.real() * delta, zi = terms[r].lambda.imag() * delta;
      // Σ_{k≤8} zᵏ/k! by Estrin's scheme (pairs c_k + c_{k+1} z, combined with z², z⁴, z⁸):
      // three complex products deep instead of Horner's eight.
      const double z2r = zr * zr - zi * zi, z2i = 2.0 * zr * zi;
      const double z4r = z2r * z2r - z2i * z2i, z4i = 2.0 * z2r * z2i;
      const double z8r = z4r * z4r - z4i * z4i, z8i = 2.0 * z4r * z4i;
      const double p01r = 1.0 + zr, p01i = zi;
      const double p23r = kFactorial[2] + kFactorial[3] * zr, p23i = kFactorial[3] * zi;
      const double p45r = kFactorial[4] + kFactorial[5] * zr, p45i = kFactorial[5] * zi;
      const double p67r = kFactorial[6] + kFactorial[7] * zr, p67i = kFactorial[7] * zi;
      const double q0r = p01r + (z2r * p23r - z2i * p23i), q0i = p01i + (z2r * p23i + z2i * p23r);
      const double q1r = p45r + (z2r * p67r - z2i * p67i), q1i = p45i + (z2r * p67i + z2i * p67r);
      const double pr = q0r + (z4r * q1r - z4i * q1i) + kFactorial[8] * z8r;
      const double pi = q0i + (z4r * q1i + z4i * q1r) + kFactorial[8] * z8i;
      // e^{Re z} the same way, in reals.
      const double x2 = zr * zr, x4 = x2 * x2;
      const double g = (1.0 + zr) + x2 * (kFactorial[2] + kFactorial[3] * zr) +
                       x4 * ((kFactorial[4] + kFactorial[5] * zr) + x2 * (kFactorial[6] + kFactorial[7] * zr)) +
                       kFactorial[8] * x4 * x4;
      if (base >= 0) {
        const std::complex<double> b = cache_e_(static_cast<Eigen::Index>(r), base);
        e[r] = {b.real() * pr - b.imag() * pi, b.real() * pi + b.imag() * pr};
        growth[r] = cache_growth_(static_cast<Eigen::Index>(r), base) * g;
      } else {
        e[r] = {pr, pi};
        growth[r] = g;
      }
    }
    *direct = base < 0;
    return;
  }
  direct_exponentials(terms, &tau, 1, e, growth);
  *direct = true;
}

int Segment::store_exponentials(double tau) const {
  for (int c = 0; c < cache_slots; ++c)
    if (cache_tau_[c] == tau) return c;
  if (cache_next_ == pinned_) cache_next_ = (cache_next_ + 1) % cache_slots;
  const int c = cache_next_;
  cache_next_ = (cache_next_ + 1) % cache_slots;
  bool direct = false;
  fill_exponentials(tau, &cache_e_(0, c), &cache_growth_(0, c), &direct);
  cache_tau_[c] = tau;  // after the fill: the slot must not serve as its own base
  cache_direct_[c] = direct;
  return c;
}

const std::complex<double>* Segment::exponentials(double tau) const {
  return &cache_e_(0, store_exponentials(tau));
}

double Segment::row_value(Eigen::Index i, int derivative, double tau, const std::complex<double>* e) const {
  const Eigen::MatrixXcd& a = coefficients_[derivative];
  const auto K = static_cast<Eigen::Index>(offset_.size());
  double sum = 0.0;
  if (!polynomial_) {
    for (Eigen::Index r = 0; r < K; ++r) {
      const std::complex<double> c = a(i, r);
      sum += c.real() * e[r].real() - c.imag() * e[r].imag();
    }
    return sum;
  }
  const auto& terms = functionals_->flow().terms();
  for (Eigen::Index r = 0; r < K; ++r) {
    const Eigen::Index w = offset_[static_cast<std::size_t>(r)];
    std::complex<double> poly = a(i, w + terms[static_cast<std::size_t>(r)].degree);
    for (int p = terms[static_cast<std::size_t>(r)].degree - 1; p >= 0; --p) poly = poly * tau + a(i, w + p);
    sum += poly.real() * e[r].real() - poly.imag() * e[r].imag();
  }
  return sum;
}

double Segment::value(Eigen::Index i, double tau, int derivative) const {
  ++guard_evaluations_;
  if (functionals_->flow().closed_form()) return row_value(i, derivative, tau, exponentials(tau));
  return functionals_->rows(derivative).row(i).dot(pade_state(tau));
}

std::pair<double, double> Segment::value_and_slope(Eigen::Index i, double tau) const {
  ++guard_evaluations_;
  if (functionals_->flow().closed_form()) {
    const std::complex<double>* e = exponentials(tau);
    return {row_value(i, 0, tau, e), row_value(i, 1, tau, e)};
  }
  const Eigen::VectorXd& z = pade_state(tau);
  return {functionals_->rows(0).row(i).dot(z), functionals_->rows(1).row(i).dot(z)};
}

void Segment::row_jet(Eigen::Index i, double tau, double* h, double* d, double* c) const {
  ++guard_evaluations_;
  if (functionals_->flow().closed_form()) {
    const std::complex<double>* e = exponentials(tau);
    *h = row_value(i, 0, tau, e);
    *d = row_value(i, 1, tau, e);
    *c = row_value(i, 2, tau, e);
    return;
  }
  const Eigen::VectorXd& z = pade_state(tau);
  *h = functionals_->rows(0).row(i).dot(z);
  *d = functionals_->rows(1).row(i).dot(z);
  *c = functionals_->rows(2).row(i).dot(z);
}

void Segment::sample(double tau, SegmentSample& out) const {
  const Eigen::Index rows = functionals_->count();
  const LinearFlow& flow = functionals_->flow();
  out.tau = tau;
  out.h.resize(rows);
  out.d.resize(rows);
  out.c.resize(rows);
  if (flow.closed_form()) {
    const auto K = static_cast<Eigen::Index>(offset_.size());
    out.e.resize(K);
    out.growth.resize(K);
    // Through the cache (e.g. the root the finder just refined is there), so that later points
    // near this one can start from it (fill_exponentials).
    const int slot = store_exponentials(tau);
    out.e = cache_e_.col(slot);
    out.growth = cache_growth_.col(slot);
    guard_evaluations_ += rows;
    if (!polynomial_) {
      for (Eigen::Index i = 0; i < rows; ++i) {
        double h = 0.0, d = 0.0, c = 0.0;
        for (Eigen::Index r = 0; r < K; ++r) {
          const double er = out.e(r).real(), ei = out.e(r).imag();
          const std::complex<double> a0 = coefficients_[0](i, r), a1 = coefficients_[1](i, r),
                                     a2 = coefficients_[2](i, r);
          h += a0.real() * er - a0.imag() * ei;
          d += a1.real() * er - a1.imag() * ei;
          c += a2.real() * er - a2.imag() * ei;
        }
        out.h(i) = h;
        out.d(i) = d;
        out.c(i) = c;
      }
      return;
    }
    for (Eigen::Index i = 0; i < rows; ++i) {
      out.h(i) = row_value(i, 0, tau, out.e.data());
      out.d(i) = row_value(i, 1, tau, out.e.data());
      out.c(i) = row_value(i, 2, tau, out.e.data());
    }
    return;
  }
  const Eigen::VectorXd& z = pade_state(tau);
  guard_evaluations_ += rows;
  out.h.noalias() = functionals_->rows(0) * z;
  out.d.noalias() = functionals_->rows(1) * z;
  out.c.noalias() = functionals_->rows(2) * z;
  const Eigen::Index n = flow.dof();
  const double s = flow.position_scale();
  out.growth.resize(2);
  out.growth(0) = z.norm();
  out.growth(1) = std::sqrt(s * s * z.head(n).squaredNorm() + z.tail(z.size() - n).squaredNorm());
}

double Segment::pade_bound(int derivative, Eigen::Index i, double z_norm, double dz_norm, double length) const {
  // Two rigorous bounds, in the 2-norm and in the scaled norm ‖D·‖ (flow.hpp); the scaled one
  // stays finite for stiff systems, whose 2-norm log norm ~ ‖M⁻¹K‖ overflows e^{μ (b - a)}.
  const LinearFlow& flow = functionals_->flow();
  const auto& norms = functionals_->row_norms();
  const int k = derivative - 2;
  auto bound = [&](double row_norm, double norm, double mu) {  // 0 · ∞ is 0 here
    return row_norm == 0.0 || norm == 0.0 ? 0.0 : row_norm * norm * std::exp(std::max(0.0, mu * length));
  };
  const double plain = bound(norms(i, 2 * k), z_norm, flow.log_norm());
  const double scaled = bound(norms(i, 2 * k + 1), dz_norm, flow.scaled_log_norm());
  return std::fmin(plain, scaled) * (1.0 + 1e-12);
}

double Segment::closed_form_bound(int derivative, Eigen::Index i, double a, double b, const double* ga,
                                  const double* gb) const {
  // max over [a, b] of |e^{λτ}| is at one end; of τ^p (τ ≥ 0) at the end farther from 0.
  const Eigen::MatrixXd& mod = moduli_[derivative - 2];
  const auto K = static_cast<Eigen::Index>(offset_.size());
  double bound = 0.0;
  if (!polynomial_) {
    for (Eigen::Index r = 0; r < K; ++r) bound += mod(i, r) * std::max(ga[r], gb[r]);
    return bound * (1.0 + 1e-12);
  }
  const auto& terms = functionals_->flow().terms();
  const double t = std::max(std::abs(a), std::abs(b));
  for (Eigen::Index r = 0; r < K; ++r) {
    const Eigen::Index w = offset_[static_cast<std::size_t>(r)];
    double poly = mod(i, w + terms[static_cast<std::size_t>(r)].degree);
    for (int p = terms[static_cast<std::size_t>(r)].degree - 1; p >= 0; --p) poly = poly * t + mod(i, w + p);
    bound += poly * std::max(ga[r], gb[r]);
  }
  return bound * (1.0 + 1e-12);
}

double Segment::derivative_bound(int derivative, Eigen::Index i, const SegmentSample& a,
                                 const SegmentSample& b) const {
  if (!functionals_->flow().closed_form())
    return pade_bound(derivative, i, a.growth(0), a.growth(1), b.tau - a.tau);
  return closed_form_bound(derivative, i, a.tau, b.tau, a.growth.data(), b.growth.data());
}

double Segment::bound_between(int derivative, Eigen::Index i, double a, double b) const {
  if (functionals_->flow().closed_form()) {
    // Two cache slots; the first is pinned while the second is looked up.
    const int sa = store_exponentials(a);
    pinned_ = sa;
    const int sb = store_exponentials(b);
    pinned_ = -1;
    return closed_form_bound(derivative, i, a, b, &cache_growth_(0, sa), &cache_growth_(0, sb));
  }
  const Eigen::VectorXd& z = pade_state(a);
  const LinearFlow& flow = functionals_->flow();
  const Eigen::Index n = flow.dof();
  const double s = flow.position_scale();
  return pade_bound(derivative, i, z.norm(),
                    std::sqrt(s * s * z.head(n).squaredNorm() + z.tail(z.size() - n).squaredNorm()), b - a);
}

double Segment::second_derivative_bound(Eigen::Index i, double a, double b) const {
  return bound_between(2, i, a, b);
}

double Segment::third_derivative_bound(Eigen::Index i, double a, double b) const {
  return bound_between(3, i, a, b);
}

void Segment::closed_form_state(double tau, const std::complex<double>* e, Eigen::Ref<Eigen::VectorXd> out) const {
  // z(τ) = Re Σ_r V_r e^{λ_r τ} Σ_p τ^p y_{r,p}, written out so that nothing is allocated.
  const LinearFlow& flow = functionals_->flow();
  const auto& terms = flow.terms();
  const Eigen::MatrixXcd& V = flow.basis();
  if (!polynomial_) {  // spectral: one column of V per term, its coefficient w_r (V⁻¹z0)_k e^{λτ}
    const auto K = static_cast<Eigen::Index>(terms.size());
    for (Eigen::Index r = 0; r < K; ++r) {
      const std::complex<double> y = powers_(r);
      scratch_(r) = {y.real() * e[r].real() - y.imag() * e[r].imag(), y.real() * e[r].imag() + y.imag() * e[r].real()};
    }
    for (Eigen::Index i = 0; i < out.size(); ++i) {
      double sum = 0.0;
      for (Eigen::Index r = 0; r < K; ++r) {
        const std::complex<double> vr = V(i, terms[static_cast<std::size_t>(r)].column);
        sum += vr.real() * scratch_(r).real() - vr.imag() * scratch_(r).imag();
      }
      out(i) = sum;
    }
    return;
  }
  Eigen::Index at = 0;
  for (std::size_t r = 0; r < terms.size(); ++r) {
    const Eigen::Index o = terms[r].column, m = terms[r].size;
    const int degree = terms[r].degree;
    for (Eigen::Index q = 0; q < m; ++q) {
      std::complex<double> poly = powers_(at + degree * m + q);
      for (int p = degree - 1; p >= 0; --p) poly = poly * tau + powers_(at + p * m + q);
      scratch_(o + q) = poly * e[r];
    }
    at += m * (degree + 1);
  }
  for (Eigen::Index i = 0; i < out.size(); ++i) {
    double sum = 0.0;
    for (const auto& term : terms)
      for (Eigen::Index j = term.column; j < term.column + term.size; ++j)
        sum += V(i, j).real() * scratch_(j).real() - V(i, j).imag() * scratch_(j).imag();
    out(i) = sum;
  }
}

void Segment::state(const SegmentSample& s, Eigen::Ref<Eigen::VectorXd> out) const {
  if (!functionals_->flow().closed_form()) {
    out = pade_state(s.tau);
    return;
  }
  closed_form_state(s.tau, s.e.data(), out);
}

void Segment::state(double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  if (!functionals_->flow().closed_form()) {
    out = pade_state(tau);
    return;
  }
  closed_form_state(tau, exponentials(tau), out);
}

void Segment::state_unstored(double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  if (!functionals_->flow().closed_form()) {
    out = pade_state(tau);  // a memo of one z(τ): the same values whether it holds τ or not
    return;
  }
  for (int c = 0; c < cache_slots; ++c)
    if (cache_tau_[c] == tau) {
      closed_form_state(tau, &cache_e_(0, c), out);
      return;
    }
  bool direct = false;  // as store_exponentials() would fill a slot, from the same bases
  fill_exponentials(tau, unstored_e_.data(), unstored_growth_.data(), &direct);
  closed_form_state(tau, unstored_e_.data(), out);
}

// --- evaluate(): other rows of the same flow, tabulated once per segment ----------------------

namespace {

/// Times evaluate() takes side by side: independent sums that overlap in the pipeline (and
/// pair up in vector registers) instead of one chain of dependent products per time.
constexpr Eigen::Index kEvaluateLanes = 8;

/// Where evaluate() writes row i of column k: top(i, k) for i < split, else bottom(i - split, k).
struct RowOutput {
  Eigen::Index split;
  double* top;
  Eigen::Index top_stride;
  double* bottom;
  Eigen::Index bottom_stride;
  /// Row i of column k, and the step from one column to the next.
  double* row(Eigen::Index i, Eigen::Index k) const {
    return i < split ? top + i + k * top_stride : bottom + (i - split) + k * bottom_stride;
  }
  Eigen::Index stride(Eigen::Index i) const { return i < split ? top_stride : bottom_stride; }
};

/// Columns k, …, k + L - 1 of evaluate(): row i at tau[j] is Σᵣ Re(e^{λᵣτ} Σₚ αᵢᵣₚ τ^p), each
/// polynomial by Horner's rule, written out (the tables are small in most modes, a few terms of
/// low degree, where a library product costs more in set-up than in arithmetic). `e` holds
/// e^{λᵣτ_j} at r + j·K. Each time gets the same operations in the same order whatever L, so a
/// column is bit for bit the same in a batch or alone. `Unit`: every λᵣ is 0 (a polynomial
/// flow: free masses under constant forces), so e^{λᵣτ} = 1 and `e` is not read; the sums are
/// the same, x · 1 being x.
template <Eigen::Index L, bool Unit>
void table_row_sums(const std::vector<LinearFlow::Term>& terms, const Eigen::MatrixXd& table, const double* tau,
                    const std::complex<double>* e, const RowOutput& out, Eigen::Index k) {
  const auto K = static_cast<Eigen::Index>(terms.size());
  const double* a = table.data();  // one column per row, in tabulate()'s layout
  for (Eigen::Index i = 0; i < table.cols(); ++i) {
    double sum[L] = {};
    for (Eigen::Index r = 0; r < K; ++r) {
      const int degree = terms[static_cast<std::size_t>(r)].degree;
      if (terms[static_cast<std::size_t>(r)].lambda.imag() == 0.0) {
        double poly[L];
        for (Eigen::Index j = 0; j < L; ++j) poly[j] = a[degree];
        for (int p = degree - 1; p >= 0; --p)
          for (Eigen::Index j = 0; j < L; ++j) poly[j] = poly[j] * tau[j] + a[p];
        for (Eigen::Index j = 0; j < L; ++j) sum[j] += Unit ? poly[j] : poly[j] * e[r + j * K].real();
        a += degree + 1;
      } else {  // (Re α, -Im α) pairs: Re(α e) = Re α Re e + (-Im α) Im e
        double pr[L], pi[L];
        for (Eigen::Index j = 0; j < L; ++j) {
          pr[j] = a[2 * degree];
          pi[j] = a[2 * degree + 1];
        }
        for (int p = degree - 1; p >= 0; --p)
          for (Eigen::Index j = 0; j < L; ++j) {
            pr[j] = pr[j] * tau[j] + a[2 * p];
            pi[j] = pi[j] * tau[j] + a[2 * p + 1];
          }
        for (Eigen::Index j = 0; j < L; ++j) sum[j] += pr[j] * e[r + j * K].real() + pi[j] * e[r + j * K].imag();
        a += 2 * (degree + 1);
      }
    }
    double* const row = out.row(i, k);
    const Eigen::Index stride = out.stride(i);
    for (Eigen::Index j = 0; j < L; ++j) row[j * stride] = sum[j];
  }
}

}  // namespace


void Segment::tabulate(const Functionals& other) const {
  // αᵢᵣₚ = (ℓᵢᵀV)_r y_rp with y_rp the state's own coefficients (powers_), the product reset()
  // forms for the segment's own rows; a spectral term is the case m = 1, degree 0. Per row, per
  // term, per power: Re α, then -Im α only where Im λᵣ ≠ 0 (for a real λ, e^{λτ}τ^p is real and
  // Im α is not needed). One column per row, so that evaluate() reads each row's coefficients
  // in order.
  const auto& terms = functionals_->flow().terms();
  const Eigen::MatrixXcd& modal_rows = other.modal_rows();
  const Eigen::Index rows = other.count();
  Eigen::Index width = 0;
  for (const auto& term : terms) width += (term.lambda.imag() != 0.0 ? 2 : 1) * (term.degree + 1);
  table_.resize(width, rows);
  table_e_.resize(static_cast<Eigen::Index>(terms.size()) * kEvaluateLanes);
  Eigen::Index at = 0, k = 0;  // at: position in powers_ (per term, per power p, m entries)
  for (const auto& term : terms) {
    const bool complex = term.lambda.imag() != 0.0;
    for (int p = 0; p <= term.degree; ++p, at += term.size) {
      for (Eigen::Index i = 0; i < rows; ++i) {
        std::complex<double> sum = 0.0;
        for (Eigen::Index q = 0; q < term.size; ++q) sum += modal_rows(i, term.column + q) * powers_(at + q);
        table_(k, i) = sum.real();
        if (complex) table_(k + 1, i) = -sum.imag();
      }
      k += complex ? 2 : 1;
    }
  }
  tabulated_ = &other;
}

void Segment::evaluate(const Functionals& other, double tau, Eigen::Ref<Eigen::VectorXd> out) const {
  Eigen::Map<Eigen::MatrixXd> all(out.data(), out.size(), 1), none(out.data(), 0, 1);
  evaluate(other, &tau, 1, 0.0, all, none);  // τ - 0.0 is τ, bit for bit
}

void Segment::evaluate(const Functionals& other, const double* t, Eigen::Index count, double origin,
                       Eigen::Ref<Eigen::MatrixXd> top, Eigen::Ref<Eigen::MatrixXd> bottom) const {
  const Eigen::Index split = top.rows();
  if (!functionals_->flow().closed_form()) {
    rows_out_.resize(other.count());
    for (Eigen::Index k = 0; k < count; ++k) {
      rows_out_.noalias() = other.rows(0) * pade_state(t[k] - origin);
      top.col(k) = rows_out_.head(split);
      bottom.col(k) = rows_out_.tail(other.count() - split);
    }
    return;
  }
  if (tabulated_ != &other) tabulate(other);
  // e^{λτ} is formed here rather than through the search's cache, which it would evict.
  const auto& terms = functionals_->flow().terms();
  std::complex<double>* e = table_e_.data();
  double tau[kEvaluateLanes];
  Eigen::Index k = 0;
  const bool unit = rate_ == 0.0;  // maxᵣ |λᵣ| = 0: every λᵣ is 0
  const auto exponentials_at = [&](Eigen::Index lanes) {
    for (Eigen::Index j = 0; j < lanes; ++j) tau[j] = t[k + j] - origin;
    if (!unit) direct_exponentials(terms, tau, lanes, e, nullptr);
  };
  const RowOutput out{split, top.data(), top.outerStride(), bottom.data(), bottom.outerStride()};
  for (; k + kEvaluateLanes <= count; k += kEvaluateLanes) {
    exponentials_at(kEvaluateLanes);
    if (unit)
      table_row_sums<kEvaluateLanes, true>(terms, table_, tau, e, out, k);
    else
      table_row_sums<kEvaluateLanes, false>(terms, table_, tau, e, out, k);
  }
  for (; k < count; ++k) {
    exponentials_at(1);
    if (unit)
      table_row_sums<1, true>(terms, table_, tau, e, out, k);
    else
      table_row_sums<1, false>(terms, table_, tau, e, out, k);
  }
}

}  // namespace vibro
