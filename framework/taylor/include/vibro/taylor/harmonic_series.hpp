#pragma once
/// \file harmonic_series.hpp
/// The Taylor series of a harmonic drive: the coefficients of cos(w (t0 + τ)) and sin(w (t0 + τ))
/// in τ up to a given order. The k-th derivatives cycle through (cos, −sin, −cos, sin) and
/// (sin, cos, −sin, −cos), times w^k/k!. The Taylor engine (taylor_simulator.cpp) feeds its drive
/// and moving stops (every harmonic of their motion) with them, and its tangent maps
/// (analysis/src/taylor_tangent.cpp) the same; harmonic_tail bounds what the cut series leaves out.
#include <cmath>
#include <limits>

namespace vibro::taylor {

/// c[0 … order], s[0 … order]: the coefficients of cos and sin of w (t0 + τ).
inline void harmonic_series(double w, double t0, int order, double* c, double* s) {
  const double C = std::cos(w * t0), S = std::sin(w * t0);
  double f = 1.0;
  int k = 0;
  for (; k + 3 <= order; k += 4) {  // the cycle of four unrolled (the same products as below)
    c[k] = f * C; s[k] = f * S;
    f *= w / (k + 1);
    c[k + 1] = -f * S; s[k + 1] = f * C;
    f *= w / (k + 2);
    c[k + 2] = -f * C; s[k + 2] = -f * S;
    f *= w / (k + 3);
    c[k + 3] = f * S; s[k + 3] = -f * C;
    f *= w / (k + 4);
  }
  for (; k <= order; ++k) {
    switch (k % 4) {
      case 0: c[k] = f * C; s[k] = f * S; break;
      case 1: c[k] = -f * S; s[k] = f * C; break;
      case 2: c[k] = -f * C; s[k] = -f * S; break;
      default: c[k] = f * S; s[k] = -f * C; break;
    }
    f *= w / (k + 1);
  }
}

/// A bound on the tail of the series of c cos(w (t0 + τ)) + s sin(w (t0 + τ)) cut after `order`,
/// over 0 ≤ τ ≤ h: its k-th coefficient is at most A w^k / k! in size (A = hypot(c, s), the
/// cycle above), so with x = w h and p = order the tail is at most
///
///     Σ_{k>p} A x^k / k!  ≤  A x^{p+1} / (p+1)! · Σ_{i≥0} (x / (p + 2))^i  =  A x^{p+1} / ((p+1)! (1 − x/(p + 2)))
///
/// (each further term at most x/(p + 2) times the one before); infinity when x ≥ p + 2. Every
/// term grows with h, so the bound over [0, τ] is at most the bound over [0, h] times (τ/h)^{p+1}.
inline double harmonic_tail(double amplitude, double w, double h, int order) {
  if (amplitude == 0.0 || w == 0.0 || h == 0.0) return 0.0;
  const double x = std::abs(w) * h;
  if (!(x < order + 2)) return std::numeric_limits<double>::infinity();
  double term = amplitude;  // A x^k / k! for k = 0 … p + 1
  for (int k = 1; k <= order + 1; ++k) term *= x / k;
  return term / (1.0 - x / (order + 2));
}

}  // namespace vibro::taylor
