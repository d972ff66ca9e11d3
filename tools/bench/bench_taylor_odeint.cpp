// bench_taylor_odeint: work against precision of the Taylor engine (vibro/taylor_simulator.hpp)
// and of conventional integrators with dense output and event location, on two impact
// oscillators with a nonlinear restoring force, each over P forcing periods from rest:
//
//   Duffing   x'' + 0.05 x' + x + 0.5 x³ = 0.8 cos 1.3t,   x ≤ 0.6, r = 0.8
//             (experiments/examples/duffing_impact.yaml; one impact a period);
//   pendulum  θ'' + 0.1 θ' + sin θ = 0.4 cos 0.8t,          θ ≤ 0.4, r = 0.8
//             (an impacting pendulum; one impact a period).
//
// Peers (each at a ladder of tolerances, absolute = relative; the states are of order 1):
//   - Boost.Odeint: Dormand–Prince 5(4) (runge_kutta_dopri5 with dense output of order 4) and
//     Bulirsch–Stoer with dense output (bulirsch_stoer_dense_out, high order). Events the
//     conventional way: each accepted step's end is tested for penetration (x > stop), the
//     crossing is found by bisection on the step's dense output to rounding, the impact law
//     v⁺ = −r v⁻ is applied there (x = stop) and the stepper restarts with its last step size.
//   - SUNDIALS (Debian's libsundials-dev, when found at configure time), with the conventions of
//     tools/bench/sundials_peer.hpp: ARKODE ERKStep with the Dormand–Prince 5(4) table and with
//     the Fehlberg 7(8) table (its Hermite dense output), and CVODE Adams–Moulton (orders 1–12,
//     fixed-point corrector); the gap x − stop as SUNDIALS' root function (upward crossings
//     only), located by its own root finder (sign change at a step's end, then the Illinois
//     method on its interpolant); the impact law there (x = stop) and a restart (ReInit; ERKStep
//     with its last step size, CVODE at order 1 with its own first step).
// The Taylor engine runs at a ladder of series tolerances (NonlinearForces::tolerance; default
// the unit roundoff), its events certified (guard_roots.hpp).
//
// Error: against the long-double RK8 reference of tests/support/reference_duffing_impact.hpp
// (~1e-16 of the state), the largest of |Δt_i| / T over the impact times and |Δv_i| / max|v|
// over the approach speeds. A run with another number of impacts is reported as such, with no
// error. Time: the CPU time of one run (this thread's, so a shared machine's load counts less;
// the Taylor engine's includes compiling its expressions); every configuration of both problems
// runs `repeat` times (default 5), the configurations alternating within each round so that
// drifts of a shared machine spread over all of them; the median is reported. Then, for each
// target error, the fastest configuration of each method that meets it and the Taylor engine's
// speed-up over the best peer.
//
//     build/release/tools/bench/bench_taylor_odeint [--periods P] [--repeat R] [--only METHOD] [--tolerance TOL]
//                                                   [--order P]
//
// (--only: the methods whose name contains METHOD, --tolerance: that tolerance alone; for a
// profile of one configuration, e.g. `perf record ... --only Taylor --tolerance 1e-10`;
// --order: the Taylor engine's series order, NonlinearForces::order, instead of its rule's.)
// Meaningful only in a Release build; docs/performance.md quotes it.
#include "vibro/observers.hpp"
#include "vibro/taylor_simulator.hpp"

#include "support/reference_duffing_impact.hpp"

#include <boost/numeric/odeint.hpp>

#ifdef VIBRO_BENCH_WITH_SUNDIALS
#include <arkode/arkode_erkstep.h>
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <time.h>

