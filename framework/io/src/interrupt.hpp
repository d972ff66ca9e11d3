#pragma once
// Private to vibro_io: SIGINT, SIGTERM and SIGHUP as a stop flag. A run that can be stopped (a
// simulation, a sweep, the long run kinds) polls the flag at every event, search step or point;
// `vibro run` raises it from the signal handlers an InterruptGuard installs. A caller with its own
// flag (RunRequest::interrupt: the Python module) installs none.
#include <atomic>

namespace vibro::io::detail {

/// Raised by SIGINT, SIGTERM or SIGHUP while an InterruptGuard lives (cleared when one is made).
extern std::atomic<bool> g_interrupted;

/// Installs SIGINT/SIGTERM/SIGHUP handlers that raise g_interrupted, for its lifetime.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  void (*old_int_)(int);
  void (*old_term_)(int);
  void (*old_hup_)(int);
};

}  // namespace vibro::io::detail
