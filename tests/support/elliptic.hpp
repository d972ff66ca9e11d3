#pragma once
// Jacobi elliptic functions and the complete elliptic integral of the first kind, for closed-form
// references (the Duffing oscillator and the pendulum), in long double so that the reference is
// three digits more accurate than the double computation it checks.
//
// Parameter m = k² (0 ≤ m < 1). Both use the arithmetic-geometric mean (AGM) scale
//     a₀ = 1, b₀ = √(1 − m), c₀ = √m;  a_n = (a_{n−1} + b_{n−1})/2, b_n = √(a_{n−1} b_{n−1}),
//     c_n = (a_{n−1} − b_{n−1})/2, until c_N is below rounding;
// then
//     K(m) = π / (2 a_N)                                     (Abramowitz & Stegun 17.6.1–17.6.4)
//     φ_N = 2^N a_N u,  φ_{n−1} = (φ_n + arcsin(c_n sin φ_n / a_n)) / 2,
//     sn u = sin φ₀, cn u = cos φ₀                               (A&S 16.4.2–16.4.3)
//     dn u = √(1 − m sn² u)  (A&S 16.9.1; A&S's cos φ₀ / cos(φ₁ − φ₀) loses digits where cn ≈ 0)
// The argument is first reduced modulo the period 4K (sn, cn have period 4K, dn 2K).
#include <cmath>
#include <numbers>

namespace vibro::test {

struct JacobiValues {
  long double sn, cn, dn;
};

namespace detail {
struct AgmScale {
  long double a[40], c[40];
  int n = 0;
};
inline AgmScale agm(long double m) {
  AgmScale s;
  long double a = 1.0L, b = std::sqrt(1.0L - m), c = std::sqrt(m);
  s.a[0] = a;
  s.c[0] = c;
  while (std::fabs(c) > 4.0L * 1.0842e-19L * a && s.n < 38) {
    const long double an = 0.5L * (a + b), bn = std::sqrt(a * b), cn = 0.5L * (a - b);
    a = an;
    b = bn;
    c = cn;
    ++s.n;
    s.a[s.n] = a;
    s.c[s.n] = c;
  }
  return s;
}
}  // namespace detail

/// K(m), the complete elliptic integral of the first kind (quarter period of sn).
inline long double elliptic_k(long double m) {
  return std::numbers::pi_v<long double> / (2.0L * detail::agm(m).a[detail::agm(m).n]);
}

inline JacobiValues jacobi(long double u, long double m) {
  const detail::AgmScale s = detail::agm(m);
  const long double period = 4.0L * std::numbers::pi_v<long double> / (2.0L * s.a[s.n]);
  u -= period * std::nearbyint(u / period);
  long double phi = std::ldexp(s.a[s.n] * u, s.n);
  for (int i = s.n; i >= 1; --i) phi = 0.5L * (phi + std::asin(s.c[i] * std::sin(phi) / s.a[i]));
  const long double sn = std::sin(phi), cn = std::cos(phi);
  const long double dn = std::sqrt(1.0L - m * sn * sn);
  return {sn, cn, dn};
}

}  // namespace vibro::test
