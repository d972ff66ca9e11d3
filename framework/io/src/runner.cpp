#include "vibro/io/runner.hpp"
#include "vibro/io/continuation.hpp"
#include "vibro/io/locate.hpp"
#include "vibro/io/basin.hpp"
#include "vibro/io/diagram.hpp"
#include "vibro/io/lyapunov_run.hpp"
#include "vibro/io/orbit_run.hpp"

#include "vibro/io/resources.hpp"
#include "vibro/io/result_file.hpp"

#include "mpi_world.hpp"
#include "vibro/io/recorded_gaps.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#ifdef VIBRO_WITH_MPI
#define OMPI_SKIP_MPICXX 1  // the C interface only: MPI's C++ bindings are deprecated and
#define MPICH_SKIP_MPICXX 1  // would need the C++ MPI library at link time
#include <mpi.h>
#endif
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <type_traits>
#include <utility>

namespace vibro::io {
namespace {

std::atomic<bool> g_interrupted{false};
extern "C" void on_signal(int) { g_interrupted.store(true); }

/// Installs SIGINT/SIGTERM handlers for the lifetime of a sweep.
class InterruptGuard {
 public:
  InterruptGuard() {
    g_interrupted.store(false);
    old_int_ = std::signal(SIGINT, on_signal);
    old_term_ = std::signal(SIGTERM, on_signal);
  }
  ~InterruptGuard() {
    std::signal(SIGINT, old_int_);
    std::signal(SIGTERM, old_term_);
  }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  void (*old_int_)(int);
  void (*old_term_)(int);
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

struct StartState {
  double t;
  Eigen::VectorXd x, v;
};

/// Transient (unrecorded) then recorded periods of one scene from `start`. The engine polls the
/// interrupt flag (SIGINT, SIGTERM) at every event and search step, and stores the time it
/// reached in `reached` (if given) for a progress line.
Recording simulate(const Scene& base, const StartState& start, std::atomic<double>* reached = nullptr) {
  const auto clock = std::chrono::steady_clock::now();
  Scene scene = base;  // shares the built system; only the options change
  if (!scene.solver.interrupt) scene.solver.interrupt = &g_interrupted;  // the caller's flag, or signals
  scene.solver.reached = reached;
  // One engine per run (a simulation, or a sweep point): everything else in this file (transient
  // then recorded run, observers, files, threads, processes) is the same for both engines.
  const std::unique_ptr<vibro::Engine> engine = make_engine(scene);
  vibro::Engine& sim = *engine;
  const double T = scene.period();
  const double t1 = start.t + scene.run.transient_periods * T;
  RunSummary transient;
  transient.status = RunStatus::completed;
  transient.t = start.t;
  transient.x = start.x;
  transient.v = start.v;
  if (scene.run.transient_periods > 0.0) transient = sim.run(start.t, start.x, start.v, t1, {});
  Recording rec = Recording::for_scene(scene, t1);
  if (transient.status != RunStatus::completed) {
    rec.summary = transient;
    rec.summary.message = "during the transient: " + transient.message;
  } else {
    // Counts are the recorded run's (docs/results.md), as the recorded events are.
    rec.summary = sim.run(t1, transient.x, transient.v, t1 + scene.run.periods * T, rec.observers());
  }
  check_recorded_gaps(scene, rec);  // no state past a stop is stored as a result
  for (const std::string& w : transient.warnings)
    if (std::find(rec.summary.warnings.begin(), rec.summary.warnings.end(), w) == rec.summary.warnings.end())
      rec.summary.warnings.insert(rec.summary.warnings.begin(), "during the transient: " + w);
  rec.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
  return rec;
}

std::string status_line(const RunSummary& s) {
  return fmt::format("{} impacts, {} sticks, {} releases, {} chatter limits; {} contact sets built "
                     "({} sticking subsystems)",
                     s.impacts, s.sticks, s.releases, s.chatters, s.contact_sets_built,
                     s.sticking_flows_built);
}

class Progress {
 public:
  Progress(bool on, std::size_t total, std::size_t done)
      : on_(on), total_(total), start_done_(done), start_(std::chrono::steady_clock::now()) {}
  void update(std::size_t done) {
    if (!on_) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double rate = done > start_done_ ? static_cast<double>(done - start_done_) / elapsed : 0.0;
    const double eta = rate > 0 ? static_cast<double>(total_ - done) / rate : 0.0;
    const int width = 30;
    const int filled = static_cast<int>(width * static_cast<double>(done) / static_cast<double>(total_));
    std::fprintf(stderr, "\r[%s%s] %zu/%zu points, ETA %.0f s ", std::string(static_cast<std::size_t>(filled), '#').c_str(),
                 std::string(static_cast<std::size_t>(width - filled), ' ').c_str(), done, total_, eta);
    if (done == total_) std::fputc('\n', stderr);
    std::fflush(stderr);
  }

