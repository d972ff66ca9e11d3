#pragma once
/// \file reference_compliant_duffing.hpp
/// An independent reference for a forced Duffing oscillator against a compliant stop (header-only,
/// tests only):
///
///     m x'' + c x' + k x + β x³ + [g > 0] (k_s g + c_s x' + F_p) = A cos Ωt,    g = x − s,
///
/// a Kelvin–Voigt stop above the mass at s (stiffness k_s, damping c_s, preload F_p) that acts
/// while it is penetrated (g > 0), integrated by the fixed-step Cooper–Verner RK8 tableau of
/// reference_integrator.hpp in long double. It shares nothing with the engines but the numbers:
/// no series, no guard polynomials, no event loop, no mode tables; the contact force is written
/// out here as the piecewise-linear law of stops.hpp.
///
///  * Between switches: steps of h = step_rate / ρ, ρ the largest local rate (√((k + k_s +
///    3β x_max²)/m), (c + c_s)/m and Ω): at ρh = 0.02 the RK8 local error ~ (ρh)⁹/9! ≈ 1.4e-21 per
///    step, far below long double's rounding, so the reference holds ~1e-16 of the state.
///  * Switches: the sign of g at a step's end differing from the current phase's (open: g ≤ 0,
///    engaged: g > 0); the crossing is bisected on the sub-step length θ (one RK8 step of length
///    θ from the step's start, with the phase's force) to a few long-double ulps of t, the step
///    taken to the bracket's far end, and the phase switched there. The vector field jumps at a
///    switch only by F_p and c_s x' (continuous when both vanish); the far end lies a few ulps past
///    the root, so the wrong field acts over a few ulps of time only.
///
/// Usage:
///     vibro::test::ReferenceCompliantDuffing ref;
///     ref.beta = 0.5;  ref.stop = 0.6;  ref.k_s = 20;  ref.c_s = 0.3;  ...
///     ref.run(0.0L, x0, v0, t_end);   // ref.switches, ref.x, ref.v
#include "support/reference_rk8_step.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace vibro::test {

struct ReferenceCompliantDuffing {
  long double m = 1, c = 0, k = 1, beta = 0, amplitude = 0, omega = 1, stop = 1;
  long double k_s = 1, c_s = 0, preload = 0;  ///< the compliant stop's law
  long double step_rate = 0.02L;

  struct Switch {
    long double t, v;  ///< when, and the velocity there (= the gap rate: the stop is fixed)
    bool engage;
  };
  std::vector<Switch> switches;
  long double t = 0, x = 0, v = 0;
  bool engaged = false;

  long double acceleration(long double time, long double position, long double velocity, bool in_contact) const {
    long double f = amplitude * std::cos(omega * time) - c * velocity - k * position - beta * position * position * position;
    if (in_contact) f -= k_s * (position - stop) + c_s * velocity + preload;
    return f / m;
  }

  /// One RK8 step of length h from (time, x0, v0) with the force of the phase `in_contact`.
  void step(long double time, long double h, long double& x0, long double& v0, bool in_contact) const {
    rk8_step(
        tableau_, [&](long double s, long double p, long double u) { return acceleration(s, p, u, in_contact); }, time,
        h, x0, v0);
  }

  void run(long double t0, long double x0, long double v0, long double t_end) {
    t = t0;
    x = x0;
    v = v0;
    engaged = x0 - stop > 0.0L;  // penetrated at the start: engaged (CompliantStopLaw)
    switches.clear();
    const long double x_max = std::max(std::fabs(stop), std::fabs(x0)) + 2.0L;  // bounds |x| for ρ
    const long double rho = std::max({std::sqrt((std::fabs(k) + k_s + 3.0L * std::fabs(beta) * x_max * x_max) / m),
                                      (std::fabs(c) + c_s) / m, omega});
    const long double h = step_rate / rho;
    // Whether a gap is on the other side of the current phase's.
    auto crossed = [&](long double position) { return engaged ? position - stop <= 0.0L : position - stop > 0.0L; };
    while (t < t_end) {
      const long double hs = std::min(h, t_end - t);
      long double xn = x, vn = v;
      step(t, hs, xn, vn, engaged);
      if (crossed(xn)) {
        long double lo = 0.0L, hi = hs;  // not crossed at lo, crossed at hi
        for (int i = 0; i < 200 && hi - lo > 4.0L * std::numeric_limits<long double>::epsilon() * std::max(t, 1.0L); ++i) {
          const long double mid = 0.5L * (lo + hi);
          long double xm = x, vm = v;
          step(t, mid, xm, vm, engaged);
          (crossed(xm) ? hi : lo) = mid;
        }
        step(t, hi, x, v, engaged);
        t += hi;
        engaged = !engaged;
        switches.push_back({t, v, engaged});
        continue;
      }
      t += hs;
      x = xn;
      v = vn;
    }
  }

 private:
  CooperVerner8 tableau_;
};

}  // namespace vibro::test
