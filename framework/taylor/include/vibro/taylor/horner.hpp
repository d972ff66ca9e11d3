#pragma once
/// \file horner.hpp
/// Σ_{k=0}^{p} a_k τ^k by compensated Horner (Graillat, Langlois & Louvet 2005, Alg. 4): the
/// rounding error of each product (by an FMA) and each sum (TwoSum, Knuth) is carried along and
/// added at the end, so the value is as accurate as if computed in twice the working precision
/// and then rounded. A Taylor step's state (TaylorStep::state) and the Taylor engine's dense
/// output (taylor_simulator.cpp) evaluate their polynomials with it, so they carry only the
/// coefficients' own rounding.
#include <cmath>

namespace vibro::taylor {

inline double horner_compensated(const double* a, int p, double tau) {
  double s = a[p], c = 0.0;
  for (int k = p - 1; k >= 0; --k) {
    const double product = s * tau;
    const double product_error = std::fma(s, tau, -product);
    const double sum = product + a[k];
    const double virtual_a = sum - product;
    const double sum_error = (product - (sum - virtual_a)) + (a[k] - virtual_a);
    c = c * tau + (product_error + sum_error);
    s = sum;
  }
  return s + c;
}

}  // namespace vibro::taylor
