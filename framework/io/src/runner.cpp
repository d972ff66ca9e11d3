#include "vibro/io/runner.hpp"
#include "vibro/io/locate.hpp"

#include "vibro/io/result_file.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <cstdio>
#include <map>
#include <mutex>
#include <optional>

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

struct StartState {
  double t;
  Eigen::VectorXd x, v;
};

/// Transient (unrecorded) then recorded periods of one scene from `start`.
Recording simulate(const Scene& scene, const StartState& start) {
  const auto clock = std::chrono::steady_clock::now();
  const ImpactSystem impact = scene.impact_system();
  Simulator sim(impact, scene.solver);
  const double T = scene.period();
  const double t1 = start.t + scene.run.transient_periods * T;
  RunSummary transient;
  transient.status = RunStatus::completed;
  transient.t = start.t;
  transient.x = start.x;
  transient.v = start.v;
  if (scene.run.transient_periods > 0.0) transient = sim.run(start.t, start.x, start.v, t1);
  Recording rec = Recording::for_scene(scene, t1);
  if (transient.status != RunStatus::completed) {
    rec.summary = transient;
    rec.summary.message = "during the transient: " + transient.message;
  } else {
    rec.summary = sim.run(t1, transient.x, transient.v, t1 + scene.run.periods * T, rec.observers());
    rec.summary.impacts += transient.impacts;
    rec.summary.sticks += transient.sticks;
    rec.summary.releases += transient.releases;
    rec.summary.chatters += transient.chatters;
    rec.summary.segments += transient.segments;
  }
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

RunReport run_simulation(const Scene& scene, const RunRequest& request) {
  ResultFile file = ResultFile::create(request.output, scene, current_meta(1));
  const Recording rec = simulate(scene, {scene.t0, scene.x0, scene.v0});
  file.write_simulation(rec);
  RunMeta meta = current_meta(1);
  meta.wall_seconds = rec.wall_seconds;
  file.finish(meta);
  RunReport report;
  const RunSummary& s = rec.summary;
  report.exit_code = s.status == RunStatus::completed ? 0 : 1;
  report.summary = fmt::format(
      "Simulated {} from t = {:g} over {:g} transient and {:g} recorded forcing periods in {:.3f} s: {}; {}.{} "
      "Results in {}.",
      scene.file, scene.t0, scene.run.transient_periods, scene.run.periods, rec.wall_seconds,
      to_string(s.status), status_line(s), s.message.empty() ? "" : " " + s.message, request.output);
  return report;
}

RunReport run_sweep(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  // The grid, in walking order.
  const auto& axes = scene.run.axes;
  std::vector<std::vector<double>> grid;
  if (axes.size() == 1) {
    for (double a : axes[0].values) grid.push_back({a});
  } else {
    for (double a : axes[0].values)
      for (double b : axes[1].values) grid.push_back({a, b});
  }
  if (scene.run.reverse) std::reverse(grid.begin(), grid.end());
  const std::size_t total = grid.size();
  const std::size_t row_length = axes.size() == 1 ? total : axes[1].values.size();

  // Build and validate every point's scene first: bad input never starts a file.
  std::vector<Scene> scenes;
  scenes.reserve(total);
  for (std::size_t p = 0; p < total; ++p) {
    SceneDocument point = doc;
    for (std::size_t a = 0; a < axes.size(); ++a) point.set(axes[a].path, grid[p][a]);
    try {
      scenes.push_back(point.build());
    } catch (const SceneError& e) {
      std::string where;
      for (std::size_t a = 0; a < axes.size(); ++a) where += fmt::format("{}{} = {:.12g}", a ? ", " : "", axes[a].path, grid[p][a]);
      throw SceneError(e.file(), e.line(), e.column(), e.path(), e.problem() + " (at sweep point " + std::to_string(p) + ": " + where + ")");
    }
  }

  std::vector<std::string> names;
  for (const auto& a : axes) names.push_back(a.path);
#ifdef _OPENMP
  const int threads = request.threads > 0 ? request.threads : omp_get_max_threads();
#else
  const int threads = 1;
#endif
  if (!request.resume && std::filesystem::exists(ResultFile::partial_path(request.output)))
    throw SceneError(scene.file, 0, 0, "",
                     "an interrupted sweep exists in " + ResultFile::partial_path(request.output) +
                         ": finish it with --resume, or delete it to start again");
  ResultFile file = request.resume ? ResultFile::open_partial(request.output, scene)
                                   : ResultFile::create(request.output, scene, current_meta(threads));
  file.begin_sweep(names, total);
  const std::size_t first = file.completed_points();

  // Chains of points that must run in order: with `follow`, a whole row; else one point each.
  const bool follow = scene.run.follow;
  const std::size_t chain_length = follow ? row_length : 1;
  const std::size_t chains = (total + chain_length - 1) / chain_length;
  std::optional<StartState> resumed;
  if (follow && first > 0 && first % chain_length != 0) {
    StartState s{scene.t0, {}, {}};
    if (file.last_state(s.t, s.x, s.v)) resumed = s;
  }

  std::mutex lock;
  std::map<std::size_t, Recording> done;  // finished, not yet written
  std::size_t next_to_write = first;
  long stopped_early = 0;
  RunSummary totals;
  double cpu_seconds = 0.0;
  Progress progress(request.progress, total, first);
  std::optional<ResultError> write_error;
  const auto wall_start = std::chrono::steady_clock::now();
  InterruptGuard guard;

#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (long c = 0; c < static_cast<long>(chains); ++c) {
    const std::size_t begin = static_cast<std::size_t>(c) * chain_length;
    const std::size_t end = std::min(total, begin + chain_length);
    if (end <= first) continue;
    std::optional<StartState> carried;
    for (std::size_t p = begin; p < end; ++p) {
      if (g_interrupted.load()) break;
      const Scene& sc = scenes[p];
      if (p < first) continue;
      StartState start{sc.t0, sc.x0, sc.v0};
      if (follow && carried) start = {sc.t0, carried->x, carried->v};
      if (follow && !carried && p == first && resumed) start = {sc.t0, resumed->x, resumed->v};
      Recording rec;
      try {
        rec = simulate(sc, start);
      } catch (const InvalidInput& e) {
        rec = Recording::for_scene(sc, start.t);
        rec.summary.status = RunStatus::numerical_failure;
        rec.summary.message = std::string("cannot start this point: ") + e.what();
        rec.summary.t = start.t;
        rec.summary.x = start.x;
        rec.summary.v = start.v;
      }
      if (follow) carried = StartState{sc.t0, rec.summary.x, rec.summary.v};
      std::lock_guard<std::mutex> hold(lock);
      cpu_seconds += rec.wall_seconds;
      done.emplace(p, std::move(rec));
      while (!write_error && done.count(next_to_write)) {
        auto node = done.extract(next_to_write);
        const Recording& r = node.mapped();
        try {
          file.append_point(next_to_write, grid[next_to_write], r);
        } catch (const ResultError& e) {
          write_error = e;
          g_interrupted.store(true);
          break;
        }
        if (r.summary.status != RunStatus::completed) ++stopped_early;
        totals.impacts += r.summary.impacts;
        totals.sticks += r.summary.sticks;
        totals.releases += r.summary.releases;
        totals.chatters += r.summary.chatters;
        ++next_to_write;
        progress.update(next_to_write);
        if (request.interrupt_after > 0 && next_to_write >= request.interrupt_after) g_interrupted.store(true);
      }
    }
  }
  if (write_error) throw *write_error;
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  RunReport report;
  if (next_to_write < total) {
    report.exit_code = 130;
    report.summary = fmt::format(
        "Interrupted: {} of {} sweep points are kept in {}; run the same command with --resume to "
        "finish the rest.",
        next_to_write, total, ResultFile::partial_path(request.output));
    return report;  // the partial file is kept by ResultFile's destructor
  }
  RunMeta meta = current_meta(threads);
  meta.wall_seconds = wall;
  file.finish(meta);
  report.exit_code = stopped_early > 0 ? 1 : 0;
  report.summary = fmt::format(
      "Swept {} over {} points ({} computed now{}) on {} threads in {:.2f} s wall ({:.2f} s CPU in "
      "simulations): {} impacts, {} sticks, {} releases, {} chatter limits; {} points stopped early{}. "
      "Results in {}.",
      scene.file, total, total - first, first ? fmt::format(", {} resumed", first) : "", threads, wall,
      cpu_seconds, totals.impacts, totals.sticks, totals.releases, totals.chatters, stopped_early,
      stopped_early ? " (see /sweep/status and /sweep/message)" : "", request.output);
  return report;
}

}  // namespace

RunReport run_scene(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  if (scene.run.kind == RunSpec::Kind::sweep) return run_sweep(doc, scene, request);
  if (scene.run.kind == RunSpec::Kind::locate && !request.resume) return run_locate(doc, scene, request);
  if (request.resume)
    throw SceneError(scene.file, 1, 1, "run.kind", "--resume continues an interrupted sweep; this scene is not a sweep");
  return run_simulation(scene, request);
}

}  // namespace vibro::io
