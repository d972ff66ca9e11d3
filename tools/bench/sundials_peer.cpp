#include "sundials_peer.hpp"

#include "baseline_flow.hpp"

#include <arkode/arkode_erkstep.h>
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace vibro::bench {

const char* to_string(SundialsMethod m) {
  switch (m) {
    case SundialsMethod::arkode_dp5: return "arkode_dp5";
    case SundialsMethod::arkode_f78: return "arkode_f78";
    case SundialsMethod::cvode_adams: return "cvode_adams";
  }
  return "?";
}

namespace {

/// The one SUNDIALS integrator of a run behind a common face: create, evolve, restart, counters.
class Integrator {
 public:
  virtual ~Integrator() = default;
  /// Advances towards tout (NORMAL mode): returns 0 at tout, 1 at a root, < 0 on failure.
  virtual int evolve(double tout, N_Vector y, double* tret) = 0;
  virtual void roots(int* found) = 0;
  virtual void restart(double t, N_Vector y) = 0;
  virtual long steps() = 0;
  virtual long rhs() = 0;
};

template <class Data>
int rhs_fn(realtype t, N_Vector y, N_Vector ydot, void* user) {
  auto* d = static_cast<Data*>(user);
  typename Data::MapC z(NV_DATA_S(y), d->size);
  typename Data::Map dz(NV_DATA_S(ydot), d->size);
  (*d->flow)(t, z, dz);
  return 0;
}

template <class Data>
int root_fn(realtype t, N_Vector y, realtype* gout, void* user) {
  auto* d = static_cast<Data*>(user);
  typename Data::MapC z(NV_DATA_S(y), d->size);
  for (int j = 0; j < d->stops; ++j) gout[j] = d->guards->guard(*d->flow, j, t, z) - (*d->triggers)(j);
  return 0;
}

void check(int flag, const char* what) {
  if (flag < 0) throw std::runtime_error(std::string("SUNDIALS: ") + what + " failed (flag " + std::to_string(flag) + ")");
}

template <class Data>
class Erk final : public Integrator {
 public:
  Erk(SUNContext ctx, Data& d, ARKODE_ERKTableID table, double t0, N_Vector y, double rtol, double atol, long max_steps,
      double t_end)
      : t_end_(t_end) {
    mem_ = ERKStepCreate(rhs_fn<Data>, t0, y, ctx);
    if (!mem_) throw std::runtime_error("SUNDIALS: ERKStepCreate failed");
    check(ERKStepSetTableNum(mem_, table), "ERKStepSetTableNum");
    check(ERKStepSStolerances(mem_, rtol, atol), "ERKStepSStolerances");
    check(ERKStepSetUserData(mem_, &d), "ERKStepSetUserData");
    check(ERKStepSetMaxNumSteps(mem_, max_steps), "ERKStepSetMaxNumSteps");
    check(ERKStepSetStopTime(mem_, t_end), "ERKStepSetStopTime");
    check(ERKStepRootInit(mem_, d.stops, root_fn<Data>), "ERKStepRootInit");
    std::vector<int> up(static_cast<std::size_t>(d.stops), 1);
    if (d.stops > 0) check(ERKStepSetRootDirection(mem_, up.data()), "ERKStepSetRootDirection");
    check(ERKStepSetNoInactiveRootWarn(mem_), "ERKStepSetNoInactiveRootWarn");
  }
  ~Erk() override { ERKStepFree(&mem_); }
  int evolve(double tout, N_Vector y, double* tret) override {
    const int flag = ERKStepEvolve(mem_, tout, y, tret, ARK_NORMAL);
    return flag == ARK_ROOT_RETURN ? 1 : (flag < 0 ? flag : 0);
  }
  void roots(int* found) override { check(ERKStepGetRootInfo(mem_, found), "ERKStepGetRootInfo"); }
  void restart(double t, N_Vector y) override {
    long s = 0, f = 0;
    ERKStepGetNumSteps(mem_, &s);
    ERKStepGetNumRhsEvals(mem_, &f);
    steps_ += s;
    rhs_ += f;
    realtype h = 0.0;
    ERKStepGetLastStep(mem_, &h);
    check(ERKStepReInit(mem_, rhs_fn<Data>, t, y), "ERKStepReInit");
    check(ERKStepSetStopTime(mem_, t_end_), "ERKStepSetStopTime");
    if (h > 0.0) check(ERKStepSetInitStep(mem_, h), "ERKStepSetInitStep");  // as the RK baselines restart
  }
  long steps() override {
    long s = 0;
    ERKStepGetNumSteps(mem_, &s);
    return steps_ + s;
  }
  long rhs() override {
    long f = 0;
    ERKStepGetNumRhsEvals(mem_, &f);
    return rhs_ + f;
  }

 private:
  void* mem_ = nullptr;
  double t_end_;
  long steps_ = 0, rhs_ = 0;
};

template <class Data>
class Cvode final : public Integrator {
 public:
  Cvode(SUNContext ctx, Data& d, double t0, N_Vector y, double rtol, double atol, long max_steps, double t_end)
      : t_end_(t_end) {
    mem_ = CVodeCreate(CV_ADAMS, ctx);
    if (!mem_) throw std::runtime_error("SUNDIALS: CVodeCreate failed");
    check(CVodeInit(mem_, rhs_fn<Data>, t0, y), "CVodeInit");
    check(CVodeSStolerances(mem_, rtol, atol), "CVodeSStolerances");
    check(CVodeSetUserData(mem_, &d), "CVodeSetUserData");
    check(CVodeSetMaxNumSteps(mem_, max_steps), "CVodeSetMaxNumSteps");
    check(CVodeSetStopTime(mem_, t_end), "CVodeSetStopTime");
    nls_ = SUNNonlinSol_FixedPoint(y, 0, ctx);
    if (!nls_) throw std::runtime_error("SUNDIALS: SUNNonlinSol_FixedPoint failed");
    check(CVodeSetNonlinearSolver(mem_, nls_), "CVodeSetNonlinearSolver");
    check(CVodeRootInit(mem_, d.stops, root_fn<Data>), "CVodeRootInit");
    std::vector<int> up(static_cast<std::size_t>(d.stops), 1);
    if (d.stops > 0) check(CVodeSetRootDirection(mem_, up.data()), "CVodeSetRootDirection");
    check(CVodeSetNoInactiveRootWarn(mem_), "CVodeSetNoInactiveRootWarn");
  }
  ~Cvode() override {
    CVodeFree(&mem_);
    SUNNonlinSolFree(nls_);
  }
  int evolve(double tout, N_Vector y, double* tret) override {
    const int flag = CVode(mem_, tout, y, tret, CV_NORMAL);
    return flag == CV_ROOT_RETURN ? 1 : (flag < 0 ? flag : 0);
  }
  void roots(int* found) override { check(CVodeGetRootInfo(mem_, found), "CVodeGetRootInfo"); }
  void restart(double t, N_Vector y) override {
    long s = 0, f = 0;
    CVodeGetNumSteps(mem_, &s);
    CVodeGetNumRhsEvals(mem_, &f);
    steps_ += s;
    rhs_ += f;
    // A multistep method restarts at order 1: CVODE picks its own first step.
    check(CVodeReInit(mem_, t, y), "CVodeReInit");
    check(CVodeSetStopTime(mem_, t_end_), "CVodeSetStopTime");
  }
  long steps() override {
    long s = 0;
    CVodeGetNumSteps(mem_, &s);
    return steps_ + s;
  }
  long rhs() override {
    long f = 0;
    CVodeGetNumRhsEvals(mem_, &f);
    return rhs_ + f;
  }

 private:
  void* mem_ = nullptr;
  SUNNonlinearSolver nls_ = nullptr;
  double t_end_;
  long steps_ = 0, rhs_ = 0;
};

template <int N>
struct UserData {
  using Flow = FixedFlow<N>;
  using Map = Eigen::Map<typename Flow::State>;
  using MapC = Eigen::Map<const typename Flow::State>;
  Eigen::Index size = 0;
  int stops = 0;
  Flow* flow = nullptr;
  const FixedGuards<N>* guards = nullptr;
  const Eigen::VectorXd* triggers = nullptr;
};

/// Owns the SUNDIALS context and vector of a run.
struct Context {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr;
  explicit Context(Eigen::Index size) {
    if (SUNContext_Create(nullptr, &ctx) != 0) throw std::runtime_error("SUNDIALS: SUNContext_Create failed");
    y = N_VNew_Serial(static_cast<sunindextype>(size), ctx);
    if (!y) throw std::runtime_error("SUNDIALS: N_VNew_Serial failed");
  }
  ~Context() {
    N_VDestroy(y);
    SUNContext_Free(&ctx);
  }
};

template <int N>
RkResult run_fixed(const ImpactSystem& scene, const SundialsOptions& opt, double t0, const Eigen::VectorXd& x0,
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
  Eigen::VectorXd triggers = Eigen::VectorXd::Zero(stops);
  UserData<N> data{2 * n, stops, &flow, &guards, &triggers};
  Context sun(2 * n);
  Eigen::Map<State> z(NV_DATA_S(sun.y), 2 * n);
  State dz(2 * n);

  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  std::size_t next_sample = 0;
  while (next_sample < sample_times.size() && sample_times[next_sample] < t0) ++next_sample;
  const auto wanted = static_cast<Eigen::Index>(
      std::upper_bound(sample_times.begin(), sample_times.end(), t_end) - sample_times.begin()) -
      static_cast<Eigen::Index>(next_sample);
  result.x.resize(n, std::max<Eigen::Index>(wanted, 0));
  result.v.resize(n, result.x.cols());
  Eigen::Index taken = 0;
  std::unique_ptr<Integrator> integrator;
  auto finish = [&] {
    result.x.conservativeResize(Eigen::NoChange, taken);
    result.v.conservativeResize(Eigen::NoChange, taken);
    result.impacts = ev.impacts();
    if (integrator) {
      result.steps = integrator->steps();
      result.rhs = integrator->rhs();
    }
    return result;
  };
  auto fail = [&](const std::string& why) {
    result.ok = false;
    result.message = why + " at t = " + number_text(t);
    return finish();
  };
  std::string why;
  {  // initial contacts, as the framework's run start
    const Eigen::VectorXd g = scene.gaps(t, x), gd = scene.gap_rates(t, v);
    ContactSet impacting, resting;
    const double vc = opt.rules.contact_velocity * opt.rules.velocity_scale;
    for (int j = 0; j < stops; ++j) {
      if (g(j) < -ev.eps_gap()) continue;
      if (gd(j) > vc) impacting.push_back(j);
      else if (gd(j) >= -vc) resting.push_back(j);
    }
    if (!ev.resolve(t, x, v, stuck, impacting, {}, resting, result.events, &why)) return fail(why);
    enter();
  }
  auto pack = [&] {
    z.head(n) = x;
    z.tail(n) = v;
  };
  auto arm = [&] {  // trigger levels, re-armed above a guard that starts positive moving away
    flow(t, z, dz);
    for (int j = 0; j < stops; ++j) {
      triggers(j) = guards.held(j) ? ev.eps_force() : ev.eps_gap();
      const double h0 = guards.guard(flow, j, t, z);
      if (h0 > 0.0 && guards.guard_rate(flow, j, t, z, dz) <= 0.0) triggers(j) += h0;
    }
  };
  pack();
  arm();
  const double atol = opt.rtol * std::min(opt.rules.length_scale, opt.rules.velocity_scale);
  if (opt.method == SundialsMethod::cvode_adams)
    integrator = std::make_unique<Cvode<UserData<N>>>(sun.ctx, data, t, sun.y, opt.rtol, atol, opt.max_steps, t_end);
  else
    integrator = std::make_unique<Erk<UserData<N>>>(
        sun.ctx, data, opt.method == SundialsMethod::arkode_dp5 ? ARKODE_DORMAND_PRINCE_7_4_5 : ARKODE_FEHLBERG_13_7_8,
        t, sun.y, opt.rtol, atol, opt.max_steps, t_end);
  std::vector<int> found(static_cast<std::size_t>(std::max(stops, 1)));
  while (t < t_end) {
    const double tout = next_sample < sample_times.size() ? std::min(sample_times[next_sample], t_end) : t_end;
    double tret = t;
    const int flag = integrator->evolve(tout, sun.y, &tret);
    if (flag < 0) return fail("SUNDIALS integrator failed (flag " + std::to_string(flag) + ")");
    if (!z.allFinite()) return fail("non-finite state");
    t = tret;
    if (flag == 0) {
      if (next_sample < sample_times.size() && sample_times[next_sample] == tout && taken < result.x.cols()) {
        result.x.col(taken) = z.head(n);
        result.v.col(taken) = z.tail(n);
        ++taken;
        ++next_sample;
      }
      continue;
    }
    // A root: the stops whose guards it found, and those within the simultaneity window.
    integrator->roots(found.data());
    flow(t, z, dz);
    ContactSet impacting, releasing;
    for (int j = 0; j < stops; ++j) {
      const double h = guards.guard(flow, j, t, z), hd = guards.guard_rate(flow, j, t, z, dz);
      const bool fired = found[static_cast<std::size_t>(j)] != 0 ||
                         (hd > 0.0 && h >= -std::max(triggers(j), hd * ev.dt_simultaneous()));
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
    arm();
    integrator->restart(t, sun.y);
  }
  return finish();
}

}  // namespace

RkResult run_sundials(const ImpactSystem& scene, const SundialsOptions& options, double t0, const Eigen::VectorXd& x0,
                      const Eigen::VectorXd& v0, double t_end, const std::vector<double>& sample_times) {
  try {
    if (!(options.rtol > 0.0)) throw InvalidInput("run_sundials: rtol must be > 0");
    switch (scene.dof()) {
      case 1: return run_fixed<1>(scene, options, t0, x0, v0, t_end, sample_times);
      case 2: return run_fixed<2>(scene, options, t0, x0, v0, t_end, sample_times);
      case 10: return run_fixed<10>(scene, options, t0, x0, v0, t_end, sample_times);
      default: return run_fixed<Eigen::Dynamic>(scene, options, t0, x0, v0, t_end, sample_times);
    }
  } catch (const std::runtime_error& e) {
    RkResult r;
    r.ok = false;
    r.message = e.what();
    return r;
  }
}

}  // namespace vibro::bench
