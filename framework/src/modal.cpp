#include "vibro/modal.hpp"

#include "vibro/contact.hpp"  // solve_lcp

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <stdexcept>

#ifdef VIBRO_HAVE_LAPACK
extern "C" {
// LAPACK's MRRR tridiagonal eigensolver (Fortran calling convention; the two trailing arguments
// are the hidden lengths of the character arguments JOBZ and RANGE).
void dstemr_(const char* jobz, const char* range, const int* n, double* d, double* e,
             const double* vl, const double* vu, const int* il, const int* iu, int* m, double* w,
             double* z, const int* ldz, const int* nzc, int* isuppz, int* tryrac, double* work,
             const int* lwork, int* iwork, const int* liwork, int* info, std::size_t jobz_len,
             std::size_t range_len);
}
#endif

namespace vibro {
namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void require_finite_vector(const Eigen::VectorXd& v, const std::string& name) {
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!std::isfinite(v(i)))
      throw InvalidInput(name + "[" + std::to_string(i) + "] = " + number_text(v(i)) +
                         ": must be a finite number");
}

void require_length(const Eigen::VectorXd& v, Eigen::Index n, const std::string& name) {
  if (v.size() != n)
    throw InvalidInput(name + ": has " + std::to_string(v.size()) + " entries, expected " +
                       std::to_string(n));
}

/// The nonzero entries of a stop's normal w: (mass, weight) pairs.
struct Normal {
  Eigen::Index i = 0, k = -1;
  double wi = 1.0, wk = 0.0;
};

Normal normal_of(const Stop& s) {
  switch (s.kind) {
    case Stop::Kind::upper: return {s.mass, -1, 1.0, 0.0};
    case Stop::Kind::lower: return {s.mass, -1, -1.0, 0.0};
    case Stop::Kind::between: return {s.mass, s.other, 1.0, -1.0};
  }
  return {};
}

/// w_aᵀ M⁻¹ w_b for diagonal M.
double delassus_entry(const Normal& a, const Normal& b, const Eigen::VectorXd& mass) {
  double sum = 0.0;
  auto add = [&](Eigen::Index ia, double wa) {
    if (ia < 0) return;
    if (ia == b.i) sum += wa * b.wi / mass(ia);
    if (b.k >= 0 && ia == b.k) sum += wa * b.wk / mass(ia);
  };
  add(a.i, a.wi);
  add(a.k, a.wk);
  return sum;
}

/// Upper bound of h over [a, b] from the end values and slopes and B ≥ |h''| (events.hpp).
double upper_bound(double ha, double da, double hb, double db, double B, double L) {
  const double chord = std::max(ha, hb) + B * L * L / 8.0;
  const double from_a = std::max(ha, ha + da * L + 0.5 * B * L * L);
  const double from_b = std::max(hb, hb - db * L + 0.5 * B * L * L);
  return std::min({chord, from_a, from_b});
}

/// Ring buffer of recent event times (Zeno guard), as in the dense simulator.
class EventRate {
 public:
  EventRate(long capacity, double window)
      : times_(static_cast<std::size_t>(capacity) + 1), window_(window) {}
  bool exceeded(double t) {
    times_[head_] = t;
    head_ = (head_ + 1) % times_.size();
    count_ = std::min(count_ + 1, times_.size());
    if (count_ < times_.size()) return false;
    return t - times_[head_] < window_;
  }

 private:
  std::vector<double> times_;
  std::size_t head_ = 0, count_ = 0;
  double window_;
};

void require_option(double value, const char* field, bool allow_zero = false) {
  if (!std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0))
    throw InvalidInput(std::string("solver.") + field + " = " + number_text(value) +
                       ": must be a finite number " + (allow_zero ? "≥ 0" : "> 0"));
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// BandedChain

void BandedChain::validate() const {
  const Eigen::Index n = mass.size();
  if (n == 0) throw InvalidInput("chain.masses: is empty: a chain needs at least one mass");
  require_length(stiffness_diagonal, n, "chain stiffness diagonal");
  require_length(stiffness_off, n - 1, "chain stiffness off-diagonal");
  require_finite_vector(mass, "chain.masses");
  require_finite_vector(stiffness_diagonal, "chain stiffness diagonal");
  require_finite_vector(stiffness_off, "chain stiffness off-diagonal");
  for (Eigen::Index i = 0; i < n; ++i)
    if (!(mass(i) > 0.0))
      throw InvalidInput("chain.masses[" + std::to_string(i) + "] = " + number_text(mass(i)) +
                         ": every mass must be positive");
  for (const auto& [value, name] : {std::pair{rayleigh_mass, "rayleigh_mass (alpha)"},
                                   std::pair{rayleigh_stiffness, "rayleigh_stiffness (beta)"}})
    if (!std::isfinite(value) || value < 0.0)
      throw InvalidInput(std::string("chain.") + name + " = " + number_text(value) +
                         ": must be a finite number ≥ 0");
  require_length(forcing.constant, n, "forcing.constant");
  require_length(forcing.cosine, n, "forcing.cosine");
  require_length(forcing.sine, n, "forcing.sine");
  require_finite_vector(forcing.constant, "forcing.constant");
  require_finite_vector(forcing.cosine, "forcing.cosine");
  require_finite_vector(forcing.sine, "forcing.sine");
  if (!std::isfinite(forcing.frequency) || forcing.frequency < 0.0)
    throw InvalidInput("forcing.frequency: is " + number_text(forcing.frequency) +
                       ": must be a finite number ≥ 0");
}

