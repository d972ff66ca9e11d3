#include "vibro/modal.hpp"

#include "vibro/contact.hpp"  // solve_lcp

#include "secular.hpp"

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

/// out = Qᵀ in (transpose) or Q in. For a few columns one matrix-vector product each: a matrix
/// product would first copy (pack) all of Q, as much memory traffic as the product itself and,
/// at N = 10 000, several times slower (measured: 80 % of a Newton–Krylov run in the packing).
void times(const Eigen::MatrixXd& Q, bool transpose, const Eigen::Ref<const Eigen::MatrixXd>& in,
           Eigen::Ref<Eigen::MatrixXd> out) {
  if (in.cols() > 8) {
    if (transpose) out.noalias() = Q.transpose() * in;
    else out.noalias() = Q * in;
    return;
  }
  for (Eigen::Index c = 0; c < in.cols(); ++c) {
    if (transpose) out.col(c).noalias() = Q.transpose() * in.col(c);
    else out.col(c).noalias() = Q * in.col(c);
  }
}

/// out = Qᵀ in (in: N × k, a few columns), reading Q once. A contact set's forcing is nonzero
/// only on the driven masses' rows, often a few: then the sum over those rows of Q (each a
/// strided sweep, one cache line per entry), else each column of Q against all of in (which
/// stays in cache). times() would read all of Q once per column (~0.03 s each at N = 10 000).
void times_once(const Eigen::MatrixXd& Q, const Eigen::Ref<const Eigen::MatrixXd>& in, Eigen::Ref<Eigen::MatrixXd> out) {
  std::vector<Eigen::Index> rows;
  for (Eigen::Index l = 0; l < in.rows(); ++l)
    if (in.row(l).cwiseAbs().maxCoeff() > 0.0) rows.push_back(l);
  // A strided sweep moves 8 times the bytes it uses, so rows win below N/8 of them (N/16: a margin).
  if (static_cast<Eigen::Index>(rows.size()) * 16 <= Q.rows()) {
    out.setZero();
    for (Eigen::Index l : rows) out.noalias() += Q.row(l).transpose() * in.row(l);
    return;
  }
  for (Eigen::Index k = 0; k < Q.cols(); ++k) out.row(k).noalias() = Q.col(k).transpose() * in;
}

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
  for (std::size_t h = 0; h < forcing.harmonics.size(); ++h) {
    const ForcingHarmonic& fh = forcing.harmonics[h];
    const std::string who = "forcing.harmonics[" + std::to_string(h) + "]";
    if (fh.order < 2)
      throw InvalidInput(who + ".order: is " + std::to_string(fh.order) +
                         ": an extra harmonic has order ≥ 2 (order 1 is forcing.cosine and forcing.sine)");
    for (std::size_t g = 0; g < h; ++g)
      if (forcing.harmonics[g].order == fh.order)
        throw InvalidInput(who + ".order: order " + std::to_string(fh.order) + " is given twice (also harmonics[" +
                           std::to_string(g) + "])");
    require_length(fh.cosine, n, who + ".cosine");
    require_length(fh.sine, n, who + ".sine");
    require_finite_vector(fh.cosine, who + ".cosine");
    require_finite_vector(fh.sine, who + ".sine");
  }
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
  // Modal forcing φ_kᵀ f = Qᵀ M^{-1/2} f.
  const HarmonicForcing& f = chain_.forcing;
  const auto H = static_cast<Eigen::Index>(f.harmonics.size());
  Eigen::MatrixXd Pc(n, H), Ps(n, H);
  if (H > 0) {
    Eigen::MatrixXd Fc(n, H), Fs(n, H);
    for (Eigen::Index h = 0; h < H; ++h) {
      Fc.col(h) = f.harmonics[static_cast<std::size_t>(h)].cosine.cwiseProduct(inv_sqrt_mass_);
      Fs.col(h) = f.harmonics[static_cast<std::size_t>(h)].sine.cwiseProduct(inv_sqrt_mass_);
    }
    Pc.noalias() = q_.transpose() * Fc;
    Ps.noalias() = q_.transpose() * Fs;
  }
  finish(q_.transpose() * f.constant.cwiseProduct(inv_sqrt_mass_), q_.transpose() * f.cosine.cwiseProduct(inv_sqrt_mass_),
         q_.transpose() * f.sine.cwiseProduct(inv_sqrt_mass_), Pc, Ps);
  setup_seconds_ = seconds_since(start);
}

