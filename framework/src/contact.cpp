#include "vibro/contact.hpp"

#include "engaged_system.hpp"
#include "event_resolution.hpp"

#include "vibro/bounded_wait.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vibro {
namespace {
/// Subsystems of at least this many free coordinates build their flow under run_bounded.
constexpr Eigen::Index kBoundedFromCoordinates = 64;
}  // namespace

namespace {

std::string set_name(const ContactSet& s) {
  std::string out = "{";
  for (std::size_t i = 0; i < s.size(); ++i) out += (i ? "," : "") + std::to_string(s[i]);
  return out + "}";
}

Eigen::MatrixXd symmetric(const Eigen::MatrixXd& a) { return 0.5 * (a + a.transpose()); }

}  // namespace

void LcpWorkspace::reserve(Eigen::Index m) {
  sub.resize(m, m);
  factor.resize(m, m);
  q_sub.resize(m);
  lambda_sub.resize(m);
  slack.resize(m);
  basis.reserve(static_cast<std::size_t>(m));
  basic.reserve(static_cast<std::size_t>(m));
}

Eigen::VectorXd solve_lcp(const Eigen::MatrixXd& G, const Eigen::VectorXd& q) {
  LcpWorkspace work;
  work.reserve(q.size());
  Eigen::VectorXd lambda(q.size());
  solve_lcp(G, q, lambda, work);
  return lambda;
}

void solve_lcp(const Eigen::Ref<const Eigen::MatrixXd>& G, const Eigen::Ref<const Eigen::VectorXd>& q,
               Eigen::Ref<Eigen::VectorXd> lambda, LcpWorkspace& work) {
  // Find a basis B (stops with λ > 0) with λ_B = G_BB⁻¹ q_B ≥ 0 and w = G λ - q ≥ 0 outside B.
  const Eigen::Index m = q.size();
  if (m == 1) {  // the pivoting below, written out: λ = q/G if q > 0, else 0
    lambda(0) = q(0) > 0.0 ? std::max(q(0) / G(0, 0), 0.0) : 0.0;
    return;
  }
  if (work.sub.rows() < m) work.reserve(m);
  work.basic.assign(static_cast<std::size_t>(m), 0);
  lambda.setZero();
  // Tolerances relative to the problem's own scale, so the answer does not depend on units.
  const double q_scale = q.cwiseAbs().maxCoeff();
  const double g_scale = G.cwiseAbs().maxCoeff();
  const long limit = (m < 20 ? (1L << m) : (1L << 20)) * std::max<Eigen::Index>(m, 1) + 10;
  auto slack = work.slack.head(m);
  for (long pivot = 0; pivot < limit; ++pivot) {
    work.basis.clear();
    for (Eigen::Index i = 0; i < m; ++i)
      if (work.basic[static_cast<std::size_t>(i)]) work.basis.push_back(i);
    lambda.setZero();
    if (!work.basis.empty()) {
      const auto k = static_cast<Eigen::Index>(work.basis.size());
      auto Gb = work.sub.topLeftCorner(k, k);
      auto qb = work.q_sub.head(k);
      auto lb = work.lambda_sub.head(k);
      for (Eigen::Index a = 0; a < k; ++a) {
        qb(a) = q(work.basis[static_cast<std::size_t>(a)]);
        for (Eigen::Index b = 0; b < k; ++b)
          Gb(a, b) = G(work.basis[static_cast<std::size_t>(a)], work.basis[static_cast<std::size_t>(b)]);
      }
      if (!detail::spd_solve(Gb, qb, lb, work.factor.topLeftCorner(k, k)))
        lb = Eigen::MatrixXd(Gb).ldlt().solve(Eigen::VectorXd(qb));  // semidefinite: pivoted (allocates)
      for (Eigen::Index a = 0; a < k; ++a) lambda(work.basis[static_cast<std::size_t>(a)]) = lb(a);
    }
    for (Eigen::Index i = 0; i < m; ++i) {  // w = G λ - q (small: written out)
      double sum = -q(i);
      for (Eigen::Index j = 0; j < m; ++j) sum += G(i, j) * lambda(j);
      slack(i) = sum;
    }
    const double w_tol = 1e-14 * (q_scale + g_scale * lambda.cwiseAbs().maxCoeff());
    const double l_tol = g_scale > 0.0 ? w_tol / g_scale : 0.0;
    // Least index violating complementarity: a basic λ < 0 or a non-basic w < 0.
    Eigen::Index bad = -1;
    for (Eigen::Index i = 0; i < m && bad < 0; ++i) {
      const bool b = work.basic[static_cast<std::size_t>(i)];
      if ((b && lambda(i) < -l_tol) || (!b && slack(i) < -w_tol)) bad = i;
    }
    if (bad < 0) {
      for (Eigen::Index i = 0; i < m; ++i) lambda(i) = std::max(lambda(i), 0.0);
      return;
    }
    work.basic[static_cast<std::size_t>(bad)] = !work.basic[static_cast<std::size_t>(bad)];
  }
  throw std::runtime_error("contact LCP: no solution after " + std::to_string(limit) +
                           " pivots (Delassus matrix not positive definite?)");
}

