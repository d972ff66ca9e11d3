// bench_taylor_odeint: work against precision of the Taylor engine (vibro/taylor_simulator.hpp)
// and of Boost.Odeint's integrators with dense output, on the forced Duffing impact oscillator
//
//     x'' + 0.05 x' + x + 0.5 x³ = 0.8 cos 1.3t,   x ≤ 0.6 (rigid stop, r = 0.8), from rest,
//
// (experiments/examples/duffing_impact.yaml) over P forcing periods (one impact a period).
//
// The Odeint runs locate impacts the conventional way: each accepted step's end is tested for
// penetration (x > 0.6), the crossing is found by bisection on the step's dense output to
// rounding, the impact law v⁺ = −r v⁻ is applied there and the stepper restarts. Methods:
// Dormand–Prince 5(4) (runge_kutta_dopri5, dense output of order 4) and Bulirsch–Stoer with
// dense output (bulirsch_stoer_dense_out, high order), each at a ladder of tolerances (absolute
// = relative); the Taylor engine at a ladder of series tolerances (NonlinearForces::tolerance;
// default the unit roundoff).
//
// Error: against the long-double RK8 reference of tests/support/reference_duffing_impact.hpp
// (~1e-16 of the state), the largest of |Δt_i| / T over the impact times and |Δv_i| / max|v| over
// the approach speeds. A run with another number of impacts is reported as such, with no error.
// Time: the CPU time of one run (this thread's, so a shared machine's load counts less); every configuration runs `repeat` times (default 5), the
// configurations alternating within each round so that drifts of a shared machine spread over
// all of them; the median is reported. Then, for each target error, the fastest configuration of
// each method that meets it and the Taylor engine's speed-up over the best Odeint method.
//
//     build/release/tools/bench/bench_taylor_odeint [--periods P] [--repeat R]
//
// Meaningful only in a Release build; docs/performance.md quotes it.
#include "vibro/observers.hpp"
#include "vibro/taylor_simulator.hpp"

#include "support/reference_duffing_impact.hpp"

#include <boost/numeric/odeint.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <time.h>

namespace {

namespace odeint = boost::numeric::odeint;

constexpr double kC = 0.05, kK = 1.0, kBeta = 0.5, kA = 0.8, kOmega = 1.3, kStop = 0.6, kR = 0.8;

struct Impact {
  double t, v_before;
};

struct Outcome {
  std::vector<Impact> impacts;
  double x = 0.0, v = 0.0;
  long steps = 0;  ///< Taylor steps, or the stepper's accepted steps
};

using State = std::array<double, 2>;

struct Rhs {
  void operator()(const State& z, State& dz, double t) const {
    dz[0] = z[1];
    dz[1] = kA * std::cos(kOmega * t) - kC * z[1] - kK * z[0] - kBeta * z[0] * z[0] * z[0];
  }
};

/// One run with an Odeint dense-output stepper; events by bisection on its dense output.
template <class Stepper>
Outcome run_odeint(Stepper stepper, double t_end) {
  Outcome out;
  const Rhs rhs;
  State z{0.0, 0.0};
  double t = 0.0;
  stepper.initialize(z, t, 1e-2);
  while (stepper.current_time() < t_end) {
    const auto [t0, t1_raw] = stepper.do_step(rhs);
    ++out.steps;
    const double t1 = std::min(t1_raw, t_end);
    State z1;
    stepper.calc_state(t1, z1);
    if (z1[0] - kStop > 0.0) {  // penetration at the step's end: bisect the crossing on the dense output
      double lo = t0, hi = t1;
      State zm;
      while (hi - lo > 2.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, hi)) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        stepper.calc_state(mid, zm);
        (zm[0] - kStop > 0.0 ? hi : lo) = mid;
      }
      stepper.calc_state(lo, zm);
      out.impacts.push_back({lo, zm[1]});
      z = {kStop, -kR * zm[1]};
      stepper.initialize(z, lo, std::max(stepper.current_time_step(), 1e-6));
      continue;
    }
    if (t1 >= t_end) {
      out.x = z1[0];
      out.v = z1[1];
      return out;
    }
  }
  const State& e = stepper.current_state();
  out.x = e[0];
  out.v = e[1];
  return out;
}

vibro::ImpactSystem duffing_linear_part() {
  vibro::HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, kA),
                           .sine = Eigen::VectorXd::Zero(1), .frequency = kOmega};
  vibro::LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, kC),
                          Eigen::MatrixXd::Constant(1, 1, kK), f);
  return vibro::ImpactSystem(sys, {vibro::Stop::upper(0, kStop, kR)});
}

/// This thread's CPU time (a shared machine's other load does not count).
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Config {
  std::string method;
  double tolerance;
  std::function<Outcome(double)> run;
  std::vector<double> seconds;
  Outcome last;
  double error = 0.0;
  bool same_events = false;
  double median() const {
    std::vector<double> s = seconds;
    std::sort(s.begin(), s.end());
    return s[s.size() / 2];
  }
};

}  // namespace