namespace {

/// The largest periodic response of a mode, as a multiple of its drive's largest quasi-static
/// modal response, that the modal engine accepts.
///
/// Why. ChainModes writes mode k as q_k = p_k(t) + u_k, p_k its periodic response to a harmonic
/// of rate r (amplitude |φ_kᵀ f| / √((ω_k² − r²)² + (2σ_k r)²)) and u_k a free vibration. Near
/// resonance p_k is large and u_k starts as nearly −p_k, so q_k carries the rounding of p_k (of
/// its phase r t above all, ε r t |p_k|) however small q_k is. Measured on an undamped 3-mass
/// chain with 2Ω = ω_0 (1 + δ) and a stop (tests/framework/test_modal_harmonics.cpp, 40 periods,
/// impact times against the long-double reference): 9.4e-11 T at δ = 1e-4, 1.4e-7 T at 1e-6,
/// 4.8e-4 T at 1e-8, while the dense engine, whose augmented flow divides by no detuning, stayed
/// within 2.2e-8 T at every δ down to exact resonance; free flight of x'' + x = F cos rt against
/// its closed form: the modal error is 2.3e-14 |p_k| at t ≈ 365, growing with t. A mode whose
/// |p_k| exceeds kMaxResonanceGain times R = max_l |φ_lᵀ f| / max(ω_l², r²), the drive's largest
/// quasi-static modal response, is therefore refused (InvalidInput naming the mode, the harmonic,
/// the detuning and the damping ratio): the rounding it adds stays below kMaxResonanceGain · ε
/// ≈ 2e-12 of R per unit of phase. For a mode forced as much as any other this refuses an
/// undamped mode within a relative 5e-5 of r, or one with damping ratio below 5e-5 at r. An
/// undamped forced mode in exact resonance (no periodic response) is refused as before.
constexpr double kMaxResonanceGain = 1e4;

void check_resonance(const Eigen::VectorXd& omega2, const Eigen::VectorXd& sigma, int order, double rate,
                     const Eigen::Ref<const Eigen::VectorXd>& pc, const Eigen::Ref<const Eigen::VectorXd>& ps,
                     const Eigen::Ref<const Eigen::VectorXd>& cc, const Eigen::Ref<const Eigen::VectorXd>& cs) {
  const Eigen::Index n = omega2.size();
  const std::string drive = order == 1 ? "the forcing (Ω = " + number_text(rate) + ")"
                                       : "the forcing's harmonic of order " + std::to_string(order) + " (" +
                                             std::to_string(order) + "Ω = " + number_text(rate) + ")";
  // R: the harmonic's largest quasi-static modal response |P_k| / max(ω_k², r²).
  double quasi_static = 0.0;
  for (Eigen::Index k = 0; k < n; ++k)
    quasi_static = std::max(quasi_static, std::hypot(pc(k), ps(k)) / std::max(omega2(k), rate * rate));
  for (Eigen::Index k = 0; k < n; ++k) {
    if (pc(k) == 0.0 && ps(k) == 0.0) continue;  // a mode the harmonic does not force
    const double detune = omega2(k) - rate * rate, friction = 2.0 * sigma(k) * rate;
    const double scale = std::max(omega2(k), rate * rate);
    if (detune * detune + friction * friction <= 1e-24 * scale * scale)
      throw InvalidInput("chain: mode " + std::to_string(k) + " (ω = " + number_text(std::sqrt(omega2(k))) +
                         ") is in undamped resonance with " + drive +
                         ": its response grows secularly, which the modal chain engine does not represent — use the "
                         "dense engine (solver.engine: dense), which is exact at resonance, or add damping");
    const double amplitude = std::hypot(cc(k), cs(k));
    if (amplitude > kMaxResonanceGain * quasi_static)
      throw InvalidInput("chain: mode " + std::to_string(k) + " (ω = " + number_text(std::sqrt(omega2(k))) +
                         ") is near resonance with " + drive + " (relative detuning " +
                         number_text(std::abs(std::sqrt(omega2(k)) - rate) / std::sqrt(omega2(k))) + ", modal damping ratio " +
                         number_text(sigma(k) / std::sqrt(omega2(k))) + "): its periodic response is " +
                         number_text(amplitude / quasi_static) +
                         " times the drive's quasi-static one (above " + number_text(kMaxResonanceGain) +
                         "), and the modal engine, which writes the motion as that response plus a free "
                         "vibration nearly cancelling it, would lose as many digits to rounding — use the dense "
                         "engine (solver.engine: dense), which is exact at and near resonance");
  }
}

}  // namespace

