#pragma once
/// \file reference_integrator.hpp
/// Independent high-accuracy references for the flow tests (header-only, tests only).
///
///  * ReferenceIntegrator: the classical 11-stage, order-8 explicit Runge–Kutta method of
///    Cooper & Verner (1972, "Some explicit Runge–Kutta methods of high order", SIAM J. Numer.
///    Anal. 9(3), 389–405), used with a fixed step, in long double, on
///
///        x' = v,   v' = M⁻¹ (f(t) - C v - K x),   f(t) = F0 + Fc cos Ωt + Fs sin Ωt
///                                                       + Σ_h (Fc_h cos k_hΩt + Fs_h sin k_hΩt).
///
///    It never forms a matrix exponential nor an eigen-decomposition of the generator, so it
///    shares nothing with vibro::LinearFlow but the input matrices.
///
///    Step-size rule. For a linear system one step multiplies each mode by the stability
///    polynomial R(hλ) = Σ_{k≤8} (hλ)ᵏ/k! + O((hλ)⁹); the local error per mode is therefore about
///    |hλ|⁹/9!. With |hλ| ≤ 0.05 (rate ρ = max(|λ(A)|, Ω), A the 2n×2n first-order matrix) that is
///    0.05⁹/9! ≈ 5e-18 per step relative to the state; 10⁵ steps (more than any test uses)
///    accumulate at most ~5e-13, and long-double rounding (ε ≈ 1.1e-19) adds ~1e-14. The
///    reference is thus ≥ 100 times more accurate than the 1e-10 the tests demand of the flow.
///    test_flow.cpp checks the order (error ratio ≈ 2⁸ when h halves) and this accuracy on a
///    closed-form oscillator, so the claim is measured, not assumed.
///
///  * GaussLegendre: the m-point Gauss–Legendre rule (exact for polynomials of degree 2m - 1),
///    nodes by Newton's method on Pₘ in long double, used as a composite rule for ∫ vᵀ C v dt.
///
/// Usage:
///     vibro::test::ReferenceIntegrator ref(system);
///     vibro::test::ReferenceIntegrator::State s{t0, x0, v0};   // long double
///     ref.advance(s, t1, ref.steps_for(t1 - t0));
#include "vibro/system.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

namespace vibro::test {

using VectorL = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
using MatrixL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;

/// Butcher tableau of the Cooper–Verner order-8 method (11 stages; s = √21).
struct CooperVerner8 {
  static constexpr int stages = 11;
  std::array<long double, stages> c{};
  std::array<long double, stages> b{};
  std::array<std::array<long double, stages>, stages> a{};

  CooperVerner8() {
    const long double s = std::sqrt(21.0L);
    c = {0.0L, 0.5L, 0.5L, (7 + s) / 14, (7 + s) / 14, 0.5L, (7 - s) / 14, (7 - s) / 14, 0.5L,
         (7 + s) / 14, 1.0L};
    b = {1.0L / 20, 0, 0, 0, 0, 0, 0, 49.0L / 180, 16.0L / 45, 49.0L / 180, 1.0L / 20};
    a[1] = {0.5L};
    a[2] = {0.25L, 0.25L};
    a[3] = {1.0L / 7, -(7 + 3 * s) / 98, (21 + 5 * s) / 49};
    a[4] = {(11 + s) / 84, 0, (18 + 4 * s) / 63, (21 - s) / 252};
    a[5] = {(5 + s) / 48, 0, (9 + s) / 36, (-231 + 14 * s) / 360, (63 - 7 * s) / 80};
    a[6] = {(10 - s) / 42,          0, (-432 + 92 * s) / 315, (633 - 145 * s) / 90,
            (-504 + 115 * s) / 70, (63 - 13 * s) / 35};
    a[7] = {1.0L / 14, 0, 0, 0, (14 - 3 * s) / 126, (13 - 3 * s) / 63, 1.0L / 9};
    a[8] = {1.0L / 32,          0, 0, 0, (91 - 21 * s) / 576, 11.0L / 72, -(385 + 75 * s) / 1152,
            (63 + 13 * s) / 128};
    a[9] = {1.0L / 14,
            0,
            0,
            0,
            1.0L / 9,
            -(733 + 147 * s) / 2205,
            (515 + 111 * s) / 504,
            -(51 + 11 * s) / 56,
            (132 + 28 * s) / 245};
    a[10] = {0,
             0,
             0,
             0,
             (-42 + 7 * s) / 18,
             (-18 + 28 * s) / 45,
             -(273 + 53 * s) / 72,
             (301 + 53 * s) / 72,
             (28 - 28 * s) / 45,
             (49 - 7 * s) / 18};
  }
};

/// Fixed-step Cooper–Verner RK8 for M x'' + C x' + K x = f(t), in long double.
class ReferenceIntegrator {
 public:
  struct State {
    long double t;
    VectorL x, v;
  };