BandedChain BandedChain::from_links(const std::vector<double>& masses,
                                    const std::vector<double>& springs,
                                    const std::vector<double>& dampers, double left_spring,
                                    double left_damper, double right_spring, double right_damper,
                                    HarmonicForcing forcing) {
  const std::size_t n = masses.size();
  if (n == 0) throw InvalidInput("chain.masses: is empty: a chain needs at least one mass");
  if (springs.size() != n - 1 && !(n == 1 && springs.empty()))
    throw InvalidInput("chain.springs: has " + std::to_string(springs.size()) +
                       " entries, expected " + std::to_string(n - 1));
  if (!dampers.empty() && dampers.size() != n - 1)
    throw InvalidInput("chain.dampers: has " + std::to_string(dampers.size()) +
                       " entries, expected " + std::to_string(n - 1) + " (or none)");
  // Links as (spring, damper, name): n - 1 inner links and the two walls.
  struct Link {
    double k, c;
    std::string name;
  };
  std::vector<Link> links;
  for (std::size_t i = 0; i + 1 < n; ++i)
    links.push_back({springs[i], dampers.empty() ? 0.0 : dampers[i],
                     "dampers[" + std::to_string(i) + "]"});
  links.push_back({left_spring, left_damper, "left_wall.damper"});
  links.push_back({right_spring, right_damper, "right_wall.damper"});
  double kmax = 0.0, cmax = 0.0;
  for (const Link& l : links) {
    if (!std::isfinite(l.k) || l.k < 0.0 || !std::isfinite(l.c) || l.c < 0.0)
      throw InvalidInput("chain: link " + l.name + ": spring " + number_text(l.k) + ", damper " +
                         number_text(l.c) + ": both must be finite numbers ≥ 0");
    kmax = std::max(kmax, l.k);
    cmax = std::max(cmax, l.c);
  }
  double beta = 0.0;
  for (const Link& l : links)
    if (l.c > 0.0) {
      if (l.k == 0.0)
        throw InvalidInput("chain." + l.name + " = " + number_text(l.c) +
                           " beside a zero spring: the damping is not proportional (C ≠ βK); "
                           "the modal chain engine needs Rayleigh damping, use the dense Simulator");
      beta = l.c / l.k;
      break;
    }
  for (const Link& l : links)
    if (std::abs(l.c - beta * l.k) > 1e-12 * std::max(cmax, beta * kmax))
      throw InvalidInput("chain." + l.name + " = " + number_text(l.c) + " but β × spring = " +
                         number_text(beta * l.k) + " (β = " + number_text(beta) +
                         " from the first damped link): the damping is not proportional (C ≠ βK); "
                         "the modal chain engine needs Rayleigh damping, use the dense Simulator");
  BandedChain out;
  const auto N = static_cast<Eigen::Index>(n);
  out.mass = Eigen::Map<const Eigen::VectorXd>(masses.data(), N);
  out.stiffness_diagonal = Eigen::VectorXd::Zero(N);
  out.stiffness_off = Eigen::VectorXd::Zero(N - 1);
  for (Eigen::Index i = 0; i + 1 < N; ++i) {
    const double k = springs[static_cast<std::size_t>(i)];
    out.stiffness_diagonal(i) += k;
    out.stiffness_diagonal(i + 1) += k;
    out.stiffness_off(i) = -k;
  }
  out.stiffness_diagonal(0) += left_spring;
  out.stiffness_diagonal(N - 1) += right_spring;
  out.rayleigh_stiffness = beta;
  out.forcing = std::move(forcing);
  out.validate();
  return out;
}

BandedChain BandedChain::from_system(const LinearSystem& system) {
  const Eigen::MatrixXd& M = system.mass();
  const Eigen::MatrixXd& C = system.damping();
  const Eigen::MatrixXd& K = system.stiffness();
  const Eigen::Index n = M.rows();
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i) {
      if (i != j && M(i, j) != 0.0)
        throw InvalidInput("mass matrix: entry (" + std::to_string(i) + "," + std::to_string(j) +
                           ") = " + number_text(M(i, j)) +
                           ": the modal chain engine needs a diagonal mass matrix");
      if (std::abs(i - j) > 1 && K(i, j) != 0.0)
        throw InvalidInput("stiffness matrix: entry (" + std::to_string(i) + "," +
                           std::to_string(j) + ") = " + number_text(K(i, j)) +
                           ": the modal chain engine needs a tridiagonal stiffness matrix");
    }
  // Fit C = αM + βK: β from the largest off-diagonal of K, α from the diagonal where β K_ii is
  // smallest relative to m_i; then check every entry.
  double alpha = 0.0, beta = 0.0;
  Eigen::Index best = -1;
  for (Eigen::Index i = 0; i + 1 < n; ++i)
    if (K(i, i + 1) != 0.0 && (best < 0 || std::abs(K(i, i + 1)) > std::abs(K(best, best + 1))))
      best = i;
  const double cmax = C.cwiseAbs().maxCoeff();
  if (best >= 0) {
    beta = C(best, best + 1) / K(best, best + 1);
    Eigen::Index d = 0;
    for (Eigen::Index i = 1; i < n; ++i)
      if (M(i, i) > M(d, d)) d = i;
    alpha = (C(d, d) - beta * K(d, d)) / M(d, d);
    if (std::abs(alpha) <= 1e-13 * std::max(cmax, 1e-300) / M(d, d)) alpha = 0.0;
  } else {
    // Decoupled masses: try C = βK, then C = αM.
    Eigen::Index d = 0;
    for (Eigen::Index i = 1; i < n; ++i)
      if (K(i, i) > K(d, d)) d = i;
    if (K(d, d) > 0.0) beta = C(d, d) / K(d, d);
    if ((C - beta * K).cwiseAbs().maxCoeff() > 1e-12 * cmax) {
      beta = 0.0;
      alpha = C(0, 0) / M(0, 0);
    }
  }
  const Eigen::MatrixXd residual = C - alpha * M - beta * K;
  Eigen::Index ri = 0, rj = 0;
  const double worst = residual.cwiseAbs().maxCoeff(&ri, &rj);
  if (worst > 1e-12 * cmax || alpha < 0.0 || beta < 0.0)
    throw InvalidInput("damping matrix: entry (" + std::to_string(ri) + "," + std::to_string(rj) +
                       ") = " + number_text(C(ri, rj)) + " but αM + βK gives " +
                       number_text(C(ri, rj) - residual(ri, rj)) + " (α = " + number_text(alpha) +
                       ", β = " + number_text(beta) +
                       "): the damping is not proportional; the modal chain engine needs "
                       "Rayleigh damping C = αM + βK with α, β ≥ 0, use the dense Simulator");
  BandedChain out;
  out.mass = M.diagonal();
  out.stiffness_diagonal = K.diagonal();
  out.stiffness_off = n > 1 ? Eigen::VectorXd(K.diagonal(1)) : Eigen::VectorXd(0);
  out.rayleigh_mass = alpha;
  out.rayleigh_stiffness = beta;
  out.forcing = system.forcing();
  out.validate();
  return out;
}