 private:
  bool on_;
  std::size_t total_, start_done_;
  std::chrono::steady_clock::time_point start_;
};

/// A progress line for one long simulation, on stderr from a thread of its own: the time the
/// engine reached (SimulatorOptions::reached), the share of the run done and an estimate of the
/// time left, every second once the run has taken 2 s. Only on a terminal (RunRequest::progress).
class SimulationProgress {
 public:
  SimulationProgress(bool on, double t_begin, double t_end) : t_begin_(t_begin), t_end_(t_end) {
    reached_.store(t_begin);
    if (on) watcher_ = std::thread([this] { watch(); });
  }
  ~SimulationProgress() {
    {
      std::lock_guard<std::mutex> hold(lock_);
      done_ = true;
    }
    wake_.notify_all();
    if (watcher_.joinable()) watcher_.join();
  }
  SimulationProgress(const SimulationProgress&) = delete;
  SimulationProgress& operator=(const SimulationProgress&) = delete;
  std::atomic<double>* reached() { return &reached_; }

 private:
  void watch() {
    const auto start = std::chrono::steady_clock::now();
    bool printed = false;
    std::unique_lock<std::mutex> hold(lock_);
    while (!wake_.wait_for(hold, std::chrono::seconds(1), [this] { return done_; })) {
      const double elapsed = seconds_since(start);
      if (elapsed < 2.0) continue;
      const double share = t_end_ > t_begin_ ? (reached_.load() - t_begin_) / (t_end_ - t_begin_) : 1.0;
      const std::string left = share > 0.0 ? fmt::format(", about {:.0f} s left", elapsed * (1.0 - share) / share)
                                            : std::string(", no event yet");
      std::fprintf(stderr, "\r  t = %.6g of %.6g (%.1f %%), %.0f s%s   ", reached_.load(), t_end_, 100.0 * share,
                   elapsed, left.c_str());
      std::fflush(stderr);
      printed = true;
    }
    if (printed) std::fputc('\n', stderr);
  }

  double t_begin_, t_end_;
  std::atomic<double> reached_{0.0};
  std::mutex lock_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread watcher_;
};

RunReport run_simulation(const Scene& scene, const RunRequest& request) {
  // Ctrl-C ends the run at its next event: `vibro run` writes nothing then; a caller with its own
  // flag (Python) gets the run up to there.
  std::optional<InterruptGuard> guard;
  if (!request.interrupt) guard.emplace();
  ResultFile file = open_result_file(request, scene, current_meta(1));
  Scene interruptible = scene;
  interruptible.solver.interrupt = request.interrupt;  // null: the signal flag (simulate)
  Recording rec;
  {
    SimulationProgress progress(request.progress, scene.t0,
                                scene.t0 + (scene.run.transient_periods + scene.run.periods) * scene.period());
    rec = simulate(interruptible, {scene.t0, scene.x0, scene.v0}, progress.reached());
  }
  if (rec.summary.status == RunStatus::interrupted && !request.in_memory)
    return {130, fmt::format("Interrupted at t = {:g}: {} was not written (a simulation keeps nothing; only sweeps "
                             "can be resumed).",
                             rec.summary.t, request.output),
            {}};  // the ResultFile removes its .partial
  file.write_simulation(rec);
  RunMeta meta = current_meta(1);
  meta.wall_seconds = rec.wall_seconds;
  file.finish(meta);
  RunReport report;
  const RunSummary& s = rec.summary;
  report.exit_code = s.status == RunStatus::completed ? 0 : s.status == RunStatus::interrupted ? 130 : 1;
  std::string warnings;
  for (const std::string& w : s.warnings) warnings += "\nwarning: " + w;
  report.summary = fmt::format(
      "Simulated {} with the {} engine from t = {:g} over {:g} transient and {:g} recorded forcing periods in "
      "{:.3f} s: {}; {}.{} Results in {}.{}",
      scene.file, to_string(scene.engine), scene.t0, scene.run.transient_periods, scene.run.periods, rec.wall_seconds,
      to_string(s.status), status_line(s), s.message.empty() ? "" : " " + s.message, file.path(), warnings);
  if (request.in_memory) report.image = file.image();
  return report;
}

// ---------------------------------------------------------------------------------------------
// Sweeps. The same pieces serve one process (OpenMP threads) and several (MPI ranks, each with
// its threads): a plan every process builds alike, units of work ("chains") handed out one at a
// time, and one writer on rank 0 that puts finished points in grid order.

/// The grid, its validated scenes and its units of work, identical on every process.
struct SweepPlan {
  std::vector<std::vector<double>> grid;  ///< parameter values, in walking order
  std::vector<Scene> scenes;              ///< one per grid point
  std::vector<std::string> names;         ///< the swept paths
  std::size_t total = 0;
  bool follow = false;
  /// Chains of points that must run in order: with `follow`, a whole row; else one point each.
  std::size_t chain_length = 1;
  std::size_t chains = 0;
  /// Stops the sweep: raised by a signal (the process-wide flag), by the caller
  /// (RunRequest::interrupt), or by the writer itself (a write error, interrupt_after).
  std::atomic<bool>* interrupted = nullptr;
};

SweepPlan plan_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  SweepPlan plan;
  plan.interrupted = request.interrupt ? request.interrupt : &g_interrupted;
  const auto& axes = scene.run.axes;
  if (axes.size() == 1) {
    for (double a : axes[0].values) plan.grid.push_back({a});
  } else {
    for (double a : axes[0].values)
      for (double b : axes[1].values) plan.grid.push_back({a, b});
  }
  if (scene.run.reverse) std::reverse(plan.grid.begin(), plan.grid.end());
  plan.total = plan.grid.size();
  const std::size_t row_length = axes.size() == 1 ? plan.total : axes[1].values.size();

