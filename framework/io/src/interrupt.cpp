#include "interrupt.hpp"

#include "vibro/io/signals.hpp"

#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstring>

namespace vibro::io::detail {

std::atomic<bool> g_interrupted{false};

namespace {

std::atomic<int> g_depth{0};
std::atomic<bool> g_exit_at_once{false};
char g_line[2048];
std::size_t g_line_size = 0;

[[noreturn]] void exit_now() {
  if (g_line_size > 0 && ::write(STDERR_FILENO, g_line, g_line_size) < 0) {
    // nothing more to do: the exit code says it
  }
  ::_exit(130);
}

extern "C" void on_signal(int) {
  g_interrupted.store(true);  // before the test below: see disarm_exit_at_once
  if (g_exit_at_once.load()) exit_now();
}

}  // namespace

InterruptGuard::InterruptGuard() {
  if (g_depth.fetch_add(1) != 0) return;
  outermost_ = true;
  g_interrupted.store(false);
  old_int_ = std::signal(SIGINT, on_signal);
  old_term_ = std::signal(SIGTERM, on_signal);
  old_hup_ = std::signal(SIGHUP, on_signal);  // a closed terminal or ssh session: stop cleanly too
}

InterruptGuard::~InterruptGuard() {
  g_depth.fetch_sub(1);
  if (!outermost_) return;
  std::signal(SIGINT, old_int_);
  std::signal(SIGTERM, old_term_);
  std::signal(SIGHUP, old_hup_);
}

void arm_exit_at_once(const std::string& line) {
  g_line_size = 0;
  if (!line.empty()) {
    g_line_size = std::min(line.size(), sizeof g_line - 1);
    std::memcpy(g_line, line.data(), g_line_size);
    g_line[g_line_size++] = '\n';
  }
  g_exit_at_once.store(true);
}

void disarm_exit_at_once() {
  // Sequentially consistent: either the handler saw the exit armed (and ends the process), or
  // this thread sees the flag the handler raised before looking.
  if (g_exit_at_once.exchange(false) && g_interrupted.load()) exit_now();
}

}  // namespace vibro::io::detail

namespace vibro::io {

struct RunSignals::Guard {
  detail::InterruptGuard guard;
};

RunSignals::RunSignals(const std::string& line) : guard_(std::make_unique<Guard>()) { detail::arm_exit_at_once(line); }

RunSignals::~RunSignals() { detail::g_exit_at_once.store(false); }

}  // namespace vibro::io
