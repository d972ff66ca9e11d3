#pragma once
// Private to vibro_core: the Zeno guard shared by the dense (simulator.cpp) and modal
// (modal_simulator.cpp) engines.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace vibro::detail {

/// Ring buffer of recent event times (allocated once per run): exceeded(t) records an event at t
/// and is true if more than `capacity` events fall within the last `window` time units.
class EventRate {
 public:
  EventRate(long capacity, double window)
      : times_(static_cast<std::size_t>(capacity) + 1), window_(window) {}
  bool exceeded(double t) {
    times_[head_] = t;
    head_ = (head_ + 1) % times_.size();
    count_ = std::min(count_ + 1, times_.size());
    if (count_ < times_.size()) return false;
    return t - times_[head_] < window_;  // the oldest of capacity+1 events is within the window
  }

 private:
  std::vector<double> times_;
  std::size_t head_ = 0, count_ = 0;
  double window_;
};

}  // namespace vibro::detail