LinearSystem BandedChain::dense() const {
  validate();
  const Eigen::Index n = dof();
  Eigen::MatrixXd M = mass.asDiagonal();
  Eigen::MatrixXd K = stiffness_diagonal.asDiagonal();
  for (Eigen::Index i = 0; i + 1 < n; ++i) K(i, i + 1) = K(i + 1, i) = stiffness_off(i);
  Eigen::MatrixXd C = rayleigh_mass * M + rayleigh_stiffness * K;
  return LinearSystem(std::move(M), std::move(C), std::move(K), forcing);
}

bool lapack_available() {
#ifdef VIBRO_HAVE_LAPACK
  return true;
#else
  return false;
#endif
}

// ---------------------------------------------------------------------------------------------
// ChainModes

ChainModes::ChainModes(BandedChain chain, TridiagonalSolver solver)
    : chain_(std::move(chain)), solver_(solver) {
  chain_.validate();
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index n = chain_.dof();
  sqrt_mass_ = chain_.mass.cwiseSqrt();
  inv_sqrt_mass_ = sqrt_mass_.cwiseInverse();
  // A = M^{-1/2} K M^{-1/2}, symmetric tridiagonal.
  Eigen::VectorXd diag = chain_.stiffness_diagonal.cwiseQuotient(chain_.mass);
  Eigen::VectorXd off(std::max<Eigen::Index>(n - 1, 0));
  for (Eigen::Index i = 0; i + 1 < n; ++i)
    off(i) = chain_.stiffness_off(i) * inv_sqrt_mass_(i) * inv_sqrt_mass_(i + 1);
  if (solver_ == TridiagonalSolver::automatic)
    solver_ = lapack_available() ? TridiagonalSolver::lapack : TridiagonalSolver::eigen;
  if (solver_ == TridiagonalSolver::lapack) {
#ifdef VIBRO_HAVE_LAPACK
    if (n > std::numeric_limits<int>::max() / 18)
      throw InvalidInput("chain: " + std::to_string(n) + " masses is too many for LAPACK's int sizes");
    const int N = static_cast<int>(n);
    Eigen::VectorXd d = diag, e = Eigen::VectorXd::Zero(n);
    if (n > 1) e.head(n - 1) = off;
    omega2_.resize(n);
    q_.resize(n, n);
    const double vl = 0.0, vu = 0.0;
    const int il = 0, iu = 0, ldz = N, nzc = N, lwork = 18 * N, liwork = 10 * N;
    int m = 0, tryrac = 1, info = 0;
    std::vector<int> isuppz(2 * static_cast<std::size_t>(n)), iwork(static_cast<std::size_t>(liwork));
    std::vector<double> work(static_cast<std::size_t>(lwork));
    dstemr_("V", "A", &N, d.data(), e.data(), &vl, &vu, &il, &iu, &m, omega2_.data(), q_.data(),
            &ldz, &nzc, isuppz.data(), &tryrac, work.data(), &lwork, iwork.data(), &liwork, &info,
            1, 1);
    if (info != 0 || m != N)
      throw std::runtime_error("LAPACK dstemr failed (info = " + std::to_string(info) + ", " +
                               std::to_string(m) + " of " + std::to_string(N) + " eigenpairs)");
#else
    throw InvalidInput("chain modes: TridiagonalSolver::lapack requested but this build has no LAPACK");
#endif
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
    eig.computeFromTridiagonal(diag, off, Eigen::ComputeEigenvectors);
    if (eig.info() != Eigen::Success)
      throw std::runtime_error("tridiagonal eigensolver (Eigen) did not converge");
    omega2_ = eig.eigenvalues();
    q_ = eig.eigenvectors();
  }
  const double top = omega2_.maxCoeff();
  if (!(omega2_(0) > 1e-13 * top))
    throw InvalidInput("chain: lowest ω² = " + number_text(omega2_(0)) + " (largest " +
                       number_text(top) +
                       "): a rigid-body mode; the modal chain engine needs K positive definite "
                       "(tie the chain to a wall) — the dense Simulator handles free chains");
  omega_ = omega2_.cwiseSqrt();
  sigma_ = 0.5 * (chain_.rayleigh_mass + chain_.rayleigh_stiffness * omega2_.array()).matrix();
  root_.resize(n);
  regime_.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double D = omega2_(k) - sigma_(k) * sigma_(k);
    regime_(k) = D > 0.0 ? 1 : (D < 0.0 ? -1 : 0);
    root_(k) = std::sqrt(std::abs(D));
  }
  // Modal forcing φ_kᵀ f = Qᵀ M^{-1/2} f and the periodic particular solution.
  const HarmonicForcing& f = chain_.forcing;
  const double W = f.frequency;
  const Eigen::VectorXd p0 = q_.transpose() * f.constant.cwiseProduct(inv_sqrt_mass_);
  const Eigen::VectorXd pc = q_.transpose() * f.cosine.cwiseProduct(inv_sqrt_mass_);
  const Eigen::VectorXd ps = q_.transpose() * f.sine.cwiseProduct(inv_sqrt_mass_);
  c0_ = p0.cwiseQuotient(omega2_);
  cc_.resize(n);
  cs_.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double detune = omega2_(k) - W * W, friction = 2.0 * sigma_(k) * W;
    const double det = detune * detune + friction * friction;
    const double scale = std::max(omega2_(k), W * W);
    if (det <= 1e-24 * scale * scale && (pc(k) != 0.0 || ps(k) != 0.0))
      throw InvalidInput("chain: mode " + std::to_string(k) + " (ω = " + number_text(omega_(k)) +
                         ") is in undamped resonance with the forcing (Ω = " + number_text(W) +
                         "): its response grows secularly, which the modal chain engine does not "
                         "represent — use the dense Simulator or add damping");
    cc_(k) = det > 0.0 ? (detune * pc(k) - friction * ps(k)) / det : 0.0;
    cs_(k) = det > 0.0 ? (detune * ps(k) + friction * pc(k)) / det : 0.0;
  }
  setup_seconds_ = seconds_since(start);
}