namespace detail {

bool spd_solve(const Eigen::Ref<const Eigen::MatrixXd>& G, const Eigen::Ref<const Eigen::VectorXd>& b,
               Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::MatrixXd> scratch) {
  // G = L D Lᵀ with unit lower L (below the diagonal of `scratch`) and D on its diagonal.
  const Eigen::Index k = G.rows();
  const double scale = G.cwiseAbs().maxCoeff();
  for (Eigen::Index j = 0; j < k; ++j) {
    double d = G(j, j);
    for (Eigen::Index l = 0; l < j; ++l) d -= scratch(j, l) * scratch(j, l) * scratch(l, l);
    if (!(d > 1e-300 * std::max(scale, 1e-300)) || !std::isfinite(d)) return false;
    scratch(j, j) = d;
    for (Eigen::Index i = j + 1; i < k; ++i) {
      double s = G(i, j);
      for (Eigen::Index l = 0; l < j; ++l) s -= scratch(i, l) * scratch(j, l) * scratch(l, l);
      scratch(i, j) = s / d;
    }
  }
  x = b;
  for (Eigen::Index i = 0; i < k; ++i)
    for (Eigen::Index l = 0; l < i; ++l) x(i) -= scratch(i, l) * x(l);
  for (Eigen::Index i = 0; i < k; ++i) x(i) /= scratch(i, i);
  for (Eigen::Index i = k - 1; i >= 0; --i)
    for (Eigen::Index l = i + 1; l < k; ++l) x(i) -= scratch(l, i) * x(l);
  return true;
}

}  // namespace detail

namespace detail {

EngagedSystem engaged_system(const ImpactSystem& scene, const ContactSet& engaged) {
  const LinearSystem& sys = scene.system();
  const double omega = sys.forcing().frequency;
  EngagedSystem out{sys.damping(), sys.stiffness(), sys.forcing()};
  for (int j : engaged) {
    const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
    const Eigen::VectorXd w = scene.normals().col(j);
    out.stiffness += st.stiffness * w * w.transpose();
    out.damping += st.damping * w * w.transpose();
    out.forcing.constant += (st.stiffness * st.s0() - st.preload) * w;
    out.forcing.cosine += (st.stiffness * st.s_cos() + st.damping * omega * st.s_sin()) * w;
    out.forcing.sine += (st.stiffness * st.s_sin() - st.damping * omega * st.s_cos()) * w;
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
      ForcingHarmonic& fh = out.forcing.harmonics[forcing_slot(out.forcing, st.harmonics[i].order)];
      const double wh = fh.rate(omega), hc = st.h_cos(i), hs = st.h_sin(i);
      fh.cosine += (st.stiffness * hc + st.damping * wh * hs) * w;
      fh.sine += (st.stiffness * hs - st.damping * wh * hc) * w;
    }
  }
  return out;
}

}  // namespace detail

