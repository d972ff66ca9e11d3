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
  Eigen::VectorXd particular(double t) const { return particular(t, omega); }
  /// Unit-amplitude particular solution (P_x, P_v) at forcing frequency w.
  Eigen::VectorXd particular(double t, double w) const {
    const double den = (1.0 - w * w) * (1.0 - w * w) + c * c * w * w;
    const double a = (1.0 - w * w) / den, b = c * w / den;
    Eigen::VectorXd p(2);
    p << a * std::cos(w * t) + b * std::sin(w * t), w * (b * std::cos(w * t) - a * std::sin(w * t));
    return p;
  }

  // With s and A fixed, the period-1 orbits at any frequency w: the impact time t* and speed u
  // solve G(u, t*, w) = 0 (the periodicity condition above), and their monodromy matrix is
  // M(u, t*, w) = Φ(T/2) S Φ(T/2). A fold of the family in w is where ∂G/∂(u, t*) is singular, a
  // period doubling where M has the eigenvalue −1 (tr M + 1 + det M = 0).
  Eigen::Vector2d G(double speed, double ts, double w) const {
    const double period = 2.0 * std::numbers::pi / w;
    const Eigen::VectorXd p = particular(ts, w);
    const Eigen::Vector2d before(s - A * p(0), speed - A * p(1)), after(s - A * p(0), -r * speed - A * p(1));
    return before - phi(period) * after;
  }
  Eigen::Matrix2d dG(double speed, double ts, double w) const {
    (void)speed;
    const double period = 2.0 * std::numbers::pi / w;
    const Eigen::VectorXd p = particular(ts, w);
    const Eigen::Vector2d dp(p(1), -w * w * p(0));  // d/dt of (P_x, P_v)
    Eigen::Matrix2d out;
    out.col(0) = Eigen::Vector2d(0.0, 1.0) - phi(period) * Eigen::Vector2d(0.0, -r);
    out.col(1) = -A * dp + phi(period) * (A * dp);
    return out;
  }
  Eigen::Matrix2d monodromy(double speed, double ts, double w) const {
    const double period = 2.0 * std::numbers::pi / w;
    const double force = A * std::cos(w * ts) - s;
    const double a_minus = force - c * speed, a_plus = force + c * r * speed;
    Eigen::Matrix2d S;
    S << -r, 0.0, (a_plus + r * a_minus) / speed, -r;
    return phi(0.5 * period) * S * phi(0.5 * period);
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
  /// The monodromy matrix of the designed orbit, from half a period after the impact.
  Eigen::MatrixXd monodromy() const { return monodromy(u, t_star, omega); }
};

}  // namespace vibro::test
