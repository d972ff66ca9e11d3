/// \file bench_harmonics.cpp
/// Cost of a drive with several harmonics (docs/performance.md, "Drives with several harmonics"):
/// the paper's system (Wagg 2004, fig. 2: two masses, two stops, Ω = 0.255, sticking and chatter)
/// with its drive written as the plain `forcing.cosine`, as `forcing.harmonics` of order 1 only
/// (the same scene), and with harmonics 2 … H added (H = 2, 4, 8; small amplitudes, 1 % of the
/// first harmonic's, so the motion and its events stay alike). Each variant runs a transient once,
/// then `--periods` periods (no observer) timed in thread CPU time; the variants alternate, round
/// after round (`--rounds`, default 5), and the median per variant is printed: µs per forcing
/// period, µs per event (impacts, sticks, releases and chatter limits of the timed run) and
/// events per period.
///     build/release/tools/bench/bench_harmonics [--periods 200] [--rounds 5]
#include "vibro/io/scene.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <ctime>
#include <string>
#include <vector>

namespace {

double thread_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

const char* kModel = R"(name: bench-harmonics
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
initial: {x: [0, 0], v: [0, 0]}
)";

struct Variant {
  std::string name;
  vibro::io::Scene scene;
  vibro::RunSummary start;
  std::vector<double> per_period, per_event, events;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

}  // namespace

int main(int argc, char** argv) {
  int periods = 200, rounds = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--periods") periods = std::atoi(argv[i + 1]);
    else if (a == "--rounds") rounds = std::atoi(argv[i + 1]);
    else {
      fmt::print(stderr, "usage: bench_harmonics [--periods P] [--rounds R]\n");
      return 2;
    }
  }
  if (periods < 1 || rounds < 1) {
    fmt::print(stderr, "bench_harmonics: --periods and --rounds must be ≥ 1\n");
    return 2;
  }
  std::vector<Variant> variants;
  auto add = [&](const std::string& name, const std::string& forcing) {
    const vibro::io::Scene s = vibro::io::SceneDocument::parse(std::string(kModel) + forcing).build();
    variants.push_back({name, s, {}, {}, {}, {}});
  };
  add("plain forcing.cosine", "forcing: {frequency: 0.255, cosine: [0.5, 0]}\n");
  for (int H : {1, 2, 4, 8}) {
    std::string f = "forcing:\n  frequency: 0.255\n  harmonics:\n    - {order: 1, cosine: [0.5, 0]}\n";
    for (int k = 2; k <= H; ++k) f += "    - {order: " + std::to_string(k) + ", cosine: [0.005, 0], sine: [0, 0.002]}\n";
    add(fmt::format("H = {} harmonic{}", H, H > 1 ? "s" : ""), f);
  }
  for (Variant& v : variants) {  // the transient, untimed: every timed run starts on the attractor
    const double T = v.scene.period();
    v.start = vibro::io::make_engine(v.scene)->run(0.0, v.scene.x0, v.scene.v0, 200 * T, {});
    if (v.start.status != vibro::RunStatus::completed) {
      fmt::print(stderr, "bench_harmonics: {}: the transient stopped: {}\n", v.name, v.start.message);
      return 1;
    }
  }
  for (int r = 0; r < rounds; ++r)
    for (Variant& v : variants) {
      const double T = v.scene.period();
      const std::unique_ptr<vibro::Engine> engine = vibro::io::make_engine(v.scene);
      const double t0 = thread_seconds();
      const vibro::RunSummary s = engine->run(v.start.t, v.start.x, v.start.v, v.start.t + periods * T, {});
      const double cpu = thread_seconds() - t0;
      if (s.status != vibro::RunStatus::completed) {
        fmt::print(stderr, "bench_harmonics: {}: the run stopped: {}\n", v.name, s.message);
        return 1;
      }
      const double events = static_cast<double>(s.impacts + s.sticks + s.releases + s.chatters);
      v.per_period.push_back(1e6 * cpu / periods);
      v.per_event.push_back(events > 0 ? 1e6 * cpu / events : 0.0);
      v.events.push_back(events / periods);
    }
  fmt::print("{} periods per run, median of {} alternated rounds (thread CPU time)\n", periods, rounds);
  fmt::print("{:<22} {:>12} {:>12} {:>14}\n", "drive", "µs/period", "µs/event", "events/period");
  for (const Variant& v : variants)
    fmt::print("{:<22} {:>12.1f} {:>12.2f} {:>14.2f}\n", v.name, median(v.per_period), median(v.per_event),
               median(v.events));
  return 0;
}