namespace {

namespace odeint = boost::numeric::odeint;

/// One problem: x'' + c x' + k x + β x³ + γ sin x = A cos Ωt, x ≤ stop (restitution r).
struct Problem {
  const char* name;
  double c, k, beta, gamma, amplitude, omega, stop, r;
};

constexpr Problem kDuffing{"Duffing impact oscillator", 0.05, 1.0, 0.5, 0.0, 0.8, 1.3, 0.6, 0.8};
constexpr Problem kPendulum{"impacting pendulum", 0.1, 0.0, 0.0, 1.0, 0.4, 0.8, 0.4, 0.8};

struct Impact {
  double t, v_before;
};

struct Outcome {
  std::vector<Impact> impacts;
  double x = 0.0, v = 0.0;
  long steps = 0;  ///< Taylor steps, or the integrator's accepted steps
};

using State = std::array<double, 2>;

/// The right-hand sides as a peer would write them (no term the problem does not have).
struct DuffingRhs {
  void operator()(const State& z, State& dz, double t) const {
    dz[0] = z[1];
    dz[1] = kDuffing.amplitude * std::cos(kDuffing.omega * t) - kDuffing.c * z[1] - kDuffing.k * z[0] -
            kDuffing.beta * z[0] * z[0] * z[0];
  }
};
struct PendulumRhs {
  void operator()(const State& z, State& dz, double t) const {
    dz[0] = z[1];
    dz[1] = kPendulum.amplitude * std::cos(kPendulum.omega * t) - kPendulum.c * z[1] - kPendulum.gamma * std::sin(z[0]);
  }
};

/// One run with an Odeint dense-output stepper; events by bisection on its dense output.
template <class Rhs, class Stepper>
Outcome run_odeint(const Problem& pb, Stepper stepper, double t_end) {
  Outcome out;
  const Rhs rhs;
  State z{0.0, 0.0};
  stepper.initialize(z, 0.0, 1e-2);
  while (stepper.current_time() < t_end) {
    const auto [t0, t1_raw] = stepper.do_step(rhs);
    ++out.steps;
    const double t1 = std::min(t1_raw, t_end);
    State z1;
    stepper.calc_state(t1, z1);
    if (z1[0] - pb.stop > 0.0) {  // penetration at the step's end: bisect the crossing on the dense output
      double lo = t0, hi = t1;
      State zm;
      while (hi - lo > 2.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, hi)) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        stepper.calc_state(mid, zm);
        (zm[0] - pb.stop > 0.0 ? hi : lo) = mid;
      }
      stepper.calc_state(lo, zm);
      out.impacts.push_back({lo, zm[1]});
      z = {pb.stop, -pb.r * zm[1]};
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

#ifdef VIBRO_BENCH_WITH_SUNDIALS
enum class SundialsMethod { arkode_dp5, arkode_f78, cvode_adams };

template <class Rhs>
struct SundialsData {
  Rhs rhs;
  double stop;
};

template <class Rhs>
int sundials_rhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  const State z{NV_Ith_S(y, 0), NV_Ith_S(y, 1)};
  State dz;
  static_cast<const SundialsData<Rhs>*>(user)->rhs(z, dz, t);
  NV_Ith_S(ydot, 0) = dz[0];
  NV_Ith_S(ydot, 1) = dz[1];
  return 0;
}

template <class Rhs>
int sundials_gap(realtype /*t*/, N_Vector y, realtype* g, void* user) {
  g[0] = NV_Ith_S(y, 0) - static_cast<const SundialsData<Rhs>*>(user)->stop;
  return 0;
}

void check(int flag, const char* what) {
  if (flag < 0) throw std::runtime_error(std::string("SUNDIALS: ") + what + " failed (flag " + std::to_string(flag) + ")");
}

/// One run with a SUNDIALS integrator and its root finding (the context, vector and memory
/// freed on every exit).
template <class Rhs>
class SundialsRun {
 public:
  SundialsRun(const Problem& pb, SundialsMethod method, double tol, double t_end)
      : pb_(pb), method_(method), t_end_(t_end), data_{Rhs{}, pb.stop} {
    if (SUNContext_Create(nullptr, &ctx_) != 0) throw std::runtime_error("SUNDIALS: SUNContext_Create failed");
    y_ = N_VNew_Serial(2, ctx_);
    if (!y_) throw std::runtime_error("SUNDIALS: N_VNew_Serial failed");
    NV_Ith_S(y_, 0) = 0.0;
    NV_Ith_S(y_, 1) = 0.0;
    int up = 1;
    if (method == SundialsMethod::cvode_adams) {
      mem_ = CVodeCreate(CV_ADAMS, ctx_);
      if (!mem_) throw std::runtime_error("SUNDIALS: CVodeCreate failed");
      check(CVodeInit(mem_, sundials_rhs<Rhs>, 0.0, y_), "CVodeInit");
      check(CVodeSStolerances(mem_, tol, tol), "CVodeSStolerances");
      check(CVodeSetUserData(mem_, &data_), "CVodeSetUserData");
      check(CVodeSetMaxNumSteps(mem_, 50000000), "CVodeSetMaxNumSteps");
      check(CVodeSetStopTime(mem_, t_end), "CVodeSetStopTime");
      nls_ = SUNNonlinSol_FixedPoint(y_, 0, ctx_);
      if (!nls_) throw std::runtime_error("SUNDIALS: SUNNonlinSol_FixedPoint failed");
      check(CVodeSetNonlinearSolver(mem_, nls_), "CVodeSetNonlinearSolver");
      check(CVodeRootInit(mem_, 1, sundials_gap<Rhs>), "CVodeRootInit");
      check(CVodeSetRootDirection(mem_, &up), "CVodeSetRootDirection");
      check(CVodeSetNoInactiveRootWarn(mem_), "CVodeSetNoInactiveRootWarn");
    } else {
      mem_ = ERKStepCreate(sundials_rhs<Rhs>, 0.0, y_, ctx_);
      if (!mem_) throw std::runtime_error("SUNDIALS: ERKStepCreate failed");
      check(ERKStepSetTableNum(mem_, method == SundialsMethod::arkode_dp5 ? ARKODE_DORMAND_PRINCE_7_4_5
                                                                          : ARKODE_FEHLBERG_13_7_8),
            "ERKStepSetTableNum");
      check(ERKStepSStolerances(mem_, tol, tol), "ERKStepSStolerances");
      check(ERKStepSetUserData(mem_, &data_), "ERKStepSetUserData");
      check(ERKStepSetMaxNumSteps(mem_, 50000000), "ERKStepSetMaxNumSteps");
      check(ERKStepSetStopTime(mem_, t_end), "ERKStepSetStopTime");
      check(ERKStepRootInit(mem_, 1, sundials_gap<Rhs>), "ERKStepRootInit");
      check(ERKStepSetRootDirection(mem_, &up), "ERKStepSetRootDirection");
      check(ERKStepSetNoInactiveRootWarn(mem_), "ERKStepSetNoInactiveRootWarn");
    }
  }
  ~SundialsRun() {
    if (method_ == SundialsMethod::cvode_adams) {
      CVodeFree(&mem_);
      SUNNonlinSolFree(nls_);
    } else {
      ERKStepFree(&mem_);
    }
    N_VDestroy(y_);
    SUNContext_Free(&ctx_);
  }
  SundialsRun(const SundialsRun&) = delete;
  SundialsRun& operator=(const SundialsRun&) = delete;