void ChainModes::finish(const Eigen::VectorXd& p0, const Eigen::VectorXd& pc, const Eigen::VectorXd& ps,
                        const Eigen::MatrixXd& Pc, const Eigen::MatrixXd& Ps) {
  const Eigen::Index n = omega2_.size();
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
  // The periodic particular solution of each mode for the modal forcing p0, pc, ps, and the same
  // for each extra harmonic at its rate k_h Ω (no constant part).
  const double W = chain_.forcing.frequency;
  c0_.resize(n);
  cc_.resize(n);
  cs_.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const HarmonicResponse<double> h = harmonic_response(omega2_(k), sigma_(k), W, p0(k), pc(k), ps(k));
    c0_(k) = h.c0;
    cc_(k) = h.cc;
    cs_(k) = h.cs;
  }
  check_resonance(omega2_, sigma_, 1, W, pc, ps, cc_, cs_);
  const auto H = static_cast<Eigen::Index>(chain_.forcing.harmonics.size());
  rates_.resize(H);
  hc_.resize(n, H);
  hs_.resize(n, H);
  for (Eigen::Index j = 0; j < H; ++j) {
    const ForcingHarmonic& fh = chain_.forcing.harmonics[static_cast<std::size_t>(j)];
    const double rate = fh.rate(W);
    rates_(j) = rate;
    for (Eigen::Index k = 0; k < n; ++k) {
      const HarmonicResponse<double> h = harmonic_response(omega2_(k), sigma_(k), rate, 0.0, Pc(k, j), Ps(k, j));
      hc_(k, j) = h.cc;
      hs_(k, j) = h.cs;
    }
    check_resonance(omega2_, sigma_, fh.order, rate, Pc.col(j), Ps.col(j), hc_.col(j), hs_.col(j));
  }
}

void ChainModes::add_particular(double t, double sign, Eigen::Ref<Eigen::VectorXd> q,
                                Eigen::Ref<Eigen::VectorXd> qd) const {
  for (Eigen::Index j = 0; j < rates_.size(); ++j) {
    const double r = rates_(j), c = std::cos(r * t), s = std::sin(r * t);
    q += sign * (hc_.col(j) * c + hs_.col(j) * s);
    qd += (sign * r) * (hs_.col(j) * c - hc_.col(j) * s);
  }
}

/// The secular route's data: the free modes, where the reduced coordinates sit, the restriction
/// levels (one per held stop) and scratch for the basis changes (these modes belong to one
/// simulator's cache, so one thread).
Eigen::Map<Eigen::MatrixXd> ChainModes::Workspace::matrix(int slot, Eigen::Index n, Eigen::Index k) {
  Eigen::VectorXd& store = store_[slot];
  if (store.size() < n * k) store.resize(n * k);
  return {store.data(), n, k};
}

/// The secular route's data: the free modes, where the reduced coordinates sit, and the
/// restriction levels (one per held stop). The products below use a Workspace's buffers:
/// 0 and 1 alternate between levels, 2 is the levels' own scratch.
struct ChainModes::Implicit {
  const ChainModes* free = nullptr;
  ChainReduction reduction;
  std::vector<detail::SecularLevel> levels;
  Eigen::VectorXd group_mass;  // M_r

