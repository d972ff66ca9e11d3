#pragma once
// Private to vibro_io: what a run tells the user while it runs — the shared status line of a
// simulation's counts, and the progress of every run kind alike: `done` of `total` units (grid
// points, or forcing periods of one long simulation), the rate and the time left, shown
//   on a terminal (RunRequest::progress): one line on stderr, redrawn, with a bar;
//   not on a terminal (RunRequest::progress_lines): a compact line on stderr at each tenth done,
//     "vibro: diagram 40/200 points (20 %), 3.1 points/s, about 51 s left", so that a log
//     gets at most ten lines per run;
//   to a caller (RunRequest::on_progress, the Python module): done and total as they change.
#include "vibro/io/run_request.hpp"
#include "vibro/simulator.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <string>
#include <thread>

namespace vibro::io::detail {

double seconds_since(std::chrono::steady_clock::time_point start);

/// "N impacts, N sticks, N releases, N chatter limits; N contact sets built (N sticking subsystems)".
std::string status_line(const RunSummary& s);

/// The text of a progress report: `what` (the run kind), done of total `unit`, the rate over
/// `elapsed` seconds (of the units done in this run, `done − first`) and the time left; with a
/// bar for a terminal, else "vibro: what done/total unit (P %), R unit/s, about S s left".
std::string progress_text(const std::string& what, const std::string& unit, double done, double total, double first,
                          double elapsed, bool bar);

/// A run's progress over `total` units, of which `first` were done before it started (a resumed
/// sweep). update() and add() may be called from any thread; what they show depends on the
/// request (see the file's comment). On a terminal the line is drawn once `quiet` seconds have
/// passed (a short run stays silent) and at most every 0.2 s.
class Progress {
 public:
  Progress(const RunRequest& request, std::string what, std::string unit, double total, double first = 0.0,
           double quiet = 0.0);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  /// `done` units are done (never less than before).
  void update(double done);
  /// One more unit (or `count`) is done.
  void add(double count = 1.0);

 private:
  void show(double done);  // under lock_

  const RunRequest& request_;
  std::string what_, unit_;
  double total_, first_, quiet_;
  std::chrono::steady_clock::time_point start_;
  std::mutex lock_;
  double done_ = 0.0;
  int tenths_shown_ = 0;
  double drawn_at_ = -1.0;  // elapsed seconds at the last terminal redraw (< 0: none)
};

/// The progress of one long simulation, in forcing periods: a thread of its own reads the time
/// the engine reached (SimulatorOptions::reached) every 0.25 s and reports it through a Progress
/// ("simulate", periods), silent on a terminal for the first 2 s.
class SimulationProgress {
 public:
  SimulationProgress(const RunRequest& request, const std::string& what, double t_begin, double t_end, double period);
  ~SimulationProgress();
  SimulationProgress(const SimulationProgress&) = delete;
  SimulationProgress& operator=(const SimulationProgress&) = delete;
  /// Where the engine stores the time it reached (null when nothing is shown).
  std::atomic<double>* reached() { return on_ ? &reached_ : nullptr; }
  /// Stops reporting (the destructor does it too): an engine may go on storing to reached()
  /// while the object lives, e.g. shooting after the run this progress was about.
  void stop();

 private:
  void watch();

  bool on_;
  double t_begin_, period_;
  std::atomic<double> reached_{0.0};
  Progress progress_;
  std::mutex lock_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread watcher_;
};

}  // namespace vibro::io::detail
