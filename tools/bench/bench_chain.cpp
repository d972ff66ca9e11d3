/// \file bench_chain.cpp
/// Long chains with the modal engine (framework/include/vibro/modal.hpp): cost per event against
/// the number of masses N, for (i) 4 stops and (ii) a stop on every tenth mass.
///
/// The chain (the same as experiments/chains/*.yaml): unit masses and springs, a left wall
/// (spring 1), Rayleigh damping C = βK with β = 0.02 (every damper 0.02 beside its unit
/// spring), driven by 0.6 cos(0.8 t) on mass 0, starting at rest.
///  (i)  4 stops near the driven end: upper x1 ≤ 0.35, lower x2 ≥ -0.3,
///       between x3 - x4 ≤ 0.25, upper x5 ≤ 0.25, all with r = 0.95;
///  (ii) a stop on every tenth mass i = 0, 10, 20, …: upper at 0.3 for even i/10, lower at -0.3
///       for odd i/10, r = 0.95;
///  (iii) "4 sticking": the stops of (i) with r = 0.5, so that chatter, sticking and releases
///       occur: each such event is resolved in physical coordinates and changes basis, O(N n_r),
///       and each new contact set is a reduced chain's tridiagonal eigenproblem (modal.hpp).
/// For each N: set-up (the tridiagonal eigenproblem, LAPACK dstemr when available), the stop
/// rows Φᵀw_j (the modal engine's whole "contact set" data: the Delassus matrix of any set is
/// then read off the diagonal M), the O(N²) transforms into and out of modal coordinates (once
/// per run), and a run of `--impacts` impacts: CPU seconds per event (impacts, sticks and
/// releases; run time minus the two transforms), events per CPU second, mode evaluations per
/// impact, the sticking it met (sticks, events resolved in physical coordinates, contact sets
/// built and their build time), then the build of contact sets {first stop} and {first two
/// stops} on a fresh simulator (each a reduced chain's tridiagonal eigenproblem), and the
/// process's peak resident memory before and after those builds (getrusage ru_maxrss, which
/// never decreases, so N is taken ascending). Finally the least-squares slope of
/// log(cost per event) against log N over N = 100 … 10 000.
///
/// Usage:
///   bench_chain [--max-n N] [--impacts K] [--quick] [--eigen] [--dense] [--sets-only [--n N] [--every-10th]]
///     --quick    N = 10, 100 and 100 impacts: a smoke test (seconds)
///     --sets-only  only the contact-set builds of the "4 stops" chain at one N (--n, default
///                10 000; the free chain's set-up, ~11 s at 10 000, is paid once and no run is
///                made): set {0}, then {0, 1} on the same simulator (as in the table), then
///                {0, 1} again on a fresh one (from scratch, nothing cached), each its CPU
///                seconds and the peak memory after it; with --every-10th, of the "every 10th"
///                chain instead (N/10 stops: the rows of all the free stops make the build)
///     --eigen    Eigen's computeFromTridiagonal instead of LAPACK (O(N³): minutes at N = 10 000)
///     --dense    also time the dense engine (Simulator) on the same chains with non-proportional
///                damping (only the wall dashpot, c = 0.02), N = 10 … 200, to show its limit
/// Meaningful only in a Release build. CPU time is measured (CLOCK_PROCESS_CPUTIME_ID), since
/// the machine is shared.
#include "vibro/modal.hpp"
#include "vibro/simulator.hpp"

#include <sys/resource.h>
#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