int main(int argc, char** argv) {
  int periods = 20, repeat = 5;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--periods") && i + 1 < argc) periods = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: %s [--periods P] [--repeat R]\n", argv[0]);
      return 2;
    }
  }
  if (periods < 1 || repeat < 1) return 2;
  const double T = 2.0 * std::acos(-1.0) / kOmega, t_end = periods * T;

  vibro::test::ReferenceDuffingImpact ref;
  ref.c = kC;
  ref.k = kK;
  ref.beta = kBeta;
  ref.amplitude = kA;
  ref.omega = kOmega;
  ref.stop = kStop;
  ref.restitution = kR;
  ref.run(0.0L, 0.0L, 0.0L, t_end);
  double u_scale = 0.0;
  for (const auto& i : ref.impacts) u_scale = std::max(u_scale, std::abs(static_cast<double>(i.v_before)));

  const vibro::ImpactSystem system = duffing_linear_part();
  std::vector<Config> configs;
  for (double tol : {std::numeric_limits<double>::epsilon(), 1e-14, 1e-12, 1e-10, 1e-8, 1e-6}) {
    configs.push_back({"Taylor engine", tol, [&system, tol](double end) {
                         vibro::NonlinearForces forces;
                         forces.parameters = {{"beta", kBeta}};
                         forces.forces = {"-beta*x0^3"};
                         forces.tolerance = tol;
                         vibro::TaylorSimulator sim(system, forces);
                         vibro::EventLog log;
                         const Eigen::VectorXd zero = Eigen::VectorXd::Zero(1);
                         const vibro::RunSummary s = sim.run(0.0, zero, zero, end, {&log});
                         Outcome o;
                         for (const vibro::Event& e : log.events) o.impacts.push_back({e.t, e.v_before});
                         o.x = s.x(0);
                         o.v = s.v(0);
                         o.steps = sim.steps();
                         return o;
                       }, {}, {}, 0.0, false});
  }
  for (double tol : {1e-4, 1e-6, 1e-8, 1e-10, 1e-11, 1e-12, 1e-13})
    configs.push_back({"Odeint dopri5", tol, [tol](double end) {
                         return run_odeint(odeint::make_dense_output(tol, tol, odeint::runge_kutta_dopri5<State>()), end);
                       }, {}, {}, 0.0, false});
  for (double tol : {1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 1e-14})
    configs.push_back({"Odeint Bulirsch-Stoer", tol, [tol](double end) {
                         return run_odeint(odeint::bulirsch_stoer_dense_out<State>(tol, tol), end);
                       }, {}, {}, 0.0, false});

  for (int round = 0; round < repeat; ++round)
    for (Config& c : configs) {
      const double start = cpu_seconds();
      c.last = c.run(t_end);
      c.seconds.push_back(cpu_seconds() - start);
    }

  std::printf("Duffing impact oscillator, %d periods from rest, %zu impacts in the reference; CPU time, median of %d "
              "alternated runs\n\n",
              periods, ref.impacts.size(), repeat);
  std::printf("| method | tolerance | impacts | steps | error | CPU time (ms) |\n|---|---|---|---|---|---|\n");
  for (Config& c : configs) {
    c.same_events = c.last.impacts.size() == ref.impacts.size();
    double e = 0.0;
    if (c.same_events)
      for (std::size_t i = 0; i < ref.impacts.size(); ++i)
        e = std::max({e, std::abs(c.last.impacts[i].t - static_cast<double>(ref.impacts[i].t)) / T,
                      std::abs(c.last.impacts[i].v_before - static_cast<double>(ref.impacts[i].v_before)) / u_scale});
    c.error = e;
    char error[32] = "other impacts";
    if (c.same_events) std::snprintf(error, sizeof error, "%.1e", e);
    std::printf("| %s | %.0e | %zu | %ld | %s | %.3f |\n", c.method.c_str(), c.tolerance, c.last.impacts.size(),
                c.last.steps, error, 1e3 * c.median());
  }
  // At matched error: the fastest configuration of each method that meets the target.
  std::printf("\n| error ≤ | Taylor engine (ms) | Odeint dopri5 (ms) | Odeint Bulirsch-Stoer (ms) | speed-up over the best Odeint |\n"
              "|---|---|---|---|---|\n");
  for (double target : {1e-6, 1e-8, 1e-10, 1e-12, 1e-13}) {
    double best[3];
    const char* names[3] = {"Taylor engine", "Odeint dopri5", "Odeint Bulirsch-Stoer"};
    std::printf("| %.0e |", target);
    for (int m = 0; m < 3; ++m) {
      best[m] = std::numeric_limits<double>::infinity();
      for (const Config& c : configs)
        if (c.method == names[m] && c.same_events && c.error <= target) best[m] = std::min(best[m], c.median());
      if (std::isfinite(best[m])) std::printf(" %.3f |", 1e3 * best[m]);
      else std::printf(" not reached |");
    }
    const double odeint_best = std::min(best[1], best[2]);
    if (std::isfinite(best[0]) && std::isfinite(odeint_best)) std::printf(" %.1f× |\n", odeint_best / best[0]);
    else if (std::isfinite(best[0])) std::printf(" Odeint does not reach it |\n");
    else std::printf(" – |\n");
  }
  return 0;
}