  Outcome run() {
    Outcome out;
    double t = 0.0;
    while (t < t_end_) {
      double tret = t;
      const bool cvode = method_ == SundialsMethod::cvode_adams;
      const int flag = cvode ? CVode(mem_, t_end_, y_, &tret, CV_NORMAL) : ERKStepEvolve(mem_, t_end_, y_, &tret, ARK_NORMAL);
      check(flag, cvode ? "CVode" : "ERKStepEvolve");
      t = tret;
      if (flag != (cvode ? CV_ROOT_RETURN : ARK_ROOT_RETURN)) break;  // at t_end
      const double v = NV_Ith_S(y_, 1);
      out.impacts.push_back({t, v});
      NV_Ith_S(y_, 0) = pb_.stop;
      NV_Ith_S(y_, 1) = -pb_.r * v;
      restart(t);
    }
    out.x = NV_Ith_S(y_, 0);
    out.v = NV_Ith_S(y_, 1);
    out.steps = steps_ + steps();
    return out;
  }

 private:
  long steps() {
    long s = 0;
    if (method_ == SundialsMethod::cvode_adams) CVodeGetNumSteps(mem_, &s);
    else ERKStepGetNumSteps(mem_, &s);
    return s;
  }
  void restart(double t) {
    steps_ += steps();
    if (method_ == SundialsMethod::cvode_adams) {  // a multistep method restarts at order 1 with its own first step
      check(CVodeReInit(mem_, t, y_), "CVodeReInit");
      check(CVodeSetStopTime(mem_, t_end_), "CVodeSetStopTime");
      return;
    }
    realtype h = 0.0;
    ERKStepGetLastStep(mem_, &h);
    check(ERKStepReInit(mem_, sundials_rhs<Rhs>, t, y_), "ERKStepReInit");
    check(ERKStepSetStopTime(mem_, t_end_), "ERKStepSetStopTime");
    if (h > 0.0) check(ERKStepSetInitStep(mem_, h), "ERKStepSetInitStep");
  }

  const Problem& pb_;
  SundialsMethod method_;
  double t_end_;
  SundialsData<Rhs> data_;
  SUNContext ctx_ = nullptr;
  N_Vector y_ = nullptr;
  void* mem_ = nullptr;
  SUNNonlinearSolver nls_ = nullptr;
  long steps_ = 0;
};
#endif

/// The problem's linear part (mass 1, damping c, stiffness k, the drive, the stop) for the
/// Taylor engine, and its nonlinear force as an expression.
vibro::ImpactSystem linear_part(const Problem& pb) {
  vibro::HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, pb.amplitude),
                           .sine = Eigen::VectorXd::Zero(1), .frequency = pb.omega};
  vibro::LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, pb.c),
                          Eigen::MatrixXd::Constant(1, 1, pb.k), f);
  return vibro::ImpactSystem(sys, {vibro::Stop::upper(0, pb.stop, pb.r)});
}

