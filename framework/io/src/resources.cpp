/// \file resources.cpp
/// Memory and thread checks before a run (resources.hpp). The per-n² constants are measured
/// peaks (`/usr/bin/time -f %M vibro run` on chains with a wall, r = 0.8 stops on masses 0 and
/// n−1, 1 period; Debian 12, GCC 12, -O3), divided by n² and rounded up:
///   dense engine, n = 200 / 400 / 800: 44 / 135 / 500 MB peak → ≤ 800 bytes · n²;
///   modal engine, n = 2000 / 4000 / 8000: 105 / 400 / 1560 MB peak → ≤ 25 bytes · n².
#include "vibro/io/resources.hpp"

#include <fmt/format.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <thread>

namespace vibro::io {
namespace {

constexpr double kDenseBytesPerDof2 = 800.0;
constexpr double kModalBytesPerDof2 = 25.0;

/// A "Key: value kB" line of a /proc file, in bytes (or none).
std::optional<double> proc_kb(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key + ":", 0) != 0) continue;
    std::istringstream fields(line.substr(key.size() + 1));
    double kb = 0.0;
    if (fields >> kb) return kb * 1024.0;
  }
  return std::nullopt;
}

/// A number in a cgroup v2 file ("max" or absent: none).
std::optional<double> cgroup_number(const std::string& file) {
  std::ifstream in(file);
  std::string word;
  if (!(in >> word) || word == "max") return std::nullopt;
  try {
    return std::stod(word);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::uint64_t available_memory() {
  double available = std::numeric_limits<double>::infinity();
  if (const auto free = proc_kb("/proc/meminfo", "MemAvailable")) available = *free;
  const auto limit = cgroup_number("/sys/fs/cgroup/memory.max");
  const auto usage = cgroup_number("/sys/fs/cgroup/memory.current");
  if (limit && usage) available = std::min(available, std::max(0.0, *limit - *usage));
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    const double mapped = proc_kb("/proc/self/status", "VmSize").value_or(0.0);
    available = std::min(available, std::max(0.0, static_cast<double>(as.rlim_cur) - mapped));
  }
  if (!std::isfinite(available)) return std::numeric_limits<std::uint64_t>::max();
  return static_cast<std::uint64_t>(available);
}

std::string bytes_text(double bytes) {
  const char* units[] = {"bytes", "kB", "MB", "GB", "TB"};
  int u = 0;
  while (bytes >= 1000.0 && u < 4) {
    bytes /= 1000.0;
    ++u;
  }
  if (u == 0) return fmt::format("{:.0f} bytes", bytes);
  return bytes >= 1e4 ? fmt::format("{:.2g} {}", bytes, units[u]) : fmt::format("{:.3g} {}", bytes, units[u]);
}

void require_memory(double bytes, const std::string& what) {
  const auto available = static_cast<double>(available_memory());
  if (!(bytes <= available))
    throw ResourceError(what + " needs about " + bytes_text(bytes) + "; " + bytes_text(available) +
                        " of memory is available");
}

double least_engine_bytes(double n) { return std::min(kModalBytesPerDof2, kDenseBytesPerDof2) * n * n; }

std::vector<MemoryNeed> estimate_run_memory(const Scene& scene, int threads) {
  std::vector<MemoryNeed> needs;
  const double n = static_cast<double>(scene.dof());
  const double m = static_cast<double>(scene.stops.size());
  const bool sweep = scene.run.kind == RunSpec::Kind::sweep;
  std::size_t points = 1;
  for (const SweepAxis& a : scene.run.axes) points *= std::max<std::size_t>(a.values.size(), 1);
  if (scene.run.kind == RunSpec::Kind::locate) points = 1;
  const double at_once = sweep ? std::min<double>(std::max(threads, 1), static_cast<double>(points)) : 1.0;

  if (scene.engine == EngineKind::modal)
    needs.push_back({fmt::format("the modal engine's set-up ({} masses: the n × n modes)", scene.dof()),
                     at_once * kModalBytesPerDof2 * n * n});
  else
    needs.push_back({fmt::format("the dense engine's set-up ({} degrees of freedom: n × n matrices, (2n + 3)² flow)",
                                 scene.dof()),
                     at_once * kDenseBytesPerDof2 * n * n});

  // Recordings of known size: one per point running, plus every finished point waiting for its
  // turn to be written (at most one per thread).
  const double periods = std::ceil(scene.run.periods);
  const double state_bytes = 8.0 + 2.0 * (8.0 * n + 32.0);  // t, and x, v as VectorXd
  const RecordSpec& r = scene.record;
  double samples = static_cast<double>(r.sample_times.size());
  if (r.samples_per_period > 0) samples = static_cast<double>(r.samples_per_period) * scene.run.periods;
  double per_point = samples * (state_bytes + 8.0);  // + the requested time
  if (r.poincare) per_point += (periods + 1.0) * state_bytes;
  if (r.statistics) per_point += periods * (m * 12.0 + 64.0);
  if (per_point > 0.0)
    needs.push_back({fmt::format("the recording ({:.6g} samples{}{} of {} degrees of freedom{})", samples,
                                 r.poincare ? ", Poincaré points" : "", r.statistics ? ", per-period statistics" : "",
                                 scene.dof(), sweep ? fmt::format(", for {:.0f} points at once", 2.0 * at_once) : ""),
                     (sweep ? 2.0 * at_once : 1.0) * per_point});
  if (sweep)
    needs.push_back({fmt::format("the sweep's {} validated point scenes", points),
                     static_cast<double>(points) *
                         (static_cast<double>(sizeof(Scene) + scene.yaml_text.size()) + 16.0 * n + m * sizeof(Stop) + 512.0)});
  return needs;
}

WorkEstimate estimate_run_work(const Scene& scene) {
  WorkEstimate w;
  // Row sums of M⁻¹|C| and M⁻¹|K| (M diagonal), row by row: the largest of each and its mass.
  double a = 0.0, b = 0.0;
  auto row = [&](Eigen::Index i, double mass, double c_sum, double k_sum) {
    const double ai = c_sum / mass, bi = k_sum / mass;
    if (!(ai <= a)) {
      a = ai;
      w.damping_mass = i;
    }
    if (!(bi <= b)) {
      b = bi;
      w.stiffness_mass = i;
    }
  };
  if (scene.engine == EngineKind::modal && scene.chain) {
    const BandedChain& c = *scene.chain;
    const Eigen::Index n = c.dof();
    for (Eigen::Index i = 0; i < n; ++i) {
      double k = std::abs(c.stiffness_diagonal(i));
      if (i > 0) k += std::abs(c.stiffness_off(i - 1));
      if (i + 1 < n) k += std::abs(c.stiffness_off(i));
      row(i, c.mass(i), c.rayleigh_mass * c.mass(i) + c.rayleigh_stiffness * k, k);
    }
  } else if (scene.engine == EngineKind::dense) {
    const LinearSystem& sys = scene.system();
    const Eigen::MatrixXd& M = sys.mass();
    if (!M.isDiagonal(0.0)) return w;  // (a bound would need M's least eigenvalue: not estimated)
    for (Eigen::Index i = 0; i < M.rows(); ++i)
      row(i, M(i, i), sys.damping().row(i).cwiseAbs().sum(), sys.stiffness().row(i).cwiseAbs().sum());
  } else {
    return w;
  }
  // Every eigenvalue λ of the first-order flow (λ² M x + λ C x + K x = 0) has |λ|² ≤ a|λ| + b
  // (the row of x's largest entry), so |λ| ≤ a + √b: an upper bound of the rate the certified
  // event search steps by (one step per 1/ρ, simulator.cpp), within a small factor for chains.
  w.rate = a + std::sqrt(b);
  w.damping_rate = a;
  w.stiffness_rate = std::sqrt(b);
  // A simulation (or sweep point) runs its transient and recorded periods; every other kind
  // integrates at least one forcing period per point (a lower bound of its work).
  const bool simulates = scene.run.kind == RunSpec::Kind::simulate || scene.run.kind == RunSpec::Kind::sweep;
  w.span = (simulates ? scene.run.transient_periods + scene.run.periods : 1.0) * scene.period();
  w.steps = w.rate * w.span;
  return w;
}

void check_run_resources(const Scene& scene, int threads) {
  const std::vector<MemoryNeed> needs = estimate_run_memory(scene, threads);
  double total = 0.0;
  std::string parts;
  for (const MemoryNeed& need : needs) {
    total += need.bytes;
    parts += (parts.empty() ? "" : ", ") + need.what + ": " + bytes_text(need.bytes);
  }
  try {
    require_memory(total, "this run");
  } catch (const ResourceError& e) {
    throw ResourceError(std::string(e.what()) + " (" + parts + ")");
  }
  // Then the time (after the memory: a dense scene's bound builds its n × n system).
  if (std::string why = work_refusal(scene); !why.empty()) throw ResourceError(why);
}

std::string work_refusal(const Scene& scene) {
  const WorkEstimate work = estimate_run_work(scene);
  if (!(work.steps <= kMaxSearchSteps)) {
    const bool damped = work.damping_rate >= work.stiffness_rate;
    return fmt::format(
        "this run needs about {:.3g} steps of the certified event search (its fastest rate is up to {:.3g} per time "
        "unit, from the {} of mass {}, over {:.3g} time units); refused above {:.0e} "
        "(days to months of computing): lower the {} at mass {} (or raise that mass), raise the forcing frequency "
        "(the period is {:.3g} time units), or shorten the run",
        work.steps, work.rate, damped ? "damping" : "stiffness over the mass",
        damped ? work.damping_mass : work.stiffness_mass, work.span, kMaxSearchSteps, damped ? "dampers" : "springs",
        damped ? work.damping_mass : work.stiffness_mass, scene.period());
  }
  return {};
}

int checked_threads(int requested, std::size_t units) {
  if (requested < 0 || requested > kMaxThreads)
    throw ResourceError(fmt::format("--threads {}: at most {} threads (this machine has {} cores)", requested,
                                    kMaxThreads, std::thread::hardware_concurrency()));
  int threads = requested;
#ifdef _OPENMP
  if (threads == 0) threads = omp_get_max_threads();
#else
  threads = 1;
#endif
  threads = std::clamp<int>(threads, 1, kMaxThreads);
  return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(threads), std::max<std::size_t>(units, 1)));
}

}  // namespace vibro::io
