#pragma once
// Private to vibro_io: the pieces of a sweep (run.kind: sweep) shared by one process (OpenMP
// threads, kinds/sweep.cpp) and several (MPI ranks, each with its threads, mpi_sweep.cpp).
#include "progress.hpp"
#include "simulation.hpp"

#include "vibro/io/result_file.hpp"
#include "vibro/io/run_request.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <map>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace vibro::io::detail {

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

SweepPlan plan_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

/// Where the sweep (re)starts: the first point not in the file and, for a followed row cut by an
/// interruption, the state its next point starts from.
struct SweepStart {
  std::size_t first = 0;
  std::optional<StartState> resumed;
};

/// Opens (or resumes) the result file; throws before creating anything if a stale .partial
/// is in the way.
ResultFile open_sweep_file(const SweepPlan& plan, const Scene& scene, const RunRequest& request,
                           int threads, SweepStart& start);

/// One point; a point that cannot start (its initial state violates a stop) is recorded as a
/// numerical failure with the reason, like any point that stops early.
Recording run_point(const Scene& sc, const StartState& start);

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
        progress_(request, "sweep", "points", static_cast<double>(plan.total), static_cast<double>(first)) {}

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
      progress_.update(static_cast<double>(next_to_write_));
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
int thread_count(const RunRequest& request, const SweepPlan& plan);

#ifdef VIBRO_WITH_MPI
/// The sweep across MPI processes (mpi_sweep.cpp): rank 0 writes the file, every rank computes.
RunReport run_sweep_mpi(const SweepPlan& plan, const Scene& scene, const RunRequest& request, int threads,
                        int rank, int size);
#endif

}  // namespace vibro::io::detail