Eigen::VectorXd ChainModes::phi_row(Eigen::Index i) const {
  return q_.row(i).transpose() * inv_sqrt_mass_(i);
}

void ChainModes::to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                          Eigen::Ref<Eigen::VectorXd> ud) const {
  const double W = frequency(), c = std::cos(W * t), s = std::sin(W * t);
  u.noalias() = q_.transpose() * x.cwiseProduct(sqrt_mass_);
  ud.noalias() = q_.transpose() * v.cwiseProduct(sqrt_mass_);
  u -= c0_ + cc_ * c + cs_ * s;
  ud -= W * (cs_ * c - cc_ * s);
}

void ChainModes::to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                             const Eigen::Ref<const Eigen::VectorXd>& ud,
                             Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  const double W = frequency(), c = std::cos(W * t), s = std::sin(W * t);
  const Eigen::VectorXd q = u + c0_ + cc_ * c + cs_ * s;
  const Eigen::VectorXd qd = ud + W * (cs_ * c - cc_ * s);
  x.noalias() = q_ * q;
  v.noalias() = q_ * qd;
  x.array() *= inv_sqrt_mass_.array();
  v.array() *= inv_sqrt_mass_.array();
}

void ChainModes::advance(double tau, const Eigen::Ref<const Eigen::VectorXd>& u,
                         const Eigen::Ref<const Eigen::VectorXd>& ud,
                         Eigen::Ref<Eigen::VectorXd> u_out, Eigen::Ref<Eigen::VectorXd> ud_out,
                         double* bound) const {
  const Eigen::Index n = dof();
  for (Eigen::Index k = 0; k < n; ++k) {
    const double sg = sigma_(k), w2 = omega2_(k), r = root_(k);
    double ec, es;  // e^{-στ} C(τ), e^{-στ} S(τ)
    if (regime_(k) > 0) {
      const double e = std::exp(-sg * tau);
      ec = e * std::cos(r * tau);
      es = e * std::sin(r * tau) / r;
    } else if (regime_(k) < 0) {
      // Rates σ ∓ r; the slow one written without cancellation (σ - r = ω²/(σ + r)).
      const double e1 = std::exp(-(w2 / (sg + r)) * tau), e2 = std::exp(-(sg + r) * tau);
      ec = 0.5 * (e1 + e2);
      es = r * tau < 0.5 ? e2 * std::expm1(2.0 * r * tau) / (2.0 * r) : (e1 - e2) / (2.0 * r);
    } else {
      const double e = std::exp(-sg * tau);
      ec = e;
      es = e * tau;
    }
    const double u0 = u(k), v0 = ud(k);
    const double u1 = ec * u0 + es * (v0 + sg * u0);
    const double v1 = ec * v0 - es * (sg * v0 + w2 * u0);
    u_out(k) = u1;
    ud_out(k) = v1;
    if (bound) bound[k] = (2.0 * sg + omega_(k)) * std::sqrt(v1 * v1 + w2 * u1 * u1);
  }
}

// ---------------------------------------------------------------------------------------------
// Simulator

void ModalSimulatorOptions::validate() const {
  require_option(trigger, "trigger");
  require_option(simultaneity, "simultaneity", true);
  require_option(chatter_height, "chatter_height", true);
  require_option(chatter_velocity, "chatter_velocity", true);
  require_option(contact_velocity, "contact_velocity", true);
  require_option(event_window, "event_window", true);
  require_option(length_scale, "length_scale", true);
  if (max_events < 1)
    throw InvalidInput("solver.max_events = " + std::to_string(max_events) + ": must be ≥ 1");
  if (stop_after_impacts < 0)
    throw InvalidInput("stop_after_impacts = " + std::to_string(stop_after_impacts) + ": must be ≥ 0");
  if (trigger >= 1e-3)
    throw InvalidInput("solver.trigger = " + number_text(trigger) + ": must be < 1e-3");
}

