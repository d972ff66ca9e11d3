#pragma once
/// \file rk_baseline.hpp
/// Conventional baselines for the work-precision report: adaptive embedded Runge–Kutta pairs
/// with dense output and event location, applying the framework's OWN event rules.
///
///  * Motion between events: the index-reduced equations of the current contact mode in full
///    coordinates (baseline_events.hpp), x'' = f0 + f_c cos Ωt + f_s sin Ωt − K_S x − C_S v, in
///    fixed-size storage for 1, 2 and 10 degrees of freedom (Eigen::Matrix<double, n, n>; other
///    sizes dynamic): a right-hand side is two n × n products and one cos and sin.
///  * Time integration (rk_steppers.hpp, written here from the published tables): Dormand–Prince
///    5(4) with its 4th-order dense output, or Prince–Dormand 8(5,3) (DOP853) with its
///    7th-order dense output; Hairer's error norm (RMS of err_i / (atol + rtol·max(|y0_i|, |y1_i|))),
///    atol = rtol · min(L, V) (L, V the framework's length and velocity scales).
///  * Guards as in the framework: g_j = w_jᵀ x − s_j(t) for free stops (s_j evaluated only for
///    moving stops), −λ_j for held ones. An event is a guard above its trigger level at the END
///    of an accepted step that was ≤ 0 at its start (or, for a guard that starts on zero just
///    after an event, ≤ 0 at some point 2^-k into the step): the conventional check of step
///    ends, so an excursion past a stop that begins and ends inside one step is missed (the
///    framework's certified search does not miss it). The crossing is located by Brent's method
///    (Brent 1973, ch. 4) on the dense output, down to a few ulps of t.
///  * At an event: vibro::detail::resolve_event, the framework's own rules (baseline_events.hpp):
///    simultaneity window, impulse LCP, the chatter test against chatter_height (a setting of
///    its own, not tied to rtol), the third-order chatter rule with its state correction and
///    Budd–Dux accumulation time, the acceleration LCP for the held set. The dense output is
///    restarted from the post-event state.
///
/// Numerical trouble (non-finite state, the framework's Zeno guard, a step budget, step-size
/// underflow) ends the run with ok = false and a message: never a silent NaN.
#include "baseline_events.hpp"

#include <string>
#include <vector>

namespace vibro::bench {

enum class RkMethod { dopri5, dop853 };
const char* to_string(RkMethod m);

struct RkOptions {
  RkMethod method = RkMethod::dopri5;
  double rtol = 1e-6;
  double atol = 0.0;  ///< absolute; 0 = rtol · min(L, V)
  long max_steps = 50000000;
  BaselineRules rules;  ///< chatter_height, trigger, …, and the scales L, V, F, T
};

/// What a baseline run produced (also the SUNDIALS peer's, sundials_peer.hpp).
struct RkResult {
  bool ok = true;
  std::string message;
  std::vector<Event> events;              ///< impacts, sticks, releases, chatter limits
  /// At the requested sample times, a column each (n × samples taken): sized once for all the
  /// times in [t0, t_end] and filled in place, as vibro::Samples stores the framework's.
  Eigen::MatrixXd x, v;
  long steps = 0, rejected = 0, rhs = 0;  ///< accepted steps, rejected steps, RHS evaluations
  long impacts = 0;
};

class RkBaseline {
 public:
  RkBaseline(const ImpactSystem& scene, RkOptions options);
  /// Runs from (t0, x0, v0) to t_end; states are recorded at `sample_times` (ascending).
  RkResult run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
               const std::vector<double>& sample_times);

 private:
  const ImpactSystem* scene_;
  RkOptions options_;
};

}  // namespace vibro::bench