int g_order = 0;  // --order (0: the rule's)

Outcome run_taylor(const vibro::ImpactSystem& system, const Problem& pb, double tol, double t_end) {
  vibro::NonlinearForces forces;
  if (pb.gamma != 0.0) {
    forces.parameters = {{"gamma", pb.gamma}};
    forces.forces = {"-gamma*sin(x0)"};
  } else {
    forces.parameters = {{"beta", pb.beta}};
    forces.forces = {"-beta*x0^3"};
  }
  forces.tolerance = tol;
  forces.order = g_order;
  vibro::TaylorSimulator sim(system, forces);
  vibro::EventLog log;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(1);
  const vibro::RunSummary s = sim.run(0.0, zero, zero, t_end, {&log});
  Outcome o;
  for (const vibro::Event& e : log.events) o.impacts.push_back({e.t, e.v_before});
  o.x = s.x(0);
  o.v = s.v(0);
  o.steps = sim.steps();
  return o;
}

/// This thread's CPU time (a shared machine's other load does not count).
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Config {
  int problem;
  std::string method;
  double tolerance;
  std::function<Outcome()> run;
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

const char* const kTaylor = "Taylor engine";

Config config(int problem, std::string method, double tolerance, std::function<Outcome()> run) {
  return {problem, std::move(method), tolerance, std::move(run), {}, {}, 0.0, false};
}

template <class Rhs>
void add_peers(std::vector<Config>& configs, int index, const Problem& pb, double t_end) {
  for (double tol : {1e-4, 1e-6, 1e-8, 1e-10, 1e-11, 1e-12, 1e-13})
    configs.push_back(config(index, "Odeint dopri5", tol, [&pb, tol, t_end] {
      return run_odeint<Rhs>(pb, odeint::make_dense_output(tol, tol, odeint::runge_kutta_dopri5<State>()), t_end);
    }));
  for (double tol : {1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 1e-14})
    configs.push_back(config(index, "Odeint Bulirsch-Stoer", tol, [&pb, tol, t_end] {
      return run_odeint<Rhs>(pb, odeint::bulirsch_stoer_dense_out<State>(tol, tol), t_end);
    }));
#ifdef VIBRO_BENCH_WITH_SUNDIALS
  const struct {
    const char* name;
    SundialsMethod method;
    std::vector<double> tolerances;
  } sundials[] = {{"ARKODE DP5", SundialsMethod::arkode_dp5, {1e-6, 1e-8, 1e-10, 1e-11, 1e-12}},
                  {"ARKODE F78", SundialsMethod::arkode_f78, {1e-6, 1e-8, 1e-10, 1e-12, 1e-13}},
                  {"CVODE Adams", SundialsMethod::cvode_adams, {1e-6, 1e-8, 1e-10, 1e-11, 1e-12, 1e-13}}};
  for (const auto& s : sundials)
    for (double tol : s.tolerances)
      configs.push_back(config(index, s.name, tol, [&pb, method = s.method, tol, t_end] {
        SundialsRun<Rhs> run(pb, method, tol, t_end);
        return run.run();
      }));
#else
  (void)pb;
  (void)t_end;
#endif
}

}  // namespace

