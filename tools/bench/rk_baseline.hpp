#pragma once
/// \file rk_baseline.hpp
/// A conventional baseline for the work-precision report: adaptive Runge–Kutta with event
/// location, applying the SAME impact and sticking rules as vibro::Simulator.
///
/// What is shared with the framework: the scene (matrices, forcing, stops), the contact-set
/// algebra of contact.hpp (Delassus matrix G = Wᵀ M⁻¹ W, M⁻¹ W, the LCP solver) and the event
/// rules (written out again below, not called). What is the baseline's own: the time integration
/// and the event location.
///
///  * Motion in contact set S (stops held): M x'' = f(t) - C v - K x - W_S λ with
///        λ = G_S⁻¹ (W_Sᵀ a_free - s_S''(t)),   a_free = M⁻¹ (f - C v - K x),
///    i.e. the index-reduced constrained equations in full coordinates, integrated by a
///    Boost.Odeint controlled stepper: runge_kutta_dopri5 (with its dense output, 4th-order
///    continuous extension) or runge_kutta_fehlberg78 (no dense output: states inside a step are
///    obtained by re-stepping from the step start with a step of the wanted length, which keeps
///    the method's order). Error control: odeint's default, |err_i| ≤ atol + rtol·(|z_i| + h|z_i'|),
///    atol = rtol·min(L, V) (L, V the framework's length and velocity scales).
///  * Guards as in the framework: g_j = w_jᵀ x - s_j(t) for free stops, -λ_j for held ones. An
///    event is a guard > 0 at the END of an accepted step that was ≤ 0 at its start (or, for a
///    guard that starts on zero just after an event, ≤ 0 at some point 2^-k into the step):
///    the conventional check of step ends, so an excursion past a stop that begins and ends
///    inside one step is missed (the framework's certified search does not miss it). The
///    crossing is located by Brent's method (Brent 1973, ch. 4) on the interpolated or
///    re-stepped guard, down to a few ulps of t.
///  * At an event the framework's rules: guards within the simultaneity window fire together;
///    impacts by the impulse LCP over S ∪ I (Newton restitution per stop); chatter → sticking
///    when the stop would hold and the next bounce would rise less than chatter_height·L
///    (that stop's r is then taken as 0, and a chatter_limit event is logged at the Budd–Dux
///    accumulation time t + 2 r u / (a (1 - r))); impacting gaps placed exactly at zero; the held
///    set from the acceleration LCP; the residual normal velocity of held stops removed.
///
/// Numerical trouble (non-finite state, an event cap like the framework's Zeno guard, a step
/// budget) ends the run with ok = false and a message: never a silent NaN.
#include "vibro/contact.hpp"
#include "vibro/observers.hpp"

#include <string>
#include <vector>

namespace vibro::bench {

enum class RkMethod { dopri5, fehlberg78 };
const char* to_string(RkMethod m);

struct RkOptions {
  RkMethod method = RkMethod::dopri5;
  double rtol = 1e-6;
  double atol = 0.0;  ///< absolute; 0 = rtol · min(L, V)
  /// The framework's rules and their defaults (fractions of L, V, T).
  double chatter_height = 1e-9;
  double contact_velocity = 1e-11;
  double simultaneity = 1e-12;
  double trigger = 1e-13;  ///< rounding allowance: a guard must exceed this (× L or F) to fire
  long max_events = 100000;  ///< per time scale T, as the framework's Zeno guard
  long max_steps = 50000000;
  /// Scales L, V, F, T (take them from the framework's RunSummary for the same start).
  double length_scale = 1.0, velocity_scale = 1.0, force_scale = 1.0, time_scale = 1.0;
};

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
  struct Impl;
  const ImpactSystem* scene_;
  RkOptions options_;
};

}  // namespace vibro::bench