  // Build and validate every point's scene first: bad input never starts a file.
  plan.scenes.reserve(plan.total);
  SceneDocument point = doc;  // one working copy: set() replaces the swept values per point
  for (std::size_t p = 0; p < plan.total; ++p) {
    for (std::size_t a = 0; a < axes.size(); ++a) point.set(axes[a].path, plan.grid[p][a]);
    try {
      plan.scenes.push_back(point.build_point());  // build() checks the whole grid: once, in main
      plan.scenes.back().solver.interrupt = plan.interrupted;
    } catch (const SceneError& e) {
      std::string where;
      for (std::size_t a = 0; a < axes.size(); ++a) where += fmt::format("{}{} = {:.12g}", a ? ", " : "", axes[a].path, plan.grid[p][a]);
      throw SceneError(e.file(), e.line(), e.column(), e.path(), e.problem() + " (at sweep point " + std::to_string(p) + ": " + where + ")");
    }
  }
  for (const auto& a : axes) plan.names.push_back(a.path);
  plan.follow = scene.run.follow;
  plan.chain_length = plan.follow ? row_length : 1;
  plan.chains = (plan.total + plan.chain_length - 1) / plan.chain_length;
  return plan;
}

/// Where the sweep (re)starts: the first point not in the file and, for a followed row cut by an
/// interruption, the state its next point starts from.
struct SweepStart {
  std::size_t first = 0;
  std::optional<StartState> resumed;
};

/// Opens (or resumes) the result file; throws before creating anything if a stale .partial
/// is in the way.
ResultFile open_sweep_file(const SweepPlan& plan, const Scene& scene, const RunRequest& request,
                           int threads, SweepStart& start) {
  if (request.in_memory && request.resume) throw std::logic_error("runner: a sweep in memory cannot be resumed");
  ResultFile file = request.resume ? ResultFile::open_partial(request.output, scene, request.force)
                                   : open_result_file(request, scene, current_meta(threads));
  file.begin_sweep(plan.names, plan.total);
  start.first = file.completed_points();
  start.resumed.reset();
  if (plan.follow && start.first > 0 && start.first % plan.chain_length != 0) {
    StartState s{scene.t0, {}, {}};
    if (file.last_state(s.t, s.x, s.v)) start.resumed = s;
  }
  return file;
}

/// One point; a point that cannot start (its initial state violates a stop) is recorded as a
/// numerical failure with the reason, like any point that stops early.
Recording run_point(const Scene& sc, const StartState& start) {
  try {
    return simulate(sc, start);
  } catch (const InvalidInput& e) {
    Recording rec = Recording::for_scene(sc, start.t);
    rec.summary.status = RunStatus::numerical_failure;
    rec.summary.message = std::string("cannot start this point: ") + e.what();
    rec.summary.t = start.t;
    rec.summary.x = start.x;
    rec.summary.v = start.v;
    return rec;
  }
}

/// Runs chain `c` from `from.first` on, in order, handing every finished point to
/// deliver(index, Recording&&). Stops before the next point once interrupted.
template <class Deliver>
void run_chain(const SweepPlan& plan, const SweepStart& from, std::size_t c, Deliver& deliver) {
  const std::size_t begin = c * plan.chain_length;
  const std::size_t end = std::min(plan.total, begin + plan.chain_length);
  std::optional<StartState> carried;
  for (std::size_t p = std::max(begin, from.first); p < end; ++p) {
    if (plan.interrupted->load()) break;
    const Scene& sc = plan.scenes[p];
    StartState start{sc.t0, sc.x0, sc.v0};
    if (plan.follow && carried) start = {sc.t0, carried->x, carried->v};
    if (plan.follow && !carried && p == from.first && from.resumed) start = {sc.t0, from.resumed->x, from.resumed->v};
    Recording rec = run_point(sc, start);
    if (rec.summary.status == RunStatus::interrupted) break;  // not a result: computed again on --resume
    if (plan.follow) carried = StartState{sc.t0, rec.summary.x, rec.summary.v};
    deliver(p, std::move(rec));
  }
}

/// Runs chains on `threads` OpenMP threads while take() gives them (dynamic: sticking-heavy
/// points cost more, so each thread takes the next chain when it is free).
template <class Take, class Deliver>
void run_chains(int threads, const SweepPlan& plan, const SweepStart& from, Take& take, Deliver& deliver) {
  (void)threads;  // without OpenMP: one thread
  // An exception must not leave an OpenMP region (std::terminate): the first one ends the sweep
  // (the others stop before their next point, the partial file keeps what was written) and is
  // rethrown here, where the caller reports it like any error.
  std::exception_ptr failure;
  std::mutex failure_lock;
#ifdef _OPENMP
#pragma omp parallel num_threads(threads)
#endif
  {
    try {
      while (const std::optional<std::size_t> c = take()) run_chain(plan, from, *c, deliver);
    } catch (...) {
      std::lock_guard<std::mutex> hold(failure_lock);
      if (!failure) failure = std::current_exception();
      plan.interrupted->store(true);
    }
  }
  if (failure) std::rethrow_exception(failure);
}

/// Hands out the chains in grid order, one per call, from any thread.
class ChainDispenser {
 public:
  ChainDispenser(const SweepPlan& plan, std::size_t first_chain)
      : next_(first_chain), chains_(plan.chains), interrupted_(*plan.interrupted) {}
  /// The next chain, or none once all are handed out or the sweep is interrupted.
  std::optional<std::size_t> operator()() {
    if (interrupted_.load()) return std::nullopt;
    const std::size_t c = next_.fetch_add(1);
    if (c >= chains_) return std::nullopt;
    return c;
  }