ContactMode::ContactMode(const ImpactSystem& scene, ContactSet active, FlowOptions flow_options,
                         const std::atomic<bool>* interrupt)
    : scene_(&scene), active_(std::move(active)), flow_options_(flow_options), interrupt_(interrupt) {
  if (has_compliant(scene.stops())) {  // split the key: held rigid stops, engaged compliant ones
    ContactSet key = std::move(active_);
    active_.clear();
    for (int j : key) (scene.stops()[static_cast<std::size_t>(j)].is_compliant() ? engaged_ : active_).push_back(j);
  }
  const Eigen::Index n = scene.dof();
  const Eigen::Index m = size();
  normals_.resize(n, m);
  for (Eigen::Index a = 0; a < m; ++a)
    normals_.col(a) = scene.normals().col(active_[static_cast<std::size_t>(a)]);
  const LinearSystem& sys = scene.system();
  // No stop held (m = 0): an n × 0 solve would hand Eigen's kernels a null pointer (UBSan).
  minv_w_ = m > 0 ? Eigen::MatrixXd(sys.mass().llt().solve(normals_)) : Eigen::MatrixXd(n, 0);
  delassus_ = symmetric(normals_.transpose() * minv_w_);
  restitution_ = Eigen::MatrixXd::Identity(n, n);
  if (m > 0) {
    Eigen::LLT<Eigen::MatrixXd> g(delassus_);
    if (g.info() != Eigen::Success)
      throw std::runtime_error("contact set " + set_name(active_) +
                               ": the stops' normals are linearly dependent (Delassus matrix "
                               "singular); such a set cannot be held by independent forces");
    Eigen::VectorXd one_plus_r(m);
    for (Eigen::Index a = 0; a < m; ++a)
      one_plus_r(a) = 1.0 + scene.stops()[static_cast<std::size_t>(active_[static_cast<std::size_t>(a)])].restitution;
    restitution_ -= minv_w_ * g.solve(one_plus_r.asDiagonal() * normals_.transpose());
  }
}

const ContactMode::Reduced& ContactMode::reduced() const {
  if (!reduced_) build_reduced();
  return *reduced_;
}

