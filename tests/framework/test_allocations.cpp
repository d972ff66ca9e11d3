/// \file test_allocations.cpp
/// Both engines allocate nothing per event (issue 13): every heap allocation of this executable
/// is counted — a replaced global operator new, and malloc, calloc, realloc and the aligned
/// allocators interposed (Eigen allocates through malloc, not operator new) — and a run after
/// its warm-up (the contact sets it visits built, the per-mode scratch sized) must make none
/// between its first event after the warm-up and its end. An observer that allocates nothing
/// itself switches the count on and off. The dense engine's runs also record states on a grid
/// (vibro::Samples, storage sized at the run's start): recording must allocate nothing either. This is its own executable: the replaced allocators
/// must not reach the other tests (ctest runs them as separate processes anyway).
#include "vibro/modal.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <numbers>
#include <vector>

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};

void count() {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    // VIBRO_ALLOC_ABORT=1 stops at the first counted allocation, for a debugger's backtrace.
    static const bool abort_on = std::getenv("VIBRO_ALLOC_ABORT") != nullptr;
    if (abort_on) std::abort();
  }
}

void* checked(void* p) {
  if (!p) throw std::bad_alloc();
  return p;
}

}  // namespace

extern "C" {
void* malloc(std::size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) {
  count();
  return __libc_realloc(p, n);
}
void free(void* p) { __libc_free(p); }
void* aligned_alloc(std::size_t alignment, std::size_t n) {
  count();
  return __libc_memalign(alignment, n);
}
void* memalign(std::size_t alignment, std::size_t n) {
  count();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) {
  count();
  *out = __libc_memalign(alignment, n);
  return *out ? 0 : 12;  // ENOMEM
}
}

void* operator new(std::size_t n) {
  count();
  return checked(__libc_malloc(n ? n : 1));
}
void* operator new[](std::size_t n) {
  count();
  return checked(__libc_malloc(n ? n : 1));
}
void* operator new(std::size_t n, std::align_val_t a) {
  count();
  return checked(__libc_memalign(static_cast<std::size_t>(a), n ? n : 1));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  count();
  return checked(__libc_memalign(static_cast<std::size_t>(a), n ? n : 1));
}
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }

namespace {

using Eigen::VectorXd;

/// Counts from the first event at or after `warm_up` to the end of the run; allocates nothing.
class AllocationWindow final : public vibro::Observer {
 public:
  explicit AllocationWindow(double warm_up) : warm_up_(warm_up) {}
  void event(const vibro::Event& e) override {
    if (e.t < warm_up_) return;
    if (!g_counting.load()) {
      g_allocations.store(0);
      g_counting.store(true);
    }
    ++events;
  }
  void end(double) override { g_counting.store(false); }
  long events = 0;

 private:
  double warm_up_;
};

struct Counted {
  long allocations = 0, events = 0;
  vibro::RunStatus status = vibro::RunStatus::completed;
};

/// With `samples` states on an even grid over [0, t_end] (the window first among the observers,
/// so that its end() stops the count before any other observer's).
Counted dense_run(const vibro::ImpactSystem& scene, const VectorXd& x0, const VectorXd& v0, double warm_up,
                  double t_end, int samples = 4000) {
  vibro::Simulator sim(scene);
  AllocationWindow window(warm_up);
  std::vector<double> times;
  for (int i = 0; i < samples; ++i) times.push_back(t_end * i / samples);
  vibro::Samples grid(times);
  const vibro::RunSummary s = sim.run(0.0, x0, v0, t_end, {&window, &grid});
  g_counting.store(false);
  REQUIRE(grid.t.size() == times.size());
  return {g_allocations.load(), window.events, s.status};
}

}  // namespace

TEST_CASE("allocations: the dense engine allocates nothing per event (paper's system, chatter and sticking)",
          "[allocations]") {
  for (const double omega : {0.255, 0.27}) {
    vibro::models::Wagg2004 p;
    p.frequency = omega;
    const vibro::ImpactSystem scene = vibro::models::wagg2004(p);
    const double T = 2.0 * std::numbers::pi / omega;
    const Counted c = dense_run(scene, VectorXd::Zero(2), VectorXd::Zero(2), 5.0 * T, 30.0 * T);
    INFO("Ω = " << omega << ": " << c.events << " events after the warm-up");
    REQUIRE(c.status == vibro::RunStatus::completed);
    CHECK(c.events > 1000);
    CHECK(c.allocations == 0);
  }
}

