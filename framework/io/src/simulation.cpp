#include "simulation.hpp"

#include "interrupt.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/engine.hpp"
#include "vibro/io/recorded_gaps.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vibro::io::detail {
namespace {

/// The recording of a run that records nothing (interrupted before its recorded periods): the
/// scene's observers over no period, and no sample times (a listed time lies past a span of 0).
Recording nothing_recorded(const Scene& scene, double t) {
  Scene shape = scene;
  shape.run.periods = 0.0;
  const bool listed = !shape.record.sample_times.empty();
  shape.record.sample_times.clear();
  Recording rec = Recording::for_scene(shape, t);
  if (listed && !rec.samples) rec.samples.emplace(std::vector<double>{});
  return rec;
}

/// A part [t_begin, t_end] of a segment, the same exact flow: what Samples is given when the
/// sample times of one segment are evaluated in batches (SampleBatches). Only Samples sees it, and
/// it asks for states alone (a force's minimum would be the whole segment's).
class Window final : public SegmentView {
 public:
  Window(const SegmentView& whole, double t_begin, double t_end) : SegmentView(t_begin, t_end), whole_(whole) {}
  Eigen::Index dof() const override { return whole_.dof(); }
  const ContactSet& active() const override { return whole_.active(); }
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override {
    whole_.state(t, x, v);
  }
  void states(const double* t, Eigen::Index count, Eigen::Ref<Eigen::MatrixXd> x,
              Eigen::Ref<Eigen::MatrixXd> v) const override {
    whole_.states(t, count, x, v);
  }
  double force(Eigen::Index a, double t) const override { return whole_.force(a, t); }
  Minimum force_minimum(Eigen::Index a) const override { return whole_.force_minimum(a); }
  std::vector<Minimum> force_local_minima(Eigen::Index a) const override { return whole_.force_local_minima(a); }
  void plane_crossings(const Hyperplane& plane, double trigger, int& side,
                       std::vector<PlaneCrossing>& out) const override {
    whole_.plane_crossings(plane, trigger, side, out);
  }

 private:
  const SegmentView& whole_;
};

/// The recording's Samples with the interrupt flag looked at between batches of its times. A
/// segment free of events may hold millions of sample times, each state O(n²) to evaluate
/// (seconds in all): its times are handed to Samples in windows of about kWork / n² times (at
/// least 1, at most kMostTimes: milliseconds each), the flag looked at before each; once it is
/// raised segment() throws Interrupted (bounded_wait.hpp), which ends the run as interrupted. A
/// state is the same bits in a batch of any size (SegmentView::states), so the samples are those
/// of one call. `time(i)`, i < count, is the i-th sample time as the recording laid them out
/// (ascending): where a segment's times begin and end is found by bisection.
class SampleBatches final : public Observer {
 public:
  static constexpr std::size_t kWork = std::size_t{1} << 20, kMostTimes = std::size_t{1} << 16;
  SampleBatches(Samples& samples, std::function<double(std::size_t)> time, std::size_t count,
                const std::atomic<bool>& stop)
      : samples_(samples), time_(std::move(time)), count_(count), stop_(stop) {}
  void begin(const RunContext& run, double t0) override {
    samples_.begin(run, t0);
    const auto n = static_cast<std::size_t>(std::max<Eigen::Index>(run.dof, 1));
    batch_ = n * n >= kWork ? 1 : std::min(kWork / (n * n), kMostTimes);
  }
  void segment(const SegmentView& view) override {
    const std::size_t first = first_after(view.t_begin(), false), last = first_after(view.t_end(), true);
    if (last <= first + batch_) {
      samples_.segment(view);
      return;
    }
    double a = view.t_begin();
    for (std::size_t j = first; j < last; j += batch_) {
      if (stop_.load(std::memory_order_relaxed)) throw Interrupted();
      const std::size_t k = std::min(last, j + batch_);
      const double b = k < last ? time_(k - 1) : view.t_end();  // the window holds times j … k - 1
      samples_.segment(Window(view, a, b));
      a = b;
    }
  }
  void event(const Event& e) override { samples_.event(e); }
  void end(double t_end) override { samples_.end(t_end); }

 private:
  /// The first index whose time is ≥ t (after: > t).
  std::size_t first_after(double t, bool after) const {
    std::size_t lo = 0, hi = count_;
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      const double tm = time_(mid);
      if (after ? tm <= t : tm < t)
        lo = mid + 1;
      else
        hi = mid;
    }
    return lo;
  }

