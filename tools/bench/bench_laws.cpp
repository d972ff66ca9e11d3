/// \file bench_laws.cpp
/// The cost of an event under each contact law, on one 2-DOF scene.
///
/// The scene: two unit masses, a wall spring and a coupling spring (k = 1), dashpots 0.05 to the
/// wall and between the masses, forced on mass 1 by 0.6 cos Ωt (Ω = 1.1, near the first mode's
/// resonance). Mass 0 meets, in turn,
///   rigid      a rigid stop x_0 ≤ 0.3 with r = 0.8 (impacts, chatter, sticking as they come);
///   compliant  a compliant stop at the same place, k_s = 20, c_s = 0.1 (an engage and a
///              disengage switch per contact);
///   friction   no stop, dry friction on a fixed surface, N = 1, μ_s = 0.3, μ_k = 0.2 (stick,
///              slip start and reversal events).
/// Each run goes `periods` forcing periods from rest; an event is a segment's end (every located
/// switch: impacts, sticks, releases, chatter limits, engage/disengage, stick/slip). Runs are
/// alternated between the laws, `repeat` times, and the median CPU time (this thread's) per event
/// is reported with its spread, beside the rigid law's in the same sitting.
///
/// Usage: bench_laws [--periods P] [--repeat R] [--law rigid|compliant|friction]
/// (--law runs that law alone, e.g. under a profiler).
#include "vibro/friction.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <numbers>
#include <string>
#include <vector>

namespace {

double thread_cpu() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

constexpr double kOmega = 1.1;

vibro::LinearSystem two_masses() {
  return vibro::models::build_chain({.masses = {1, 1},
                                     .springs = {1},
                                     .dampers = {0.05},
                                     .left_spring = 1,
                                     .left_damper = 0.05,
                                     .force_constant = {},
                                     .force_cosine = {0, 0.6},
                                     .force_sine = {},
                                     .frequency = kOmega});
}

struct Sample {
  double cpu = 0.0;
  long events = 0;
  std::string status;
};

Sample run_stop(const vibro::Stop& stop, double periods) {
  const vibro::ImpactSystem scene(two_masses(), {stop});
  vibro::Simulator sim(scene);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(2);
  const double t_end = periods * 2.0 * std::numbers::pi / kOmega;
  const double start = thread_cpu();
  const vibro::RunSummary s = sim.run(0.0, zero, zero, t_end);
  return {thread_cpu() - start, s.segments - 1, vibro::to_string(s.status)};
}

Sample run_friction(double periods) {
  const vibro::LinearSystem system = two_masses();  // the simulator keeps a reference to it
  vibro::FrictionSimulator sim(system, {vibro::FrictionContact::on_surface(0, 1.0, 0.3, 0.2)});
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(2);
  const double t_end = periods * 2.0 * std::numbers::pi / kOmega;
  const double start = thread_cpu();
  const vibro::FrictionSummary s = sim.run(0.0, zero, zero, t_end);
  return {thread_cpu() - start, s.segments - 1, vibro::to_string(s.status)};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  double periods = 400;
  int repeat = 7;
  std::string only;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--periods")) periods = std::atof(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--repeat")) repeat = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--law")) only = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: bench_laws [--periods P] [--repeat R] [--law rigid|compliant|friction]\n");
      return 2;
    }
  }
  const char* names[] = {"rigid", "compliant", "friction"};
  if (!(periods > 0) || repeat < 1 ||
      (!only.empty() && only != names[0] && only != names[1] && only != names[2])) {
    std::fprintf(stderr, "bench_laws: --periods must be > 0, --repeat ≥ 1, --law rigid, compliant or friction\n");
    return 2;
  }
  std::vector<double> us[3];
  long events[3] = {0, 0, 0};
  std::string status[3];
  for (int r = 0; r < repeat; ++r) {
    for (int law = 0; law < 3; ++law) {
      if (!only.empty() && only != names[law]) continue;
      const Sample s = law == 0   ? run_stop(vibro::Stop::upper(0, 0.3, 0.8), periods)
                       : law == 1 ? run_stop(vibro::Stop::upper(0, 0.3, 1.0).compliant(20.0, 0.1), periods)
                                  : run_friction(periods);
      us[law].push_back(1e6 * s.cpu / static_cast<double>(std::max(1L, s.events)));
      events[law] = s.events;
      status[law] = s.status;
    }
  }
  std::printf("2-DOF scene, %.0f forcing periods from rest, %d alternated runs per law (thread CPU time)\n\n", periods,
              repeat);
  std::printf("| law | events | events per period | CPU µs per event, median | min … max | / rigid | status |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  const double rigid = us[0].empty() ? std::nan("") : median(us[0]);
  for (int law = 0; law < 3; ++law) {
    if (us[law].empty()) continue;
    const auto [lo, hi] = std::minmax_element(us[law].begin(), us[law].end());
    std::printf("| %s | %ld | %.1f | %.3f | %.3f … %.3f | %.2f | %s |\n", names[law], events[law],
                static_cast<double>(events[law]) / periods, median(us[law]), *lo, *hi, median(us[law]) / rigid,
                status[law].c_str());
  }
  return 0;
}
