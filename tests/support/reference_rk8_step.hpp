#pragma once
/// \file reference_rk8_step.hpp
/// One step of the Cooper–Verner order-8 tableau (reference_integrator.hpp) on a scalar
/// second-order equation x'' = a(t, x, v), in long double (header-only, tests only): the free
/// flight of the impact references (reference_duffing_impact.hpp, reference_compliant_duffing.hpp).
#include "support/reference_integrator.hpp"

#include <array>

namespace vibro::test {

/// (x0, v0) at `time` advanced by h, in place.
template <class Acceleration>
void rk8_step(const CooperVerner8& tableau, const Acceleration& a, long double time, long double h, long double& x0,
              long double& v0) {
  std::array<long double, CooperVerner8::stages> kx{}, kv{};
  for (int i = 0; i < CooperVerner8::stages; ++i) {
    long double xs = x0, vs = v0;
    for (int j = 0; j < i; ++j) {
      xs += h * tableau.a[i][j] * kx[j];
      vs += h * tableau.a[i][j] * kv[j];
    }
    kx[i] = vs;
    kv[i] = a(time + tableau.c[i] * h, xs, vs);
  }
  for (int i = 0; i < CooperVerner8::stages; ++i) {
    x0 += h * tableau.b[i] * kx[i];
    v0 += h * tableau.b[i] * kv[i];
  }
}

}  // namespace vibro::test
