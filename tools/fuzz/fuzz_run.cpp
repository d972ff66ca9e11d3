// libFuzzer target: `vibro check`, a short run and the scene's own run kind for any scene the
// loader accepts; what one input does, and why it costs a few milliseconds, is docs/fuzzing.md's
// table. In short:
//  0. grids are cut to kRunGridPoints points per axis (fuzz_input.hpp), scenes of more than 16
//     degrees of freedom or stops skipped, and phases 2 and 3 skipped for a scene whose run would
//     need more than kRunKindMemory by the product's own estimate (libFuzzer's memory limit is
//     below the machine's, which the product checks against);
//  1. the scene's engine runs a capped copy of the scene (at most 2 periods, no transient, ≤ 100
//     samples per period, 2000 events per window, a sweep's first point), interrupted through
//     SimulatorOptions::interrupt after kShortRun of wall time as Ctrl-C would (a stiff scene may
//     legitimately need millions of search steps): a completed run must end on a finite state and
//     record no state past a stop;
//  2. the whole scene runs as `vibro run` runs it (every run kind: a sweep's points with their
//     sample times, orbit, continue, locate, basin, diagram, Lyapunov), in memory as the Python
//     module runs it, on one thread, its stop flag raised as a signal would 0, 1, 5 or 20 ms after
//     it starts (the input's digest chooses): a signal in its set-up or first steps;
//  3. one input in FUZZ_RUN_LATE (default 256, by its digest) runs the whole scene once more with
//     the flag raised after 1 s: a signal late in a long run.
// A run kind must end within 25 s of its flag (a phase deaf to it takes minutes; 25 s leaves room
// for a sanitizer and a loaded machine, below libFuzzer's 30 s timeout): the watchdog aborts.
// What is fuzzed is that every path ends in a status or a SceneError / InvalidInput /
// ResourceError (ResultError for a value that cannot be written), never in a crash, an abort, a
// hang, a completed run with a non-finite state or a recorded state past a stop, or a sanitizer
// report. With FUZZ_RUN_TIMES=FILE each input appends one line of its phases' times to FILE
// (measuring where the time goes; tools/fuzz/times.py sums them). Build and run: docs/fuzzing.md.
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

#include <time.h>

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

/// The short run's wall-time budget: its flag is raised after this (phase 1 above).
constexpr double kShortRun = 0.05;
/// When the run kind's flag is raised (phase 2), the input's digest choosing.
constexpr double kEarly[] = {0.0, 0.001, 0.005, 0.02};
/// The late flag (phase 3), and the time any run kind has to end once its flag is raised.
constexpr double kLate = 1.0, kGrace = 25.0;

/// The largest memory estimate (io::estimate_run_memory) of a run kind phases 2 and 3 run. The
/// product compares its estimate with the machine's memory (check_run_resources), which libFuzzer's
/// -rss_limit_mb (4 GB) undercuts: a scene that rightly runs in 5 GB (10⁸ listed sample times) would
/// be reported as out-of-memory here. Such a scene runs phase 1 only (capped), not the run kind.
/// The estimate counts the big allocations only, hence the margin below the limit.
constexpr double kRunKindMemory = 1e9;

/// FNV-1a of the input: the choices above follow from its bytes alone, so an input does the same
/// each time it runs (a finding reproduces from its file).
std::uint64_t digest(const std::uint8_t* data, std::size_t size) {
  std::uint64_t h = 14695981039346656037ull;
  for (std::size_t i = 0; i < size; ++i) h = (h ^ data[i]) * 1099511628211ull;
  return h;
}

/// One input in this many runs phase 3: FUZZ_RUN_LATE (a whole number ≥ 1), default 256.
std::uint64_t late_one_in() {
  static const std::uint64_t n = [] {
    const char* text = std::getenv("FUZZ_RUN_LATE");
    const long long v = text ? std::atoll(text) : 0;
    return v >= 1 ? static_cast<std::uint64_t>(v) : std::uint64_t{256};
  }();
  return n;
}

