#include "vibro/taylor/horner.hpp"

#include <cmath>

// Built with -ffp-contract=off (CMakeLists.txt): every product and sum below must round on its
// own (a multiply-add fused by the compiler would break the error-free transformations).

#if (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || defined(__i386__)) && !defined(__FMA__)
#define VIBRO_HORNER_FMA_DISPATCH 1
#endif
#if defined(__GNUC__) || defined(__clang__)
#define VIBRO_ALWAYS_INLINE [[gnu::always_inline]] inline
#else
#define VIBRO_ALWAYS_INLINE inline
#endif

namespace vibro::taylor {

namespace {

/// Compensated Horner; TwoProduct by a fused multiply-add (kFma) or by Dekker's product.
template <bool kFma>
VIBRO_ALWAYS_INLINE double compensated(const double* a, int p, double tau) {
  constexpr double kSplitter = 134217729.0;  // 2^27 + 1: Veltkamp's splitting into 26 + 26 bits
  [[maybe_unused]] const double tau_scaled = kSplitter * tau;
  [[maybe_unused]] const double tau_high = tau_scaled - (tau_scaled - tau), tau_low = tau - tau_high;
  double s = a[p], c = 0.0;
  for (int k = p - 1; k >= 0; --k) {
    const double product = s * tau;
    double product_error;
    if constexpr (kFma) {
      product_error = std::fma(s, tau, -product);
    } else {
      const double s_scaled = kSplitter * s;
      const double s_high = s_scaled - (s_scaled - s), s_low = s - s_high;
      product_error = ((s_high * tau_high - product) + s_high * tau_low + s_low * tau_high) + s_low * tau_low;
    }
    const double sum = product + a[k];
    const double virtual_a = sum - product;
    const double sum_error = (product - (sum - virtual_a)) + (a[k] - virtual_a);
    c = c * tau + (product_error + sum_error);
    s = sum;
  }
  return s + c;
}

#ifdef VIBRO_HORNER_FMA_DISPATCH
__attribute__((target("fma"))) double horner_fma(const double* a, int p, double tau) {
  return compensated<true>(a, p, tau);
}
#endif

}  // namespace

double horner_compensated(const double* a, int p, double tau) {
#if defined(__FMA__)
  return compensated<true>(a, p, tau);
#elif defined(VIBRO_HORNER_FMA_DISPATCH)
  static const bool has_fma = __builtin_cpu_supports("fma");
  return has_fma ? horner_fma(a, p, tau) : compensated<false>(a, p, tau);
#else
  return compensated<false>(a, p, tau);
#endif
}

}  // namespace vibro::taylor
