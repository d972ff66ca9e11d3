/// \file bench_flow.cpp
/// Flow evaluations per second on one thread, for damped chains of n = 2, 10, 100, 1000 masses.
///
/// The chain: unit masses and springs, dampers c = 0.02 (mild, so LinearFlow's automatic choice
/// is the spectral method), a left wall, a cosine force of amplitude 1 at Ω = 0.7 on mass 0.
/// For each n and each method (automatic → spectral, and FlowOptions{FlowMethod::exponential}):
///  (a) set-up: constructing LinearFlow (eigen-decomposition of the (2n+3)² generator, ...);
///  (b) state evaluations: flow.propagate(z0, τ, out) of the augmented state, τ varying in (0, 10);
///  (c) functional evaluations: Segment::value of one functional (the position of the last mass,
///      a row with a 1 in column n-1) through vibro::Functionals / vibro::Segment, τ varying.
/// Each figure is the median of ≥ 5 repetitions (fewer for the slow n = 1000 cases, as the
/// output says); a rate repetition is a batch of calls sized to last ≥ 50 ms. Results are summed
/// into a volatile sink so that nothing is optimised away.
///
/// Usage:  bench_flow [--quick]      (--quick: n = 2, 10 only, a smoke test, seconds)
/// The full run is dominated by the single n = 1000 set-up: about half an hour of CPU time with
/// LinearFlow as of this writing, most of it in the JacobiSVD that computes cond(V).
#include "vibro/flow.hpp"
#include "vibro/models/chain.hpp"

#include <Eigen/Core>

#include <sched.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

volatile double sink = 0.0;  // every measured result ends up here

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// CPU time of this thread: unlike the wall time it does not grow when other processes compete
/// for the cores, so it is reported beside the set-up's wall time.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// τ for call i: 100 values spread over (0, 10), about one forcing period 2π/Ω ≈ 9.
double tau_of(long i) { return 0.1 * static_cast<double>(i % 100) + 0.05; }

/// Median over `reps` of the wall time of f(), in seconds.
template <class F>
double median_time(int reps, F&& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const auto start = Clock::now();
    f();
    t.push_back(seconds_since(start));
  }
  return median(t);
}

/// Calls per second of call(i): the batch size doubles until a batch lasts ≥ 50 ms (this also
/// warms up), then the median over `reps` batches. A single call longer than 50 ms gives batch 1.
template <class F>
double rate(int reps, F&& call) {
  long batch = 1;
  for (;;) {
    const auto start = Clock::now();
    for (long i = 0; i < batch; ++i) call(i);
    if (seconds_since(start) >= 0.05 || batch >= (1L << 26)) break;
    batch *= 2;
  }
  const double t = median_time(reps, [&] {
    for (long i = 0; i < batch; ++i) call(i);
  });
  return static_cast<double>(batch) / t;
}

vibro::LinearSystem damped_chain(int n) {
  const auto N = static_cast<std::size_t>(n);
  vibro::models::Chain c;
  c.masses.assign(N, 1.0);
  c.springs.assign(N - 1, 1.0);
  c.dampers.assign(N - 1, 0.02);
  c.left_spring = 1.0;
  c.left_damper = 0.02;
  c.force_cosine.assign(N, 0.0);
  c.force_cosine[0] = 1.0;
  c.frequency = 0.7;
  return vibro::models::build_chain(c);
}

struct Row {
  int n = 0;
  std::string method;
  std::string setup;  // ms, formatted (or a reason it was not measured)
  std::string state;  // evals/s
  std::string functional;
  std::string note;
};

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string format_ms(double ms) { return ms >= 1e3 ? format("%.0f", ms) : format("%.4g", ms); }

/// Constructs LinearFlow(sys, options) `reps` times; the last flow is kept. Fills row.setup with
/// the median wall time and returns a note with the median CPU time.
std::unique_ptr<vibro::LinearFlow> timed_setup(const vibro::LinearSystem& sys,
                                               vibro::FlowOptions options, int reps, Row& row) {
  std::vector<double> wall, cpu;
  std::unique_ptr<vibro::LinearFlow> flow;
  for (int r = 0; r < reps; ++r) {
    flow.reset();
    const auto start = Clock::now();
    const double cpu_start = thread_cpu_seconds();
    flow = std::make_unique<vibro::LinearFlow>(sys, options);
    cpu.push_back(thread_cpu_seconds() - cpu_start);
    wall.push_back(seconds_since(start));
    sink = sink + flow->spectral_radius();
  }
  row.setup = format_ms(1e3 * median(wall));
  row.note = "set-up median of " + std::to_string(reps) + " (CPU time " +
             format_ms(1e3 * median(cpu)) + " ms)";
  return flow;
}

struct Plan {
  int setup_reps;      // repetitions of the LinearFlow construction
  int rate_reps;       // repetitions of each rate batch
  bool run_exponential_setup;  // construct an exponential flow (else reuse the spectral one's Â)
};

const char* method_name(vibro::FlowMethod m) {
  switch (m) {
    case vibro::FlowMethod::spectral: return "spectral";
    case vibro::FlowMethod::exponential: return "exponential";
    case vibro::FlowMethod::automatic: return "automatic";
  }
  return "?";
}

