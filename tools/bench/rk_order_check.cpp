/// \file rk_order_check.cpp
/// Convergence check of rk_steppers.hpp: steps of fixed length h on x'' = −x + cos 2t from rest
/// (x = (cos t − cos 2t)/3) over [0, 10]: the largest error at the step ends and at the steps'
/// midpoints (continuous extension), for h = 1/4 … 1/32 (Dopri5) and 1 … 1/8 (Dop853). The observed slopes must be the orders: Dopri5's
/// step 5 and its 4th-order interpolant 5 (local error h⁵), Dop853's step 8 and its 7th-order
/// interpolant 8. Exit status 1 if a slope is off by more than 0.5.
///   build/<dir>/tools/bench/rk_order_check
#include "rk_steppers.hpp"

#include <cmath>
#include <cstdio>

namespace {
using State = Eigen::Matrix<double, 2, 1>;
struct Forced {
  void operator()(double t, const State& z, State& dz) const {
    dz(0) = z(1);
    dz(1) = -z(0) + std::cos(2.0 * t);
  }
};
double exact(double t) { return (std::cos(t) - std::cos(2.0 * t)) / 3.0; }

template <template <class, class> class Method>
bool check(const char* name, int order, int k0) {
  Forced f;
  double prev_step = 0, prev_dense = 0;
  bool ok = true;
  for (int k = k0; k <= k0 + 3; ++k) {
    const int steps = 10 << k;
    const double h = 10.0 / steps;
    Method<State, Forced> m(f, 1e10, 1e10);  // tolerances that accept every step
    m.init(0.0, State::Zero(), 1e9);
    double dense_err = 0.0, step_err = 0.0;
    for (int i = 1; i <= steps; ++i) {
      m.step(i * h);
      State mid;
      const double tm = 0.5 * (m.t0() + m.t1());
      m.state_at(tm, mid);
      dense_err = std::max(dense_err, std::abs(mid(0) - exact(tm)));
      step_err = std::max(step_err, std::abs(m.z1()(0) - exact(m.t1())));
    }
    if (k > k0) {
      const double s1 = std::log2(prev_step / step_err), s2 = std::log2(prev_dense / dense_err);
      std::printf("%s h = 1/%d: step error %.3e (slope %.2f), dense error %.3e (slope %.2f)\n", name, steps / 10,
                  step_err, s1, dense_err, s2);
      if (std::abs(s1 - order) > 0.5 || std::abs(s2 - order) > 0.5) ok = false;
    }
    prev_step = step_err;
    prev_dense = dense_err;
  }
  return ok;
}
}  // namespace

int main() {
  const bool a = check<vibro::bench::Dopri5>("dopri5", 5, 2);
  const bool b = check<vibro::bench::Dop853>("dop853", 8, 0);
  std::printf("%s\n", a && b ? "orders as expected" : "ORDER CHECK FAILED");
  return a && b ? 0 : 1;
}