const char* to_string(ModalRunStatus s) {
  switch (s) {
    case ModalRunStatus::completed: return "completed";
    case ModalRunStatus::event_cap: return "event cap reached";
    case ModalRunStatus::chatter: return "chatter (sticking not supported by the modal engine)";
    case ModalRunStatus::sticking: return "sticking (not supported by the modal engine)";
    case ModalRunStatus::numerical_failure: return "numerical failure";
  }
  return "?";
}

ModalChainSimulator::ModalChainSimulator(const ChainModes& modes, std::vector<Stop> stops,
                                         ModalSimulatorOptions options)
    : modes_(&modes), stops_(std::move(stops)), options_(options) {
  options_.validate();
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index n = modes.dof();
  const double W = modes.frequency();
  const auto m = static_cast<Eigen::Index>(stops_.size());
  for (std::size_t j = 0; j < stops_.size(); ++j) {
    Stop& s = stops_[j];
    const std::string label = "stops[" + std::to_string(j) + "]";
    if (s.mass < 0 || s.mass >= n)
      throw InvalidInput(label + ": mass " + std::to_string(s.mass) + " is not in [0, " +
                         std::to_string(n - 1) + "]");
    if (s.kind == Stop::Kind::between && (s.other < 0 || s.other >= n || s.other == s.mass))
      throw InvalidInput(label + ": other mass " + std::to_string(s.other) +
                         " must be in [0, " + std::to_string(n - 1) + "] and differ from mass");
    if (!std::isfinite(s.position) || !std::isfinite(s.amplitude) || !std::isfinite(s.phase) ||
        s.amplitude < 0.0)
      throw InvalidInput(label + ": position, amplitude and phase must be finite, amplitude ≥ 0");
    if (!(s.restitution >= 0.0 && s.restitution <= 1.0))
      throw InvalidInput(label + ": restitution = " + number_text(s.restitution) + ": must be in [0, 1]");
    if (s.amplitude > 0.0 && !(W > 0.0))
      throw InvalidInput(label + ": a moving stop needs forcing.frequency > 0");
    if (s.name.empty()) {
      s.name = s.kind == Stop::Kind::upper ? "upper" : (s.kind == Stop::Kind::lower ? "lower" : "between");
      s.name += " x" + std::to_string(s.mass);
      if (s.kind == Stop::Kind::between) s.name += "-x" + std::to_string(s.other);
    }
  }
  phi_.resize(m, n);
  h_const_.resize(m);
  h_cos_.resize(m);
  h_sin_.resize(m);
  const Eigen::MatrixXd& Q = modes.vectors();
  const Eigen::VectorXd& mass = modes.chain().mass;
  for (Eigen::Index j = 0; j < m; ++j) {
    const Stop& s = stops_[static_cast<std::size_t>(j)];
    const Normal w = normal_of(s);
    phi_.row(j) = Q.row(w.i) * (w.wi / std::sqrt(mass(w.i)));
    if (w.k >= 0) phi_.row(j) += Q.row(w.k) * (w.wk / std::sqrt(mass(w.k)));
    h_const_(j) = phi_.row(j).dot(modes.particular_constant()) - s.s0();
    h_cos_(j) = phi_.row(j).dot(modes.particular_cosine()) - s.s_cos();
    h_sin_(j) = phi_.row(j).dot(modes.particular_sine()) - s.s_sin();
  }
  abs_phi_ = phi_.cwiseAbs();
  curvature_ = (W * W) * (h_cos_.cwiseAbs2() + h_sin_.cwiseAbs2()).cwiseSqrt();
  stop_setup_seconds_ = seconds_since(start);
  u0_.resize(n);
  ud0_.resize(n);
  u_.resize(n);
  ud_.resize(n);
  bnd_.resize(n);
  stack_.resize(200);
  for (Point& p : stack_) {
    p.h.resize(m);
    p.d.resize(m);
    p.bound.resize(m);
  }
  trig_.resize(m);
  last_below_.resize(m);
  leaving_.assign(static_cast<std::size_t>(m), false);
}

void ModalChainSimulator::harmonic(int j, double t, double* value, double* slope) const {
  const double W = modes_->frequency(), c = std::cos(W * t), s = std::sin(W * t);
  *value = h_const_(j) + h_cos_(j) * c + h_sin_(j) * s;
  *slope = W * (h_sin_(j) * c - h_cos_(j) * s);
}

double ModalChainSimulator::gap_from(int stop, double t, const Eigen::Ref<const Eigen::VectorXd>& u) const {
  double value, slope;
  harmonic(stop, t, &value, &slope);
  return phi_.row(stop).dot(u) + value;
}

void ModalChainSimulator::evaluate(double tau, Point& p, int only) {
  ++evaluations_;
  p.tau = tau;
  const bool full = only < 0;
  modes_->advance(tau, u0_, ud0_, u_, ud_, full ? bnd_.data() : nullptr);
  const double t = seg_t0_ + tau;
  const double W = modes_->frequency(), c = std::cos(W * t), s = std::sin(W * t);
  if (full) {
    p.h.noalias() = phi_ * u_;
    p.d.noalias() = phi_ * ud_;
    p.bound.noalias() = abs_phi_ * bnd_;
    p.bound += curvature_;
    p.h += h_const_ + h_cos_ * c + h_sin_ * s;
    p.d += W * (h_sin_ * c - h_cos_ * s);
  } else {
    p.h(only) = phi_.row(only).dot(u_) + h_const_(only) + h_cos_(only) * c + h_sin_(only) * s;
    p.d(only) = phi_.row(only).dot(ud_) + W * (h_sin_(only) * c - h_cos_(only) * s);
  }
}

bool ModalChainSimulator::certified(int j, const Point& a, const Point& b) const {
  const double L = b.tau - a.tau;
  return upper_bound(a.h(j), a.d(j), b.h(j), b.d(j), a.bound(j), L) <= trig_(j);
}