  /// out (n_r × k) = Ψᵀ x for x in the free modal coordinates (N × k; not in buffers 0-2).
  void down(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Ref<Eigen::MatrixXd> out, Workspace& w) const {
    through(x, out, w, true);
  }
  /// out (N × k) = Ψ y.
  void up(const Eigen::Ref<const Eigen::MatrixXd>& y, Eigen::Ref<Eigen::MatrixXd> out, Workspace& w) const {
    through(y, out, w, false);
  }
  void through(const Eigen::Ref<const Eigen::MatrixXd>& in, Eigen::Ref<Eigen::MatrixXd> out, Workspace& w,
               bool down) const {
    const Eigen::Index k = in.cols(), count = static_cast<Eigen::Index>(levels.size());
    if (count == 0) {
      out = in;
      return;
    }
    const double* from = in.data();
    Eigen::Index rows = in.rows();
    int slot = 0;
    for (Eigen::Index i = 0; i < count; ++i) {
      const detail::SecularLevel& level = down ? levels[static_cast<std::size_t>(i)]
                                               : levels[static_cast<std::size_t>(count - 1 - i)];
      const Eigen::Map<const Eigen::MatrixXd> current(from, rows, k);
      double* scratch = w.matrix(2, level.scratch_size(k), 1).data();
      const Eigen::Index next_rows = down ? level.child_size() : level.parent_size();
      if (i + 1 == count) {
        if (down) level.to_child(current, out, scratch);
        else level.to_parent(current, out, scratch);
        return;
      }
      Eigen::Map<Eigen::MatrixXd> next = w.matrix(slot, next_rows, k);
      if (down) level.to_child(current, next, scratch);
      else level.to_parent(current, next, scratch);
      from = next.data();
      rows = next_rows;
      slot = 1 - slot;
    }
  }
  /// out = √m ∘ (T y): reduced coordinates to the mass-scaled full coordinates (held masses 0).
  void spread(const Eigen::Ref<const Eigen::MatrixXd>& y, Eigen::Ref<Eigen::MatrixXd> out) const {
    out.setZero();
    for (std::size_t r = 0; r < reduction.first.size(); ++r)
      for (Eigen::Index l = reduction.first[r]; l <= reduction.last[r]; ++l)
        out.row(l) = free->sqrt_mass_(l) * y.row(static_cast<Eigen::Index>(r));
  }
  /// out = the M-weighted mean over each group of M^{-1/2}·(rows of x) = Σ √m_l x_l / M_r (the
  /// M-orthogonal projection onto the reduced coordinates).
  void gather(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Ref<Eigen::MatrixXd> out) const {
    out.setZero();
    for (std::size_t r = 0; r < reduction.first.size(); ++r) {
      for (Eigen::Index l = reduction.first[r]; l <= reduction.last[r]; ++l)
        out.row(static_cast<Eigen::Index>(r)) += free->sqrt_mass_(l) * x.row(l);
      out.row(static_cast<Eigen::Index>(r)) /= group_mass(static_cast<Eigen::Index>(r));
    }
  }
};

