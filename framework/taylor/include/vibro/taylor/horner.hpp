#pragma once
/// \file horner.hpp
/// Σ_{k=0}^{p} a_k τ^k by compensated Horner (Graillat, Langlois & Louvet 2005, Alg. 4): the
/// rounding error of each product (TwoProduct) and each sum (TwoSum, Knuth) is carried along and
/// added at the end, so the value is as accurate as if computed in twice the working precision
/// and then rounded. A Taylor step's state (TaylorStep::state) and the Taylor engine's dense
/// output (taylor_simulator.cpp) evaluate their polynomials with it, so they carry only the
/// coefficients' own rounding.
///
/// TwoProduct: the exact error s·τ − fl(s·τ) by a fused multiply-add where the target has one
/// (__FMA__), else by Dekker's product (Dekker 1971; Ogita, Rump & Oishi 2005, Alg. 3.3) with
/// Veltkamp's splitting of τ done once per polynomial — the same value (both are exact barring
/// overflow and underflow), without a call to the library's fma() on a target compiled without
/// FMA instructions.
#include <cmath>

namespace vibro::taylor {

inline double horner_compensated(const double* a, int p, double tau) {
  double s = a[p], c = 0.0;
#ifndef __FMA__
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1: Veltkamp's splitting into 26 + 26 bits
  const double tau_scaled = kSplitter * tau;
  const double tau_high = tau_scaled - (tau_scaled - tau), tau_low = tau - tau_high;
#endif
  for (int k = p - 1; k >= 0; --k) {
    const double product = s * tau;
#ifdef __FMA__
    const double product_error = std::fma(s, tau, -product);
#else
    const double s_scaled = kSplitter * s;
    const double s_high = s_scaled - (s_scaled - s), s_low = s - s_high;
    const double product_error =
        ((s_high * tau_high - product) + s_high * tau_low + s_low * tau_high) + s_low * tau_low;
#endif
    const double sum = product + a[k];
    const double virtual_a = sum - product;
    const double sum_error = (product - (sum - virtual_a)) + (a[k] - virtual_a);
    c = c * tau + (product_error + sum_error);
    s = sum;
  }
  return s + c;
}

}  // namespace vibro::taylor