/// Seconds of wall time and of the process's CPU time (every thread's).
double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double cpu_now() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// With FUZZ_RUN_TIMES=FILE, one line per input appended to FILE when it is done: the run kind
/// (RunSpec::Kind as a number; −1: skipped or refused before phase 1), the input's wall and CPU
/// time in ms, the wall times of the build and phases 1, 2 and 3, then their CPU times (−1: not
/// run), phase 2's flag time in ms, and the exit codes of phases 2 and 3 (−1: an error, −2: not
/// run). A loaded machine stretches wall times, not CPU times.
class Times {
 public:
  Times() : start_{now(), cpu_now()}, mark_{start_[0], start_[1]} {}
  ~Times() {
    static std::FILE* file = std::getenv("FUZZ_RUN_TIMES") ? std::fopen(std::getenv("FUZZ_RUN_TIMES"), "a") : nullptr;
    if (!file) return;
    std::fprintf(file, "%d %.3f %.3f", kind, 1e3 * (now() - start_[0]), 1e3 * (cpu_now() - start_[1]));
    for (const double (&phases)[4] : ms_)
      for (const double t : phases) std::fprintf(file, " %.3f", t);
    std::fprintf(file, " %g %d %d\n", 1e3 * early_after, code[0], code[1]);
    std::fflush(file);
  }
  /// Ends phase `k` (0 the build, 1–3 the phases): its time since the previous mark.
  void lap(int k) {
    const double t[2] = {now(), cpu_now()};
    for (int c = 0; c < 2; ++c) {
      ms_[c][k] = 1e3 * (t[c] - mark_[c]);
      mark_[c] = t[c];
    }
  }
  int kind = -1;
  double early_after = -1.0;
  int code[2] = {-2, -2};

 private:
  double start_[2], mark_[2];
  double ms_[2][4] = {{-1.0, -1.0, -1.0, -1.0}, {-1.0, -1.0, -1.0, -1.0}};
};

/// The run kind as `vibro run` runs it (the runner, its files in memory), its flag raised
/// `after` seconds after it starts as by a signal: an exit code, or one of the documented errors
/// (−1); never an abort (an exception in a sweep's worker), never deaf to the flag.
int run_kind(const vibro::io::SceneDocument& doc, const vibro::io::Scene& scene, double after) {
  using namespace vibro;
  std::atomic<bool> stop{false};
  try {
    io::MemoryRunOptions options;
    options.threads = 1;
    options.interrupt = &stop;
    const Watchdog watchdog(stop, after, kGrace);
    const io::MemoryRun run = io::run_in_memory(doc, scene, options);
    if (run.exit_code == 130 && !stop.load()) __builtin_trap();  // interrupted, with no interrupt
    return run.exit_code;
  } catch (const io::SceneError&) {
  } catch (const InvalidInput&) {
  } catch (const io::ResourceError&) {
  } catch (const io::ResultError&) {  // a value that cannot be written (not finite): exit code 3
  } catch (const Interrupted&) {      // a bounded set-up (bounded_wait.hpp) ended by the flag
    if (!stop.load()) __builtin_trap();
  }
  return -1;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace vibro;
  Times times;
  auto doc = fuzz::document(data, size);
  if (!doc || !fuzz::limit_grids(*doc, fuzz::kRunGridPoints, true)) return 0;
  std::optional<io::Scene> whole;
  std::optional<io::SceneDocument> whole_doc;
  try {
    io::Scene scene = doc->build();
    if (scene.dof() > 16 || scene.stops.size() > 16) return 0;
    double run_kind_bytes = 0.0;
    for (const io::MemoryNeed& need : io::estimate_run_memory(scene, 1)) run_kind_bytes += need.bytes;
    if (run_kind_bytes <= kRunKindMemory) {
      whole.emplace(scene);  // the run kind's own run (below), before the limits
      whole_doc.emplace(*doc);
    }
    times.kind = static_cast<int>(scene.run.kind);
    times.lap(0);
    // Phase 1: the capped run.
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
    const Watchdog watchdog(stop, kShortRun);
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
  times.lap(1);
  // Phases 2 and 3: the run kind, its flag raised early (every input) and late (a sample).
  const std::uint64_t h = digest(data, size);
  times.early_after = kEarly[(h >> 32) % std::size(kEarly)];
  times.code[0] = run_kind(*whole_doc, *whole, times.early_after);
  times.lap(2);
  if (h % late_one_in() == 0) {
    times.code[1] = run_kind(*whole_doc, *whole, kLate);
    times.lap(3);
  }
  return 0;
}