void ContactMode::build_reduced() const {
  const ImpactSystem& scene = *scene_;
  const LinearSystem& sys = scene.system();
  const Eigen::Index n = sys.dof();
  const Eigen::Index m = size();
  const double omega = sys.forcing().frequency;
  auto red = std::make_unique<Reduced>();

  // Dependent coordinates D: the pivots of a column-pivoted QR of Wᵀ (m × n).
  Eigen::MatrixXd N = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n, m);
  if (m > 0) {
    const Eigen::MatrixXd Wt = normals_.transpose();
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Wt);
    if (qr.rank() < m)
      throw std::runtime_error("contact set " + set_name(active_) +
                               ": the stops' normals are linearly dependent");
    const auto& perm = qr.colsPermutation().indices();
    std::vector<bool> is_dep(static_cast<std::size_t>(n), false);
    for (Eigen::Index a = 0; a < m; ++a) is_dep[static_cast<std::size_t>(perm(a))] = true;
    for (Eigen::Index i = 0; i < n; ++i)
      (is_dep[static_cast<std::size_t>(i)] ? red->dependent : red->free).push_back(i);
    const auto nf = static_cast<Eigen::Index>(red->free.size());
    Eigen::MatrixXd A(m, m), B(m, nf);
    for (Eigen::Index a = 0; a < m; ++a) A.col(a) = Wt.col(red->dependent[static_cast<std::size_t>(a)]);
    for (Eigen::Index b = 0; b < nf; ++b) B.col(b) = Wt.col(red->free[static_cast<std::size_t>(b)]);
    const auto lu = A.fullPivLu();
    const Eigen::MatrixXd Ainv = lu.inverse();
    const Eigen::MatrixXd AinvB = nf > 0 ? Eigen::MatrixXd(Ainv * B) : Eigen::MatrixXd(m, 0);  // n × 0: as above
    N = Eigen::MatrixXd::Zero(n, nf);
    for (Eigen::Index b = 0; b < nf; ++b) N(red->free[static_cast<std::size_t>(b)], b) = 1.0;
    for (Eigen::Index a = 0; a < m; ++a) {
      const Eigen::Index d = red->dependent[static_cast<std::size_t>(a)];
      if (nf > 0) N.row(d) = -AinvB.row(a);  // every coordinate held (nf = 0): N is n × 0
      P.row(d) = Ainv.row(a);
    }
  } else {
    for (Eigen::Index i = 0; i < n; ++i) red->free.push_back(i);
  }
  const Eigen::Index nf = N.cols();

  // s(t) = s0 + sc cos Ωt + ss sin Ωt of the active stops.
  Eigen::VectorXd s0(m), sc(m), ss(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const Stop& st = scene.stops()[static_cast<std::size_t>(active_[static_cast<std::size_t>(a)])];
    s0(a) = st.s0();
    sc(a) = st.s_cos();
    ss(a) = st.s_sin();
  }
  // Their higher harmonics (stops.hpp), one column per harmonic h of the forcing (the slot
  // ImpactSystem gave each order a stop moves at): s_h(t) = Hc_h cos k_hΩt + Hs_h sin k_hΩt.
  const auto H = static_cast<Eigen::Index>(sys.forcing().harmonics.size());
  Eigen::MatrixXd Hc = Eigen::MatrixXd::Zero(m, H), Hs = Eigen::MatrixXd::Zero(m, H);
  bool higher = false;
  for (Eigen::Index a = 0; a < m; ++a) {
    const Stop& st = scene.stops()[static_cast<std::size_t>(active_[static_cast<std::size_t>(a)])];
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
      const auto h = static_cast<Eigen::Index>(forcing_slot(sys.forcing(), st.harmonics[i].order));
      Hc(a, h) += st.h_cos(i);
      Hs(a, h) += st.h_sin(i);
      higher = true;
    }
  }
  // Engaged compliant stops: their springs and dashpots join K and C, their s(t), s'(t) and
  // preload f (stops.hpp): force −w (k g + c g' + F_p) with g = wᵀx − s, g' = wᵀv − s'.
  detail::EngagedSystem engaged;
  if (!engaged_.empty()) engaged = detail::engaged_system(scene, engaged_);
  const Eigen::MatrixXd& M = sys.mass();
  const Eigen::MatrixXd& C = engaged_.empty() ? sys.damping() : engaged.damping;
  const Eigen::MatrixXd& K = engaged_.empty() ? sys.stiffness() : engaged.stiffness;
  const HarmonicForcing& f = engaged_.empty() ? sys.forcing() : engaged.forcing;
  red->mass = symmetric(N.transpose() * M * N);
  red->damping = symmetric(N.transpose() * C * N);
  red->stiffness = symmetric(N.transpose() * K * N);
  const double w2 = omega * omega;
  red->forcing.frequency = omega;
  red->forcing.constant = N.transpose() * (f.constant - K * P * s0);
  red->forcing.cosine = N.transpose() * (f.cosine - K * P * sc - omega * C * P * ss + w2 * M * P * sc);
  red->forcing.sine = N.transpose() * (f.sine - K * P * ss + omega * C * P * sc + w2 * M * P * ss);
  // Extra harmonics (system.hpp): Nᵀ f_h, and where held stops move at k_h Ω the same terms as
  // at Ω with ω_h = k_h Ω in place of Ω.
  for (std::size_t i = 0; i < f.harmonics.size(); ++i) {
    const ForcingHarmonic& h = f.harmonics[i];
    if (!higher) {
      red->forcing.harmonics.push_back({h.order, N.transpose() * h.cosine, N.transpose() * h.sine});
      continue;
    }
    const double wh = h.rate(omega), wh2 = wh * wh;
    const auto hc = Hc.col(static_cast<Eigen::Index>(i)), hs = Hs.col(static_cast<Eigen::Index>(i));
    red->forcing.harmonics.push_back({h.order, N.transpose() * (h.cosine - K * P * hc - wh * C * P * hs + wh2 * M * P * hc),
                                      N.transpose() * (h.sine - K * P * hs + wh * C * P * hc + wh2 * M * P * hs)});
  }
  const Eigen::Index extra = 2 * static_cast<Eigen::Index>(f.harmonics.size());

  // T maps [y; y'; c; s; 1; c_h; s_h…] to [x; v; c; s; 1; c_h; s_h…].
  const Eigen::Index Nf = augmented_size(n, f), Nr = augmented_size(nf, f);
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(Nf, Nr);
  T.block(0, 0, n, nf) = N;
  T.block(n, nf, n, nf) = N;
  T.block(0, 2 * nf, n, 1) = P * sc;
  T.block(0, 2 * nf + 1, n, 1) = P * ss;
  T.block(0, 2 * nf + 2, n, 1) = P * s0;
  T.block(n, 2 * nf, n, 1) = omega * P * ss;
  T.block(n, 2 * nf + 1, n, 1) = -omega * P * sc;
  T.block(2 * n, 2 * nf, 3 + extra, 3 + extra).setIdentity();
  if (higher)
    for (std::size_t i = 0; i < f.harmonics.size(); ++i) {
      const double wh = f.harmonics[i].rate(omega);
      const auto hc = Hc.col(static_cast<Eigen::Index>(i)), hs = Hs.col(static_cast<Eigen::Index>(i));
      const Eigen::Index col = augmented_size(nf, i);
      T.block(0, col, n, 1) = P * hc;
      T.block(0, col + 1, n, 1) = P * hs;
      T.block(n, col, n, 1) = wh * P * hs;
      T.block(n, col + 1, n, 1) = -wh * P * hc;
    }
  red->to_full = T;

  // The flow's set-up (eigenvectors, Schur form, exponential of the 2n_f + 3 generator) cannot
  // be polled and takes seconds for a few hundred coordinates: from 64 on it runs under
  // run_bounded, which answers the interrupt flag within 10 ms (below, it takes milliseconds).
  const bool large = nf >= kBoundedFromCoordinates;
  red->flow = run_bounded(large ? interrupt_ : nullptr,
                          [g = augmented_generator(red->mass, red->damping, red->stiffness, red->forcing), nf, omega,
                           o = flow_options_]() mutable { return std::make_unique<LinearFlow>(std::move(g), nf, omega, o); });

  // Contact forces as rows in the full augmented space.
  const Eigen::Index total = static_cast<Eigen::Index>(scene.stop_count());
  if (m > 0) {
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, Nf);  // f - C v - K x as rows of z
    rhs.block(0, 0, n, n) = -K;
    rhs.block(0, n, n, n) = -C;
    rhs.col(2 * n) = f.cosine;
    rhs.col(2 * n + 1) = f.sine;
    rhs.col(2 * n + 2) = f.constant;
    for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
      rhs.col(augmented_size(n, h)) = f.harmonics[h].cosine;
      rhs.col(augmented_size(n, h) + 1) = f.harmonics[h].sine;
    }
    Eigen::MatrixXd q = minv_w_.transpose() * rhs;  // Wᵀ M⁻¹ (…)
    q.col(2 * n) += w2 * sc;                         // - s'' = Ω² (sc cos + ss sin)
    q.col(2 * n + 1) += w2 * ss;
    if (higher)
      for (std::size_t i = 0; i < f.harmonics.size(); ++i) {
        const double wh = f.harmonics[i].rate(omega);
        q.col(augmented_size(n, i)) += wh * wh * Hc.col(static_cast<Eigen::Index>(i));
        q.col(augmented_size(n, i) + 1) += wh * wh * Hs.col(static_cast<Eigen::Index>(i));
      }
    red->force_rows = delassus_.llt().solve(q);
  } else {
    red->force_rows.resize(0, Nf);
  }

  // Watch rows: gaps of the stops not in S, then -λ of the stops in S.
  Eigen::MatrixXd rows(total, Nr);
  Eigen::Index r = 0;
  for (Eigen::Index j = 0; j < total; ++j) {
    if (std::binary_search(active_.begin(), active_.end(), static_cast<int>(j))) continue;
    if (!engaged_.empty() && std::binary_search(engaged_.begin(), engaged_.end(), static_cast<int>(j))) continue;
    const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
    Eigen::RowVectorXd g = Eigen::RowVectorXd::Zero(Nf);
    g.head(n) = scene.normals().col(j).transpose();
    g(2 * n) = -st.s_cos();
    g(2 * n + 1) = -st.s_sin();
    g(2 * n + 2) = -st.s0();
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
      const Eigen::Index col = augmented_size(n, forcing_slot(f, st.harmonics[i].order));
      g(col) = -st.h_cos(i);
      g(col + 1) = -st.h_sin(i);
    }
    rows.row(r++) = g * T;
    red->watched.push_back(static_cast<int>(j));
  }
  red->gap_rows = r;
  for (Eigen::Index a = 0; a < m; ++a) {
    rows.row(r++) = -red->force_rows.row(a) * T;
    red->watched.push_back(active_[static_cast<std::size_t>(a)]);
  }
  red->engaged_rows_from = r;
  for (int j : engaged_) {  // -g_j: it rises through 0 when the engaged stop's gap reopens
    const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
    Eigen::RowVectorXd g = Eigen::RowVectorXd::Zero(Nf);
    g.head(n) = -scene.normals().col(j).transpose();
    g(2 * n) = st.s_cos();
    g(2 * n + 1) = st.s_sin();
    g(2 * n + 2) = st.s0();
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
      const Eigen::Index col = augmented_size(n, forcing_slot(f, st.harmonics[i].order));
      g(col) = st.h_cos(i);
      g(col + 1) = st.h_sin(i);
    }
    rows.row(r++) = g * T;
    red->watched.push_back(j);
  }
  red->watch = std::make_unique<Functionals>(*red->flow, rows.topRows(r));
  reduced_ = std::move(red);
}

