#pragma once
/// \file resources.hpp
/// What a run will take, checked before it takes it: memory, threads and time (search steps). A scene that cannot fit
/// is refused up front with the numbers (what needs how much, how much there is), instead of
/// dying of std::bad_alloc halfway, or after hours, with a half-written file.
///
/// Memory available is the least of: the kernel's estimate of what can be allocated without
/// swapping (/proc/meminfo MemAvailable), the cgroup's limit less its usage (containers), and
/// the address-space limit (`ulimit -v`) less what the process has mapped. The estimates are
/// upper-bound models of the big allocations, calibrated by measuring peak memory (see
/// resources.cpp); they are compared against the available memory with no safety factor, so a
/// run that passes may still be tight, and one that fails would certainly not have fitted.
///
/// Usage:
///     vibro::io::check_run_resources(scene, threads);   // throws ResourceError with the numbers
///     const int threads = vibro::io::checked_threads(requested, sweep_units);
#include "vibro/io/scene.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro::io {

/// A run needs more memory or threads than this machine gives: "WHAT needs about X; Y available".
class ResourceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bytes this process may still allocate (see the file comment).
std::uint64_t available_memory();

/// Throws ResourceError naming `what`, `bytes` and the available memory if bytes exceed it.
/// `bytes` is a double so that products of huge counts saturate instead of wrapping.
void require_memory(double bytes, const std::string& what);

/// The least memory any engine's set-up takes for n degrees of freedom: the modal engine's n × n
/// modes (the smallest of the per-n² constants of estimate_run_memory). The scene reader checks it
/// as soon as a model's size is known, before its links and matrices are built (at ~200 bytes per
/// mass, a filled list of 10⁸ masses would take 20 GB and minutes before the run's own check).
double least_engine_bytes(double n);

/// The reader's early check (least_engine_bytes) runs only above this size, 10⁸ bytes, a chain of
/// 2000 masses: reading the available memory (three /proc and cgroup files) costs ~20 µs, as much
/// as building a small scene, and a sweep or basin builds its scene once per point. Smaller
/// chains are covered by the run's own check (check_run_resources), made once per run.
inline constexpr double kEarlyCheckBytes = 1e8;

/// "1.5 GB", "312 MB", "4.0 kB" (decimal units), "1.2e+15 GB" for absurd sizes.
std::string bytes_text(double bytes);

/// Peak bytes of yaml-cpp's tree per byte of scene text (measured: a 10⁶-mass chain, 3.9 MB of
/// text, peaks at 1.4 GB while loading: ≈ 360 bytes per byte; rounded up).
inline constexpr std::uint64_t kParseBytesPerByte = 400;

/// One line of a run's memory estimate.
struct MemoryNeed {
  std::string what;
  double bytes = 0.0;
};

/// The large allocations of running `scene` on `threads` threads (sweep points run at once
/// hold their own engine and recording): the engine's set-up (dense: the n × n system and the
/// (2n + 3)² flow of the free contact set; modal: the chain's n × n modes), recordings whose size
/// is known before running (samples, Poincaré points, per-period statistics), and a sweep's
/// validated point scenes. Events and contact intervals depend on the motion and are not counted.
std::vector<MemoryNeed> estimate_run_memory(const Scene& scene, int threads);

/// The work of a simulation or a sweep point, estimated before it runs: the certified event
/// search steps by 1/ρ (ρ the flow's fastest rate), so a run over a span S takes at least about
/// ρ·S steps. ρ is bounded from the scene's matrices in O(n) for chains, O(n²) for a dense
/// system with diagonal M (no estimate otherwise: steps = 0). S: the transient and recorded
/// periods of a simulation or sweep point; one forcing period for other run kinds (a lower bound).
struct WorkEstimate {
  double rate = 0.0;                      ///< upper bound of ρ (per time unit)
  double damping_rate = 0.0, stiffness_rate = 0.0;  ///< its parts: max M⁻¹|C| row sum, √(max M⁻¹|K| row sum)
  Eigen::Index damping_mass = 0, stiffness_mass = 0;  ///< the rows where they peak
  double span = 0.0;                      ///< S
  double steps = 0.0;                     ///< rate × span
};
WorkEstimate estimate_run_work(const Scene& scene);

/// Search steps above which a run is refused: at 10⁶–10⁷ steps a second (measured: a one-mass
/// free flight, 4.3e6 steps in 0.6 s of CPU), 10¹² are days to months. Above kWarnSearchSteps
/// (minutes) `vibro run` says so before it starts; a progress line follows on a terminal.
inline constexpr double kMaxSearchSteps = 1e12;
inline constexpr double kWarnSearchSteps = 1e9;

/// Throws ResourceError if the estimate exceeds available_memory() (the message lists its parts),
/// or if the run's search steps (estimate_run_work) exceed kMaxSearchSteps, with the estimate and
/// what sets it.
void check_run_resources(const Scene& scene, int threads);

/// Why `scene` would be refused for its search steps (check_run_resources's message), or "" when
/// it is within kMaxSearchSteps. A sweep asks it of every point before running it: a point that
/// would crawl for days is recorded as stopped early, with this message, and the others run.
std::string work_refusal(const Scene& scene);

/// The thread count to use for `requested` threads (0: all cores) over `units` independent units
/// of work: at most `units` (more threads would only wait). Throws ResourceError above
/// kMaxThreads (the OpenMP runtime aborts or crashes when thread creation fails).
int checked_threads(int requested, std::size_t units);
inline constexpr int kMaxThreads = 1024;

}  // namespace vibro::io
