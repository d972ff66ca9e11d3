#pragma once
/// \file harmonic_series.hpp
/// The Taylor series of a harmonic drive: the coefficients of cos(w (t0 + τ)) and sin(w (t0 + τ))
/// in τ up to a given order. The k-th derivatives cycle through (cos, −sin, −cos, sin) and
/// (sin, cos, −sin, −cos), times w^k/k!. The Taylor engine (taylor_simulator.cpp) feeds its drive
/// and moving stops with them, and its tangent maps (analysis/src/taylor_tangent.cpp) the same.
#include <cmath>

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

}  // namespace vibro::taylor