/// Rates (b) and (c) for one flow.
void measure_rates(const vibro::LinearFlow& flow, int reps, Row& row) {
  const Eigen::Index n = flow.dof();
  Eigen::VectorXd x0(n), v0 = Eigen::VectorXd::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) x0(i) = 0.01 * std::sin(static_cast<double>(i + 1));
  const Eigen::VectorXd z0 = flow.augment(0.0, x0, v0);
  Eigen::VectorXd out(flow.size());

  double acc = 0.0;
  const double state_rate = rate(reps, [&](long i) {
    flow.propagate(z0, tau_of(i), out);
    acc += out(n - 1);
  });
  Eigen::MatrixXd last = Eigen::MatrixXd::Zero(1, flow.size());
  last(0, n - 1) = 1.0;
  const vibro::Functionals functionals(flow, last);
  const vibro::Segment segment(functionals, 0.0, z0);
  const double functional_rate = rate(reps, [&](long i) { acc += segment.value(0, tau_of(i)); });
  sink = sink + acc;
  row.state = format("%.3g", state_rate);
  row.functional = format("%.3g", functional_rate);
}

void bench_size(int n, const Plan& plan, std::vector<Row>& rows) {
  std::fprintf(stderr, "n = %d ...\n", n);
  const vibro::LinearSystem sys = damped_chain(n);

  // Automatic choice (expected: spectral).
  {
    Row row;
    row.n = n;
    const auto flow = timed_setup(sys, vibro::FlowOptions{}, plan.setup_reps, row);
    row.method = std::string("automatic → ") + method_name(flow->method());
    row.note = "cond(V) = " + format("%.3g", flow->eigenvector_condition()) + ", " + row.note;
    std::fprintf(stderr, "  set-up %s ms (%s)\n", row.setup.c_str(), row.note.c_str());
    measure_rates(*flow, plan.rate_reps, row);
    rows.push_back(row);

    if (!plan.run_exponential_setup) {
      // The exponential flow would repeat the same O(N³) decomposition (LinearFlow's constructor
      // decomposes Â whatever the method), and each exp(Âτ) costs seconds: measure only the
      // state rate, through transition_matrix (exactly what propagate does for that method).
      Row e;
      e.n = n;
      e.method = "exponential";
      e.setup = "(not re-measured)";
      const Eigen::VectorXd z0 = Eigen::VectorXd::Ones(flow->size());
      double acc = 0.0;
      const double per_call = median_time(plan.rate_reps, [&] {
        const Eigen::VectorXd z = flow->transition_matrix(5.0) * z0;
        acc += z(n - 1);
      });
      sink = sink + acc;
      e.state = format("%.3g", 1.0 / per_call);
      e.functional = format("≈ %.3g", 1.0 / per_call);
      e.note = "reduced: median of " + std::to_string(plan.rate_reps) +
               " single exp(Â·5) via transition_matrix; functional ≈ state (Segment::value "
               "computes the same exp for each new τ)";
      rows.push_back(e);
      return;
    }
  }

  // Exponential method.
  {
    Row row;
    row.n = n;
    const auto flow = timed_setup(sys, vibro::FlowOptions{vibro::FlowMethod::exponential},
                                  plan.setup_reps, row);
    row.method = method_name(flow->method());
    measure_rates(*flow, plan.rate_reps, row);
    rows.push_back(row);
  }
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      return colon == std::string::npos ? line : line.substr(colon + 2);
    }
  return "unknown";
}

std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string one, five, fifteen;
  in >> one >> five >> fifteen;
  return in ? one + " " + five + " " + fifteen : "unknown";
}

int available_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) return CPU_COUNT(&set);
  return static_cast<int>(std::thread::hardware_concurrency());
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--quick") {
      quick = true;
    } else {
      std::fprintf(stderr, "usage: %s [--quick]\n", argv[0]);
      return 2;
    }
  }

  std::printf("machine: nproc = %d, CPU = %s, Eigen %d.%d.%d, Eigen threads = %d", available_cpus(),
              cpu_model().c_str(), EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION,
              Eigen::nbThreads());
#ifdef __VERSION__
  std::printf(", compiler %s", __VERSION__);
#endif
#ifdef NDEBUG
  std::printf(", NDEBUG\n");
#else
  std::printf(", WARNING: assertions on (not a Release build)\n");
#endif
  std::printf("load average at the start: %s\n", load_average().c_str());
  std::printf("chain: unit masses and springs, dampers 0.02, left wall, cos force on mass 0 at "
              "Ω = 0.7; τ ∈ (0, 10)\n\n");

  std::vector<Row> rows;
  const auto start = Clock::now();
  const Plan normal{5, 5, true};
  for (int n : {2, 10}) bench_size(n, normal, rows);
  if (!quick) {
    bench_size(100, normal, rows);
    bench_size(1000, Plan{1, 3, false}, rows);
  }

  std::printf("| n | method | setup ms | state evals/s | functional evals/s |\n");
  std::printf("|---:|---|---:|---:|---:|\n");
  for (const Row& r : rows)
    std::printf("| %d | %s | %s | %s | %s |\n", r.n, r.method.c_str(), r.setup.c_str(),
                r.state.c_str(), r.functional.c_str());
  std::printf("\nnotes:\n");
  for (const Row& r : rows)
    std::printf("- n = %d, %s: %s\n", r.n, r.method.c_str(), r.note.c_str());
  std::printf("\nload average at the end: %s (wall times grow when it exceeds nproc)\n",
              load_average().c_str());
  std::printf("total run time %.1f s (sink %g)\n", seconds_since(start), static_cast<double>(sink));
  return 0;
}