ChainModes::ChainModes(BandedChain reduced, const ChainModes& free, ChainReduction reduction)
    : chain_(std::move(reduced)), solver_(TridiagonalSolver::secular) {
  chain_.validate();
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Index n = chain_.dof(), N = free.dof();
  if (free.implicit_) throw std::logic_error("ChainModes: the secular route needs the free chain's own modes");
  if (static_cast<Eigen::Index>(reduction.first.size()) != n || reduction.last.size() != reduction.first.size())
    throw std::logic_error("ChainModes: the reduction has " + std::to_string(reduction.first.size()) +
                           " coordinates for a reduced chain of " + std::to_string(n));
  auto im = std::make_shared<Implicit>();
  im->free = &free;
  im->group_mass = chain_.mass;
  // Each held stop restricts the current modes by w_jᵀ x = 0, i.e. (Φᵀ w_j)ᵀ q = 0 in the free
  // modal coordinates q (Φ = M^{-1/2} Q), carried down through the levels built before it.
  // Modal forcing of the reduced chain: Φ_rᵀ F_r = Ψᵀ Φᵀ M T M_r⁻¹ F_r (Φ_r = M_r⁻¹ Tᵀ M Φ Ψ),
  // likewise carried down through every level. Each level maps all the columns still to carry
  // (the forcing, then the later stops' constraints, last stop first) to its child basis in the
  // pass over its roots that normalises its vectors (secular.hpp), so that they cost no pass of
  // their own; a level's constraint leaves the carried block as that level uses it.
  im->reduction = std::move(reduction);
  const auto& normals = im->reduction.normals;
  const auto held = static_cast<Eigen::Index>(normals.size());
  auto constraint = [&](const auto& normal, Eigen::Ref<Eigen::VectorXd> b) {
    b.setZero();
    for (const auto& [mass, weight] : normal) b += (weight * free.inv_sqrt_mass_(mass)) * free.q_.row(mass).transpose();
  };
  // Columns: the constant, cosine and sine forcing, then the extra harmonics' cosines and sines.
  const HarmonicForcing& f = chain_.forcing;
  const auto H = static_cast<Eigen::Index>(f.harmonics.size());
  const Eigen::Index F = 3 + 2 * H;
  Eigen::MatrixXd g(n, F);
  g.col(0) = f.constant.cwiseQuotient(chain_.mass);
  g.col(1) = f.cosine.cwiseQuotient(chain_.mass);
  g.col(2) = f.sine.cwiseQuotient(chain_.mass);
  for (Eigen::Index h = 0; h < H; ++h) {
    g.col(3 + h) = f.harmonics[static_cast<std::size_t>(h)].cosine.cwiseQuotient(chain_.mass);
    g.col(3 + H + h) = f.harmonics[static_cast<std::size_t>(h)].sine.cwiseQuotient(chain_.mass);
  }
  Eigen::MatrixXd spread(N, F), carry(N, F + std::max<Eigen::Index>(held - 1, 0));
  im->spread(g, spread);
  times_once(free.q_, spread, carry.leftCols(F));
  for (Eigen::Index j = 1; j < held; ++j) constraint(normals[static_cast<std::size_t>(j)], carry.col(F - 1 + held - j));
  Eigen::VectorXd d = free.omega2_, z(N);
  for (Eigen::Index j = 0; j < held; ++j) {
    if (j == 0) {
      constraint(normals.front(), z);
    } else {
      z = carry.rightCols(1);
      carry.conservativeResize(Eigen::NoChange, carry.cols() - 1);
    }
    im->levels.emplace_back(d, z, &carry);
    d = im->levels.back().eigenvalues();
  }
  if (d.size() != n)
    throw std::logic_error("ChainModes: " + std::to_string(held) + " held stops leave " + std::to_string(d.size()) +
                           " modes for a reduced chain of " + std::to_string(n));
  implicit_ = im;
  omega2_ = d;
  const Eigen::MatrixXd& p = carry;
  finish(p.col(0), p.col(1), p.col(2), p.middleCols(3, H), p.middleCols(3 + H, H));
  setup_seconds_ = seconds_since(start);
}

std::size_t ChainModes::bytes() const {
  std::size_t b = sizeof(double) * static_cast<std::size_t>(q_.size() + 12 * omega2_.size() + hc_.size() + hs_.size());
  if (implicit_)
    for (const auto& level : implicit_->levels) b += level.bytes();
  return b;
}

Eigen::MatrixXd ChainModes::phi_rows(const std::vector<Eigen::Index>& coordinates) const {
  const auto count = static_cast<Eigen::Index>(coordinates.size());
  if (!implicit_) {
    Eigen::MatrixXd rows(count, dof());
    for (Eigen::Index c = 0; c < count; ++c) rows.row(c) = phi_row(coordinates[static_cast<std::size_t>(c)]).transpose();
    return rows;
  }
  // Row r of Φ_r = M_r⁻¹ Tᵀ M Φ Ψ: the group's Σ √m_l Q(l, :) / M_r, carried down.
  const Implicit& im = *implicit_;
  const ChainModes& fr = *im.free;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(fr.dof(), count);
  for (Eigen::Index c = 0; c < count; ++c) {
    const auto r = static_cast<std::size_t>(coordinates[static_cast<std::size_t>(c)]);
    for (Eigen::Index l = im.reduction.first[r]; l <= im.reduction.last[r]; ++l)
      a.col(c) += fr.sqrt_mass_(l) * fr.q_.row(l).transpose();
    a.col(c) /= im.group_mass(static_cast<Eigen::Index>(r));
  }
  Workspace w;
  Eigen::MatrixXd rows(dof(), count);
  im.down(a, rows, w);
  return rows.transpose();
}

