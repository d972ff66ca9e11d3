#pragma once
/// \file designed_orbit.hpp
/// A 1-DOF impact oscillator whose period-1 orbit with one impact per period is known in closed
/// form (tests only): the stop position and the forcing amplitude are solved from the wanted
/// impact time t* and approach speed u, so the orbit, its monodromy matrix and its Floquet
/// multipliers follow from the 2 × 2 exponential and the saltation matrix of one impact.
///
///   x'' + c x' + x = A cos Ωt, upper stop at s with restitution r (ω = 1);
///   homogeneous flow Φ(τ) = exp([[0, 1], [−1, −c]] τ) (damped oscillator);
///   particular solution A·P(t), P = ((1 − Ω²) cos Ωt + cΩ sin Ωt) / ((1 − Ω²)² + c²Ω²);
///   periodicity from the post-impact state (s, −ru) at t* to the pre-impact one (s, u) at
///   t* + T:  [s; u] − A P(t*) = Φ(T) ([s; −ru] − A P(t*)), two linear equations in (s, A).
/// The saltation matrix of the impact (Müller 1995) with R = diag(1, −r), h = x − s, ḣ = u and
/// f∓ = (v∓, a∓), a∓ = A cos Ωt* − s − c v∓:
///   S = R + (f⁺ − R f⁻) h_xᵀ / ḣ = [[−r, 0], [(a⁺ + r a⁻)/u, −r]]   (det S = r², tr S = −2r),
/// so starting half a period after the impact the map over one period is Φ(T/2) S Φ(T/2).
/// Whether the designed orbit exists (stays below the stop between impacts) depends on (u, t*):
/// the defaults, and (u, t*) = (0.5, 5T/16) (an unstable orbit, multipliers 0.253 and 1.501),
/// were checked by sampling (tests/analysis check it again through the engine's event count).
#include "vibro/stops.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <numbers>

namespace vibro::test {

struct DesignedOrbit {
  double c = 0.1, omega = 1.2, r = 0.8, u = 0.5;
  double T = 2.0 * std::numbers::pi / 1.2;
  double t_star = T / 8.0;
  double s = 0.0, A = 0.0;

  /// t_star as a fraction of the period (default 1/8: a stable orbit, |μ| = 0.616).
  explicit DesignedOrbit(double fraction = 0.125, double speed = 0.5) : u(speed), t_star(fraction * T) {
    const Eigen::MatrixXd F = phi(T);
    const Eigen::VectorXd P = particular(t_star);
    // Unknowns d = s − A P_x and A.
    Eigen::MatrixXd L(2, 2);
    Eigen::VectorXd rhs(2);
    L << 1.0 - F(0, 0), F(0, 1) * P(1), -F(1, 0), (F(1, 1) - 1.0) * P(1);
    rhs << -F(0, 1) * r * u, -u - F(1, 1) * r * u;
    const Eigen::VectorXd sol = L.partialPivLu().solve(rhs);
    A = sol(1);
    s = sol(0) + A * P(0);
  }

  Eigen::MatrixXd phi(double tau) const {
    const double z = c / 2.0, wd = std::sqrt(1.0 - z * z), e = std::exp(-z * tau);
    const double C = std::cos(wd * tau), S = std::sin(wd * tau);
    Eigen::MatrixXd P(2, 2);
    P << e * (C + z / wd * S), e * S / wd, -e * S / wd, e * (C - z / wd * S);
    return P;
  }
  Eigen::VectorXd particular(double t) const {  // unit amplitude: (P_x, P_v)
    const double den = (1.0 - omega * omega) * (1.0 - omega * omega) + c * c * omega * omega;
    const double a = (1.0 - omega * omega) / den, b = c * omega / den;
    Eigen::VectorXd p(2);
    p << a * std::cos(omega * t) + b * std::sin(omega * t), omega * (b * std::cos(omega * t) - a * std::sin(omega * t));
    return p;
  }
  ImpactSystem system() const {
    HarmonicForcing f = HarmonicForcing::zero(1, omega);
    f.cosine(0) = A;
    return ImpactSystem(LinearSystem(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, c),
                                     Eigen::MatrixXd::Identity(1, 1), f),
                        {Stop::upper(0, s, r)});
  }
  /// State (x, v) at t* + τ (0 < τ < T) on the orbit.
  Eigen::VectorXd state_after_impact(double tau) const {
    Eigen::VectorXd post(2);
    post << s, -r * u;
    return phi(tau) * (post - A * particular(t_star)) + A * particular(t_star + tau);
  }
  Eigen::MatrixXd saltation() const {
    const double force = A * std::cos(omega * t_star) - s;
    const double a_minus = force - c * u, a_plus = force + c * r * u;
    Eigen::MatrixXd S(2, 2);
    S << -r, 0.0, (a_plus + r * a_minus) / u, -r;
    return S;
  }
  /// The monodromy matrix from half a period after the impact.
  Eigen::MatrixXd monodromy() const { return phi(0.5 * T) * saltation() * phi(0.5 * T); }
};

}  // namespace vibro::test
