#include "progress.hpp"

#include <fmt/format.h>

#include <cstdio>

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

void Progress::update(std::size_t done) {
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

SimulationProgress::SimulationProgress(bool on, double t_begin, double t_end) : t_begin_(t_begin), t_end_(t_end) {
  reached_.store(t_begin);
  if (on) watcher_ = std::thread([this] { watch(); });
}

SimulationProgress::~SimulationProgress() {
  {
    std::lock_guard<std::mutex> hold(lock_);
    done_ = true;
  }
  wake_.notify_all();
  if (watcher_.joinable()) watcher_.join();
}

void SimulationProgress::watch() {
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

}  // namespace vibro::io::detail