double ModalChainSimulator::refine_root(int j, double lo, double hi) {
  // Safeguarded Newton on h_j = 0 keeping a bracket h_j(lo) ≤ 0 < h_j(hi): it converges to the
  // sign change inside the bracket; the answer is the converged iterate, or the end of the closed
  // bracket with the smaller |h| (never an end that was merely never moved).
  Point& p = stack_.back();
  evaluate(lo, p, j);
  double h_lo = p.h(j);
  if (h_lo > 0.0) return lo;
  double h_hi = std::numeric_limits<double>::infinity();
  double x = 0.5 * (lo + hi);
  for (int it = 0; it < 200; ++it) {
    evaluate(x, p, j);
    const double h = p.h(j), d = p.d(j);
    if (h == 0.0) return x;
    if (h < 0.0) {
      lo = x;
      h_lo = h;
    } else {
      hi = x;
      h_hi = h;
    }
    const double t_abs = std::abs(seg_t0_) + std::abs(hi);
    if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() * t_abs)
      return std::abs(h_lo) <= std::abs(h_hi) ? lo : hi;  // bracket closed on the sign change
    double next = d != 0.0 ? x - h / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // Newton inside the bracket, else bisection
    // Newton has converged when its step no longer moves x: x is then the root (the far end of
    // the bracket may still be the starting point, e.g. a root of h = 0 just left behind).
    if (next == x) return x;
    x = next;
  }
  return x;
}

bool ModalChainSimulator::search(int ia, int ib, int free, double* tau_hit, int* stop_hit) {
  // Slots: ia = evaluated left end A, ib = evaluated right end B, slots ≥ free are scratch.
  if (free + 2 >= static_cast<int>(stack_.size()))
    throw std::runtime_error("modal crossing search: subdivision depth exceeded");
  const Point& A = stack_[static_cast<std::size_t>(ia)];
  const Point& B = stack_[static_cast<std::size_t>(ib)];
  const auto m = static_cast<int>(trig_.size());
  // A guard that starts on its surface and leaves it (just after an impact) is within rounding
  // of zero at τ = 0: that point must not bracket a root, or the root finder could return the
  // surface just left (rounding makes h(0⁺) of either sign); its first bracket point is later.
  for (int j = 0; j < m; ++j)
    if (A.h(j) <= 0.0 && !(A.tau == 0.0 && leaving_[static_cast<std::size_t>(j)]))
      last_below_(j) = std::max(last_below_(j), A.tau);
  int uncertified = 0, above = -1;
  for (int j = 0; j < m; ++j)
    if (!certified(j, A, B)) {
      ++uncertified;
      if (B.h(j) > trig_(j) && above < 0) above = j;
    }
  if (uncertified == 0) return false;
  // The root of h_j = 0 before B, bracketed from the last point seen with h_j ≤ 0. A guard that
  // has not been ≤ 0 since the segment began (it started inside its band, just after an impact,
  // and is re-armed above its start) has no such bracket: it is placed at B, where it has risen
  // above its re-armed trigger (penetration ≤ h(0) + ε, as in the dense engine).
  auto root_of = [&](int j) {
    if (!std::isfinite(last_below_(j))) return B.tau;
    return refine_root(j, last_below_(j), B.tau);
  };
  if (B.tau - A.tau <= resolution_) {
    bool found = false;
    for (int j = 0; j < m; ++j)
      if (B.h(j) > trig_(j)) {
        const double r = root_of(j);
        if (!found || r < *tau_hit) {
          *tau_hit = r;
          *stop_hit = j;
          found = true;
        }
      }
    return found;
  }
  if (uncertified == 1 && above >= 0 && std::isfinite(last_below_(above))) {
    // Shortcut: the one uncertified guard rises above ε at b; accept its root r if [a, r] is
    // certified for it (the others are certified on all of [a, b]).
    const double r = root_of(above);
    if (r <= A.tau) {
      *tau_hit = r;
      *stop_hit = above;
      return true;
    }
    Point& R = stack_[static_cast<std::size_t>(free)];
    evaluate(r, R, above);
    if (upper_bound(A.h(above), A.d(above), R.h(above), R.d(above), A.bound(above), r - A.tau) <=
        trig_(above)) {
      *tau_hit = r;
      *stop_hit = above;
      return true;
    }
  }
  // Halve, earliest half first.
  evaluate(A.tau + 0.5 * (B.tau - A.tau), stack_[static_cast<std::size_t>(free)]);
  if (search(ia, free, free + 1, tau_hit, stop_hit)) return true;
  return search(free, ib, free + 1, tau_hit, stop_hit);
}

