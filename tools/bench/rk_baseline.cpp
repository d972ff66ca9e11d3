#include "rk_baseline.hpp"

#include "baseline_flow.hpp"
#include "brent.hpp"
#include "rk_steppers.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vibro::bench {

const char* to_string(RkMethod m) {
  switch (m) {
    case RkMethod::dopri5: return "dopri5";
    case RkMethod::dop853: return "dop853";
  }
  return "?";
}

namespace {

template <int N, template <class, class> class Method>
RkResult run_fixed(const ImpactSystem& scene, const RkOptions& opt, double t0, const Eigen::VectorXd& x0,
                   const Eigen::VectorXd& v0, double t_end, const std::vector<double>& sample_times) {
  using Flow = FixedFlow<N>;
  using State = typename Flow::State;
  RkResult result;
  BaselineEvents ev(scene, opt.rules);
  const Eigen::Index n = ev.dof();
  const int stops = ev.stops();
  Flow flow;
  flow.n = n;
  flow.omega = ev.omega();
  FixedGuards<N> guards;
  guards.init(ev);
  ContactSet stuck;
  auto enter = [&] {
    flow.enter(ev.mode(stuck));
    guards.enter(flow);
  };
  enter();
  const double atol = opt.atol > 0.0 ? opt.atol : opt.rtol * std::min(opt.rules.length_scale, opt.rules.velocity_scale);
  Method<State, Flow> stepper(flow, atol, opt.rtol);

  double t = t0;
  Eigen::VectorXd x = x0, v = v0;  // the state at events (resolve_event's form)
  std::size_t next_sample = 0;
  while (next_sample < sample_times.size() && sample_times[next_sample] < t0) ++next_sample;
  const auto wanted = static_cast<Eigen::Index>(
      std::upper_bound(sample_times.begin(), sample_times.end(), t_end) - sample_times.begin()) -
      static_cast<Eigen::Index>(next_sample);
  result.x.resize(n, std::max<Eigen::Index>(wanted, 0));
  result.v.resize(n, result.x.cols());
  Eigen::Index taken = 0;
  auto finish = [&] {
    result.x.conservativeResize(Eigen::NoChange, taken);  // a run that stopped early took fewer
    result.v.conservativeResize(Eigen::NoChange, taken);
    result.rhs = flow.evaluations;
    result.rejected = stepper.rejected;
    result.impacts = ev.impacts();
    return result;
  };
  auto fail = [&](const std::string& why) {
    result.ok = false;
    result.message = why + " at t = " + number_text(t);
    return finish();
  };
  State z(2 * n), zt(2 * n), zb(2 * n), zs(2 * n), dz(2 * n);
  auto pack = [&] {
    z.head(n) = x;
    z.tail(n) = v;
  };
  auto record_until = [&](double t_hi) {  // samples in (previous, t_hi] from the current step
    while (next_sample < sample_times.size() && sample_times[next_sample] <= t_hi && taken < result.x.cols()) {
      stepper.state_at(sample_times[next_sample], zt);
      result.x.col(taken) = zt.head(n);
      result.v.col(taken) = zt.tail(n);
      ++taken;
      ++next_sample;
    }
  };
  std::string why;
  {  // initial contacts, as the framework's run start
    const Eigen::VectorXd g = scene.gaps(t, x), gd = scene.gap_rates(t, v);
    ContactSet impacting, resting;
    for (int j = 0; j < stops; ++j) {
      if (g(j) < -ev.eps_gap()) continue;
      if (gd(j) > opt.rules.contact_velocity * opt.rules.velocity_scale) impacting.push_back(j);
      else if (gd(j) >= -opt.rules.contact_velocity * opt.rules.velocity_scale) resting.push_back(j);
    }
    if (!ev.resolve(t, x, v, stuck, impacting, {}, resting, result.events, &why)) return fail(why);
    enter();
  }
  pack();
  stepper.init(t, z, 1e-3 * opt.rules.time_scale);
  Eigen::VectorXd triggers(stops);
  auto arm = [&] {  // trigger levels, re-armed above a guard that starts positive moving away
    flow(t, z, dz);
    for (int j = 0; j < stops; ++j) {
      triggers(j) = guards.held(j) ? ev.eps_force() : ev.eps_gap();
      const double h0 = guards.guard(flow, j, t, z);
      if (h0 > 0.0 && guards.guard_rate(flow, j, t, z, dz) <= 0.0) triggers(j) += h0;
    }
  };
  arm();
  const double resolution = 4.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), opt.rules.time_scale);
  while (t < t_end) {
    if (++result.steps > opt.max_steps) return fail("step budget exhausted");
    if (!stepper.step(t_end)) return fail("step size underflow");
    const double ta = stepper.t0(), tb = stepper.t1();
    zb = stepper.z1();
    if (!zb.allFinite()) return fail("non-finite state");
    // Earliest guard crossing in (ta, tb].
    double best = std::numeric_limits<double>::infinity();
    int best_stop = -1;
    for (int j = 0; j < stops; ++j) {
      const double hb = guards.guard(flow, j, tb, zb);
      if (!(hb > triggers(j))) continue;
      auto f = [&](double time) {
        stepper.state_at(time, zs);
        return guards.guard(flow, j, time, zs);
      };
      double a = ta, fa = f(ta);
      if (fa >= 0.0) {  // starts on or above zero (just after an event): find a point below
        bool found = false;
        for (int k = 1; k <= 60 && !found; ++k) {
          const double tk = ta + (tb - ta) * std::ldexp(1.0, -k);
          if (tk <= ta) break;
          const double fk = f(tk);
          if (fk < 0.0) {
            a = tk;
            fa = fk;
            found = true;
          }
        }
        if (!found) {  // positive throughout: the event is at the step start
          if (ta < best) {
            best = ta;
            best_stop = j;
          }
          continue;
        }
      }
      const double root = brent(f, a, tb, fa, hb, resolution);
      if (root < best) {
        best = root;
        best_stop = j;
      }
    }
    if (best_stop < 0) {
      record_until(tb);
      t = tb;
      continue;
    }
    record_until(best);
    stepper.state_at(best, z);
    t = best;
    flow(t, z, dz);  // the rates at the event (held stops' guards)
    ContactSet impacting, releasing;
    for (int j = 0; j < stops; ++j) {
      const double h = guards.guard(flow, j, t, z), hd = guards.guard_rate(flow, j, t, z, dz);
      const bool fired = j == best_stop || (hd > 0.0 && h >= -std::max(triggers(j), hd * ev.dt_simultaneous()));
      if (!fired) continue;
      (guards.held(j) ? releasing : impacting).push_back(j);
    }
    x = z.head(n);
    v = z.tail(n);
    if (!ev.resolve(t, x, v, stuck, impacting, releasing, {}, result.events, &why)) return fail(why);
    if (ev.too_many(t))
      return fail("event cap: more than " + std::to_string(opt.rules.max_events) + " events within T");
    enter();
    pack();
    stepper.init(t, z, std::max(stepper.dt(), 1e-12 * opt.rules.time_scale));
    arm();
  }
  return finish();
}

