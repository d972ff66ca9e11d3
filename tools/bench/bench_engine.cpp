/// \file bench_engine.cpp
/// Speed and accuracy of the whole event loop on the paper's system.
///
/// Problems: Wagg (2004), vibro::models::wagg2004(), from rest x = v = 0, over 100 forcing
/// periods, at (a) Ω = 0.255 and (b) Ω = 0.27 (after rising).
///
/// For each chatter threshold (solver.chatter_height) it reports
///  * CPU time per forcing period (µs), the median of `--repeat` runs on this thread
///    (CLOCK_THREAD_CPUTIME_ID, so other jobs on a loaded machine do not count), with no observer
///    attached (the engine alone); and events (impacts + sticks + releases) per CPU second;
///  * the max state error over a fixed grid of 20 samples per period (Samples observer: exact
///    states from the flow), max(|Δx|/L, |Δv|/V), against the same run at the tightest setting
///    (chatter_height = 1e-13: bounces are resolved until they rise less than 1e-13 L, the
///    trigger level itself), leaving out samples inside either run's chatter tails (there the
///    true motion still bounces with rebound speeds up to r·u while a run that ended the
///    chatter holds the stop: an error of the order of u whatever the rule).
/// --rule selects the chatter rule (vibro::ChatterRule; default third); --trigger sets
/// solver.trigger for every run but the 1e-13 reference (default: SimulatorOptions' own).
/// With --reference every run (each threshold and the 1e-13 one) is also cross-checked against
/// the independent fine-step RK8 hybrid integrator of tests/support/reference_hybrid.hpp: for
/// every release and every stick (chatter limit) of the engine, the nearest reference event of
/// the same stop and kind; worst and median |Δt|/T (the reference takes about a second).
///
/// Usage: bench_engine [--periods P] [--repeat R] [--reference] [--height h]... [--problem a|b|ab]
///                     [--timing-only] [--rule first|second|third] [--trigger ε]
///   (--height may be repeated; default thresholds 1e-6 … 1e-10). --timing-only runs only the
///   timed runs (no samples, no reference), e.g. for instruction counts:
///     valgrind --tool=callgrind --toggle-collect='vibro::Simulator::run*'
///              bench_engine --timing-only --problem a --repeat 1 --height 1e-9
#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"

