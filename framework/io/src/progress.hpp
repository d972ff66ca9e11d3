#pragma once
// Private to vibro_io: what a run tells the user while it runs, on stderr — the shared status
// line of a simulation's counts, a progress bar over the points of a grid, a progress line for
// one long simulation — for every run kind alike.
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

/// A progress bar with an estimate of the time left over `total` points (a sweep's), on stderr.
class Progress {
 public:
  Progress(bool on, std::size_t total, std::size_t done)
      : on_(on), total_(total), start_done_(done), start_(std::chrono::steady_clock::now()) {}
  void update(std::size_t done);

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
  SimulationProgress(bool on, double t_begin, double t_end);
  ~SimulationProgress();
  SimulationProgress(const SimulationProgress&) = delete;
  SimulationProgress& operator=(const SimulationProgress&) = delete;
  std::atomic<double>* reached() { return &reached_; }

 private:
  void watch();

  double t_begin_, t_end_;
  std::atomic<double> reached_{0.0};
  std::mutex lock_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread watcher_;
};

}  // namespace vibro::io::detail
