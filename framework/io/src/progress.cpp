#include "progress.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace vibro::io::detail {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string status_line(const RunSummary& s) {
  return fmt::format("{} impacts, {} sticks, {} releases, {} chatter limits; {} contact sets built "
                     "({} sticking subsystems)",
                     s.impacts, s.sticks, s.releases, s.chatters, s.contact_sets_built,
                     s.sticking_flows_built);
}

namespace {

/// A count as text: whole numbers without decimals, others with one.
std::string amount(double x) {
  return x == std::floor(x) && std::abs(x) < 1e15 ? fmt::format("{:.0f}", x) : fmt::format("{:.1f}", x);
}

}  // namespace

std::string progress_text(const std::string& what, const std::string& unit, double done, double total, double first,
                          double elapsed, bool bar) {
  const double share = total > 0.0 ? std::clamp(done / total, 0.0, 1.0) : 1.0;
  const double rate = elapsed > 0.0 && done > first ? (done - first) / elapsed : 0.0;
  const std::string left = done >= total ? std::string("done")
                           : rate > 0.0  ? fmt::format("about {:.0f} s left", (total - done) / rate)
                                         : std::string("time left unknown yet");
  const std::string counts = fmt::format("{}/{} {} ({:.0f} %), {:.3g} {}/s, {}", amount(done), amount(total), unit,
                                         100.0 * share, rate, unit, left);
  if (!bar) return fmt::format("vibro: {} {}", what, counts);
  const int width = 30;
  const int filled = static_cast<int>(width * share);
  return fmt::format("[{}{}] {} {}", std::string(static_cast<std::size_t>(filled), '#'),
                     std::string(static_cast<std::size_t>(width - filled), ' '), what, counts);
}

Progress::Progress(const RunRequest& request, std::string what, std::string unit, double total, double first,
                   double quiet)
    : request_(request), what_(std::move(what)), unit_(std::move(unit)), total_(total), first_(first), quiet_(quiet),
      start_(std::chrono::steady_clock::now()), done_(first) {
  if (total_ > 0.0) tenths_shown_ = static_cast<int>(std::floor(10.0 * first / total_));
}

Progress::~Progress() {
  if (drawn_at_ >= 0.0) std::fputc('\n', stderr);  // end the redrawn line
}

void Progress::add(double count) {
  const std::lock_guard<std::mutex> hold(lock_);
  done_ += count;
  show(done_);
}

void Progress::update(double done) {
  const std::lock_guard<std::mutex> hold(lock_);
  if (done < done_) return;  // reported out of order by another thread
  done_ = done;
  show(done);
}

void Progress::show(double done) {
  if (request_.on_progress) request_.on_progress(done, total_);
  const double elapsed = seconds_since(start_);
  if (request_.progress) {
    const bool last = done >= total_;
    if (elapsed < quiet_ || (!last && drawn_at_ >= 0.0 && elapsed - drawn_at_ < 0.2)) return;
    std::fprintf(stderr, "\r%s   ", progress_text(what_, unit_, done, total_, first_, elapsed, true).c_str());
    std::fflush(stderr);
    drawn_at_ = elapsed;
  } else if (request_.progress_lines && total_ > 0.0) {
    const int tenths = static_cast<int>(std::floor(10.0 * std::min(done, total_) / total_));
    if (tenths <= tenths_shown_) return;
    tenths_shown_ = tenths;
    std::fprintf(stderr, "%s\n", progress_text(what_, unit_, done, total_, first_, elapsed, false).c_str());
    std::fflush(stderr);
  }
}

SimulationProgress::SimulationProgress(const RunRequest& request, const std::string& what, double t_begin,
                                       double t_end, double period)
    : on_(request.progress || request.progress_lines || static_cast<bool>(request.on_progress)),
      t_begin_(t_begin), period_(period > 0.0 ? period : 1.0),
      progress_(request, what, "periods", (t_end - t_begin) / (period > 0.0 ? period : 1.0), 0.0, 2.0) {
  reached_.store(t_begin);
  if (on_) watcher_ = std::thread([this] { watch(); });
}

SimulationProgress::~SimulationProgress() { stop(); }

void SimulationProgress::stop() {
  {
    std::lock_guard<std::mutex> hold(lock_);
    done_ = true;
  }
  wake_.notify_all();
  if (watcher_.joinable()) watcher_.join();
}

void SimulationProgress::watch() {
  std::unique_lock<std::mutex> hold(lock_);
  while (!wake_.wait_for(hold, std::chrono::milliseconds(250), [this] { return done_; }))
    progress_.update((reached_.load(std::memory_order_relaxed) - t_begin_) / period_);
}

}  // namespace vibro::io::detail