  Samples& samples_;
  std::function<double(std::size_t)> time_;
  std::size_t count_;
  const std::atomic<bool>& stop_;
  std::size_t batch_ = 1;
};

/// The recording's observers, its Samples (if any) in SampleBatches (kept in `batches`).
std::vector<Observer*> polled_observers(const Scene& scene, Recording& rec, double t_start,
                                        std::optional<SampleBatches>& batches) {
  std::vector<Observer*> observers = rec.observers();
  if (!rec.samples || !scene.solver.interrupt) return observers;
  const RecordSpec& spec = scene.record;
  std::function<double(std::size_t)> time;
  std::size_t count = 0;
  if (!spec.sample_times.empty()) {  // as recording_for lays them out: t_start + s, sorted
    auto times = std::make_shared<std::vector<double>>();
    for (const double s : spec.sample_times) times->push_back(t_start + s);
    std::sort(times->begin(), times->end());
    count = times->size();
    time = [times](std::size_t i) { return (*times)[i]; };
  } else {  // t_start + i·T/N
    const double T = scene.period();
    const auto N = static_cast<double>(spec.samples_per_period);
    count = static_cast<std::size_t>(std::max(0.0, std::floor(N * scene.run.periods + 1e-9)));
    time = [t_start, T, N](std::size_t i) { return t_start + static_cast<double>(i) * T / N; };
  }
  batches.emplace(*rec.samples, std::move(time), count, *scene.solver.interrupt);
  std::replace(observers.begin(), observers.end(), static_cast<Observer*>(&*rec.samples),
               static_cast<Observer*>(&*batches));
  return observers;
}

}  // namespace

Recording simulate(const Scene& base, const StartState& start, std::atomic<double>* reached) {
  const auto clock = std::chrono::steady_clock::now();
  Scene scene = base;  // shares the built system; only the options change
  if (!scene.solver.interrupt) scene.solver.interrupt = &g_interrupted;  // the caller's flag, or signals
  scene.solver.reached = reached;
  // Interrupted in a set-up that runs under run_bounded (the modal engine's modes of a long
  // chain) or while the sample times are laid out: nothing recorded, the state kept at `t`.
  const auto interrupted = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
    Recording rec = nothing_recorded(scene, t);
    rec.summary.status = RunStatus::interrupted;
    rec.summary.message = "interrupted at t = " + number_text(t);
    rec.summary.t = t;
    rec.summary.x = x;
    rec.summary.v = v;
    rec.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
    return rec;
  };
  // One engine per run (a simulation, or a sweep point): everything else in this file (transient
  // then recorded run, observers, files, threads, processes) is the same for both engines.
  std::unique_ptr<vibro::Engine> engine;
  try {
    engine = make_engine(scene);
  } catch (const Interrupted&) {
    return interrupted(start.t, start.x, start.v);
  }
  vibro::Engine& sim = *engine;
  const double T = scene.period();
  const double t1 = start.t + scene.run.transient_periods * T;
  RunSummary transient;
  transient.status = RunStatus::completed;
  transient.t = start.t;
  transient.x = start.x;
  transient.v = start.v;
  if (scene.run.transient_periods > 0.0) transient = sim.run(start.t, start.x, start.v, t1, {});
  // An interrupted transient records nothing: no sample times laid out for the recorded periods
  // (millions of them take seconds to allocate, after the signal).
  Recording rec;
  try {
    rec = transient.status == RunStatus::interrupted ? nothing_recorded(scene, t1)
                                                     : recording_for(scene, t1, scene.solver.interrupt);
  } catch (const Interrupted&) {
    return interrupted(transient.t, transient.x, transient.v);
  }
  if (transient.status != RunStatus::completed) {
    rec.summary = transient;
    rec.summary.message = "during the transient: " + transient.message;
  } else {
    // Counts are the recorded run's (docs/results.md), as the recorded events are.
    std::optional<SampleBatches> batches;
    rec.summary = sim.run(t1, transient.x, transient.v, t1 + scene.run.periods * T,
                          polled_observers(scene, rec, t1, batches));
  }
  check_recorded_gaps(scene, rec);  // no state past a stop is stored as a result
  rec.map_to_result_frame();        // (the gaps are checked in the frame the engine computed in)
  for (const std::string& w : transient.warnings)
    if (std::find(rec.summary.warnings.begin(), rec.summary.warnings.end(), w) == rec.summary.warnings.end())
      rec.summary.warnings.insert(rec.summary.warnings.begin(), "during the transient: " + w);
  rec.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
  return rec;
}

}  // namespace vibro::io::detail