#ifdef VIBRO_BENCH_WITH_REFERENCE
#include "support/reference_hybrid.hpp"
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace {

double thread_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Settings {
  int periods = 100;
  int repeat = 7;
  bool reference = false;
  bool timing_only = false;  // only the timed runs (for callgrind: --toggle-collect on Simulator::run)
  std::string problems = "ab";
  std::vector<double> heights;
};

struct Sampled {
  Eigen::MatrixXd x, v;  // a column per sample
  vibro::RunSummary summary;
  std::vector<vibro::Event> events;
};

vibro::ChatterRule g_rule = vibro::ChatterRule::third_order;  // --rule
double g_trigger = 0.0;                                          // --trigger (0: the default)

vibro::SimulatorOptions options_for(double height) {
  vibro::SimulatorOptions o;
  o.chatter_height = height;
  o.chatter_rule = g_rule;
  if (g_trigger > 0.0 && height > 1e-13) o.trigger = g_trigger;  // the reference keeps the default
  return o;
}

Sampled sampled_run(const vibro::ImpactSystem& scene, double t_end, int periods, double height) {
  vibro::Simulator sim(scene, options_for(height));
  std::vector<double> times;
  const int count = 20 * periods;
  for (int i = 1; i <= count; ++i) times.push_back(t_end * i / count);
  vibro::Samples samples(times);
  vibro::EventLog log;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(scene.dof());
  Sampled out;
  out.summary = sim.run(0.0, zero, zero, t_end, {&samples, &log});
  out.x = samples.x;
  out.v = samples.v;
  out.events = std::move(log.events);
  if (out.summary.status != vibro::RunStatus::completed)
    std::printf("  (run at chatter_height %.0e stopped: %s)\n", height, out.summary.message.c_str());
  return out;
}

struct Timing {
  double median_seconds = 0.0;
  long events = 0;
  long searches = 0;  // segments: each ends in a located event (or t_end)
  long guard_evaluations = 0, evaluation_points = 0;
};

/// Guard evaluations of each search (the work between two located events), read from the
/// simulator's running count when the segment the search found is reported.
class WorkProbe final : public vibro::Observer {
 public:
  explicit WorkProbe(const vibro::Simulator& sim) : sim_(&sim) {}
  void segment(const vibro::SegmentView&) override {
    const long now = sim_->guard_evaluations();
    per_search.push_back(now - last_);
    last_ = now;
  }
  std::vector<long> per_search;

 private:
  const vibro::Simulator* sim_;
  long last_ = 0;
};

/// Bounces per chatter sequence: for each chatter limit, the impacts on its stop since that
/// stop's previous release, stick or chatter limit (or the start of the run); mean and max.
std::pair<double, long> chatter_bounces(const Sampled& run) {
  long sequences = 0, total = 0, most = 0;
  for (std::size_t i = 0; i < run.events.size(); ++i) {
    const vibro::Event& e = run.events[i];
    if (e.kind != vibro::EventKind::chatter_limit) continue;
    long bounces = 0;
    for (std::size_t k = i; k-- > 0;) {
      const vibro::Event& b = run.events[k];
      if (b.stop != e.stop) continue;
      if (b.kind != vibro::EventKind::impact) break;
      ++bounces;
    }
    ++sequences;
    total += bounces;
    most = std::max(most, bounces);
  }
  return {sequences > 0 ? static_cast<double>(total) / static_cast<double>(sequences) : 0.0, most};
}

/// Median and mean guard evaluations per search over a whole run.
std::pair<double, double> search_work(const vibro::ImpactSystem& scene, double t_end, double height) {
  vibro::Simulator sim(scene, options_for(height));
  WorkProbe probe(sim);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(scene.dof());
  sim.run(0.0, zero, zero, t_end, {&probe});
  std::vector<long> w = probe.per_search;
  if (w.empty()) return {0.0, 0.0};
  std::sort(w.begin(), w.end());
  double sum = 0.0;
  for (long x : w) sum += static_cast<double>(x);
  return {static_cast<double>(w[w.size() / 2]), sum / static_cast<double>(w.size())};
}

Timing timed_runs(const vibro::ImpactSystem& scene, double t_end, double height, int repeat) {
  std::vector<double> seconds;
  Timing out;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(scene.dof());
  for (int k = 0; k < repeat; ++k) {
    vibro::Simulator sim(scene, options_for(height));  // contact sets built inside the timing
    const double start = thread_seconds();
    const vibro::RunSummary s = sim.run(0.0, zero, zero, t_end);
    seconds.push_back(thread_seconds() - start);
    out.events = s.impacts + s.sticks + s.releases;
    out.searches = s.segments;
    out.guard_evaluations = s.guard_evaluations;
    out.evaluation_points = s.evaluation_points;
  }
  std::sort(seconds.begin(), seconds.end());
  out.median_seconds = seconds[seconds.size() / 2];
  return out;
}

/// Chatter tails [impact that ends the chatter, chatter limit] of a run: inside them the true
/// motion still bounces while a run that ended the chatter holds the stop, whatever the rule, so
/// the state error there is of the order of the rebound speed (not what the threshold buys).
std::vector<std::pair<double, double>> tails(const Sampled& run) {
  std::vector<std::pair<double, double>> out;
  for (std::size_t i = 1; i < run.events.size(); ++i)
    if (run.events[i].kind == vibro::EventKind::chatter_limit) out.emplace_back(run.events[i - 1].t, run.events[i].t);
  return out;
}

/// max(|Δx|/L, |Δv|/V) on the grid, outside both runs' chatter tails.
double state_error(const Sampled& run, const Sampled& ref, double t_end) {
  const double L = ref.summary.length_scale, V = ref.summary.velocity_scale;
  double err = 0.0;
  const Eigen::Index count = std::min(run.x.cols(), ref.x.cols());
  if (run.x.cols() != ref.x.cols()) return std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, double>> skip = tails(run);
  for (const auto& tail : tails(ref)) skip.push_back(tail);
  for (Eigen::Index i = 0; i < count; ++i) {
    const double t = t_end * static_cast<double>(i + 1) / static_cast<double>(count);
    if (std::any_of(skip.begin(), skip.end(), [&](const auto& s) { return t >= s.first && t <= s.second; }))
      continue;
    err = std::max(err, (run.x.col(i) - ref.x.col(i)).cwiseAbs().maxCoeff() / L);
    err = std::max(err, (run.v.col(i) - ref.v.col(i)).cwiseAbs().maxCoeff() / V);
  }
  return err;
}

#ifdef VIBRO_BENCH_WITH_REFERENCE
/// Chatter-limit (stick) and release times of each run against the independent RK8 hybrid
/// reference: for every release and every stick (chatter limit) of the engine, the nearest
/// reference event of the same stop and kind; worst and median |Δt|/T per run.
void cross_check(const vibro::ImpactSystem& scene, double t_end, double period,
                 const std::vector<std::pair<std::string, const Sampled*>>& runs) {
  using namespace vibro::test;
  ReferenceHybridOptions o;
  o.stick_velocity = 1e-7L;
  ReferenceHybrid ref(scene, o);
  const double start = thread_seconds();
  ref.run(0.0L, VectorL::Zero(scene.dof()), VectorL::Zero(scene.dof()), static_cast<long double>(t_end));
  const double seconds = thread_seconds() - start;
  std::printf("\nagainst the independent RK8 hybrid reference (tests/support/reference_hybrid.hpp, %.1f s): |Δt|/T of "
              "the nearest reference event of the same stop and kind\n\n"
              "| chatter_height | sticks / chatter limits | worst | median | releases | worst |\n|---|---|---|---|---|---|\n",
              seconds);
  for (const auto& [name, run] : runs) {
    std::vector<double> stick, release;
    for (const vibro::Event& e : run->events) {
      const bool is_release = e.kind == vibro::EventKind::release;
      const bool is_stick = e.kind == vibro::EventKind::chatter_limit || e.kind == vibro::EventKind::stick;
      if (!is_release && !is_stick) continue;
      double best = std::numeric_limits<double>::infinity();
      for (const ReferenceEvent& r : ref.events) {
        if (r.stop != e.stop) continue;
        if (is_release && r.kind != ReferenceEventKind::release) continue;
        if (is_stick && r.kind != ReferenceEventKind::stick) continue;
        const double t_ref = static_cast<double>(is_stick ? r.t_limit : r.t);
        best = std::min(best, std::abs(t_ref - e.t) / period);
      }
      (is_release ? release : stick).push_back(best);
    }
    std::sort(stick.begin(), stick.end());
    std::sort(release.begin(), release.end());
    std::printf("| %s | %zu | %.2e | %.2e | %zu | %.2e |\n", name.c_str(), stick.size(), stick.empty() ? 0.0 : stick.back(),
                stick.empty() ? 0.0 : stick[stick.size() / 2], release.size(), release.empty() ? 0.0 : release.back());
  }
}
#endif

void study(const char* name, double omega, const Settings& set) {
  vibro::models::Wagg2004 p;
  p.frequency = omega;
  const vibro::ImpactSystem scene = vibro::models::wagg2004(p);
  const double t_end = set.periods * 2.0 * std::numbers::pi / omega;
  std::printf("\n### %s, %d periods\n\n", name, set.periods);
  if (set.timing_only) {
    for (double h : set.heights) {
      const Timing t = timed_runs(scene, t_end, h, set.repeat);
      std::printf("chatter_height %.0e: %.1f µs / period, %ld events\n", h,
                  1e6 * t.median_seconds / set.periods, t.events);
    }
    return;
  }
  // Work of the event loop: CPU per located event (per search) and guard evaluations per
  // search (median and mean), events (impacts, sticks, releases) per period.
  std::printf("| chatter_height | µs / period | µs / search | searches / period | events / period | "
              "guard evaluations / search (median, mean) | evaluation points / search |\n"
              "|---|---|---|---|---|---|---|\n");
  for (double h : set.heights) {
    const Timing t = timed_runs(scene, t_end, h, set.repeat);
    const auto [median, mean] = search_work(scene, t_end, h);
    std::printf("| %.0e | %.1f | %.3f | %.1f | %.1f | %.0f, %.1f | %.1f |\n", h, 1e6 * t.median_seconds / set.periods,
                1e6 * t.median_seconds / static_cast<double>(t.searches),
                static_cast<double>(t.searches) / set.periods, static_cast<double>(t.events) / set.periods, median,
                mean, static_cast<double>(t.evaluation_points) / static_cast<double>(t.searches));
  }
  std::printf("\n");
  const Sampled tight = sampled_run(scene, t_end, set.periods, 1e-13);
  const Timing tight_time = timed_runs(scene, t_end, 1e-13, std::max(1, set.repeat / 3));
  std::printf("| chatter_height | µs / period | events / s | impacts | chatters | bounces / chatter sequence (mean, max) | max state error |\n"
              "|---|---|---|---|---|---|---|\n");
  std::vector<Sampled> kept;
  kept.reserve(set.heights.size());
  for (double h : set.heights) {
    kept.push_back(sampled_run(scene, t_end, set.periods, h));
    const Sampled& r = kept.back();
    const Timing t = timed_runs(scene, t_end, h, set.repeat);
    const auto [bounces, most] = chatter_bounces(r);
    std::printf("| %.0e | %.1f | %.3g | %ld | %ld | %.1f, %ld | %.2e |\n", h, 1e6 * t.median_seconds / set.periods,
                static_cast<double>(t.events) / t.median_seconds, r.summary.impacts, r.summary.chatters, bounces, most,
                state_error(r, tight, t_end));
  }
  const auto [tight_bounces, tight_most] = chatter_bounces(tight);
  std::printf("| 1e-13 (reference) | %.1f | %.3g | %ld | %ld | %.1f, %ld | 0 |\n",
              1e6 * tight_time.median_seconds / set.periods,
              static_cast<double>(tight_time.events) / tight_time.median_seconds, tight.summary.impacts,
              tight.summary.chatters, tight_bounces, tight_most);
#ifdef VIBRO_BENCH_WITH_REFERENCE
  if (set.reference) {
    std::vector<std::pair<std::string, const Sampled*>> runs;
    char name[32];
    for (std::size_t i = 0; i < set.heights.size(); ++i) {
      std::snprintf(name, sizeof name, "%.0e", set.heights[i]);
      runs.emplace_back(name, &kept[i]);
    }
    runs.emplace_back("1e-13", &tight);
    cross_check(scene, t_end, 2.0 * std::numbers::pi / omega, runs);
  }
#else
  if (set.reference) std::printf("(--reference: built without tests/support; not available)\n");
#endif
}

}  // namespace

