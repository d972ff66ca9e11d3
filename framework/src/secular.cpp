#include "secular.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro::detail {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// The O(m) kernels every pass runs: these passes are the whole cost of a contact set of a long
// chain (one division per pole and pass), so they are written four poles at a time in explicit
// vector lanes (built for AVX2 and for the baseline, chosen at run time). Left to the compiler,
// the former scalar loops with four partial sums became unrolled scalar additions around the
// divisions, ~3 cycles a pole on the benchmark machine against ~1.3 now. Each lane sums the poles
// p ≡ lane (mod 4), the order of those loops, so the results are the same to the bit.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define VIBRO_KERNEL __attribute__((target_clones("avx2", "default")))
#else
#define VIBRO_KERNEL
#endif
#if defined(__GNUC__)
#define VIBRO_INLINE inline __attribute__((always_inline))
#else
#define VIBRO_INLINE inline
#endif

#if defined(__GNUC__)
using Lanes = double __attribute__((vector_size(32)));  // GCC and Clang vector extensions
// splat and load below return Lanes by value: GCC warns that this ABI differs with and without
// AVX, which cannot matter here (file-local, always inlined into each kernel clone). GCC reports
// it where it emits the functions, at the end of the file, so it is silenced for the whole
// file; arguments are passed by reference (by value, GCC adds a note on the same ABI change).
#pragma GCC diagnostic ignored "-Wpsabi"
#else
struct Lanes {  // the same four lanes for other compilers, element by element
  double v[4];
  double& operator[](int i) { return v[i]; }
  double operator[](int i) const { return v[i]; }
};
#define VIBRO_LANEWISE(op)                                      \
  inline Lanes operator op(Lanes a, Lanes b) {                  \
    for (int i = 0; i < 4; ++i) a.v[i] = a.v[i] op b.v[i];      \
    return a;                                                   \
  }                                                             \
  inline Lanes& operator op##=(Lanes& a, Lanes b) { return a = a op b; }
VIBRO_LANEWISE(+)
VIBRO_LANEWISE(-)
VIBRO_LANEWISE(*)
VIBRO_LANEWISE(/)
#undef VIBRO_LANEWISE
#endif

VIBRO_INLINE Lanes splat(double x) { return Lanes{x, x, x, x}; }
VIBRO_INLINE Lanes load(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof v);  // unaligned load
  return v;
}
VIBRO_INLINE void store(double* p, const Lanes& v) { std::memcpy(p, &v, sizeof v); }
VIBRO_INLINE double lane_sum(const Lanes& v) { return (v[0] + v[1]) + (v[2] + v[3]); }

/// Σ w_p / ((d_p - d_o) - τ) and Σ w_p / ((d_p - d_o) - τ)² over p ∈ [0, n).
VIBRO_KERNEL void pole_sums(const double* d, const double* w, long n, double d_o, double tau, double* sum,
                            double* slope) {
  const Lanes origin = splat(d_o), shift = splat(tau), one = splat(1.0);
  Lanes s = splat(0.0), t = splat(0.0);
  long p = 0;
  for (; p + 4 <= n; p += 4) {
    const Lanes inv = one / ((load(d + p) - origin) - shift);
    const Lanes term = load(w + p) * inv;
    s += term;
    t += term * inv;
  }
  for (; p < n; ++p) {
    const double inv = 1.0 / ((d[p] - d_o) - tau);
    s[0] += w[p] * inv;
    t[0] += w[p] * inv * inv;
  }
  *sum = lane_sum(s);
  *slope = lane_sum(t);
}