 private:
  std::atomic<std::size_t> next_;
  std::size_t chains_;
  const std::atomic<bool>& interrupted_;
};

/// Takes finished points from any thread and writes them in grid order (points that finish
/// early wait in memory for their turn). The only user of the file while the sweep runs.
class SweepWriter {
 public:
  SweepWriter(ResultFile& file, const SweepPlan& plan, std::size_t first, const RunRequest& request)
      : file_(file), plan_(plan), request_(request), first_(first), next_to_write_(first),
        progress_(request.progress, plan.total, first) {}

  void operator()(std::size_t p, Recording&& rec) {
    std::lock_guard<std::mutex> hold(lock_);
    if (rec.summary.status == RunStatus::interrupted) {  // cut short: never written as a result
      plan_.interrupted->store(true);
      return;
    }
    cpu_seconds_ += rec.wall_seconds;
    done_.emplace(p, std::move(rec));
    while (!write_error_ && done_.count(next_to_write_)) {
      auto node = done_.extract(next_to_write_);
      const Recording& r = node.mapped();
      try {
        file_.append_point(next_to_write_, plan_.grid[next_to_write_], r);
      } catch (const ResultError& e) {
        write_error_ = e;
        plan_.interrupted->store(true);
        break;
      }
      if (r.summary.status != RunStatus::completed) ++stopped_early_;
      totals_.impacts += r.summary.impacts;
      totals_.sticks += r.summary.sticks;
      totals_.releases += r.summary.releases;
      totals_.chatters += r.summary.chatters;
      ++next_to_write_;
      progress_.update(next_to_write_);
      if (request_.interrupt_after > 0 && next_to_write_ >= request_.interrupt_after) {
        // Write nothing more: points other threads finished meanwhile would otherwise complete
        // the file before the interruption is seen (a race a faster engine loses more often).
        plan_.interrupted->store(true);
        break;
      }
    }
  }

  /// After the last point: throws a write error, else finishes the file (all points written) or
  /// keeps the .partial (interrupted), and says so. `on` says where the points ran.
  RunReport report(const Scene& scene, int threads, double wall, const std::string& on) {
    if (write_error_) throw *write_error_;
    RunReport report;
    const std::size_t total = plan_.total;
    if (next_to_write_ < total) {
      report.exit_code = 130;
      report.summary = fmt::format(
          "Interrupted: {} of {} sweep points are kept in {}{}.", next_to_write_, total,
          request_.in_memory ? "memory" : ResultFile::partial_path(request_.output),
          request_.in_memory ? "" : "; run the same command with --resume to finish the rest");
      return report;  // the partial file is kept by ResultFile's destructor
    }
    RunMeta meta = current_meta(threads);
    meta.wall_seconds = wall;
    file_.finish(meta);
    report.exit_code = stopped_early_ > 0 ? 1 : 0;
    report.summary = fmt::format(
        "Swept {} over {} points ({} computed now{}) on {} in {:.2f} s wall ({:.2f} s CPU in "
        "simulations): {} impacts, {} sticks, {} releases, {} chatter limits; {} points stopped early{}. "
        "Results in {}.",
        scene.file, total, total - first_, first_ ? fmt::format(", {} resumed", first_) : "", on, wall,
        cpu_seconds_, totals_.impacts, totals_.sticks, totals_.releases, totals_.chatters, stopped_early_,
        stopped_early_ ? " (see /sweep/status and /sweep/message)" : "", file_.path());
    return report;
  }