namespace {

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double peak_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

struct Chain {
  std::vector<double> masses, springs, dampers;
  vibro::HarmonicForcing forcing;
};

Chain make_chain(int n, double beta) {
  Chain c;
  c.masses.assign(static_cast<std::size_t>(n), 1.0);
  c.springs.assign(static_cast<std::size_t>(n - 1), 1.0);
  c.dampers.assign(static_cast<std::size_t>(n - 1), beta);
  c.forcing = vibro::HarmonicForcing::zero(n, 0.8);
  c.forcing.cosine(0) = 0.6;
  return c;
}

std::vector<vibro::Stop> four_stops() {
  return {vibro::Stop::upper(1, 0.35, 0.95), vibro::Stop::lower(2, -0.3, 0.95),
          vibro::Stop::between(3, 4, 0.25, 0.95), vibro::Stop::upper(5, 0.25, 0.95)};
}

/// The four stops with restitution 0.5: chatter caught by the chatter rule, sticking, releases.
std::vector<vibro::Stop> four_sticking() {
  std::vector<vibro::Stop> s = four_stops();
  for (vibro::Stop& stop : s) stop.restitution = 0.5;
  return s;
}

std::vector<vibro::Stop> every_tenth(int n) {
  std::vector<vibro::Stop> s;
  for (int i = 0; i < n; i += 10)
    s.push_back((i / 10) % 2 == 0 ? vibro::Stop::upper(i, 0.3, 0.95) : vibro::Stop::lower(i, -0.3, 0.95));
  return s;
}

struct Row {
  int n;
  std::string config;
  std::size_t stops;
  double setup, stop_rows, transforms, per_event, evals_per_event, memory;
  long impacts;
  double t_reached;
  std::string status;
  long sticks = 0, general = 0;
  std::size_t sets = 0;
  double build_total = 0.0, build_max = 0.0;
  double set1 = 0.0, set2 = 0.0, memory_sets = 0.0;  // contact-set builds, peak memory after
};

Row measure(int n, const std::string& config, vibro::TridiagonalSolver solver, long impacts) {
  const Chain c = make_chain(n, 0.02);
  double t = cpu_seconds();
  const vibro::ChainModes modes(
      vibro::BandedChain::from_links(c.masses, c.springs, c.dampers, 1.0, 0.02, 0.0, 0.0, c.forcing), solver);
  const double setup = cpu_seconds() - t;
  std::vector<vibro::Stop> stops = config == "4 stops" ? four_stops()
                                   : config == "4 sticking" ? four_sticking()
                                                            : every_tenth(n);
  vibro::ModalSimulatorOptions options;
  options.stop_after_impacts = impacts;
  t = cpu_seconds();
  vibro::ModalChainSimulator sim(modes, stops, options);
  const double stop_rows = cpu_seconds() - t;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  // The two O(N²) transforms a run does once (into modal coordinates, and the final state).
  Eigen::VectorXd u(n), ud(n), x(n), v(n);
  t = cpu_seconds();
  modes.to_modal(0.0, zero, zero, u, ud);
  modes.to_physical(0.0, u, ud, x, v);
  const double transforms = cpu_seconds() - t;
  t = cpu_seconds();
  const auto s = sim.run(0.0, zero, zero, 1e6, {});
  const double run = cpu_seconds() - t;
  // Contact-set builds (each a reduced chain's tridiagonal eigenproblem, modal.hpp): the first
  // stop held, then the first two, on a fresh simulator so nothing is cached.
  const double memory_run = peak_mib();
  vibro::ModalChainSimulator fresh(modes, stops, options);
  t = cpu_seconds();
  fresh.contact_mode({0});
  const double set1 = cpu_seconds() - t;
  t = cpu_seconds();
  if (stops.size() > 1) fresh.contact_mode({0, 1});
  const double set2 = stops.size() > 1 ? cpu_seconds() - t : 0.0;
  const long events = s.impacts + s.sticks + s.releases;
  const double per_event = events > 0 ? std::max(run - transforms, 0.0) / static_cast<double>(events) : 0.0;
  return {n, config, stops.size(), setup, stop_rows, transforms, per_event,
          s.impacts > 0 ? static_cast<double>(s.evaluations) / static_cast<double>(s.impacts) : 0.0,
          memory_run, s.impacts, s.t, std::string(vibro::to_string(s.status)) +
                                          (s.status == vibro::RunStatus::completed ? "" : ": " + s.message),
          s.sticks, s.general_events, s.sticking_flows_built, s.mode_build_seconds, s.mode_build_max_seconds,
          set1, set2, peak_mib()};
}

/// --sets-only: the contact-set columns of the table, and {0, 1} from scratch, at one N.
void sets_only(int n, bool many, vibro::TridiagonalSolver solver) {
  const Chain c = make_chain(n, 0.02);
  double t = cpu_seconds();
  const vibro::ChainModes modes(
      vibro::BandedChain::from_links(c.masses, c.springs, c.dampers, 1.0, 0.02, 0.0, 0.0, c.forcing), solver);
  const std::vector<vibro::Stop> stops = many ? every_tenth(n) : four_stops();
  std::printf("N = %d, %zu stops: free set-up %.3g CPU s, peak %.0f MiB\n", n, stops.size(), cpu_seconds() - t,
              peak_mib());
  auto timed = [&](vibro::ModalChainSimulator& sim, const vibro::ContactSet& set, const char* what) {
    const double before = peak_mib();
    const double start = cpu_seconds();
    sim.contact_mode(set);
    const double seconds = cpu_seconds() - start;
    std::printf("%-34s %9.3f CPU s   peak %6.0f -> %6.0f MiB\n", what, seconds, before, peak_mib());
    std::fflush(stdout);
  };
  {
    vibro::ModalChainSimulator fresh(modes, stops, {});
    timed(fresh, {0}, "set {0}");
    timed(fresh, {0, 1}, "set {0, 1} (after {0}, as the table)");
  }
  vibro::ModalChainSimulator scratch(modes, stops, {});
  timed(scratch, {0, 1}, "set {0, 1} (from scratch)");
}

double fitted_slope(const std::vector<Row>& rows, const std::string& config) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int k = 0;
  for (const Row& r : rows) {
    if (r.config != config || r.n < 100 || r.per_event <= 0.0) continue;
    const double x = std::log(static_cast<double>(r.n)), y = std::log(r.per_event);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    ++k;
  }
  if (k < 2) return std::nan("");
  return (k * sxy - sx * sy) / (k * sxx - sx * sx);
}