/// out_j = Σ_p a_{p,j} / ((d_p - d_o) - τ) for K columns of a (column-major, leading dimension
/// lda): one division per p shared by the columns. With Norm, also *norm = Σ_p w_p / ((d_p -
/// d_o) - τ)², summed as pole_sums' slope (the same bits).
template <int K, bool Norm>
VIBRO_INLINE void cauchy_dots_k(const double* d, long n, double d_o, double tau, const double* a, long lda,
                                double* out, const double* w, double* norm) {
  const Lanes origin = splat(d_o), shift = splat(tau), one = splat(1.0);
  Lanes acc[K], t = splat(0.0);
  for (int j = 0; j < K; ++j) acc[j] = splat(0.0);
  long p = 0;
  for (; p + 4 <= n; p += 4) {
    const Lanes inv = one / ((load(d + p) - origin) - shift);
    for (int j = 0; j < K; ++j) acc[j] += load(a + j * lda + p) * inv;
    if constexpr (Norm) t += (load(w + p) * inv) * inv;
  }
  for (; p < n; ++p) {
    const double inv = 1.0 / ((d[p] - d_o) - tau);
    for (int j = 0; j < K; ++j) acc[j][0] += a[j * lda + p] * inv;
    if constexpr (Norm) t[0] += w[p] * inv * inv;
  }
  for (int j = 0; j < K; ++j) out[j] = lane_sum(acc[j]);
  if constexpr (Norm) *norm = lane_sum(t);
}

/// b_{p,j} += c_j / ((d_p - d_o) - τ) for K columns of b (column-major, leading dimension ldb).
template <int K>
VIBRO_INLINE void cauchy_axpys_k(const double* d, long n, double d_o, double tau, const double* c, double* b,
                                 long ldb) {
  const Lanes origin = splat(d_o), shift = splat(tau), one = splat(1.0);
  Lanes coef[K];
  for (int j = 0; j < K; ++j) coef[j] = splat(c[j]);
  long p = 0;
  for (; p + 4 <= n; p += 4) {
    const Lanes inv = one / ((load(d + p) - origin) - shift);
    for (int j = 0; j < K; ++j) store(b + j * ldb + p, load(b + j * ldb + p) + coef[j] * inv);
  }
  for (; p < n; ++p) {
    const double inv = 1.0 / ((d[p] - d_o) - tau);
    for (int j = 0; j < K; ++j) b[j * ldb + p] += c[j] * inv;
  }
}

// The column count as a template argument keeps each column's accumulator in a register.
#define VIBRO_BY_COLUMNS(call) \
  switch (k) {                 \
    case 1: call(1); break;    \
    case 2: call(2); break;    \
    case 3: call(3); break;    \
    case 4: call(4); break;    \
    case 5: call(5); break;    \
    case 6: call(6); break;    \
    case 7: call(7); break;    \
    default: call(8); break;   \
  }

/// cauchy_dots_k for 1 ≤ k ≤ 8 columns, with the norm sum if w is given.
VIBRO_KERNEL void cauchy_dots(const double* d, long n, double d_o, double tau, const double* a, long lda, int k,
                              double* out, const double* w = nullptr, double* norm = nullptr) {
#define VIBRO_DOTS(K) cauchy_dots_k<K, false>(d, n, d_o, tau, a, lda, out, w, norm)
#define VIBRO_DOTS_NORM(K) cauchy_dots_k<K, true>(d, n, d_o, tau, a, lda, out, w, norm)
  if (w) {
    VIBRO_BY_COLUMNS(VIBRO_DOTS_NORM)
  } else {
    VIBRO_BY_COLUMNS(VIBRO_DOTS)
  }
#undef VIBRO_DOTS
#undef VIBRO_DOTS_NORM
}

/// cauchy_axpys_k for k ≤ 8 columns.
VIBRO_KERNEL void cauchy_axpys(const double* d, long n, double d_o, double tau, const double* c, double* b, long ldb,
                               int k) {
#define VIBRO_AXPYS(K) cauchy_axpys_k<K>(d, n, d_o, tau, c, b, ldb)
  VIBRO_BY_COLUMNS(VIBRO_AXPYS)
#undef VIBRO_AXPYS
}
#undef VIBRO_BY_COLUMNS