Eigen::VectorXd ContactMode::reduce(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                                    const Eigen::Ref<const Eigen::VectorXd>& v) const {
  Eigen::VectorXd z(reduced().flow->size());
  reduce(t, x, v, z);
  return z;
}

void ContactMode::reduce(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                         const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> z) const {
  const Reduced& red = reduced();
  const auto nf = static_cast<Eigen::Index>(red.free.size());
  for (Eigen::Index b = 0; b < nf; ++b) {
    z(b) = x(red.free[static_cast<std::size_t>(b)]);
    z(nf + b) = v(red.free[static_cast<std::size_t>(b)]);
  }
  const double omega = scene_->system().forcing().frequency;
  z(2 * nf) = std::cos(omega * t);
  z(2 * nf + 1) = std::sin(omega * t);
  z(2 * nf + 2) = 1.0;
  const std::vector<double>& rates = red.flow->harmonic_rates();
  for (std::size_t h = 0; h < rates.size(); ++h) {
    z(augmented_size(nf, h)) = std::cos(rates[h] * t);
    z(augmented_size(nf, h) + 1) = std::sin(rates[h] * t);
  }
}

void ContactMode::expand(const Eigen::Ref<const Eigen::VectorXd>& reduced_state, Eigen::Ref<Eigen::VectorXd> full) const {
  if (active_.empty()) {
    full = reduced_state;
    return;
  }
  full.noalias() = reduced().to_full * reduced_state;
}

const Functionals& ContactMode::state_rows() const {
  if (!state_rows_) {
    const Reduced& red = reduced();
    const Eigen::Index n = scene_->dof();
    state_rows_ = std::make_unique<Functionals>(*red.flow, red.to_full.topRows(2 * n));
  }
  return *state_rows_;
}

const ContactMode& ContactModes::get(const ContactSet& set) {
  auto it = modes_.find(set);
  if (it == modes_.end())
    it = modes_.emplace(set, std::make_unique<ContactMode>(*scene_, set, flow_options_, interrupt_)).first;
  return *it->second;
}

std::size_t ContactModes::reduced_built() const {
  std::size_t count = 0;
  for (const auto& [set, mode] : modes_) count += mode->reduced_built() ? 1 : 0;
  return count;
}

}  // namespace vibro