void dense_limit(long impacts) {
  std::printf("\nDense engine (vibro::Simulator), the same chain with non-proportional damping (wall dashpot "
              "0.02 only), 4 stops, %ld impacts:\n", impacts);
  std::printf("%6s %14s %14s %14s %12s\n", "N", "first set (s)", "CPU s/impact", "sets built", "peak MiB");
  for (int n : {10, 25, 50, 100, 200}) {
    Chain c = make_chain(n, 0.0);
    std::vector<double> none;
    Eigen::MatrixXd M = Eigen::MatrixXd::Identity(n, n), K = Eigen::MatrixXd::Zero(n, n), C = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i + 1 < n; ++i) {
      K(i, i) += 1; K(i + 1, i + 1) += 1; K(i, i + 1) = K(i + 1, i) = -1;
    }
    K(0, 0) += 1;
    C(0, 0) = 0.02;
    const vibro::ImpactSystem scene(vibro::LinearSystem(M, C, K, c.forcing), four_stops());
    vibro::SimulatorOptions o;
    const double t0 = cpu_seconds();
    vibro::Simulator sim(scene, o);
    // The run's first segment builds the free flow (the (2N+3)² eigendecomposition); time a
    // zero-length run for it, then the impacts.
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
    sim.run(0.0, zero, zero, 0.0);
    const double first = cpu_seconds() - t0;
    vibro::EventLog log;
    const double t1 = cpu_seconds();
    // Run period by period until enough impacts (no impact cap in the dense options).
    double t = 0.0;
    Eigen::VectorXd x = zero, v = zero;
    long count = 0;
    while (count < impacts && t < 2000.0) {
      const auto s = sim.run(t, x, v, t + 2.0 * M_PI / 0.8, {&log});
      count += s.impacts;
      t = s.t;
      x = s.x;
      v = s.v;
      if (s.status != vibro::RunStatus::completed) break;
    }
    const double per = count > 0 ? (cpu_seconds() - t1) / static_cast<double>(count) : 0.0;
    std::printf("%6d %14.3g %14.3g %14zu %12.0f\n", n, first, per, sim.modes().built(), peak_mib());
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  int max_n = 10000;
  long impacts = 400;
  int sets_n = 10000;
  bool quick = false, dense = false, sets = false, many = false;
  vibro::TridiagonalSolver solver = vibro::TridiagonalSolver::automatic;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--dense") dense = true;
    else if (a == "--sets-only") sets = true;
    else if (a == "--n" && i + 1 < argc) sets_n = std::atoi(argv[++i]);
    else if (a == "--every-10th") many = true;
    else if (a == "--eigen") solver = vibro::TridiagonalSolver::eigen;
    else if (a == "--max-n" && i + 1 < argc) max_n = std::atoi(argv[++i]);
    else if (a == "--impacts" && i + 1 < argc) impacts = std::atol(argv[++i]);
    else {
      std::fprintf(stderr,
                   "usage: bench_chain [--max-n N] [--impacts K] [--quick] [--eigen] [--dense] "
                   "[--sets-only [--n N] [--every-10th]]\n");
      return 2;
    }
  }
  if (sets) {
    if (sets_n < (many ? 11 : 6)) {
      std::fprintf(stderr, "bench_chain: --n %d: the set {0, 1} needs two stops (N ≥ 6, or 11 with --every-10th)\n",
                   sets_n);
      return 2;
    }
    sets_only(sets_n, many, solver);
    return 0;
  }
  if (quick) {
    max_n = std::min(max_n, 100);
    impacts = std::min(impacts, 100L);
  }
  std::printf("modal chain engine, eigensolver: %s, %ld impacts per run\n",
              solver == vibro::TridiagonalSolver::eigen ? "Eigen computeFromTridiagonal"
                                                        : (vibro::lapack_available() ? "LAPACK dstemr" : "Eigen"),
              impacts);
  std::printf("%6s %-13s %6s %10s %11s %11s %12s %11s %9s %8s %9s %7s %8s %5s %9s %9s %9s %9s %6s  %s\n", "N", "stops", "m",
              "set-up s", "stop rows s", "O(N²) xf s", "CPU s/event", "events/s", "evals/imp", "MiB", "t",
              "sticks", "general", "sets", "build s", "max build", "set {0} s", "{0,1} s", "MiB", "status");
  std::vector<Row> rows;
  for (int n : {10, 100, 1000, 10000}) {
    if (n > max_n) break;
    for (const char* config : {"4 stops", "every 10th", "4 sticking"}) {
      const Row r = measure(n, config, solver, impacts);
      rows.push_back(r);
      std::printf("%6d %-13s %6zu %10.3g %11.3g %11.3g %12.3g %11.3g %9.1f %8.0f %9.4g %7ld %8ld %5zu %9.3g %9.3g %9.3g %9.3g %6.0f  %s\n",
                  r.n, r.config.c_str(), r.stops, r.setup, r.stop_rows, r.transforms, r.per_event,
                  r.per_event > 0 ? 1.0 / r.per_event : 0.0, r.evals_per_event, r.memory, r.t_reached,
                  r.sticks, r.general, r.sets, r.build_total, r.build_max, r.set1, r.set2, r.memory_sets,
                  r.status.c_str());
      std::fflush(stdout);
    }
  }
  std::printf("\nfitted slope of log(CPU s per event) vs log N, N = 100 … %d: 4 stops %.3f, every 10th %.3f, "
              "4 sticking %.3f\n",
              max_n, fitted_slope(rows, "4 stops"), fitted_slope(rows, "every 10th"), fitted_slope(rows, "4 sticking"));
  if (dense) dense_limit(std::min(impacts, 100L));
  return 0;
}
