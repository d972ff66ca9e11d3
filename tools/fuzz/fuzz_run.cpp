// libFuzzer target: `vibro check` and a short run of any scene the loader accepts, then the
// scene's own run kind. The short run is cut short on purpose (at most 2 periods, no transient,
// ≤ 100 samples per period, 2000 events per window, ≤ 16 degrees of freedom and stops, grids of
// at most 65 536 points (fuzz_input.hpp), the first point of a sweep) and, as Ctrl-C would,
// interrupted through SimulatorOptions::interrupt after 2 s of wall time (a stiff scene may legitimately need millions of search steps). Then the whole
// scene runs as `vibro run` runs it (every run kind: a sweep's points with their sample times,
// orbit, continue, locate, basin, diagram, Lyapunov), in memory as the Python module runs it, on
// one thread, its stop flag raised after 1 s as a signal would: it must end within 25 s of that
// (a phase deaf to the flag takes minutes; 25 s leaves room for ASan and a loaded machine, below
// run.sh's 30 s timeout); and again with the flag raised 0, 2 or 20 ms after it starts (the
// input's bytes choose), a signal in its set-up or first steps.
// What is fuzzed is that every path ends in a status or a SceneError / InvalidInput /
// ResourceError (ResultError for a value that cannot be written), never in a crash, an abort, a
// hang (an interrupt not honoured: the watchdog aborts), a completed run with a non-finite state
// or a recorded state past a stop, or a sanitizer report. Build and run: docs/fuzzing.md.
#include "fuzz_input.hpp"

#include "vibro/bounded_wait.hpp"
#include "vibro/io/recorded_gaps.hpp"
#include "vibro/io/resources.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/results.hpp"
#include "vibro/io/session.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <thread>

namespace {

/// Raises `flag` after `seconds`, unless destroyed first. With `grace` > 0, aborts the process if
/// it is still not destroyed `grace` seconds after raising the flag: the run did not answer it
/// (libFuzzer reports the abort with the input).
class Watchdog {
 public:
  Watchdog(std::atomic<bool>& flag, double seconds, double grace = 0.0)
      : thread_([this, &flag, seconds, grace] {
          std::unique_lock<std::mutex> hold(lock_);
          if (wake_.wait_for(hold, std::chrono::duration<double>(seconds), [this] { return done_; })) return;
          flag.store(true);
          if (grace > 0.0 && !wake_.wait_for(hold, std::chrono::duration<double>(grace), [this] { return done_; })) {
            std::fprintf(stderr, "fuzz_run: the run kind did not end within %g s of its interrupt\n", grace);
            std::abort();
          }
        }) {}
  ~Watchdog() {
    {
      std::lock_guard<std::mutex> hold(lock_);
      done_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

 private:
  std::mutex lock_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace vibro;
  auto doc = fuzz::document(data, size);
  if (!doc) return 0;
  std::optional<io::Scene> whole;
  std::optional<io::SceneDocument> whole_doc;
  try {
    io::Scene scene = doc->build();
    if (scene.dof() > 16 || scene.stops.size() > 16) return 0;
    std::size_t cells = 1;  // each axis has at most kMaxGridPoints values (fuzz::document)
    for (const io::SweepAxis& axis : scene.run.axes) cells *= axis.values.size();
    if (cells > fuzz::kMaxGridCells) return 0;
    whole.emplace(scene);  // the run kind's own run (below), before the limits
    whole_doc.emplace(*doc);
    if (scene.run.kind == io::RunSpec::Kind::sweep && !scene.run.axes.empty()) {
      // The first point of the sweep, as the runner builds it.
      for (const io::SweepAxis& axis : scene.run.axes) doc->set(axis.path, axis.values.front());
      scene = doc->build_point();
    }
    scene.run.transient_periods = 0.0;
    scene.run.periods = std::min(scene.run.periods, 2.0);
    scene.record.samples_per_period = std::min(scene.record.samples_per_period, 100);
    if (scene.record.sample_times.size() > 1000) scene.record.sample_times.resize(1000);
    scene.solver.max_events = std::min(scene.solver.max_events, 2000L);
    io::check_run_resources(scene, 1);  // `vibro check`
    std::atomic<bool> stop{false};
    scene.solver.interrupt = &stop;
    const Watchdog watchdog(stop, 2.0);
    const std::unique_ptr<Engine> engine = io::make_engine(scene);
    io::Recording rec = io::Recording::for_scene(scene, scene.t0);
    rec.summary = engine->run(scene.t0, scene.x0, scene.v0, rec.t_end, rec.observers());
    if (rec.summary.status == RunStatus::completed && !(rec.summary.x.allFinite() && rec.summary.v.allFinite()))
      __builtin_trap();  // a completed run never ends on a non-finite state
    // Nor records a state past a stop beyond the trigger tolerance (the runner's check before
    // writing, recorded_gaps.hpp, would turn it into a numerical failure: the engine lost a stop).
    if (rec.summary.status == RunStatus::completed) {
      io::check_recorded_gaps(scene, rec);
      if (rec.summary.status != RunStatus::completed) __builtin_trap();
    }
  } catch (const io::SceneError&) {
  } catch (const InvalidInput&) {     // an initial state or a time the engine refuses
  } catch (const io::ResourceError&) {
  }
  if (!whole) return 0;
  // The run kind as `vibro run` runs it (the runner, its files in memory), stopped after 1 s as
  // by a signal: a status and an exit code, or one of the documented errors; never an abort (an
  // exception in a sweep's worker), never deaf to the flag.
  // Then once more with the flag raised almost at once — 0, 2 or 20 ms after the run starts, as
  // the input's bytes choose: a signal in its set-up or its first points, which the run above
  // meets only when it is slow. It must end the same ways, within 25 s of the flag.
  unsigned sum = 0;
  for (std::size_t i = 0; i < size; ++i) sum += data[i];
  constexpr double kEarly[] = {0.0, 0.002, 0.02};
  for (const double after : {1.0, kEarly[sum % 3]}) {
    std::atomic<bool> stop{false};
    try {
      io::MemoryRunOptions options;
      options.threads = 1;
      options.interrupt = &stop;
      const Watchdog watchdog(stop, after, 25.0);
      const io::MemoryRun run = io::run_in_memory(*whole_doc, *whole, options);
      if (run.exit_code == 130 && !stop.load()) __builtin_trap();  // interrupted, with no interrupt
    } catch (const io::SceneError&) {
    } catch (const InvalidInput&) {
    } catch (const io::ResourceError&) {
    } catch (const io::ResultError&) {  // a value that cannot be written (not finite): exit code 3
    } catch (const Interrupted&) {      // a bounded set-up (bounded_wait.hpp) ended by the flag
      if (!stop.load()) __builtin_trap();
    }
  }
  return 0;
}