Eigen::VectorXd ChainModes::phi_row(Eigen::Index i) const {
  if (implicit_) return phi_rows({i}).row(0).transpose();
  return q_.row(i).transpose() * inv_sqrt_mass_(i);
}

void ChainModes::to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                          Eigen::Ref<Eigen::VectorXd> ud) const {
  Workspace work;
  to_modal(t, x, v, u, ud, work);
}

void ChainModes::to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                          const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                          Eigen::Ref<Eigen::VectorXd> ud, Workspace& work) const {
  const double W = frequency(), c = std::cos(W * t), s = std::sin(W * t);
  if (implicit_) {
    // Ψᵀ Qᵀ √m ∘ (T y): buffers 3 (y, then the result), 4 (spread), 5 (free modal).
    const Implicit& im = *implicit_;
    const Eigen::Index n = dof(), N = im.free->dof();
    Eigen::Map<Eigen::MatrixXd> y = work.matrix(3, n, 2), spread = work.matrix(4, N, 2), modal = work.matrix(5, N, 2);
    y.col(0) = x;
    y.col(1) = v;
    im.spread(y, spread);
    for (int j = 0; j < 2; ++j) modal.col(j).noalias() = im.free->q_.transpose() * spread.col(j);
    im.down(modal, y, work);
    u = y.col(0);
    ud = y.col(1);
  } else {
    Eigen::Map<Eigen::MatrixXd> scaled = work.matrix(3, x.size(), 2);
    scaled.col(0) = x.cwiseProduct(sqrt_mass_);
    scaled.col(1) = v.cwiseProduct(sqrt_mass_);
    u.noalias() = q_.transpose() * scaled.col(0);
    ud.noalias() = q_.transpose() * scaled.col(1);
  }
  u -= c0_ + cc_ * c + cs_ * s;
  ud -= W * (cs_ * c - cc_ * s);
  if (rates_.size() > 0) add_particular(t, -1.0, u, ud);
}

void ChainModes::to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                             const Eigen::Ref<const Eigen::VectorXd>& ud,
                             Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  Workspace work;
  to_physical(t, u, ud, x, v, work);
}

void ChainModes::to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                             const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                             Eigen::Ref<Eigen::VectorXd> v, Workspace& work) const {
  const double W = frequency(), c = std::cos(W * t), s = std::sin(W * t);
  const Eigen::Index n = dof();
  Eigen::Map<Eigen::MatrixXd> q = work.matrix(3, n, 2);  // the modal state with its particular part
  q.col(0) = u + c0_ + cc_ * c + cs_ * s;
  q.col(1) = ud + W * (cs_ * c - cc_ * s);
  if (rates_.size() > 0) add_particular(t, 1.0, q.col(0), q.col(1));
  if (implicit_) {
    const Implicit& im = *implicit_;
    const Eigen::Index N = im.free->dof();
    Eigen::Map<Eigen::MatrixXd> modal = work.matrix(5, N, 2), full = work.matrix(4, N, 2);
    im.up(q, modal, work);
    for (int j = 0; j < 2; ++j) full.col(j).noalias() = im.free->q_ * modal.col(j);
    Eigen::Map<Eigen::MatrixXd> y = work.matrix(3, n, 2);
    im.gather(full, y);
    x = y.col(0);
    v = y.col(1);
    return;
  }
  x.noalias() = q_ * q.col(0);
  v.noalias() = q_ * q.col(1);
  x.array() *= inv_sqrt_mass_.array();
  v.array() *= inv_sqrt_mass_.array();
}


void ChainModes::tangent_to_modal(const Eigen::Ref<const Eigen::MatrixXd>& y, Eigen::Ref<Eigen::MatrixXd> u,
                                  Workspace& work) const {
  const Eigen::Index k = y.cols();
  if (implicit_) {
    const Implicit& im = *implicit_;
    const Eigen::Index N = im.free->dof();
    Eigen::Map<Eigen::MatrixXd> spread = work.matrix(4, N, k), modal = work.matrix(5, N, k);
    im.spread(y, spread);
    times(im.free->q_, true, spread, modal);
    im.down(modal, u, work);
    return;
  }
  Eigen::Map<Eigen::MatrixXd> scaled = work.matrix(4, y.rows(), k);
  scaled = sqrt_mass_.asDiagonal() * y;
  times(q_, true, scaled, u);
}

