/// \file bench_harmonic_cost.cpp
/// Cost of one state evaluation per extra harmonic of the drive, on both engines
/// (docs/performance.md, "One state evaluation per harmonic").
///
/// Dense engine: LinearFlow::propagate of the augmented state z = [x; v; 1; cos Ωt; sin Ωt; …]
/// (flow.hpp; each harmonic of order ≥ 2 adds the conjugate pair ±ikΩ to the spectral flow, one
/// complex exponential term, and two components to z). Modal engine: a mode state at a new
/// time, ChainModes::advance of the homogeneous part (one 2 × 2 propagator per mode, the same
/// whatever the drive) plus ChainModes::add_particular (per harmonic one cosine and sine and two
/// n-vector updates, modal.hpp). Chains of n masses (uniform, k = 1, c = 0.01 k, both walls),
/// the first harmonic on mass 0 and H extra harmonics of orders 2 … H + 1 on every mass.
/// A stop's gap g = wᵀx − s(t) (stops.hpp, stop_gap) with H higher harmonics of its own motion
/// (orders 2 … H + 1 beside its first harmonic): per harmonic one cosine and sine of kΩt; the
/// engines evaluate it where they check a state against the stops (each order a stop moves at
/// is also a harmonic slot of the drive, priced by the rows above when the drive lacks it).
/// Each (engine, n, H) is timed over `--evaluations` evaluations at times spread over ten
/// periods (thread CPU time); the variants of one engine and n alternate round after round
/// (`--rounds`, default 5) and the median per variant is printed in ns per evaluation, with
/// the increment per extra harmonic fitted over H = 0 … 8 (least squares).
///     build/release/tools/bench/bench_harmonic_cost [--evaluations 20000] [--rounds 5]
#include "vibro/flow.hpp"
#include "vibro/modal.hpp"
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <ctime>
#include <numbers>
#include <string>
#include <vector>

namespace {

double thread_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

constexpr double kOmega = 0.45;
const std::vector<int> kExtra{0, 1, 2, 4, 8};

vibro::BandedChain chain(int n, int extra) {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(n, kOmega);
  f.cosine(0) = 0.5;
  for (int k = 2; k <= extra + 1; ++k)
    f.harmonics.push_back({k, Eigen::VectorXd::Constant(n, 0.05 / k), Eigen::VectorXd::Constant(n, 0.02 / k)});
  const auto N = static_cast<std::size_t>(n);
  return vibro::BandedChain::from_links(std::vector<double>(N, 1.0), std::vector<double>(N - 1, 1.0),
                                        std::vector<double>(N - 1, 0.01), 1.0, 0.01, 1.0, 0.01, f);
}

/// Slope of y against x (least squares).
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < x.size(); ++i) mx += x[i], my += y[i];
  mx /= static_cast<double>(x.size());
  my /= static_cast<double>(y.size());
  double sxy = 0, sxx = 0;
  for (std::size_t i = 0; i < x.size(); ++i) sxy += (x[i] - mx) * (y[i] - my), sxx += (x[i] - mx) * (x[i] - mx);
  return sxy / sxx;
}