/// Π_l num_l / den_l with num_l = (a_l - x) + b_l, den_l = c_l - x (every ratio in (0, 1]).
VIBRO_KERNEL double ratio_product(const double* a, const double* b, const double* c, long n, double x) {
  const Lanes at = splat(x);
  Lanes s = splat(1.0);
  long l = 0;
  for (; l + 4 <= n; l += 4) s *= ((load(a + l) - at) + load(b + l)) / (load(c + l) - at);
  for (; l < n; ++l) s[0] *= ((a[l] - x) + b[l]) / (c[l] - x);
  return (s[0] * s[1]) * (s[2] * s[3]);
}

/// The root in (A, B) (A < 0 < B) of c + s1/(A - η) + s2/(B - η) = 0, whose value at η = 0 is
/// g (so its constant term is g A B): c η² - (c (A + B) + s1 + s2) η + g A B = 0. NaN if none.
double middle_way_step(double g, double c, double s1, double s2, double A, double B) {
  const double beta = c * (A + B) + s1 + s2, gamma = g * A * B;
  auto inside = [&](double eta) { return eta > A && eta < B; };
  if (c == 0.0) {
    const double eta = beta != 0.0 ? gamma / beta : std::numeric_limits<double>::quiet_NaN();
    return inside(eta) ? eta : std::numeric_limits<double>::quiet_NaN();
  }
  const double disc = beta * beta - 4.0 * c * gamma;
  if (!(disc >= 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const double q = 0.5 * (beta + std::copysign(std::sqrt(disc), beta));
  const double small = q != 0.0 ? gamma / q : std::numeric_limits<double>::quiet_NaN();
  const double large = q / c;
  if (inside(small)) return small;
  if (inside(large)) return large;
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

SecularLevel::SecularLevel(const Eigen::VectorXd& d, const Eigen::VectorXd& z, Eigen::MatrixXd* carry)
    : m_(d.size()) {
  if (z.size() != m_ || m_ < 1) throw std::logic_error("secular level: sizes do not match");
  const double norm = z.norm();
  if (!(norm > 0.0) || !std::isfinite(norm))
    throw std::runtime_error("secular level: the constraint is zero in the parent's modes (dependent on the others)");
  Eigen::VectorXd w = z / norm, dd = d;
  const double dmax = std::max(d.cwiseAbs().maxCoeff(), 1e-300);
  // Deflation (dlaed2): negligible weights, then poles too close to tell apart (rotated so that
  // one of the pair carries the whole weight and the other none).
  std::vector<Eigen::Index> kept, deflated;
  for (Eigen::Index i = 0; i < m_; ++i) {
    if (std::abs(w(i)) <= 8.0 * kEps) {
      deflated.push_back(i);
      continue;
    }
    if (!kept.empty()) {
      const Eigen::Index j = kept.back();
      const double r = std::hypot(w(j), w(i)), c = w(j) / r, s = w(i) / r;
      if (std::abs((dd(i) - dd(j)) * c * s) <= 8.0 * kEps * dmax) {
        rotations_.push_back({j, i, c, s});
        const double dj = dd(j), di = dd(i);
        dd(j) = c * c * dj + s * s * di;
        dd(i) = s * s * dj + c * c * di;
        w(j) = r;
        w(i) = 0.0;
        deflated.push_back(i);
        continue;
      }
    }
    kept.push_back(i);
  }
  poles_ = kept;
  const auto q = static_cast<Eigen::Index>(kept.size());
  d_.resize(q);
  Eigen::VectorXd zk(q);
  for (Eigen::Index p = 0; p < q; ++p) {
    d_(p) = dd(kept[static_cast<std::size_t>(p)]);
    zk(p) = w(kept[static_cast<std::size_t>(p)]);
  }
  const Eigen::VectorXd z2 = zk.cwiseAbs2();

  // Roots: μ_l = d[origin] + τ_l in (d_l, d_{l+1}), l = 0 … q - 2.
  const Eigen::Index roots = std::max<Eigen::Index>(q - 1, 0);
  origin_.resize(static_cast<std::size_t>(roots));
  tau_.resize(roots);
  // The first guess for each root: where it sits in its interval, as a fraction of the gap,
  // extrapolated from the roots before it. For a smooth constraint (weights alike from pole to
  // pole, as for a stop on a uniform chain) that fraction drifts smoothly with l, wrapping from
  // near 1 to near 0 when the roots move past a pole, so it is extrapolated modulo 1 (quadratic
  // through the last three): at N = 10 000 the first step is then below 1e-9 of τ for 99 % of
  // the roots, and each costs one pass over the poles instead of three (the previous fraction
  // alone was off by ~1e-3 of τ). Where the fractions are not smooth (second difference above
  // 0.01) the previous fraction is the guess, as before; a poor guess costs iterations, never
  // accuracy (the iteration below is bracketed).
  double recent[3] = {0.5, 0.5, 0.5};  // fractions of roots l - 1, l - 2, l - 3 (unwrapped)
  auto guess_fraction = [&](Eigen::Index l) {
    if (l == 0) return 0.5;
    const bool smooth = l >= 3 && std::abs(recent[0] - 2.0 * recent[1] + recent[2]) <= 0.01;
    const double next = smooth ? 3.0 * recent[0] - 3.0 * recent[1] + recent[2] : recent[0];
    return next - std::floor(next);
  };
  for (Eigen::Index l = 0; l < roots; ++l) {
    const double gap = d_(l + 1) - d_(l);
    const double fraction = std::clamp(guess_fraction(l), 1e-6, 1.0 - 1e-6);
    Eigen::Index o = fraction <= 0.5 ? l : l + 1;
    double tau = o == l ? fraction * gap : -(1.0 - fraction) * gap;
    for (int pass = 0; pass < 2; ++pass) {
      const double d_o = d_(o);
      const double a_pole = d_(l) - d_o, b_pole = d_(l + 1) - d_o;
      double lo = a_pole, hi = b_pole;  // bracket of τ (open)
      for (int it = 0; it < 100; ++it) {
        // ψ, ψ' over the poles up to l (terms < 0), φ, φ' over those above (terms > 0).
        double psi, dpsi, phi, dphi;
        pole_sums(d_.data(), z2.data(), l + 1, d_o, tau, &psi, &dpsi);
        pole_sums(d_.data() + l + 1, z2.data() + l + 1, q - l - 1, d_o, tau, &phi, &dphi);
        const double g = psi + phi;
        if (std::abs(g) <= 8.0 * kEps * (phi - psi) || g == 0.0) break;
        (g < 0.0 ? lo : hi) = tau;
        const double A = a_pole - tau, B = b_pole - tau;
        const double s1 = dpsi * A * A, s2 = dphi * B * B;
        const double c = g - s1 / A - s2 / B;
        const double eta = middle_way_step(g, c, s1, s2, A, B);
        double next = tau + eta;
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        // The middle way converges quadratically: after a step below 1e-9 of τ the next would
        // be below rounding, so τ + η is kept without another pass.
        if (std::abs(next - tau) <= std::max(1e-9 * std::abs(tau), 2.0 * kEps * std::abs(d_o))) {
          tau = next;
          break;
        }
        tau = next;
        if (hi - lo <= 4.0 * kEps * std::max(std::abs(lo), std::abs(hi))) break;
      }
      // The root must be measured from the pole it is nearer to (every dᵢ - μ then keeps its
      // relative accuracy); if the guess chose the other, move the origin and refine.
      const double position = (d_o - d_(l)) + tau;  // μ - d_l
      const Eigen::Index nearer = position <= 0.5 * gap ? l : l + 1;
      if (nearer == o) break;
      tau = (d_o - d_(nearer)) + tau;
      o = nearer;
    }
    // This root's fraction, unwrapped to within 1/2 of the previous one (so that a root past
    // the next pole continues the sequence rather than jumping back by 1).
    double found = ((d_(o) - d_(l)) + tau) / gap;
    if (l > 0) found -= std::round(found - recent[0]);
    recent[2] = recent[1];
    recent[1] = recent[0];
    recent[0] = found;
    origin_[static_cast<std::size_t>(l)] = o;
    tau_(l) = tau;
  }
  // Löwner's weights for the computed roots.
  zhat_.resize(q);
  Eigen::VectorXd at_origin(roots);
  for (Eigen::Index l = 0; l < roots; ++l) at_origin(l) = d_(origin_[static_cast<std::size_t>(l)]);
  for (Eigen::Index p = 0; p < q; ++p) {
    const double prod = ratio_product(at_origin.data(), tau_.data(), d_.data(), p, d_(p)) *
                        ratio_product(at_origin.data() + p, tau_.data() + p, d_.data() + p + 1, roots - p, d_(p));
    zhat_(p) = std::copysign(std::sqrt(std::max(prod, 0.0)), zk(p));
  }
  // Children by ascending eigenvalue: the roots (ascending in l) merged with the deflated poles.
  std::vector<std::pair<double, Eigen::Index>> all;
  all.reserve(static_cast<std::size_t>(m_ - 1));
  for (Eigen::Index l = 0; l < roots; ++l) all.push_back({d_(origin_[static_cast<std::size_t>(l)]) + tau_(l), l});
  for (Eigen::Index i : deflated) all.push_back({dd(i), -1 - i});
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (static_cast<Eigen::Index>(all.size()) != m_ - 1)
    throw std::logic_error("secular level: " + std::to_string(all.size()) + " children for " + std::to_string(m_) +
                           " parents");
  mu_.resize(m_ - 1);
  child_.resize(all.size());
  for (std::size_t c = 0; c < all.size(); ++c) {
    mu_(static_cast<Eigen::Index>(c)) = all[c].first;
    child_[c] = all[c].second;
  }
  // The vectors' norms ‖(d - μ_l)⁻¹ ẑ‖ take a pass over the poles per root, as does a product
  // with the child basis: with columns to carry, both share that pass (its divisions).
  inv_norm_.resize(roots);
  const Eigen::VectorXd zhat2 = zhat_.cwiseAbs2();
  if (carry && carry->cols() > 0) {
    if (carry->rows() != m_) throw std::logic_error("secular level: the carried columns do not match the parent");
    std::vector<double> scratch(static_cast<std::size_t>(scratch_size(carry->cols())));
    Eigen::MatrixXd child(m_ - 1, carry->cols());
    child_pass(*carry, child, scratch.data(), &zhat2, &inv_norm_);
    *carry = std::move(child);
    return;
  }
  for (Eigen::Index l = 0; l < roots; ++l) {
    double unused, sum;  // Σ ẑ_p² / (d_p - μ_l)²
    pole_sums(d_.data(), zhat2.data(), q, at_origin(l), tau_(l), &unused, &sum);
    inv_norm_(l) = 1.0 / std::sqrt(sum);
  }
  if (carry) *carry = Eigen::MatrixXd(m_ - 1, 0);
}

void SecularLevel::rotate(Eigen::Map<Eigen::MatrixXd>& x, bool forward) const {
  auto apply = [&](const Rotation& r, double s) {
    for (Eigen::Index k = 0; k < x.cols(); ++k) {
      const double a = x(r.i, k), b = x(r.j, k);
      x(r.i, k) = r.c * a + s * b;
      x(r.j, k) = -s * a + r.c * b;
    }
  };
  if (forward)
    for (const Rotation& r : rotations_) apply(r, r.s);
  else
    for (auto it = rotations_.rbegin(); it != rotations_.rend(); ++it) apply(*it, -it->s);
}

void SecularLevel::to_child(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child) const {
  std::vector<double> scratch(static_cast<std::size_t>(scratch_size(parent.cols())));
  to_child(parent, child, scratch.data());
}

void SecularLevel::to_child(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child,
                            double* scratch) const {
  child_pass(parent, child, scratch, nullptr, nullptr);
}

void SecularLevel::child_pass(const Eigen::Ref<const Eigen::MatrixXd>& parent, Eigen::Ref<Eigen::MatrixXd> child,
                              double* scratch, const Eigen::VectorXd* zhat2, Eigen::VectorXd* inv_norm) const {
  const Eigen::Index k = parent.cols(), q = d_.size();
  Eigen::Map<Eigen::MatrixXd> x(scratch, m_, k);
  x = parent;
  rotate(x, true);
  Eigen::Map<Eigen::MatrixXd> a(scratch + m_ * k, q, k);  // ẑ_p x_p
  for (Eigen::Index p = 0; p < q; ++p) a.row(p) = zhat_(p) * x.row(poles_[static_cast<std::size_t>(p)]);
  for (std::size_t c = 0; c < child_.size(); ++c)  // deflated: a parent mode itself
    if (child_[c] < 0) child.row(static_cast<Eigen::Index>(c)) = x.row(-1 - child_[c]);
  // Blocks of 8 columns outside, roots inside: each root reads its block of a (8q doubles, 640 kB
  // at q = 10 000, held in L2) rather than all of a, which for the hundreds of columns of a set
  // with many stops (the rows its guards read) would stream from memory for every root.
  double out[8];
  for (Eigen::Index j0 = 0; j0 < k; j0 += 8) {
    const int block = static_cast<int>(std::min<Eigen::Index>(8, k - j0));
    for (std::size_t c = 0; c < child_.size(); ++c) {
      const Eigen::Index l = child_[c], row = static_cast<Eigen::Index>(c);
      if (l < 0) continue;
      const double d_o = d_(origin_[static_cast<std::size_t>(l)]);
      if (inv_norm && j0 == 0) {  // the norm with the first block (the constructor's pass)
        double sum;
        cauchy_dots(d_.data(), q, d_o, tau_(l), a.col(j0).data(), q, block, out, zhat2->data(), &sum);
        (*inv_norm)(l) = 1.0 / std::sqrt(sum);
      } else {
        cauchy_dots(d_.data(), q, d_o, tau_(l), a.col(j0).data(), q, block, out);
      }
      const double scale = inv_norm ? (*inv_norm)(l) : inv_norm_(l);
      for (int j = 0; j < block; ++j) child(row, j0 + j) = scale * out[j];
    }
  }
}

void SecularLevel::to_parent(const Eigen::Ref<const Eigen::MatrixXd>& child, Eigen::Ref<Eigen::MatrixXd> parent,
                             double* scratch) const {
  const Eigen::Index k = child.cols(), q = d_.size();
  Eigen::Map<Eigen::MatrixXd> x(scratch, m_, k), b(scratch + m_ * k, q, k);
  x.setZero();
  b.setZero();
  for (std::size_t c = 0; c < child_.size(); ++c)
    if (child_[c] < 0) x.row(-1 - child_[c]) = child.row(static_cast<Eigen::Index>(c));
  // Blocks of columns outside, roots inside, as in to_child (each root updates one block of b).
  double coef[8];
  for (Eigen::Index j0 = 0; j0 < k; j0 += 8) {
    const int block = static_cast<int>(std::min<Eigen::Index>(8, k - j0));
    for (std::size_t c = 0; c < child_.size(); ++c) {
      const Eigen::Index l = child_[c], row = static_cast<Eigen::Index>(c);
      if (l < 0) continue;
      for (int j = 0; j < block; ++j) coef[j] = inv_norm_(l) * child(row, j0 + j);
      cauchy_axpys(d_.data(), q, d_(origin_[static_cast<std::size_t>(l)]), tau_(l), coef, b.col(j0).data(), q, block);
    }
  }
  for (Eigen::Index p = 0; p < q; ++p) x.row(poles_[static_cast<std::size_t>(p)]) = zhat_(p) * b.row(p);
  rotate(x, false);
  parent = x;
}

std::size_t SecularLevel::bytes() const {
  return sizeof(double) * static_cast<std::size_t>(d_.size() + zhat_.size() + tau_.size() + inv_norm_.size() +
                                                   mu_.size()) +
         sizeof(Eigen::Index) * (poles_.size() + origin_.size() + child_.size()) +
         sizeof(Rotation) * rotations_.size();
}

}  // namespace vibro::detail