 private:
  ResultFile& file_;
  const SweepPlan& plan_;
  const RunRequest& request_;
  std::size_t first_;
  std::mutex lock_;
  std::map<std::size_t, Recording> done_;  // finished, not yet written
  std::size_t next_to_write_;
  long stopped_early_ = 0;
  RunSummary totals_;
  double cpu_seconds_ = 0.0;
  Progress progress_;
  std::optional<ResultError> write_error_;
};

/// Threads for a sweep: as requested (0: all cores), at most one per unit of work (resources.hpp).
int thread_count(const RunRequest& request, const SweepPlan& plan) {
  return checked_threads(request.threads, plan.chains);
}


using detail::world;

#ifdef VIBRO_WITH_MPI
RunReport run_sweep_mpi(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                        int rank, int size);
#endif

RunReport run_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  const SweepPlan plan = plan_sweep(doc, scene, request);
  const int threads = thread_count(request, plan);
#ifdef VIBRO_WITH_MPI
  if (const auto [rank, size] = world(); size > 1) return run_sweep_mpi(plan, scene, request, threads, rank, size);
#endif
  SweepStart from;
  ResultFile file = open_sweep_file(plan, scene, request, threads, from);
  SweepWriter writer(file, plan, from.first, request);
  ChainDispenser dispenser(plan, from.first / plan.chain_length);
  const auto wall_start = std::chrono::steady_clock::now();
  std::optional<InterruptGuard> guard;  // signals are the caller's when it gives its own flag
  if (!request.interrupt) guard.emplace();
  run_chains(threads, plan, from, dispenser, writer);
  RunReport report = writer.report(scene, threads, seconds_since(wall_start), fmt::format("{} threads", threads));
  if (request.in_memory) report.image = file.image();
  return report;
}

#ifdef VIBRO_WITH_MPI
// ---------------------------------------------------------------------------------------------
// Sweeps across MPI processes. Rank 0 owns the file and the dispenser; every rank runs chains on
// its OpenMP threads, started from a helper std::thread, while its main thread (the only one
// that calls MPI: MPI_THREAD_FUNNELED) carries the messages:
//   worker → 0  request      a thread is free: give it a chain
//   0 → worker  assign       the chain's index, or -1: no more (done or interrupted)
//   worker → 0  result       [point, bytes] then the encoded Recording in pieces of ≤ 1 GiB
//   worker → 0  bye          all its threads are done and all its results sent
//   0 → worker  stop         rank 0 is interrupted (signal, --interrupt-after, a write error):
//                            finish the point under way and take no more
//   0 → worker  done         every worker said bye: return
// Rank 0 ends when its own threads are done and every worker said bye. The main threads poll
// (MPI_Iprobe, then sleep 20 µs … 1 ms): a blocking receive would spin a core that the
// simulations need.

namespace tag {
constexpr int request = 1, assign = 2, result = 3, result_data = 4, bye = 5, stop = 6, done = 7;
}
constexpr std::size_t max_piece = std::size_t{1} << 30;

/// Bytes of a Recording (only what the result file uses: the observers' public records, the
/// summary and the recording's span). Keep in step with Recording and recorded_tables().
class Encoder {
 public:
  template <class T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    append(&value, sizeof value);
  }
  template <class T>
  void put(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    put<std::uint64_t>(values.size());
    append(values.data(), values.size() * sizeof(T));
  }
  void put(const std::string& text) {
    put<std::uint64_t>(text.size());
    append(text.data(), text.size());
  }
  template <class Scalar>
  void put(const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
    put<std::uint64_t>(static_cast<std::uint64_t>(v.size()));
    append(v.data(), static_cast<std::size_t>(v.size()) * sizeof(Scalar));
  }
  void put(const Eigen::MatrixXd& m) {
    put<std::uint64_t>(static_cast<std::uint64_t>(m.rows()));
    put<std::uint64_t>(static_cast<std::uint64_t>(m.cols()));
    append(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
  }
  template <class Scalar>
  void put(const std::vector<Eigen::Matrix<Scalar, Eigen::Dynamic, 1>>& vs) {
    put<std::uint64_t>(vs.size());
    for (const auto& v : vs) put(v);
  }
  std::vector<char> bytes;

 private:
  void append(const void* data, std::size_t n) {
    const char* c = static_cast<const char*>(data);
    bytes.insert(bytes.end(), c, c + n);
  }
};

class Decoder {
 public:
  explicit Decoder(const std::vector<char>& bytes) : bytes_(bytes) {}
  template <class T>
  void get(T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    take(&value, sizeof value);
  }
  template <class T>
  void get(std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    values.resize(count(sizeof(T)));
    take(values.data(), values.size() * sizeof(T));
  }
  void get(std::string& text) {
    text.resize(count(1));
    take(text.data(), text.size());
  }
  template <class Scalar>
  void get(Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& v) {
    v.resize(static_cast<Eigen::Index>(count(sizeof(Scalar))));
    take(v.data(), static_cast<std::size_t>(v.size()) * sizeof(Scalar));
  }
  void get(Eigen::MatrixXd& m) {
    std::uint64_t rows = 0, cols = 0;
    get(rows);
    get(cols);
    // rows · cols could overflow: compare against what is left, one factor at a time.
    if (rows > 0 && cols > (bytes_.size() - at_) / sizeof(double) / rows)
      throw std::logic_error("runner: a received recording is truncated");
    m.resize(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
    take(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
  }
  template <class Scalar>
  void get(std::vector<Eigen::Matrix<Scalar, Eigen::Dynamic, 1>>& vs) {
    vs.resize(count(sizeof(std::uint64_t)));
    for (auto& v : vs) get(v);
  }
  bool at_end() const { return at_ == bytes_.size(); }

 private:
  std::size_t count(std::size_t item_size) {
    std::uint64_t n = 0;
    get(n);
    if (item_size > 0 && n > (bytes_.size() - at_) / item_size)
      throw std::logic_error("runner: a received recording is truncated");
    return static_cast<std::size_t>(n);
  }
  void take(void* data, std::size_t n) {
    if (n > bytes_.size() - at_) throw std::logic_error("runner: a received recording is truncated");
    if (n > 0) std::memcpy(data, bytes_.data() + at_, n);
    at_ += n;
  }
  const std::vector<char>& bytes_;
  std::size_t at_ = 0;
};

template <class Coder, class Summary>
void code_summary(Coder& c, Summary& s) {
  c.put_or_get(s.status);
  c.put_or_get(s.message);
  c.put_or_get(s.t);
  c.put_or_get(s.x);
  c.put_or_get(s.v);
  c.put_or_get(s.stuck);
  for (auto* n : {&s.impacts, &s.sticks, &s.releases, &s.chatters, &s.segments}) c.put_or_get(*n);
  c.put_or_get(s.contact_sets_built);
  c.put_or_get(s.sticking_flows_built);
  for (auto* d : {&s.length_scale, &s.velocity_scale, &s.force_scale, &s.time_scale}) c.put_or_get(*d);
}

struct Writing {
  Encoder e;
  template <class T>
  void put_or_get(const T& v) { e.put(v); }
};
struct Reading {
  Decoder d;
  template <class T>
  void put_or_get(T& v) { d.get(v); }
};

std::vector<char> encode(const Recording& rec) {
  Writing w;
  Encoder& e = w.e;
  e.put(static_cast<std::uint8_t>((rec.events ? 1 : 0) | (rec.contacts ? 2 : 0) | (rec.samples ? 4 : 0) |
                                  (rec.poincare ? 8 : 0) | (rec.statistics ? 16 : 0)));
  if (rec.events) e.put(rec.events->events);
  if (rec.contacts) e.put(rec.contacts->intervals);
  if (rec.samples) {
    e.put(rec.samples->t);
    e.put(rec.samples->x);
    e.put(rec.samples->v);
  }
  if (rec.poincare) {
    e.put(rec.poincare->t);
    e.put(rec.poincare->x);
    e.put(rec.poincare->v);
  }
  if (rec.statistics) {
    e.put(rec.statistics->sticking_fraction);
    e.put(rec.statistics->impacts);
  }
  code_summary(w, rec.summary);
  e.put(rec.wall_seconds);
  e.put(rec.t_start);
  e.put(rec.t_end);
  e.put(static_cast<std::uint64_t>(rec.periods));
  return std::move(e.bytes);
}

Recording decode(const std::vector<char>& bytes) {
  Reading r{Decoder(bytes)};
  Decoder& d = r.d;
  Recording rec;
  std::uint8_t present = 0;
  d.get(present);
  if (present & 1) d.get(rec.events.emplace().events);
  if (present & 2) d.get(rec.contacts.emplace().intervals);
  if (present & 4) {
    Samples& samples = rec.samples.emplace(std::vector<double>{});
    d.get(samples.t);
    d.get(samples.x);
    d.get(samples.v);
  }
  if (present & 8) {
    Poincare& poincare = rec.poincare.emplace();
    d.get(poincare.t);
    d.get(poincare.x);
    d.get(poincare.v);
  }
  if (present & 16) {
    PeriodStatistics& statistics = rec.statistics.emplace();
    d.get(statistics.sticking_fraction);
    d.get(statistics.impacts);
  }
  code_summary(r, rec.summary);
  d.get(rec.wall_seconds);
  d.get(rec.t_start);
  d.get(rec.t_end);
  std::uint64_t periods = 0;
  d.get(periods);
  rec.periods = static_cast<std::size_t>(periods);
  if (!d.at_end()) throw std::logic_error("runner: a received recording has trailing bytes");
  return rec;
}

/// Sleeps between polls: short right after a message, longer (up to 1 ms) while nothing comes.
class Backoff {
 public:
  void wait() {
    std::this_thread::sleep_for(delay_);
    delay_ = std::min(delay_ * 2, std::chrono::microseconds(1000));
  }
  void reset() { delay_ = std::chrono::microseconds(20); }

 private:
  std::chrono::microseconds delay_{20};
};

/// Joins a thread on every way out of a scope.
class Joining {
 public:
  explicit Joining(std::thread& t) : t_(t) {}
  ~Joining() {
    if (t_.joinable()) t_.join();
  }
  Joining(const Joining&) = delete;
  Joining& operator=(const Joining&) = delete;

 private:
  std::thread& t_;
};

/// The start of the sweep, from rank 0 to all: 0 or the exit code of rank 0's failure to open
/// the file, the first point to compute and (a followed row cut by an interruption) its state.
int share_start(int failure, SweepStart& from, Eigen::Index dof) {
  long long head[3] = {failure, static_cast<long long>(from.first), from.resumed ? 1 : 0};
  MPI_Bcast(head, 3, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  if (head[0] != 0) return static_cast<int>(head[0]);
  from.first = static_cast<std::size_t>(head[1]);
  if (head[2] != 0) {
    std::vector<double> state(static_cast<std::size_t>(1 + 2 * dof));
    if (from.resumed) {
      state[0] = from.resumed->t;
      std::copy(from.resumed->x.data(), from.resumed->x.data() + dof, state.begin() + 1);
      std::copy(from.resumed->v.data(), from.resumed->v.data() + dof, state.begin() + 1 + dof);
    }
    MPI_Bcast(state.data(), static_cast<int>(state.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    from.resumed = StartState{state[0], Eigen::Map<Eigen::VectorXd>(state.data() + 1, dof),
                              Eigen::Map<Eigen::VectorXd>(state.data() + 1 + dof, dof)};
  }
  return 0;
}

void send_bytes(const std::vector<char>& bytes, int tag_of_pieces) {
  for (std::size_t at = 0; at < bytes.size(); at += max_piece) {
    const std::size_t n = std::min(max_piece, bytes.size() - at);
    MPI_Send(bytes.data() + at, static_cast<int>(n), MPI_BYTE, 0, tag_of_pieces, MPI_COMM_WORLD);
  }
}

std::vector<char> receive_bytes(int source, std::size_t size, int tag_of_pieces) {
  std::vector<char> bytes(size);
  for (std::size_t at = 0; at < size; at += max_piece) {
    const std::size_t n = std::min(max_piece, size - at);
    MPI_Recv(bytes.data() + at, static_cast<int>(n), MPI_BYTE, source, tag_of_pieces, MPI_COMM_WORLD,
             MPI_STATUS_IGNORE);
  }
  return bytes;
}

RunReport run_rank0(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                    int size, int all_threads) {
  SweepStart from;
  std::optional<ResultFile> file;
  std::exception_ptr failure;
  int code = 0;
  try {
    file.emplace(open_sweep_file(plan, scene, request, all_threads, from));
  } catch (const SceneError&) {
    failure = std::current_exception();
    code = 2;
  } catch (const ResultError&) {
    failure = std::current_exception();
    code = 3;
  } catch (...) {
    failure = std::current_exception();
    code = 1;
  }
  share_start(code, from, scene.dof());
  if (failure) std::rethrow_exception(failure);

  SweepWriter writer(*file, plan, from.first, request);
  ChainDispenser dispenser(plan, from.first / plan.chain_length);
  const auto wall_start = std::chrono::steady_clock::now();
  InterruptGuard guard;
  std::atomic<bool> computed{false};
  std::thread compute([&] {
    run_chains(threads, plan, from, dispenser, writer);
    computed.store(true);
  });
  Joining joining(compute);
  try {
    int byes = 0;
    bool stop_sent = false;
    Backoff idle;
    while (!(computed.load() && byes == size - 1)) {
      if (plan.interrupted->load() && !stop_sent) {
        for (int r = 1; r < size; ++r) MPI_Send(nullptr, 0, MPI_BYTE, r, tag::stop, MPI_COMM_WORLD);
        stop_sent = true;
      }
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (!flag) {
        idle.wait();
        continue;
      }
      idle.reset();
      const int source = status.MPI_SOURCE;
      if (status.MPI_TAG == tag::request) {
        MPI_Recv(nullptr, 0, MPI_BYTE, source, tag::request, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        const std::optional<std::size_t> c = dispenser();
        const long long chain = c ? static_cast<long long>(*c) : -1;
        MPI_Send(&chain, 1, MPI_LONG_LONG, source, tag::assign, MPI_COMM_WORLD);
      } else if (status.MPI_TAG == tag::result) {
        unsigned long long head[2];
        MPI_Recv(head, 2, MPI_UNSIGNED_LONG_LONG, source, tag::result, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        const std::size_t point = static_cast<std::size_t>(head[0]);
        if (point >= plan.total) throw std::logic_error("runner: rank " + std::to_string(source) + " sent point " + std::to_string(point));
        writer(point, decode(receive_bytes(source, static_cast<std::size_t>(head[1]), tag::result_data)));
      } else if (status.MPI_TAG == tag::bye) {
        MPI_Recv(nullptr, 0, MPI_BYTE, source, tag::bye, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        ++byes;
      } else {
        throw std::logic_error("runner: unexpected MPI message, tag " + std::to_string(status.MPI_TAG));
      }
    }
    for (int r = 1; r < size; ++r) MPI_Send(nullptr, 0, MPI_BYTE, r, tag::done, MPI_COMM_WORLD);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: MPI sweep: %s\n", e.what());
    MPI_Abort(MPI_COMM_WORLD, 3);  // the other ranks would wait for rank 0 for ever
  }
  compute.join();
  return writer.report(scene, all_threads, seconds_since(wall_start),
                       fmt::format("{} processes ({} threads in all)", size, all_threads));
}

RunReport run_worker(const SweepPlan& plan, const Scene& scene, int threads) {
  SweepStart from;
  if (share_start(0, from, scene.dof()) != 0) return {};  // rank 0 reports its failure

  struct Message {
    int tag;
    std::size_t point;
    std::vector<char> bytes;
  };
  std::mutex lock;
  std::condition_variable assigned_cv;
  std::deque<Message> outbox;
  std::deque<long long> assigned;
  auto take = [&]() -> std::optional<std::size_t> {
    if (plan.interrupted->load()) return std::nullopt;
    std::unique_lock<std::mutex> hold(lock);
    outbox.push_back({tag::request, 0, {}});
    assigned_cv.wait(hold, [&] { return !assigned.empty(); });
    const long long chain = assigned.front();
    assigned.pop_front();
    if (chain < 0) return std::nullopt;
    return static_cast<std::size_t>(chain);
  };
  auto deliver = [&](std::size_t p, Recording&& rec) {
    std::vector<char> bytes = encode(rec);
    std::lock_guard<std::mutex> hold(lock);
    outbox.push_back({tag::result, p, std::move(bytes)});
  };

  InterruptGuard guard;
  std::atomic<bool> computed{false};
  std::thread compute([&] {
    run_chains(threads, plan, from, take, deliver);
    computed.store(true);
  });
  Joining joining(compute);
  Backoff idle;
  bool bye_sent = false;
  for (;;) {
    const bool finished = computed.load();  // before taking the outbox: then it holds everything
    std::deque<Message> sending;
    {
      std::lock_guard<std::mutex> hold(lock);
      sending.swap(outbox);
    }
    for (const Message& m : sending) {
      if (m.tag == tag::request) {
        MPI_Send(nullptr, 0, MPI_BYTE, 0, tag::request, MPI_COMM_WORLD);
      } else {
        const unsigned long long head[2] = {m.point, m.bytes.size()};
        MPI_Send(head, 2, MPI_UNSIGNED_LONG_LONG, 0, tag::result, MPI_COMM_WORLD);
        send_bytes(m.bytes, tag::result_data);
      }
    }
    if (finished && sending.empty() && !bye_sent) {
      MPI_Send(nullptr, 0, MPI_BYTE, 0, tag::bye, MPI_COMM_WORLD);
      bye_sent = true;
    }
    bool received = false, done = false;
    for (;;) {
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
      if (!flag) break;
      received = true;
      if (status.MPI_TAG == tag::assign) {
        long long chain = -1;
        MPI_Recv(&chain, 1, MPI_LONG_LONG, 0, tag::assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        {
          std::lock_guard<std::mutex> hold(lock);
          assigned.push_back(chain);
        }
        assigned_cv.notify_all();
      } else {
        MPI_Recv(nullptr, 0, MPI_BYTE, 0, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (status.MPI_TAG == tag::stop) plan.interrupted->store(true);
        if (status.MPI_TAG == tag::done) done = true;
      }
    }
    if (done) break;
    if (sending.empty() && !received) {
      idle.wait();
    } else {
      idle.reset();
    }
  }
  compute.join();
  return {};
}

RunReport run_sweep_mpi(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                        int rank, int size) {
  int all_threads = 0;
  MPI_Reduce(&threads, &all_threads, 1, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
  if (rank == 0) return run_rank0(plan, scene, request, threads, size, all_threads);
  return run_worker(plan, scene, threads);
}
#endif  // VIBRO_WITH_MPI

}  // namespace

ResultFile open_result_file(const RunRequest& request, const Scene& scene, const RunMeta& meta) {
  return request.in_memory ? ResultFile::create_in_memory(scene, meta)
                           : ResultFile::create(request.output, scene, meta, request.force);
}

RunReport run_scene(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  check_run_resources(scene, checked_threads(request.threads, std::numeric_limits<std::size_t>::max()));  // before any file or allocation
  // Under MPI only sweeps and basins are split across the processes; any other run is rank 0's alone.
  if (scene.run.kind != RunSpec::Kind::sweep && scene.run.kind != RunSpec::Kind::basin && world().first != 0) return {};
  if (scene.run.kind == RunSpec::Kind::sweep) return run_sweep(doc, scene, request);
  const RunSpec::Kind kind = scene.run.kind;
  if ((kind == RunSpec::Kind::basin || kind == RunSpec::Kind::diagram || kind == RunSpec::Kind::lyapunov ||
       kind == RunSpec::Kind::locate || kind == RunSpec::Kind::continuation || kind == RunSpec::Kind::orbit) &&
      !request.resume) {
    // Long runs: SIGINT/SIGTERM stop them at the next event (a basin takes no new points) and
    // their file is written with what was done, status interrupted, exit code 130.
    RunRequest stoppable = request;
    std::optional<InterruptGuard> guard;  // signals are the caller's when it gives its own flag
    if (!stoppable.interrupt) {
      guard.emplace();
      stoppable.interrupt = &g_interrupted;
    }
    switch (kind) {
      case RunSpec::Kind::basin: return run_basin(doc, scene, stoppable);
      case RunSpec::Kind::diagram: return run_diagram(doc, scene, stoppable);
      case RunSpec::Kind::lyapunov: return run_lyapunov(doc, scene, stoppable);
      case RunSpec::Kind::orbit: return run_orbit(doc, scene, stoppable);
      case RunSpec::Kind::locate: return run_locate(doc, scene, stoppable);
      default: return run_continuation(doc, scene, stoppable);
    }
  }
  if (request.resume)
    throw SceneError(scene.file, 1, 1, "run.kind", "--resume continues an interrupted sweep; this scene is not a sweep");
  return run_simulation(scene, request);
}

}  // namespace vibro::io

namespace vibro::io {

ProcessGroup::ProcessGroup(int& argc, char**& argv) {
#ifdef VIBRO_WITH_MPI
  const bool launched = std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMI_SIZE") != nullptr ||
                        std::getenv("PMIX_RANK") != nullptr;
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (launched && !initialized) {
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    started_ = true;
  }
  std::tie(rank_, size_) = world();
#else
  (void)argc;
  (void)argv;
#endif
}

ProcessGroup::~ProcessGroup() {
#ifdef VIBRO_WITH_MPI
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (started_ && !finalized) MPI_Finalize();
#endif
}

}  // namespace vibro::io

namespace vibro::io::detail {

/// Rank and size of MPI_COMM_WORLD if MPI is running, else 0 and 1.
std::pair<int, int> world() {
#ifdef VIBRO_WITH_MPI
  int initialized = 0, finalized = 0;
  MPI_Initialized(&initialized);
  MPI_Finalized(&finalized);
  if (initialized && !finalized) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    return {rank, size};
  }
#endif
  return {0, 1};
}

}  // namespace vibro::io::detail
