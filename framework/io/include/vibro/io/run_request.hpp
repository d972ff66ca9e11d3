#pragma once
/// \file run_request.hpp
/// What a run is asked to do (RunRequest: the output, threads, resume, interruption) and what it
/// reports (RunReport): the interface every run kind (run_kinds.hpp) implements, and the result
/// file every run kind writes (open_result_file).
#include "vibro/io/results.hpp"
#include "vibro/io/scene.hpp"

#include <atomic>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace vibro::io {

struct RunRequest {
  std::string output;      ///< result file path
  int threads = 0;         ///< 0: OpenMP's default
  bool resume = false;     ///< continue OUT.partial of an interrupted sweep
  bool progress = false;   ///< progress bar with ETA on stderr (a terminal: one line, redrawn)
  /// Progress on stderr as a compact line at each tenth of the run (not a terminal: a log).
  bool progress_lines = false;
  /// Called with (done, total) as the run goes on — grid points, or forcing periods of one long
  /// simulation — from the run's threads, one call at a time; it must be quick (the Python module
  /// stores the numbers for its own thread).
  std::function<void(double done, double total)> on_progress = nullptr;
  /// Behave as if interrupted once this many points are written (0: never). For tests of
  /// interruption and --resume, which must not depend on timing a real signal.
  std::size_t interrupt_after = 0;
  /// Write the result file into memory (RunReport::image) instead of `output`, for programs
  /// using the library (session.hpp); a sweep is then not resumable and `resume` must be false.
  bool in_memory = false;
  /// The caller's stop flag (null for `vibro run`, where SIGINT/SIGTERM stop sweeps): set from
  /// another thread, it ends a simulation at its next event (status interrupted) and a sweep
  /// before its next point; the runner raises it too when it stops a sweep itself. No signal
  /// handler is installed when it is given.
  std::atomic<bool>* interrupt = nullptr;
  /// Replace an existing output file (--force); never the scene file itself.
  bool force = false;
};

struct RunReport {
  int exit_code = 0;       ///< 0 all completed, 1 some run stopped early, 130 interrupted
  std::string summary;     ///< one paragraph for the user
  std::vector<char> image; ///< RunRequest::in_memory: the result file's bytes
};

class ResultFile;
struct RunMeta;
/// The result file of a run (for each run kind's code): `request.output`, written as OUT.partial
/// until finished, or in memory (RunRequest::in_memory).
ResultFile open_result_file(const RunRequest& request, const Scene& scene, const RunMeta& meta);

}  // namespace vibro::io