template <template <class, class> class Method>
RkResult run_method(const ImpactSystem& scene, const RkOptions& opt, double t0, const Eigen::VectorXd& x0,
                    const Eigen::VectorXd& v0, double t_end, const std::vector<double>& samples) {
  switch (scene.dof()) {
    case 1: return run_fixed<1, Method>(scene, opt, t0, x0, v0, t_end, samples);
    case 2: return run_fixed<2, Method>(scene, opt, t0, x0, v0, t_end, samples);
    case 10: return run_fixed<10, Method>(scene, opt, t0, x0, v0, t_end, samples);
    default: return run_fixed<Eigen::Dynamic, Method>(scene, opt, t0, x0, v0, t_end, samples);
  }
}

}  // namespace

RkBaseline::RkBaseline(const ImpactSystem& scene, RkOptions options) : scene_(&scene), options_(options) {
  if (!(options_.rtol > 0.0)) throw InvalidInput("RkBaseline: rtol must be > 0");
}

RkResult RkBaseline::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                         const std::vector<double>& sample_times) {
  try {
    if (options_.method == RkMethod::dopri5)
      return run_method<Dopri5>(*scene_, options_, t0, x0, v0, t_end, sample_times);
    return run_method<Dop853>(*scene_, options_, t0, x0, v0, t_end, sample_times);
  } catch (const std::runtime_error& e) {
    RkResult r;
    r.ok = false;
    r.message = e.what();
    return r;
  }
}

}  // namespace vibro::bench
