#pragma once
/// \file reference_friction.hpp
/// An independent reference for one mass with Coulomb friction on a moving surface (header-only,
/// tests only).
///
/// ReferenceFriction integrates m x'' + c x' + k x = F0 + Fc cos Ωt + Fs sin Ωt + F_f against a
/// surface s(t) = a cos(Ωt + φ), with normal load N and coefficients μ_s ≥ μ_k, by the fixed-step
/// Cooper–Verner RK8 of reference_integrator.hpp in long double. It shares nothing with
/// vibro::FrictionSimulator but the input numbers: no matrix exponential, no augmented state, no
/// certified search, and its own friction logic written from Coulomb's law alone:
///  * slipping with σ = sign(u), u = v − s'(t): F_f = −μ_k N σ; a step at whose end σu ≤ 0 holds
///    the event, located by bisection on the sub-step length θ (one RK8 step of θh from the
///    step start) to long-double rounding;
///  * at u = 0 the force that holds the mass on the surface is, from m s'' = f − c s' − k x + F,
///        F = m s''(t) + c s'(t) + k x − f(t);
///    the mass sticks if |F| ≤ μ_s N, else slips with σ = −sign(F);
///  * stuck: x(t) = x_c + s(t) − s(t_c) exactly (no integration), F(t) in closed form; slip
///    starts where |F| reaches μ_s N (a sign change of |F| − μ_s N over a step of h, bisected
///    in t), with σ = −sign(F).
/// A slip shorter than a step that starts and ends inside it, or an excursion of |F| above the
/// limit inside one step, would be missed: the tests' parameters keep every phase many steps long.
#include "support/reference_integrator.hpp"

#include <cmath>
#include <vector>

namespace vibro::test {

struct ReferenceFrictionEvent {
  long double t = 0.0L;
  int kind = 0;  ///< 0 stick, 1 slip, 2 reversal
  long double x = 0.0L, v = 0.0L;
};

class ReferenceFriction {
 public:
  long double m = 1, c = 0, k = 1, f0 = 0, fc = 0, fs = 0, omega = 1;
  long double a = 0, phase = 0, load = 1, mu_s = 0, mu_k = 0;
  long double h = 1e-3L;  ///< step
  std::vector<ReferenceFrictionEvent> events;

  long double surface(long double t) const { return a * std::cos(omega * t + phase); }
  long double surface_rate(long double t) const { return -a * omega * std::sin(omega * t + phase); }
  long double surface_accel(long double t) const { return -a * omega * omega * std::cos(omega * t + phase); }
  long double forcing(long double t) const { return f0 + fc * std::cos(omega * t) + fs * std::sin(omega * t); }
  /// The force that holds the mass on the surface at (t, x).
  long double holding(long double t, long double x) const {
    return m * surface_accel(t) + c * surface_rate(t) + k * x - forcing(t);
  }

  /// Runs from (t0, x0, v0) to t1. `sigma`: the initial slip direction when u0 ≠ 0; at u0 = 0
  /// the stick test decides.
  void run(long double t, long double x, long double v, long double t1) {
    int sigma = 0;  // 0: stuck
    const long double u0 = v - surface_rate(t);
    if (u0 != 0.0L) sigma = u0 > 0 ? 1 : -1;
    else sigma = decide(t, x, /*previous*/ 2, v);
    while (t < t1) {
      if (sigma == 0) {
        const long double xc = x - surface(t);
        auto g = [&](long double tt, int side) { return side * holding(tt, xc + surface(tt)) - mu_s * load; };
        const long double tn = std::min(t + h, t1);
        int side = 0;
        for (int sd : {1, -1})
          if (g(tn, sd) > 0.0L) side = sd;
        if (side == 0) {
          t = tn;
          x = xc + surface(t);
          v = surface_rate(t);
          continue;
        }
        long double lo = t, hi = tn;
        for (int i = 0; i < 200 && hi - lo > 0.0L; ++i) {
          const long double mid = 0.5L * (lo + hi);
          if (mid == lo || mid == hi) break;
          (g(mid, side) > 0.0L ? hi : lo) = mid;
        }
        t = hi;
        x = xc + surface(t);
        v = surface_rate(t);
        sigma = -side;  // F > μ_s N: the other forces push the mass the negative way
        events.push_back({t, 1, x, v});
        continue;
      }
      const long double tn = std::min(t + h, t1);
      long double xn = x, vn = v;
      step(t, tn - t, sigma, xn, vn);
      if (sigma * (vn - surface_rate(tn)) > 0.0L) {
        t = tn;
        x = xn;
        v = vn;
        continue;
      }
      long double lo = 0.0L, hi = tn - t;
      for (int i = 0; i < 200; ++i) {
        const long double mid = 0.5L * (lo + hi);
        if (mid == lo || mid == hi) break;
        long double xm = x, vm = v;
        step(t, mid, sigma, xm, vm);
        (sigma * (vm - surface_rate(t + mid)) > 0.0L ? lo : hi) = mid;
      }
      long double xe = x, ve = v;
      step(t, hi, sigma, xe, ve);
      t += hi;
      x = xe;
      v = surface_rate(t);  // u = 0 at the root
      sigma = decide(t, x, sigma, v);
    }
    end_x = x;
    end_v = v;
  }
  long double end_x = 0.0L, end_v = 0.0L;

 private:
  /// At u = 0: 0 (stick) or the slip direction; logs the event.
  int decide(long double t, long double x, int previous, long double v) {
    const long double F = holding(t, x);
    if (std::fabs(F) <= mu_s * load) {
      events.push_back({t, 0, x, v});
      return 0;
    }
    const int sigma = F > 0 ? -1 : 1;
    events.push_back({t, previous == 2 ? 1 : 2, x, v});
    return sigma;
  }

  void step(long double t, long double dt, int sigma, long double& x, long double& v) const {
    const CooperVerner8& tab = tableau_;
    long double kx[CooperVerner8::stages], kv[CooperVerner8::stages];
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      long double xs = x, vs = v;
      for (int j = 0; j < i; ++j) {
        xs += dt * tab.a[i][j] * kx[j];
        vs += dt * tab.a[i][j] * kv[j];
      }
      kx[i] = vs;
      kv[i] = (forcing(t + tab.c[i] * dt) - c * vs - k * xs - mu_k * load * sigma) / m;
    }
    for (int i = 0; i < CooperVerner8::stages; ++i) {
      x += dt * tab.b[i] * kx[i];
      v += dt * tab.b[i] * kv[i];
    }
  }

  CooperVerner8 tableau_;
};

}  // namespace vibro::test