int main(int argc, char** argv) {
  Settings set;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--periods" && i + 1 < argc) set.periods = std::atoi(argv[++i]);
    else if (a == "--repeat" && i + 1 < argc) set.repeat = std::atoi(argv[++i]);
    else if (a == "--height" && i + 1 < argc) set.heights.push_back(std::atof(argv[++i]));
    else if (a == "--reference") set.reference = true;
    else if (a == "--timing-only") set.timing_only = true;
    else if (a == "--trigger" && i + 1 < argc) g_trigger = std::atof(argv[++i]);
    else if (a == "--rule" && i + 1 < argc) {
      const std::string r = argv[++i];
      if (r != "first" && r != "second" && r != "third") {
        std::fprintf(stderr, "bench_engine: --rule is first, second or third, not %s\n", r.c_str());
        return 2;
      }
      g_rule = r == "first"    ? vibro::ChatterRule::first_order
               : r == "second" ? vibro::ChatterRule::second_order
                               : vibro::ChatterRule::third_order;
    }
    else if (a == "--problem" && i + 1 < argc) set.problems = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_engine [--periods P] [--repeat R] [--reference] [--height h]... "
                         "[--problem a|b|ab] [--timing-only] [--rule first|second|third] [--trigger ε]\n");
      return 2;
    }
  }
  if (set.periods < 1 || set.repeat < 1) {
    std::fprintf(stderr, "bench_engine: --periods and --repeat must be ≥ 1\n");
    return 2;
  }
  if (set.heights.empty()) set.heights = {1e-6, 1e-7, 1e-8, 1e-9, 1e-10};
  if (set.problems.find('a') != std::string::npos) study("(a) Wagg (2004), Omega = 0.255", 0.255, set);
  if (set.problems.find('b') != std::string::npos) study("(b) Wagg (2004), Omega = 0.27", 0.27, set);
}