/// Runs `evaluate(i)` for i < count, rounds × variants alternated; returns ns per evaluation.
template <class Evaluate>
std::vector<double> timed(std::vector<Evaluate>& variants, int evaluations, int rounds) {
  std::vector<std::vector<double>> ns(variants.size());
  double sink = 0.0;
  for (int r = 0; r < rounds; ++r)
    for (std::size_t v = 0; v < variants.size(); ++v) {
      const double t0 = thread_seconds();
      for (int i = 0; i < evaluations; ++i) sink += variants[v](i);
      ns[v].push_back(1e9 * (thread_seconds() - t0) / evaluations);
    }
  if (sink == 42.0) fmt::print("");  // keeps the evaluations
  std::vector<double> out;
  for (const auto& s : ns) out.push_back(median(s));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int evaluations = 20000, rounds = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--evaluations") evaluations = std::atoi(argv[i + 1]);
    else if (a == "--rounds") rounds = std::atoi(argv[i + 1]);
    else {
      fmt::print(stderr, "usage: bench_harmonic_cost [--evaluations E] [--rounds R]\n");
      return 2;
    }
  }
  if (evaluations < 1 || rounds < 1) {
    fmt::print(stderr, "bench_harmonic_cost: --evaluations and --rounds must be ≥ 1\n");
    return 2;
  }
  const double T = 2.0 * std::numbers::pi / kOmega;
  auto time_of = [&](int i) { return 10.0 * T * (i % 997) / 997.0; };
  std::vector<double> H;
  for (int h : kExtra) H.push_back(h);
  fmt::print("ns per state evaluation, median of {} alternated rounds of {} evaluations (thread CPU time)\n", rounds,
             evaluations);
  fmt::print("{:<28}", "engine, masses");
  for (int h : kExtra) fmt::print(" {:>9}", fmt::format("H+{}", h));
  fmt::print(" {:>13}\n", "per harmonic");

  for (int n : {2, 8}) {  // dense: propagate the augmented state
    std::vector<vibro::LinearFlow> flows;
    std::vector<Eigen::VectorXd> z, out;
    for (int h : kExtra) {
      flows.emplace_back(chain(n, h).dense());
      z.push_back(flows.back().augment(0.0, Eigen::VectorXd::Constant(n, 0.1), Eigen::VectorXd::Zero(n)));
      out.push_back(Eigen::VectorXd::Zero(z.back().size()));
    }
    std::vector<std::function<double(int)>> variants;
    for (std::size_t v = 0; v < flows.size(); ++v)
      variants.emplace_back([&, v](int i) {
        flows[v].propagate(z[v], time_of(i), out[v]);
        return out[v](0);
      });
    const std::vector<double> ns = timed(variants, evaluations, rounds);
    fmt::print("{:<28}", fmt::format("dense, n = {}", n));
    for (double t : ns) fmt::print(" {:>9.1f}", t);
    fmt::print(" {:>13.1f}\n", slope(H, ns));
  }
  for (int n : {8, 1000}) {  // modal: advance the modes, add the particular solution
    std::vector<vibro::ChainModes> modes;
    Eigen::VectorXd u = Eigen::VectorXd::Constant(n, 0.01), ud = Eigen::VectorXd::Zero(n);
    Eigen::VectorXd q(n), qd(n);
    for (int h : kExtra) modes.emplace_back(chain(n, h));
    std::vector<std::function<double(int)>> variants;
    for (std::size_t v = 0; v < modes.size(); ++v)
      variants.emplace_back([&, v](int i) {
        const double t = time_of(i);
        modes[v].advance(t, u, ud, q, qd);
        modes[v].add_particular(t, 1.0, q, qd);
        return q(0);
      });
    const std::vector<double> ns = timed(variants, std::max(1, evaluations / (n / 8)), rounds);
    fmt::print("{:<28}", fmt::format("modal, n = {}", n));
    for (double t : ns) fmt::print(" {:>9.1f}", t);
    fmt::print(" {:>13.1f}\n", slope(H, ns));
  }
  {  // a stop's gap with H harmonics of its own motion (H+0: the first harmonic only)
    std::vector<vibro::Stop> stops;
    for (int h : kExtra) {
      std::vector<vibro::StopHarmonic> higher;
      for (int k = 2; k <= h + 1; ++k) higher.push_back({k, 0.01 / k, 0.005 / k});
      stops.push_back(vibro::Stop::upper(0, 0.5, 0.8).moving(0.05, 0.3).with_harmonics(higher));
    }
    const Eigen::VectorXd x = Eigen::VectorXd::Constant(2, 0.1);
    std::vector<std::function<double(int)>> variants;
    for (std::size_t v = 0; v < stops.size(); ++v)
      variants.emplace_back([&, v](int i) { return vibro::stop_gap(stops[v], kOmega, time_of(i), x); });
    const std::vector<double> ns = timed(variants, 10 * evaluations, rounds);
    fmt::print("{:<28}", "stop gap (stop_gap)");
    for (double t : ns) fmt::print(" {:>9.1f}", t);
    fmt::print(" {:>13.1f}\n", slope(H, ns));
  }
  return 0;
}