TEST_CASE("allocations: the dense engine allocates nothing per event (10-mass chain, stop between masses)",
          "[allocations]") {
  vibro::models::Chain c;
  c.masses.assign(10, 1.0);
  c.springs.assign(9, 1.0);
  c.dampers.assign(9, 0.05);
  c.left_spring = c.right_spring = 1.0;
  c.left_damper = c.right_damper = 0.05;
  c.force_cosine.assign(10, 0.0);
  c.force_cosine[0] = 0.5;
  c.frequency = 0.3;
  const vibro::ImpactSystem scene(vibro::models::build_chain(c),
                                  {vibro::Stop::upper(1, 0.8, 0.7), vibro::Stop::between(3, 4, 0.3, 0.6),
                                   vibro::Stop::lower(6, -0.3, 0.7), vibro::Stop::upper(9, 0.15, 0.8)});
  const double T = 2.0 * std::numbers::pi / c.frequency;
  const Counted r = dense_run(scene, VectorXd::Zero(10), VectorXd::Zero(10), 5.0 * T, 20.0 * T);
  INFO(r.events << " events after the warm-up");
  REQUIRE(r.status == vibro::RunStatus::completed);
  CHECK(r.events > 500);
  CHECK(r.allocations == 0);
}

TEST_CASE("allocations: the dense engine allocates nothing per event (free flight in closed form: a ball)",
          "[allocations]") {
  // A ball under gravity on a vibrating table (K = 0: the free flight's generator is defective,
  // evaluated by the closed-form exponential), thrown, chattering back and held, again and again.
  const double g = 9.81, a = 0.01, omega = std::sqrt(1.6 * g / a);
  Eigen::MatrixXd one = Eigen::MatrixXd::Identity(1, 1), zero = Eigen::MatrixXd::Zero(1, 1);
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
  f.constant(0) = -g;
  const vibro::ImpactSystem scene(vibro::LinearSystem(one, zero, zero, f), {vibro::Stop::lower(0, 0.0, 0.5).moving(a, 0.0)});
  const double T = 2.0 * std::numbers::pi / omega;
  const Counted r = dense_run(scene, VectorXd::Constant(1, a), VectorXd::Zero(1), 5.0 * T, 60.0 * T);
  INFO(r.events << " events after the warm-up");
  REQUIRE(r.status == vibro::RunStatus::completed);
  CHECK(r.events > 200);
  CHECK(r.allocations == 0);
}

TEST_CASE("allocations: the modal engine allocates nothing per event (chain of 100, chatter, sticking, release)",
          "[allocations]") {
  // Four stops near the driven end with r = 0.5: impacts in free flight (the rank-one fast
  // path), chatter caught by the chatter rule, sticking, releases, basis changes between sets.
  for (const auto route : {vibro::TridiagonalSolver::automatic, vibro::TridiagonalSolver::secular}) {
    const int n = 100;
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(n, 0.8);
    f.cosine(0) = 0.6;
    const vibro::ChainModes modes(vibro::BandedChain::from_links(std::vector<double>(n, 1.0),
                                                                 std::vector<double>(n - 1, 1.0),
                                                                 std::vector<double>(n - 1, 0.02), 1.0, 0.02, 0.0,
                                                                 0.0, f));
    const std::vector<vibro::Stop> stops{vibro::Stop::upper(1, 0.35, 0.5), vibro::Stop::lower(2, -0.3, 0.5),
                                         vibro::Stop::between(3, 4, 0.25, 0.5), vibro::Stop::upper(5, 0.25, 0.5)};
    vibro::ModalSimulatorOptions options;
    options.contact_modes = route;
    vibro::ModalChainSimulator sim(modes, stops, options);
    const double T = 2.0 * std::numbers::pi / 0.8;
    AllocationWindow window(10.0 * T);
    const vibro::ModalRunSummary s = sim.run(0.0, VectorXd::Zero(n), VectorXd::Zero(n), 40.0 * T, {&window});
    g_counting.store(false);
    INFO((route == vibro::TridiagonalSolver::secular ? "secular" : "tridiagonal")
         << ": " << window.events << " events after the warm-up; " << s.sticks << " sticks, " << s.general_events
         << " events resolved in physical coordinates");
    REQUIRE(s.status == vibro::RunStatus::completed);
    CHECK(window.events > 100);
    CHECK(s.sticks > 0);
    CHECK(g_allocations.load() == 0);
  }
}
