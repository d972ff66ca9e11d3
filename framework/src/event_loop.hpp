#pragma once
// Private to vibro_core: the hybrid event loop of simulator.hpp, written once for both engines.
// The frame owns everything an engine does not decide: the checks of the input and of the
// scales (with their messages), the summary, the observers' begin and end, the interruption and
// progress polling (once per event and once per step of the event search), the Zeno guard, the
// statuses and their messages, and which fired guard means what (contact_law.hpp). An engine
// supplies only how a mode's segment is built, searched and evaluated, and its ContactAlgebra
// (through `resolve`): the dense engine's exact flows (simulator.cpp) and the chain engine's
// modal coordinates (modal_simulator.cpp).
//
// An engine E provides (every call allocation-free inside the loop):
//   Eigen::Index dof();  const std::vector<Stop>& stops();  double frequency();   (Ω, 0: unforced)
//   ScaleInputs scale_inputs();                       the system's sizes for run_scales
//   void check_scene(const RunScales&, std::vector<std::string>& warnings);  engine-specific checks
//   void start(const RunScales&, RunState&);         per-run storage; enter the free mode at t0
//   void initial_guards(const RunState&, VectorXd& gaps, VectorXd& rates);  every stop's gap, rate
//   bool resolve(RunState&, impacts, releases, resting, std::string* why);   resolve, enter the mode
//   double stiffness(const RunState&, double T);      T × the fastest rate of the current mode
//   SegmentPlan begin_segment(const RunState&, double t_end);  target the mode's segment at t
//   bool search(double a, double b, Crossing*);       one step [a, b] of the certified search
//   void end_search();                               after the last step of a segment
//   void report(double t, double t_next, observers); the segment's view to the observers
//   bool advance(RunState&, const Crossing*, double tau, double t_next);  the state there; finite?
//   FiredGuards fired();                             the guards at the crossing just advanced to
//   bool event(RunState&, impacts, releases, std::string* why);  an event in the loop (resolve or
//                                                    a faster path); false: unsupported
//   bool stop_requested(std::string* why);          the engine's own end (true: stop, completed)
//   void state(const RunState&, bool physical, VectorXd& x, VectorXd& v);  the state reached
//   void finish(RunSummary&);                       the engine's counts
#include "event_rate.hpp"
#include "event_resolution.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/contact_law.hpp"
#include "vibro/events.hpp"

#include <algorithm>
#include <atomic>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vibro::detail {

/// What run_scales needs of a system: the scale frequency (the forcing's, or the fastest mode's
/// when unforced), max |K_ij|, max |M_ij| and the forcing amplitudes summed.
struct ScaleInputs {
  double omega = 1.0, kmax = 0.0, mmax = 0.0, fmax = 0.0;
};

/// The run's state as the frame keeps it: time, physical state (current after the engine's
/// advance or resolution; the modal engine keeps its modal state between events) and the held set.
struct RunState {
  double t = 0.0;
  Eigen::VectorXd x, v;
  ContactSet stuck;
};

/// One segment's search plan: the step of the search (1/ρ) and how far the segment reaches (the
/// run's end, or a flow's horizon beyond which a new segment starts).
struct SegmentPlan {
  double step = 0.0, reach = 0.0;
};

/// The guard rows at a crossing: values, slopes and trigger levels, and each row's stop; rows
/// [0, opening_rows) watch open stops, the rest held ones (GuardKind).
struct FiredGuards {
  const Eigen::VectorXd& h;
  const Eigen::VectorXd& d;
  const Eigen::VectorXd& trigger;
  Eigen::Index opening_rows;
  const std::vector<int>& stop;
};

std::string vector_text(const Eigen::VectorXd& v);
/// Throws InvalidInput for an initial state of the wrong size or not finite, or a time span that
/// is not finite or reversed.
void check_run_input(Eigen::Index n, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end);
/// The Zeno guard's message (the state only for small systems: the summary holds it).
std::string event_cap_message(const SimulatorOptions& options, double window, double t, const Stop& stop, int j,
                              const Eigen::VectorXd& x, const Eigen::VectorXd& v);

