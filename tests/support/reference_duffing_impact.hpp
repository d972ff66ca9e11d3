#pragma once
/// \file reference_duffing_impact.hpp
/// An independent reference for a forced Duffing impact oscillator (header-only, tests only):
///
///     m x'' + c x' + k x + β x³ + γ sin x = A cos Ωt,      x ≤ s (one rigid stop above), restitution r,
///
/// (γ = `gravity`, 0 by default: with k = β = 0 and γ > 0 an impacting pendulum),
/// integrated by the fixed-step Cooper–Verner RK8 tableau of reference_integrator.hpp in long
/// double. It shares nothing with the Taylor engine but the numbers: no series, no guard
/// polynomials, no event loop, no LCP.
///
///  * Free flight: steps of h = T_step / steps_per_unit with ρh ≤ 0.02 (ρ the largest local
///    frequency √((k + 3β x_max² + γ)/m) and Ω): the RK8 local error ~ (ρh)⁹/9! ≈ 1.4e-21 per step,
///    far below long double's rounding (1.1e-19), so the reference is accurate to ~1e-16 of the
///    state over the 10⁵ steps a test takes.
///  * Events: the gap g = x − s becoming > 0 at a step's end; the crossing is located by
///    bisection on the sub-step length θ (one RK8 step of length θ from the step start) to a few
///    units of long-double rounding in θ.
///  * Impact: v⁺ = −r v⁻ (Newton's law for one coordinate). Impacts only: a rebound slower than
///    `stick_velocity` throws std::runtime_error (the test's parameters must not chatter).
///  * A moving stop (`stop_harmonics`, none by default): the stop's position is
///    stop + Σ (c cos kΩt + s sin kΩt), the gap x − p(t) is bisected as above, and Newton's law
///    acts on the velocity relative to the stop: v⁺ − p'(t) = −r (v⁻ − p'(t)); `impacts` then holds
///    the relative approach speed v⁻ − p'(t).
///
/// Usage:
///     vibro::test::ReferenceDuffingImpact ref{.m = 1, .c = 0.05, .k = 1, .beta = 0.5, ...};
///     ref.run(0.0L, x0, v0, t_end);   // ref.impacts, ref.x, ref.v
#include "support/reference_rk8_step.hpp"

#include <cmath>
#include <stdexcept>
#include <vector>

namespace vibro::test {

struct ReferenceDuffingImpact {
  long double m = 1, c = 0, k = 1, beta = 0, amplitude = 0, omega = 1, stop = 1, restitution = 1;
  long double gravity = 0;  ///< γ of the pendulum term γ sin x
  long double step_rate = 0.02L;
  struct Harmonic {
    int order;
    long double cosine, sine;
  };
  std::vector<Harmonic> stop_harmonics;

  /// The stop's position p(t) (derivative 0) or its rate p'(t) (1).
  long double stop_at(long double time, int derivative) const {
    long double p = derivative == 0 ? stop : 0.0L;
    for (const Harmonic& h : stop_harmonics) {
      const long double w = h.order * omega, c = std::cos(w * time), s = std::sin(w * time);
      p += derivative == 0 ? h.cosine * c + h.sine * s : w * (-h.cosine * s + h.sine * c);
    }
    return p;
  }
  long double stick_velocity = 1e-7L;

  struct Impact {
    long double t, v_before;
  };
  std::vector<Impact> impacts;
  long double t = 0, x = 0, v = 0;

  long double acceleration(long double time, long double position, long double velocity) const {
    long double a = amplitude * std::cos(omega * time) - c * velocity - k * position - beta * position * position * position;
    if (gravity != 0.0L) a -= gravity * std::sin(position);
    return a / m;
  }

  /// One RK8 step of length h from (time, x0, v0).
  void step(long double time, long double h, long double& x0, long double& v0) const {
    rk8_step(tableau_, [this](long double s, long double p, long double u) { return acceleration(s, p, u); }, time, h,
             x0, v0);
  }

  void run(long double t0, long double x0, long double v0, long double t_end) {
    t = t0;
    x = x0;
    v = v0;
    impacts.clear();
    const long double x_max = std::max(std::fabs(stop), std::fabs(x0)) + 2.0L;  // bounds |x| for ρ
    long double fastest = omega;  // the stop's fastest harmonic bounds ρ too
    for (const Harmonic& h : stop_harmonics) fastest = std::max(fastest, h.order * omega);
    const long double rho =
        std::max(std::sqrt((std::fabs(k) + 3.0L * std::fabs(beta) * x_max * x_max + std::fabs(gravity)) / m), fastest);
    const long double h = step_rate / rho;
    while (t < t_end) {
      const long double hs = std::min(h, t_end - t);
      long double xn = x, vn = v;
      step(t, hs, xn, vn);
      if (xn - stop_at(t + hs, 0) > 0.0L) {
        long double lo = 0.0L, hi = hs;  // g(lo) ≤ 0 < g(hi)
        for (int i = 0; i < 200 && hi - lo > 4.0L * std::numeric_limits<long double>::epsilon() * std::max(t, 1.0L); ++i) {
          const long double mid = 0.5L * (lo + hi);
          long double xm = x, vm = v;
          step(t, mid, xm, vm);
          (xm - stop_at(t + mid, 0) > 0.0L ? hi : lo) = mid;
        }
        long double xe = x, ve = v;
        step(t, hi, xe, ve);
        t += hi;
        x = stop_at(t, 0);
        const long double rate = stop_at(t, 1);
        impacts.push_back({t, ve - rate});
        v = rate - restitution * (ve - rate);
        if (std::fabs(v - rate) < stick_velocity) throw std::runtime_error("reference: chatter (rebound below stick_velocity)");
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
