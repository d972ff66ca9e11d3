#pragma once
/// \file reference_general_stop.hpp
/// An independent reference for one fixed stop along a general normal (header-only, tests only).
///
/// ReferenceGeneralStop integrates M x'' + C x' + K x = f(t) (any SPD M, not only diagonal) with
/// one stop nᵀx ≤ p and restitution r, by the fixed-step Cooper–Verner RK8 of
/// reference_integrator.hpp in long double. It shares nothing with vibro::Simulator but the
/// input data (the matrices, the forcing, n, p, r): no matrix exponential, no contact LCP, no
/// reduced flow, no certified bounds.
///
///  * Free flight: ReferenceIntegrator, a fixed step h with h·ρ = step_rate (see there for the
///    accuracy: ≈ 5e-18 of the state per step at 0.05).
///  * Events: the gap g = nᵀx − p crossing from ≤ 0 to > 0 at the end of a step, or an excursion
///    inside a step (the rate nᵀv changing sign from + to − with both ends ≤ 0: the interior
///    maximum, located by bisection on the rate, is tested too). The crossing is located by
///    bisection on the sub-step length θ (one RK step of length θ from the step start: same
///    order as a full step) until θ is resolved to a few units of long-double rounding.
///  * Impact: Newton's law along n in the metric of M. An impulse P M⁻¹n changes the normal
///    velocity u = nᵀv by P nᵀM⁻¹n; asking u⁺ = −r u⁻ gives
///        v⁺ = v⁻ − (1 + r) u⁻ M⁻¹n / (nᵀM⁻¹n),
///    the impact law of a frictionless unilateral constraint (Brogliato, "Nonsmooth Mechanics",
///    3rd ed., 2016, § 5.2, Newton's law on the constraint's normal velocity). It is written
///    here from that formula alone, not from the framework's LCP.
///  * Scope: impacts only. A rebound slower than stick_velocity (chatter that would end in
///    sticking) throws std::runtime_error: the test's parameters must give an impacting orbit
///    without sticking, and the reference says so if they do not.
///
/// Usage:
///     vibro::test::ReferenceGeneralStop ref(system, n, p, r);
///     ref.run(0.0L, x0, v0, t_end);
///     for (const auto& e : ref.impacts) ... e.t, e.u_before ...
#include "support/reference_integrator.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace vibro::test {

struct ReferenceImpact {
  long double t = 0.0L;
  long double u_before = 0.0L;  ///< nᵀv⁻ (> 0: approaching)
};

class ReferenceGeneralStop {
 public:
  ReferenceGeneralStop(const LinearSystem& system, const Eigen::VectorXd& normal, double position, double restitution,
                       long double step_rate = ReferenceIntegrator::default_step_rate)
      : flow_(system), n_(normal.cast<long double>()), p_(position), r_(restitution), step_rate_(step_rate) {
    const MatrixL M = system.mass().cast<long double>();
    const Eigen::LLT<MatrixL> llt(M);
    if (llt.info() != Eigen::Success) throw std::invalid_argument("reference: M not SPD");
    minv_n_ = llt.solve(n_);
    delassus_ = n_.dot(minv_n_);
  }

  std::vector<ReferenceImpact> impacts;
  long double stick_velocity = 1e-7L;

  /// Integrates from (t0, x0, v0) to t_end; x, v hold the final state.
  void run(long double t0, const VectorL& x0, const VectorL& v0, long double t_end) {
    ReferenceIntegrator::State s{t0, x0, v0};
    const long double h = step_rate_ / flow_.rate();
    while (s.t < t_end) {
      const long double step = std::min(h, t_end - s.t);
      ReferenceIntegrator::State e = advanced(s, step);
      long double theta = -1.0L;  // sub-step of the first crossing, if any
      if (gap(e) > 0.0L) {
        theta = crossing(s, 0.0L, step);
      } else if (rate(s) > 0.0L && rate(e) < 0.0L) {
        // The interior maximum of g: bisection on the rate.
        long double a = 0.0L, b = step;
        for (int i = 0; i < 200 && b - a > 4e-19L * std::max(1.0L, std::fabs(s.t)); ++i) {
          const long double m = 0.5L * (a + b);
          (rate(advanced(s, m)) > 0.0L ? a : b) = m;
        }
        if (gap(advanced(s, a)) > 0.0L) theta = crossing(s, 0.0L, a);
      }
      if (theta < 0.0L) {
        s = e;
        continue;
      }
      s = advanced(s, theta);
      const long double u = rate(s);
      if (u <= 0.0L) throw std::runtime_error("reference: a crossing with nᵀv ≤ 0 (grazing)");
      if (r_ * u < stick_velocity) throw std::runtime_error("reference: chatter towards sticking, out of scope");
      impacts.push_back({s.t, u});
      s.v -= ((1.0L + r_) * u / delassus_) * minv_n_;
    }
    x = s.x;
    v = s.v;
  }

  VectorL x, v;

 private:
  ReferenceIntegrator::State advanced(const ReferenceIntegrator::State& s, long double dt) {
    ReferenceIntegrator::State out = s;
    if (dt > 0.0L) flow_.advance(out, s.t + dt, 1);
    return out;
  }
  long double gap(const ReferenceIntegrator::State& s) const { return n_.dot(s.x) - p_; }
  long double rate(const ReferenceIntegrator::State& s) const { return n_.dot(s.v); }

  /// The first θ in (a, b] with g > 0 after g(a) ≤ 0 < g(b), by bisection, to a few ulps of t;
  /// the far side of the root (g > 0 by at most the rounding of the bisection).
  long double crossing(const ReferenceIntegrator::State& s, long double a, long double b) {
    for (int i = 0; i < 200 && b - a > 4e-19L * std::max(1.0L, std::fabs(s.t)); ++i) {
      const long double m = 0.5L * (a + b);
      (gap(advanced(s, m)) > 0.0L ? b : a) = m;
    }
    return b;
  }

  ReferenceIntegrator flow_;
  VectorL n_, minv_n_;
  long double p_, r_, delassus_ = 0.0L, step_rate_;
};

}  // namespace vibro::test