void ChainModes::tangent_to_physical(const Eigen::Ref<const Eigen::MatrixXd>& u, Eigen::Ref<Eigen::MatrixXd> y,
                                     Workspace& work) const {
  const Eigen::Index k = u.cols();
  if (implicit_) {
    const Implicit& im = *implicit_;
    const Eigen::Index N = im.free->dof();
    Eigen::Map<Eigen::MatrixXd> modal = work.matrix(5, N, k), full = work.matrix(4, N, k);
    im.up(u, modal, work);
    times(im.free->q_, false, modal, full);
    im.gather(full, y);
    return;
  }
  times(q_, false, u, y);
  y = inv_sqrt_mass_.asDiagonal() * y;
}

void ChainModes::propagator(Eigen::Index k, double tau, double* ec, double* es) const {
  const double sg = sigma_(k), w2 = omega2_(k), r = root_(k);
  if (regime_(k) > 0) {
    const double e = std::exp(-sg * tau);
    *ec = e * std::cos(r * tau);
    *es = e * std::sin(r * tau) / r;
  } else if (regime_(k) < 0) {
    // Rates σ ∓ r; the slow one written without cancellation (σ - r = ω²/(σ + r)).
    const double e1 = std::exp(-(w2 / (sg + r)) * tau), e2 = std::exp(-(sg + r) * tau);
    *ec = 0.5 * (e1 + e2);
    *es = r * tau < 0.5 ? e2 * std::expm1(2.0 * r * tau) / (2.0 * r) : (e1 - e2) / (2.0 * r);
  } else {
    const double e = std::exp(-sg * tau);
    *ec = e;
    *es = e * tau;
  }
}

void ChainModes::advance(double tau, const Eigen::Ref<const Eigen::VectorXd>& u,
                         const Eigen::Ref<const Eigen::VectorXd>& ud,
                         Eigen::Ref<Eigen::VectorXd> u_out, Eigen::Ref<Eigen::VectorXd> ud_out,
                         double* bound) const {
  const Eigen::Index n = dof();
  for (Eigen::Index k = 0; k < n; ++k) {
    const double sg = sigma_(k), w2 = omega2_(k);
    double ec, es;  // e^{-στ} C(τ), e^{-στ} S(τ)
    propagator(k, tau, &ec, &es);
    const double u0 = u(k), v0 = ud(k);
    const double u1 = ec * u0 + es * (v0 + sg * u0);
    const double v1 = ec * v0 - es * (sg * v0 + w2 * u0);
    u_out(k) = u1;
    ud_out(k) = v1;
    if (bound) bound[k] = (2.0 * sg + omega_(k)) * std::sqrt(v1 * v1 + w2 * u1 * u1);
  }
}

void ChainModes::mode_propagator(Eigen::Index k, double tau, double p[4]) const {
  const double sg = sigma_(k), w2 = omega2_(k);
  double ec, es;
  propagator(k, tau, &ec, &es);
  p[0] = ec + es * sg;
  p[1] = es;
  p[2] = -es * w2;
  p[3] = ec - es * sg;
}

void ChainModes::advance_columns(double tau, Eigen::Ref<Eigen::MatrixXd> u, Eigen::Ref<Eigen::MatrixXd> ud) const {
  const Eigen::Index n = dof();
  for (Eigen::Index k = 0; k < n; ++k) {
    const double sg = sigma_(k), w2 = omega2_(k);
    double ec, es;
    propagator(k, tau, &ec, &es);
    for (Eigen::Index c = 0; c < u.cols(); ++c) {
      const double u0 = u(k, c), v0 = ud(k, c);
      u(k, c) = ec * u0 + es * (v0 + sg * u0);
      ud(k, c) = ec * v0 - es * (sg * v0 + w2 * u0);
    }
  }
}

}  // namespace vibro