  /// Largest accepted |h λ| (see the file comment for why 0.05 is far more than enough).
  static constexpr long double default_step_rate = 0.05L;

  explicit ReferenceIntegrator(const LinearSystem& system)
      : n_(system.dof()), omega_(system.forcing().frequency) {
    const MatrixL mass = system.mass().cast<long double>();
    const Eigen::LLT<MatrixL> llt(mass);
    if (llt.info() != Eigen::Success) throw std::invalid_argument("reference: M not SPD");
    stiffness_ = llt.solve(MatrixL(system.stiffness().cast<long double>()));
    damping_ = llt.solve(MatrixL(system.damping().cast<long double>()));
    constant_ = llt.solve(VectorL(system.forcing().constant.cast<long double>()));
    cosine_ = llt.solve(VectorL(system.forcing().cosine.cast<long double>()));
    sine_ = llt.solve(VectorL(system.forcing().sine.cast<long double>()));
    long double top_rate = omega_;
    for (const ForcingHarmonic& h : system.forcing().harmonics) {
      rates_.push_back(static_cast<long double>(h.order) * omega_);
      harmonic_cosine_.push_back(llt.solve(VectorL(h.cosine.cast<long double>())));
      harmonic_sine_.push_back(llt.solve(VectorL(h.sine.cast<long double>())));
      top_rate = std::max(top_rate, rates_.back());
    }

    // ρ = spectral radius of the first-order matrix [0 I; -M⁻¹K -M⁻¹C], and Ω: only used to
    // choose the step, so double precision is plenty.
    Eigen::MatrixXd first_order = Eigen::MatrixXd::Zero(2 * n_, 2 * n_);
    first_order.topRightCorner(n_, n_).setIdentity();
    first_order.bottomLeftCorner(n_, n_) = -stiffness_.cast<double>();
    first_order.bottomRightCorner(n_, n_) = -damping_.cast<double>();
    const Eigen::EigenSolver<Eigen::MatrixXd> eig(first_order, false);
    rate_ = std::max(static_cast<long double>(eig.eigenvalues().cwiseAbs().maxCoeff()), top_rate);

    for (auto& k : kx_) k.resize(n_);
    for (auto& k : kv_) k.resize(n_);
    xs_.resize(n_);
    vs_.resize(n_);
  }

  /// max(|λ|, Ω): the fastest rate the step must resolve.
  long double rate() const { return rate_; }

  /// Number of equal steps over `span` so that h · rate ≤ step_rate.
  long steps_for(long double span, long double step_rate = default_step_rate) const {
    const long double needed = std::fabs(span) * rate_ / step_rate;
    return std::max(1L, static_cast<long>(std::ceil(needed)));
  }

  /// Advances `s` to time t1 in `steps` equal steps.
  void advance(State& s, long double t1, long steps) {
    const long double t0 = s.t;
    const long double h = (t1 - t0) / static_cast<long double>(steps);
    for (long i = 0; i < steps; ++i) step(t0 + static_cast<long double>(i) * h, h, s.x, s.v);
    s.t = t1;
  }