int main(int argc, char** argv) {
  int periods = 20, repeat = 5;
  std::string only;        // run only the methods whose name contains it (a profile of one method)
  double only_tolerance = 0.0;  // and only this tolerance (0: all)
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--periods") && i + 1 < argc) periods = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) only = argv[++i];
    else if (!std::strcmp(argv[i], "--tolerance") && i + 1 < argc) only_tolerance = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--order") && i + 1 < argc) g_order = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: %s [--periods P] [--repeat R] [--only METHOD] [--tolerance TOL] [--order P]\n", argv[0]);
      return 2;
    }
  }
  if (periods < 1 || repeat < 1) return 2;

  const Problem* problems[2] = {&kDuffing, &kPendulum};
  vibro::test::ReferenceDuffingImpact refs[2];
  double periods_T[2], u_scale[2] = {0.0, 0.0};
  const vibro::ImpactSystem systems[2] = {linear_part(kDuffing), linear_part(kPendulum)};
  std::vector<Config> configs;
  for (int p = 0; p < 2; ++p) {
    const Problem& pb = *problems[p];
    const double T = 2.0 * std::acos(-1.0) / pb.omega, t_end = periods * T;
    periods_T[p] = T;
    vibro::test::ReferenceDuffingImpact& ref = refs[p];
    ref.c = pb.c;
    ref.k = pb.k;
    ref.beta = pb.beta;
    ref.gravity = pb.gamma;
    ref.amplitude = pb.amplitude;
    ref.omega = pb.omega;
    ref.stop = pb.stop;
    ref.restitution = pb.r;
    ref.run(0.0L, 0.0L, 0.0L, t_end);
    for (const auto& i : ref.impacts) u_scale[p] = std::max(u_scale[p], std::abs(static_cast<double>(i.v_before)));
    for (double tol : {std::numeric_limits<double>::epsilon(), 1e-14, 1e-12, 1e-10, 1e-8, 1e-6})
      configs.push_back(config(p, kTaylor, tol, [&system = systems[p], &pb, tol, t_end] { return run_taylor(system, pb, tol, t_end); }));
    if (p == 0) add_peers<DuffingRhs>(configs, p, pb, t_end);
    else add_peers<PendulumRhs>(configs, p, pb, t_end);
  }

  if (!only.empty() || only_tolerance > 0.0)
    configs.erase(std::remove_if(configs.begin(), configs.end(),
                                 [&](const Config& c) {
                                   return c.method.find(only) == std::string::npos ||
                                          (only_tolerance > 0.0 && std::abs(c.tolerance / only_tolerance - 1.0) > 1e-9);
                                 }),
                  configs.end());
  for (int round = 0; round < repeat; ++round)
    for (Config& c : configs) {
      const double start = cpu_seconds();
      c.last = c.run();
      c.seconds.push_back(cpu_seconds() - start);
    }

  for (int p = 0; p < 2; ++p) {
    const auto& ref = refs[p];
    const double T = periods_T[p];
    std::printf("%s%s, %d periods from rest, %zu impacts in the reference; CPU time, median of %d alternated runs\n\n",
                p ? "\n" : "", problems[p]->name, periods, ref.impacts.size(), repeat);
    std::printf("| method | tolerance | impacts | steps | error | CPU time (ms) |\n|---|---|---|---|---|---|\n");
    std::vector<std::string> methods;
    for (Config& c : configs) {
      if (c.problem != p) continue;
      if (std::find(methods.begin(), methods.end(), c.method) == methods.end()) methods.push_back(c.method);
      c.same_events = c.last.impacts.size() == ref.impacts.size();
      double e = 0.0;
      if (c.same_events)
        for (std::size_t i = 0; i < ref.impacts.size(); ++i)
          e = std::max({e, std::abs(c.last.impacts[i].t - static_cast<double>(ref.impacts[i].t)) / T,
                        std::abs(c.last.impacts[i].v_before - static_cast<double>(ref.impacts[i].v_before)) / u_scale[p]});
      c.error = e;
      char error[32] = "other impacts";
      if (c.same_events) std::snprintf(error, sizeof error, "%.1e", e);
      std::printf("| %s | %.0e | %zu | %ld | %s | %.3f |\n", c.method.c_str(), c.tolerance, c.last.impacts.size(),
                  c.last.steps, error, 1e3 * c.median());
    }
    // At matched error: the fastest configuration of each method that meets the target.
    std::printf("\n| error ≤ |");
    for (const std::string& m : methods) std::printf(" %s (ms) |", m.c_str());
    std::printf(" Taylor engine's speed-up over the best peer |\n|---|");
    for (std::size_t m = 0; m <= methods.size(); ++m) std::printf("---|");
    std::printf("\n");
    for (double target : {1e-6, 1e-8, 1e-10, 1e-12, 1e-13}) {
      std::printf("| %.0e |", target);
      double taylor = std::numeric_limits<double>::infinity(), peer = std::numeric_limits<double>::infinity();
      std::string best_peer;
      for (const std::string& m : methods) {
        double best = std::numeric_limits<double>::infinity();
        for (const Config& c : configs)
          if (c.problem == p && c.method == m && c.same_events && c.error <= target) best = std::min(best, c.median());
        if (std::isfinite(best)) std::printf(" %.3f |", 1e3 * best);
        else std::printf(" not reached |");
        if (m == kTaylor) taylor = best;
        else if (best < peer) {
          peer = best;
          best_peer = m;
        }
      }
      if (std::isfinite(taylor) && std::isfinite(peer)) std::printf(" %.1f× (over %s) |\n", peer / taylor, best_peer.c_str());
      else if (std::isfinite(taylor)) std::printf(" no peer reaches it |\n");
      else std::printf(" – |\n");
    }
  }
  return 0;
}
