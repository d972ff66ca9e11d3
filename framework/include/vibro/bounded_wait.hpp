#pragma once
/// \file bounded_wait.hpp
/// A computation that cannot poll a stop flag — a dense Eigen decomposition of a large system
/// (the eigenvectors, Schur form and exponential of a contact set's flow: seconds at n = 300),
/// a LAPACK call — run so that the caller still answers the flag within a bounded time.
///
/// run_bounded(stop, fn) runs fn() on a thread of its own while the calling thread waits for it,
/// looking at `stop` every 10 ms. It returns fn's result (or rethrows its exception) as a direct
/// call would: the same code on the same data, so the same bits. Once `stop` is raised it throws
/// Interrupted at once and leaves that thread to finish on its own; its result is dropped. So fn
/// must own everything it reads (capture by value, move the inputs in), never refer to the
/// caller's objects. With no flag (stop = nullptr) fn runs on the calling thread.
#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>

namespace vibro {

/// Raised by run_bounded when its stop flag is raised before the computation ended. The event
/// loops end the run with RunStatus::interrupted on it.
class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted during a set-up computation") {}
};

template <class F>
auto run_bounded(const std::atomic<bool>* stop, F fn) -> decltype(fn()) {
  using Result = decltype(fn());
  if (!stop) return fn();
  if (stop->load(std::memory_order_relaxed)) throw Interrupted();
  auto task = std::make_shared<std::packaged_task<Result()>>(std::move(fn));
  std::future<Result> result = task->get_future();
  try {
    std::thread([task] { (*task)(); }).detach();  // the thread owns the task (and fn's data)
  } catch (const std::system_error&) {            // no thread to be had: a direct call
    (*task)();
  }
  while (result.wait_for(std::chrono::milliseconds(10)) != std::future_status::ready)
    if (stop->load(std::memory_order_relaxed)) throw Interrupted();
  return result.get();
}

}  // namespace vibro