  /// M⁻¹ f(t) - M⁻¹C v - M⁻¹K x in long double.
  VectorL acceleration(long double t, const VectorL& x, const VectorL& v) const {
    VectorL a = constant_ + cosine_ * std::cos(omega_ * t) + sine_ * std::sin(omega_ * t) -
                damping_ * v - stiffness_ * x;
    for (std::size_t h = 0; h < rates_.size(); ++h)
      a += harmonic_cosine_[h] * std::cos(rates_[h] * t) + harmonic_sine_[h] * std::sin(rates_[h] * t);
    return a;
  }

 private:
  void step(long double t, long double h, VectorL& x, VectorL& v) {
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      xs_ = x;
      vs_ = v;
      for (int j = 0; j < i; ++j) {
        const long double w = h * tableau_.a[i][j];
        if (w == 0.0L) continue;
        xs_ += w * kx_[j];
        vs_ += w * kv_[j];
      }
      kx_[i] = vs_;
      kv_[i] = acceleration(t + tableau_.c[i] * h, xs_, vs_);
    }
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      const long double w = h * tableau_.b[i];
      if (w == 0.0L) continue;
      x += w * kx_[i];
      v += w * kv_[i];
    }
  }

  Eigen::Index n_;
  long double omega_;
  long double rate_ = 0.0L;
  MatrixL stiffness_, damping_;  // M⁻¹K, M⁻¹C
  VectorL constant_, cosine_, sine_;  // M⁻¹F0, M⁻¹Fc, M⁻¹Fs
  std::vector<long double> rates_;    // extra harmonics: k_h Ω, M⁻¹Fc_h, M⁻¹Fs_h
  std::vector<VectorL> harmonic_cosine_, harmonic_sine_;
  CooperVerner8 tableau_;
  std::array<VectorL, CooperVerner8::stages> kx_, kv_;
  VectorL xs_, vs_;
};

/// m-point Gauss–Legendre rule on [-1, 1], computed in long double.
class GaussLegendre {
 public:
  explicit GaussLegendre(int points) : nodes_(points), weights_(points) {
    const long double pi = std::acos(-1.0L);
    for (int i = 0; i < points; ++i) {
      // Chebyshev-like initial guess, then Newton on Pₘ (quadratic convergence).
      long double x = std::cos(pi * (i + 0.75L) / (points + 0.5L));
      for (int iteration = 0; iteration < 100; ++iteration) {
        const auto [p, dp] = legendre(points, x);
        const long double dx = p / dp;
        x -= dx;
        if (std::fabs(dx) <= 1e-18L) break;  // the next step would be below 1e-36
      }
      const long double dp = legendre(points, x).second;
      nodes_[i] = x;
      weights_[i] = 2.0L / ((1.0L - x * x) * dp * dp);
    }
  }

  int points() const { return static_cast<int>(nodes_.size()); }
  long double node(int i) const { return nodes_[i]; }
  long double weight(int i) const { return weights_[i]; }

  /// ∫_a^b g over `panels` equal panels.
  template <class Integrand>
  long double integrate(Integrand&& g, long double a, long double b, long panels) const {
    const long double width = (b - a) / static_cast<long double>(panels);
    long double sum = 0.0L;
    for (long p = 0; p < panels; ++p) {
      const long double mid = a + (static_cast<long double>(p) + 0.5L) * width;
      long double panel = 0.0L;
      for (int i = 0; i < points(); ++i) panel += weights_[i] * g(mid + 0.5L * width * nodes_[i]);
      sum += 0.5L * width * panel;
    }
    return sum;
  }

 private:
  /// (Pₘ(x), Pₘ'(x)) by the recurrence (k+1) P_{k+1} = (2k+1) x Pₖ - k P_{k-1}.
  static std::pair<long double, long double> legendre(int m, long double x) {
    long double p0 = 1.0L, p1 = x;
    for (int k = 1; k < m; ++k) {
      const long double p2 = ((2 * k + 1) * x * p1 - k * p0) / (k + 1);
      p0 = p1;
      p1 = p2;
    }
    return {p1, m * (x * p1 - p0) / (x * x - 1.0L)};
  }

  std::vector<long double> nodes_, weights_;
};

}  // namespace vibro::test
