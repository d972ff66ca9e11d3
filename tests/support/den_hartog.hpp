#pragma once
/// \file den_hartog.hpp
/// Den Hartog's closed-form steady motion of a forced oscillator with Coulomb and viscous
/// friction, without stops (header-only, long double), for the friction tests.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

namespace vibro::test {

/// Den Hartog (1931), "Forced vibrations with combined Coulomb and viscous friction", Trans. ASME
/// 53, APM-53-9, 107–115: the steady motion without stops of m x'' + c x' + k x = F0 cos Ωt
/// − F_f sign(x'), symmetric (x(t + T/2) = −x(t)), derived here in his way. On the half period
/// from the lowest point t1 (x' = 0, then x' > 0 for T/2) the friction is the constant −F_f, so
/// x = X cos(Ωt − ψ) − F_f/k + h(t − t1) with the forced response X, ψ of the viscous system and a
/// free motion h. Symmetry asks x(t1 + T/2) = −x(t1) and x'(t1 + T/2) = −x'(t1) = 0; since the
/// forced part changes sign over T/2, these are (I + Φ(T/2)) (h0, h0') = (2F_f/k, 0) with Φ
/// the free motion's transition matrix: h0, h0' in closed form, independent of t1. Then
/// x'(t1) = 0 gives sin(Ωt1 − ψ) = h0'/(XΩ), the root with x''(t1) > 0.
struct DenHartog {
  long double m, c, k, F0, Ff, W;
  long double X, psi, h0, h1, t1, T, zw, wd;
  DenHartog(long double m_, long double c_, long double k_, long double F0_, long double Ff_, long double W_)
      : m(m_), c(c_), k(k_), F0(F0_), Ff(Ff_), W(W_) {
    const long double re = k - m * W * W, im = c * W;
    X = F0 / std::sqrt(re * re + im * im);
    psi = std::atan2(im, re);
    T = 2 * std::numbers::pi_v<long double> / W;
    const long double w0 = std::sqrt(k / m);
    zw = c / (2 * m);
    wd = std::sqrt(w0 * w0 - zw * zw);  // underdamped
    // Φ(s) of h'' + 2ζω h' + ω² h = 0.
    const long double s = T / 2, e = std::exp(-zw * s), cs = std::cos(wd * s), sn = std::sin(wd * s);
    const long double p00 = e * (cs + zw / wd * sn), p01 = e * sn / wd;
    const long double p10 = -e * (w0 * w0 / wd) * sn, p11 = e * (cs - zw / wd * sn);
    const long double a00 = 1 + p00, a01 = p01, a10 = p10, a11 = 1 + p11, det = a00 * a11 - a01 * a10;
    const long double r0 = 2 * Ff / k;
    h0 = a11 * r0 / det;
    h1 = -a10 * r0 / det;
    // sin(Ω t1 − ψ) = h1 / (XΩ); lowest point: x'' = −XΩ² cos(Ωt1 − ψ) + h'' (0) > 0.
    const long double sv = h1 / (X * W);
    const long double base = std::asin(sv);
    long double best = 0;
    for (long double ang : {base, std::numbers::pi_v<long double> - base}) {
      const long double t = (ang + psi) / W;
      const long double acc = -X * W * W * std::cos(ang) + (-2 * zw * h1 - w0 * w0 * h0);
      if (acc > 0) best = t;
    }
    t1 = best;
  }
  /// x''(t1) at the lowest point, slipping with x' > 0 (the larger of the two roots of
  /// x'(t1) = 0; −∞ if there is none): the motion is without stops only where it is > 0, and
  /// where it falls to 0 a stop is born at the turning point (his boundary of motion without stops
  /// there, m x''(t1) = |F(t1) − k x(t1)| − F_f: the force that would hold the mass reaches F_f).
  long double turning_acceleration() const {
    const long double sv = h1 / (X * W);
    if (std::abs(sv) > 1) return -INFINITY;
    const long double base = std::asin(sv), w0 = std::sqrt(k / m);
    long double best = -INFINITY;
    for (long double ang : {base, std::numbers::pi_v<long double> - base})
      best = std::max(best, -X * W * W * std::cos(ang) + (-2 * zw * h1 - w0 * w0 * h0));
    return best;
  }
  /// x(t), x'(t) of the steady motion.
  std::pair<long double, long double> at(long double t) const {
    long double s = std::fmod(t - t1, T);
    if (s < 0) s += T;
    long double sign = 1;
    if (s >= T / 2) {
      s -= T / 2;
      sign = -1;
      t -= T / 2;
    }
    const long double e = std::exp(-zw * s), cs = std::cos(wd * s), sn = std::sin(wd * s);
    const long double b = (h1 + zw * h0) / wd;
    const long double h = e * (h0 * cs + b * sn);
    const long double hd = e * (-zw * (h0 * cs + b * sn) + wd * (-h0 * sn + b * cs));
    const long double x = X * std::cos(W * t - psi) - Ff / k + h;
    const long double v = -X * W * std::sin(W * t - psi) + hd;
    return {sign * x, sign * v};
  }
};


}  // namespace vibro::test