template <class Law = RigidStopLaw, class Engine>
void run_event_loop(Engine& engine, const SimulatorOptions& options, double t0, const Eigen::VectorXd& x0,
                    const Eigen::VectorXd& v0, double t_end, const std::vector<Observer*>& observers,
                    RunSummary& summary) {
  const Eigen::Index n = engine.dof();
  const std::vector<Stop>& stops = engine.stops();
  const int m = static_cast<int>(stops.size());
  check_run_input(n, t0, x0, v0, t_end);

  const ScaleInputs in = engine.scale_inputs();
  const RunScales sc = run_scales(options, in.omega, in.kmax, in.mmax, in.fmax, stops, x0, v0);
  SimulatorOptions automatic = options;
  automatic.length_scale = 0.0;
  std::vector<std::string> warnings;
  check_resolution(sc, run_scales(automatic, in.omega, in.kmax, in.mmax, in.fmax, stops, x0, v0), options, t0,
                   t_end, warnings);
  engine.check_scene(sc, warnings);
  const double eps_gap = sc.eps_gap, v_contact = sc.rules.v_contact;
  const double dt_simultaneous = sc.dt_simultaneous, window = sc.window;
  check_admissible(stops, engine.frequency(), t0, x0, eps_gap);

  summary.warnings = std::move(warnings);
  summary.length_scale = sc.L;
  summary.velocity_scale = sc.V;
  summary.force_scale = sc.F;
  summary.time_scale = sc.T;
  RunState st;
  st.t = t0;
  st.x = x0;
  st.v = v0;
  st.stuck.reserve(static_cast<std::size_t>(m));
  engine.start(sc, st);
  const RunContext context{n, stops.size(), engine.frequency(), eps_gap};
  for (Observer* o : observers) o->begin(context, t0);

  ContactSet impacting, releasing, resting;
  for (ContactSet* set : {&impacting, &releasing, &resting}) set->reserve(static_cast<std::size_t>(m));
  EventRate rate(options.max_events, window);
  // Ends the run; the state reached is the engine's (its mode's), or the physical state after
  // an event that could not be carried into a mode (physical).
  auto finish = [&](RunStatus status, std::string message, bool physical = false) {
    for (Observer* o : observers) o->end(st.t);
    summary.status = status;
    summary.message = std::move(message);
    summary.t = st.t;
    summary.x.resize(n);
    summary.v.resize(n);
    engine.state(st, physical, summary.x, summary.v);
    summary.stuck = st.stuck;
    engine.finish(summary);
  };
  auto interrupted = [&] { return options.interrupt && options.interrupt->load(std::memory_order_relaxed); };
  auto report = [&](double reached) {
    if (options.reached) options.reached->store(reached, std::memory_order_relaxed);
  };
  // The search may have reached well past the state kept (a long segment: the start of the
  // segment, or the last event): say both, so a run that seems to sit at t0 is seen to move.
  const auto interruption = [&](double reached) {
    std::string text = "interrupted at t = " + number_text(reached);
    if (reached > st.t) text += " (the state kept is the one at t = " + number_text(st.t) + ", where the segment began)";
    return text;
  };

  std::string why_not;
  try {
    {  // Stops touched at t0 (within ε) that are approached or resting.
      Eigen::VectorXd g(m), gd(m);
      engine.initial_guards(st, g, gd);
      for (int j = 0; j < m; ++j) {
        if (stops[static_cast<std::size_t>(j)].is_compliant()) continue;  // the engine's start() engaged it
        const InitialContact c = Law::initial_contact(g(j), gd(j), eps_gap, v_contact);
        if (c == InitialContact::impact) impacting.push_back(j);
        else if (c == InitialContact::resting) resting.push_back(j);
      }
      if ((!impacting.empty() || !resting.empty()) && !engine.resolve(st, impacting, releasing, resting, &why_not))
        return finish(RunStatus::unsupported, why_not, true);
    }
    // Stiff or heavily damped: the certified search steps by 1/ρ (ρ the fastest rate).
    if (const double steps = engine.stiffness(st, sc.T); steps > kStiffStepsPerPeriod)
      summary.warnings.push_back(stiff_warning(steps, (t_end - t0) / sc.T));
    while (true) {
      report(st.t);
      if (interrupted()) return finish(RunStatus::interrupted, interruption(st.t));
      const SegmentPlan plan = engine.begin_segment(st, t_end);
      const double span = t_end - st.t;
      Crossing crossing{};
      bool hit = false;
      for (double a = 0.0; a < plan.reach && !hit;) {
        if (interrupted()) return finish(RunStatus::interrupted, interruption(st.t + a));
        report(st.t + a);
        const double b = std::min(a + plan.step, plan.reach);
        hit = engine.search(a, b, &crossing);
        a = b;
      }
      engine.end_search();
      const double tau = hit ? crossing.tau : plan.reach;
      const double t_next = hit ? st.t + tau : (plan.reach < span ? st.t + plan.reach : t_end);
      ++summary.segments;
      if (!observers.empty()) engine.report(st.t, t_next, observers);
      const bool finite = engine.advance(st, hit ? &crossing : nullptr, tau, t_next);
      st.t = t_next;
      if (!finite)
        return finish(RunStatus::numerical_failure, "non-finite state at t = " + number_text(st.t) +
                                                        " in contact set of " + std::to_string(st.stuck.size()) +
                                                        " stops");
      if (!hit) {
        if (plan.reach < span) continue;
        break;
      }

      // Which guards fire together (within the simultaneity window), and what each means.
      const FiredGuards f = engine.fired();
      impacting.clear();
      releasing.clear();
      for (Eigen::Index i = 0; i < f.h.size(); ++i) {
        const double h = f.h(i), hd = f.d(i);
        const bool fired = i == crossing.row || (hd > 0.0 && h >= -std::max(f.trigger(i), hd * dt_simultaneous));
        if (!fired) continue;
        const GuardKind kind = i < f.opening_rows ? GuardKind::opening : GuardKind::holding;
        const int j = f.stop[static_cast<std::size_t>(i)];
        // A compliant stop's engage joins the impacts and its disengage the releases; the engine
        // tells them apart by the stop's law (contact_law.hpp).
        const Transition tr = stops[static_cast<std::size_t>(j)].is_compliant() ? CompliantStopLaw::transition(kind)
                                                                                 : Law::transition(kind);
        (tr == Transition::impact || tr == Transition::engage ? impacting : releasing).push_back(j);
      }
      std::sort(impacting.begin(), impacting.end());
      std::sort(releasing.begin(), releasing.end());
      if (!engine.event(st, impacting, releasing, &why_not)) return finish(RunStatus::unsupported, why_not, true);
      if (std::string why; engine.stop_requested(&why)) return finish(RunStatus::completed, why);
      if (rate.exceeded(st.t)) {
        finish(RunStatus::event_cap, "");
        if (impacting.empty() && releasing.empty()) {  // an event of another law (friction_stops.hpp)
          summary.message = "event cap: more than " + std::to_string(options.max_events) + " events within " +
                            number_text(window) + " time units, at t = " + number_text(st.t) +
                            " (stick-slip switches of the frictional contacts)";
          return;
        }
        const int j = !impacting.empty() ? impacting.front() : releasing.front();
        summary.message =
            event_cap_message(options, window, st.t, stops[static_cast<std::size_t>(j)], j, summary.x, summary.v);
        return;
      }
    }
  } catch (const Interrupted&) {  // a set-up under run_bounded (bounded_wait.hpp)
    return finish(RunStatus::interrupted, interruption(st.t));
  } catch (const std::runtime_error& e) {
    return finish(RunStatus::numerical_failure, std::string(e.what()) + " (at t = " + number_text(st.t) + ")");
  }
  finish(RunStatus::completed, "");
}

}  // namespace vibro::detail