ModalRunSummary ModalChainSimulator::run(double t0, const Eigen::VectorXd& x0,
                                         const Eigen::VectorXd& v0, double t_end,
                                         const std::vector<ModalObserver*>& observers,
                                         const std::vector<Observer*>& event_observers) {
  const ChainModes& md = *modes_;
  const BandedChain& ch = md.chain();
  const Eigen::Index n = md.dof();
  const int m = static_cast<int>(stops_.size());
  if (x0.size() != n || v0.size() != n)
    throw InvalidInput("initial state: x has " + std::to_string(x0.size()) + " and v has " +
                       std::to_string(v0.size()) + " entries, expected " + std::to_string(n));
  if (!x0.allFinite() || !v0.allFinite()) throw InvalidInput("initial state: not finite");
  if (!std::isfinite(t0) || !std::isfinite(t_end) || t_end < t0)
    throw InvalidInput("time span: [" + number_text(t0) + ", " + number_text(t_end) +
                       "] must be finite with t_end ≥ t0");

  // Scales, as Simulator::scales.
  const double W = md.frequency();
  double omega = W > 0.0 ? W : md.omega().maxCoeff();
  if (!(omega > 0.0)) omega = 1.0;
  const double kmax = std::max(ch.stiffness_diagonal.cwiseAbs().maxCoeff(),
                               n > 1 ? ch.stiffness_off.cwiseAbs().maxCoeff() : 0.0);
  const double stiff = std::max(kmax, ch.mass.maxCoeff() * omega * omega);
  const double fmax = ch.forcing.constant.cwiseAbs().maxCoeff() +
                      ch.forcing.cosine.cwiseAbs().maxCoeff() + ch.forcing.sine.cwiseAbs().maxCoeff();
  double L = options_.length_scale;
  if (L == 0.0) {
    L = x0.cwiseAbs().maxCoeff();
    for (const Stop& s : stops_) L = std::max({L, std::abs(s.position), s.amplitude});
    L = std::max({L, 1e-300, v0.cwiseAbs().maxCoeff() / omega, fmax / stiff});
  }
  const double V = L * omega, T = 2.0 * std::numbers::pi / omega;
  const double eps_gap = options_.trigger * L;
  const double v_chatter = options_.chatter_velocity * V;
  const double h_chatter = options_.chatter_height * L;
  const double v_contact = options_.contact_velocity * V;
  const double dt_simultaneous = options_.simultaneity * T;
  const double window = options_.event_window > 0.0 ? options_.event_window : T;
  resolution_ = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), T);
  const double step = 1.0 / std::max(W, md.omega().maxCoeff());

  for (int j = 0; j < m; ++j) {
    const Stop& s = stops_[static_cast<std::size_t>(j)];
    const Normal w = normal_of(s);
    const double g = w.wi * x0(w.i) + (w.k >= 0 ? w.wk * x0(w.k) : 0.0) - s.s0() -
                     s.s_cos() * std::cos(W * t0) - s.s_sin() * std::sin(W * t0);
    if (g > eps_gap)
      throw InvalidInput("initial state violates stops[" + std::to_string(j) + "] (" + s.name +
                         ") by " + number_text(g) + " at t = " + number_text(t0));
  }

  ModalRunSummary summary;
  summary.length_scale = L;
  summary.velocity_scale = V;
  summary.time_scale = T;
  evaluations_ = 0;
  seg_t0_ = t0;
  md.to_modal(t0, x0, v0, u0_, ud0_);
  for (ModalObserver* o : observers) o->begin(*this, t0);
  double t = t0;
  EventRate rate(options_.max_events, window);
  std::set<std::vector<int>> sets;

  auto emit = [&](const Event& e) {
    for (ModalObserver* o : observers) o->event(e);
    for (Observer* o : event_observers) o->event(e);
  };
  auto finish = [&](ModalRunStatus status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    summary.t = t;
    summary.x.resize(n);
    summary.v.resize(n);
    md.to_physical(t, u0_, ud0_, summary.x, summary.v);
    summary.evaluations = evaluations_;
    summary.contact_sets_built = sets.size();
    for (ModalObserver* o : observers) o->end(t);
    for (Observer* o : event_observers) o->end(t);
    return summary;
  };
  // Gap, rate and free acceleration of stop j at the current (t, u0_, ud0_).
  auto gap_rate = [&](int j) {
    double value, slope;
    harmonic(j, t, &value, &slope);
    return phi_.row(j).dot(ud0_) + slope;
  };
  auto gap_acceleration = [&](int j) {
    const double c = std::cos(W * t), s = std::sin(W * t);
    const Eigen::VectorXd& sg = md.decay();
    const Eigen::VectorXd& w2 = md.omega_squared();
    double a = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) a -= phi_(j, k) * (2.0 * sg(k) * ud0_(k) + w2(k) * u0_(k));
    return a - W * W * (h_cos_(j) * c + h_sin_(j) * s);
  };
  auto state_text = [&](int j) {
    return "stops[" + std::to_string(j) + "] (" + stops_[static_cast<std::size_t>(j)].name + ")";
  };

  // Impacts on `impacting` at time t. Returns a status other than completed if the run must end.
  std::string stop_message;
  auto impact = [&](const std::vector<int>& impacting) -> ModalRunStatus {
    const auto k = static_cast<Eigen::Index>(impacting.size());
    Eigen::VectorXd before(k), q(k), accel(k);
    Eigen::MatrixXd G(k, k);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = impacting[static_cast<std::size_t>(a)];
      const Stop& s = stops_[static_cast<std::size_t>(j)];
      before(a) = gap_rate(j);
      accel(a) = gap_acceleration(j);
      const double r = s.restitution;
      if (r > 0.0 && r < 1.0 && accel(a) > 0.0) {
        const double u = before(a);
        const double rise = (r * u) * (r * u) / (2.0 * accel(a));
        if (u <= v_chatter || rise <= h_chatter) {
          stop_message = "chatter on " + state_text(j) + " at t = " + number_text(t) +
                         ": approach speed " + number_text(u) + ", next bounce would rise " +
                         number_text(rise) + " ≤ chatter_height·L = " + number_text(h_chatter) +
                         "; the Budd–Dux accumulation point t + 2ru/(a(1-r)) = " +
                         number_text(t + 2.0 * r * u / (accel(a) * (1.0 - r))) +
                         " would start sticking, which the modal engine does not model";
          return ModalRunStatus::chatter;
        }
      }
      q(a) = (1.0 + r) * before(a);
      for (Eigen::Index b = 0; b < k; ++b)
        G(a, b) = delassus_entry(normal_of(s), normal_of(stops_[static_cast<std::size_t>(impacting[static_cast<std::size_t>(b)])]),
                                 ch.mass);
    }
    sets.insert(impacting);
    const Eigen::VectorXd impulse = solve_lcp(G, q);
    for (Eigen::Index a = 0; a < k; ++a) ud0_ -= phi_.row(impacting[static_cast<std::size_t>(a)]).transpose() * impulse(a);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = impacting[static_cast<std::size_t>(a)];
      const double g = gap_from(j, t, u0_);
      if (g > 0.0) u0_ -= phi_.row(j).transpose() * (g / G(a, a));
    }
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = impacting[static_cast<std::size_t>(a)];
      const double after = gap_rate(j);
      emit({t, j, EventKind::impact, before(a), after, 0.0});
      ++summary.impacts;
      if (after >= -v_contact && gap_acceleration(j) > 0.0) {
        stop_message = state_text(j) + " would stick at t = " + number_text(t) +
                       " (post-impact normal speed " + number_text(after) +
                       ", free gap acceleration into the stop); sticking is not modelled by the "
                       "modal engine";
        return ModalRunStatus::sticking;
      }
    }
    return ModalRunStatus::completed;
  };

  try {
    {  // Stops touched at t0.
      std::vector<int> impacting;
      for (int j = 0; j < m; ++j) {
        if (gap_from(j, t, u0_) < -eps_gap) continue;
        const double gd = gap_rate(j);
        if (gd > v_contact) impacting.push_back(j);
        else if (gd >= -v_contact && gap_acceleration(j) > 0.0)
          return finish(ModalRunStatus::sticking,
                        state_text(j) + " is in resting contact at t0 = " + number_text(t) +
                            "; sticking is not modelled by the modal engine");
      }
      if (!impacting.empty()) {
        const ModalRunStatus st = impact(impacting);
        if (st != ModalRunStatus::completed) return finish(st, stop_message);
      }
    }
    while (true) {
      const double span = t_end - t;
      Point& P0 = stack_[0];
      evaluate(0.0, P0);
      for (int j = 0; j < m; ++j) {
        trig_(j) = eps_gap;
        if (P0.h(j) > 0.0 && P0.d(j) <= 0.0) trig_(j) += P0.h(j);
        leaving_[static_cast<std::size_t>(j)] = P0.h(j) >= -eps_gap && P0.d(j) < 0.0;
        last_below_(j) = -std::numeric_limits<double>::infinity();
      }
      bool hit = false;
      double tau_hit = span;
      int stop_hit = -1;
      for (double a = 0.0; a < span && !hit && m > 0;) {
        const double b = std::min(a + step, span);
        evaluate(b, stack_[1]);
        hit = search(0, 1, 2, &tau_hit, &stop_hit);
        if (!hit) std::swap(stack_[0], stack_[1]);
        a = b;
      }
      const double tau = hit ? tau_hit : span;
      const double t_next = hit ? t + tau : t_end;
      ++summary.segments;
      if (!observers.empty()) {
        const ModalSegmentView view(*this, t, t_next);
        for (ModalObserver* o : observers) o->segment(view);
      }
      Point& P = stack_[0];
      evaluate(tau, P);
      u0_ = u_;
      ud0_ = ud_;
      t = t_next;
      seg_t0_ = t;
      if (!u0_.allFinite() || !ud0_.allFinite())
        return finish(ModalRunStatus::numerical_failure, "non-finite modal state at t = " + number_text(t));
      if (!hit) break;
      std::vector<int> impacting;
      for (int j = 0; j < m; ++j) {
        const bool fired =
            j == stop_hit || (P.d(j) > 0.0 && P.h(j) >= -std::max(trig_(j), P.d(j) * dt_simultaneous));
        if (fired) impacting.push_back(j);
      }
      const ModalRunStatus st = impact(impacting);
      if (st != ModalRunStatus::completed) return finish(st, stop_message);
      if (options_.stop_after_impacts > 0 && summary.impacts >= options_.stop_after_impacts)
        return finish(ModalRunStatus::completed,
                      "stopped after " + std::to_string(summary.impacts) + " impacts as asked (t_end not reached)");
      if (rate.exceeded(t))
        return finish(ModalRunStatus::event_cap,
                      "event cap: more than " + std::to_string(options_.max_events) +
                          " events within " + number_text(window) + " time units, at t = " +
                          number_text(t) + ", " + state_text(impacting.front()));
    }
  } catch (const std::runtime_error& e) {
    return finish(ModalRunStatus::numerical_failure, std::string(e.what()) + " (at t = " + number_text(t) + ")");
  }
  return finish(ModalRunStatus::completed, "");
}

// ---------------------------------------------------------------------------------------------
// Observers

Eigen::Index ModalSegmentView::dof() const { return sim_->modes().dof(); }

void ModalSegmentView::state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  const ChainModes& md = sim_->modes();
  Eigen::VectorXd u(md.dof()), ud(md.dof());
  md.advance(t - sim_->segment_start(), sim_->segment_u(), sim_->segment_ud(), u, ud);
  md.to_physical(t, u, ud, x, v);
}

double ModalSegmentView::gap(int stop, double t) const {
  const ChainModes& md = sim_->modes();
  Eigen::VectorXd u(md.dof()), ud(md.dof());
  md.advance(t - sim_->segment_start(), sim_->segment_u(), sim_->segment_ud(), u, ud);
  return sim_->gap_from(stop, t, u);
}

void ModalSamples::segment(const ModalSegmentView& view) {
  while (next_ < times_.size() && times_[next_] <= view.t_end()) {
    const double ti = times_[next_++];
    if (ti < view.t_begin()) continue;  // before the run started
    t.push_back(ti);
    x.emplace_back(view.dof());
    v.emplace_back(view.dof());
    view.state(ti, x.back(), v.back());
  }
}

}  // namespace vibro
