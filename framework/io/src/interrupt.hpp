#pragma once
// Private to vibro_io: SIGINT, SIGTERM and SIGHUP as a stop flag. A run that can be stopped (a
// simulation, a sweep, the long run kinds) polls the flag at every event, search step, Krylov
// product or point; `vibro run` raises it from the signal handlers an InterruptGuard installs. A
// caller with its own flag (RunRequest::interrupt: the Python module) installs none.
//
// Before the run has touched any file (the scene loaded, built and checked, its work estimated:
// Eigen decompositions of n × n matrices that nothing can poll), `vibro run` arms an exit at once
// (vibro/io/signals.hpp): a signal then writes one line and ends the process with exit code 130,
// from the handler itself (write(2) and _exit(2) are async-signal-safe). The lock disarms it
// when the output's lock is made (or, on MPI ranks other than 0, which write nothing, when the
// run kind starts), and from there the flag is polled.
#include <atomic>
#include <string>

namespace vibro::io::detail {

/// Raised by SIGINT, SIGTERM or SIGHUP while an InterruptGuard lives (cleared when the outermost
/// one is made).
extern std::atomic<bool> g_interrupted;

/// Installs SIGINT/SIGTERM/SIGHUP handlers that raise g_interrupted, for its lifetime. Guards nest:
/// only the outermost installs (and clears the flag), so a signal taken while the scene was
/// checked is still seen by the run kind's own guard.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  bool outermost_ = false;
  void (*old_int_)(int) = nullptr;
  void (*old_term_)(int) = nullptr;
  void (*old_hup_)(int) = nullptr;
};

/// From now on a signal writes `line` (plus a newline) to stderr and ends the process with exit
/// code 130 at once. Only while nothing is on disk.
void arm_exit_at_once(const std::string& line);

/// Ends the exit at once, just before the first file is created (the output's lock). A signal
/// that came while it was armed ends the process here, as the handler would have: nothing is
/// on disk yet. After it returns, no signal exits from the handler.
void disarm_exit_at_once();

}  // namespace vibro::io::detail
