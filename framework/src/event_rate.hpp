#pragma once
// Private to vibro_core: the Zeno guard of the event loop (event_loop.hpp) of both engines.
#include <algorithm>
#include <cstddef>
#include <memory>

namespace vibro::detail {

/// Ring buffer of recent event times (allocated once per run): exceeded(t) records an event at t
/// and is true if more than `capacity` events fall within the last `window` time units.
///
/// The buffer is left uninitialised: a slot is read only after it was written (count_ says how
/// many are). Zero-filling the default capacity (10⁵ events, 800 kB) was ~19 % of the
/// instructions of a 75-event run (callgrind of work_precision's problem (c): 0.8 M of 4.2 M per
/// run) and about 5 % of its CPU time; the short runs of shooting and continuation paid it on
/// every Newton iteration.
class EventRate {
 public:
  EventRate(long capacity, double window)
      : size_(static_cast<std::size_t>(capacity) + 1),
        times_(std::make_unique_for_overwrite<double[]>(size_)),
        window_(window) {}
  bool exceeded(double t) {
    times_[head_] = t;
    head_ = (head_ + 1) % size_;
    count_ = std::min(count_ + 1, size_);
    if (count_ < size_) return false;
    return t - times_[head_] < window_;  // the oldest of capacity+1 events is within the window
  }

 private:
  std::size_t size_;
  std::unique_ptr<double[]> times_;
  std::size_t head_ = 0, count_ = 0;
  double window_;
};

}  // namespace vibro::detail
