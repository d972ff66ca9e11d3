// The run kinds that only run the scene — diagram, basin, locate, sweep — on the Taylor engine
// (nonlinear forces), through `vibro run`'s runner, with the same result files as on the exact
// engines:
//  - a linear scene forced onto the Taylor engine (solver.engine: taylor, or a force with a zero
//    coefficient) writes what the exact dense engine writes: the same periods, labels,
//    transitions and events, and the same numbers to ~1e-12 of their scales;
//  - on the Duffing impact oscillator (experiments/examples/duffing_impact_continuation.yaml)
//    the diagram's jumps and locate's period transition lie where continuation (its own method:
//    Newton shooting, tangent maps, test functions) locates the folds and the period doubling;
//  - a run stopped through RunRequest::interrupt (what SIGINT/SIGTERM raise in `vibro run`)
//    stops on the Taylor engine as on the others (exit 130, the file says interrupted).
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

using vibro::io::ResultReader;
using vibro::io::RunReport;
using vibro::io::RunRequest;
using vibro::io::Scene;
using vibro::io::SceneDocument;

namespace {

/// A file in this test process's own directory (ctest runs every test case in its own process).
std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

/// The paper's two-mass system (Wagg 2004; experiments/wagg2004): impacts, chatter, sticking.
std::string wagg(double omega, const std::string& run) {
  return "model:\n  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}\n"
         "forcing: {frequency: " + std::to_string(omega) + ", cosine: [0.5, 0]}\n"
         "stops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}\n"
         "  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}\n"
         "initial: {x: [0, 0], v: [0, 0]}\n" + run;
}

/// x'' + c x' + x + 0.5 x³ = 0.8 cos Ω t, a rigid stop at x = 0.6 with r = 0.8
/// (experiments/examples/duffing_impact_continuation.yaml; c = 0.05 there).
std::string duffing(double omega, double damping, const std::string& run) {
  return "model:\n  chain:\n    masses: [1]\n    left_wall: {spring: 1, damper: " + std::to_string(damping) + "}\n"
         "forcing:\n  frequency: " + std::to_string(omega) + "\n  cosine: [0.8]\n"
         "stops:\n  - {mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop}\n"
         "parameters: {beta: 0.5}\n"
         "forces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n"
         "initial: {x: [0], v: [0]}\n" + run;
}

/// The scene with `solver: {engine: taylor}` added.
std::string on_taylor(const std::string& text) { return "solver: {engine: taylor}\n" + text; }

/// The scene with a cubic spring of coefficient 0 on mass 0: it has forces, so it runs on the
/// Taylor engine, and they add nothing.
std::string with_zero_force(const std::string& text) {
  return "parameters: {beta: 0}\nforces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n" + text;
}

/// Runs `text` into a file of its own (`name`.h5); requires the exit code and the engine.
std::string run(const std::string& text, const std::string& name, const std::string& engine, int exit_code = 0) {
  const SceneDocument doc = SceneDocument::parse(text, name + ".yaml");
  const Scene scene = doc.build();
  REQUIRE(std::string(vibro::io::to_string(scene.engine)) == engine);
  const std::string out = temp_path(name + ".h5");
  std::filesystem::remove(out);
  RunRequest request;
  request.output = out;
  request.threads = 1;
  const RunReport report = vibro::io::run_scene(doc, scene, request);
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == exit_code);
  REQUIRE(ResultReader(out).attribute_string("/meta", "engine") == engine);
  return out;
}

double max_abs(const std::vector<double>& a) {
  double m = 0.0;
  for (double x : a) m = std::max(m, std::abs(x));
  return m;
}

/// max |a − b| / max |a| (0 for two empty or zero vectors); requires equal sizes.
double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  const double s = max_abs(a);
  return s > 0.0 ? d / s : d;
}

// The engines agree to ~1e-13 of the scales per run (tests/taylor/test_taylor_engine.cpp); the
// records below come after hundreds of periods with impacts and chatter sequences on contracting
// orbits, where the differences stay at that level: measured up to 4e-12 of the dataset's largest
// value (velocities just after impacts). 2e-11 holds them with room, and a wrong event (a missed
// impact, a different chatter count) changes them by O(1e-2) or more.
constexpr double kSame = 2e-11;

/// The located bifurcations of `kind` in a continuation's result (on `branch`; any branch when
/// −1), in increasing parameter.
std::vector<double> located(const ResultReader& r, const std::string& kind, std::int64_t branch = -1) {
  const auto names = r.attribute_strings("/bifurcations/kind", "names");
  const auto kinds = r.read_integers("/bifurcations/kind");
  const auto branches = r.read_integers("/bifurcations/branch");
  const auto ps = r.read("/bifurcations/p");
  std::vector<double> out;
  for (std::size_t i = 0; i < kinds.size(); ++i)
    if (names.at(static_cast<std::size_t>(kinds[i])) == kind && (branch < 0 || branches[i] == branch))
      out.push_back(ps[i]);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

// Two stretches of the paper's system: Ω ∈ [0.24, 0.28], where the orbits stick and chatter, and
// Ω ∈ [1.1, 1.3], where a period-2 and a period-1 orbit coexist (the up and down directions
// differ, and the period changes along each).
TEST_CASE("Taylor engine: a diagram of a linear scene equals the dense engine's", "[taylor][kinds]") {
  for (const std::string grid : {"[0.24, 0.28, 3]", "[1.1, 1.3, 5]"}) {
    INFO("grid " << grid);
    const std::string text = wagg(0.24, R"(run:
  kind: diagram
  transient_periods: 100
  diagram:
    path: forcing.frequency
    linspace: )" + grid + R"(
    transient: 100
    points: 32
    directions: both
    max_period: 16
    tolerance: 1e-6
)");
    const std::string name = grid[1] == '0' ? "diagram_sticking" : "diagram_periods";
    const ResultReader dense(run(text, name + "_dense", "dense"));
    const ResultReader taylor(run(on_taylor(text), name + "_taylor", "taylor"));
    for (const std::string d : {"up", "down"}) {
      INFO("direction " << d);
      for (const std::string dataset : {"k_", "reached_", "verdict_", "extra_periods_"})
        CHECK(taylor.read_integers("/diagram/" + dataset + d) == dense.read_integers("/diagram/" + dataset + d));
      CHECK(taylor.read("/diagram/impacts_" + d) == dense.read("/diagram/impacts_" + d));
      CHECK(relative_difference(dense.read("/diagram/x_" + d), taylor.read("/diagram/x_" + d)) < kSame);
      CHECK(relative_difference(dense.read("/diagram/v_" + d), taylor.read("/diagram/v_" + d)) < kSame);
    }
    if (name == "diagram_periods") {  // not a trivial diagram: periods 1, 2 and 5 met
      const auto up = dense.read_integers("/diagram/k_up"), down = dense.read_integers("/diagram/k_down");
      CHECK(up != down);
      CHECK(*std::max_element(up.begin(), up.end()) > *std::min_element(up.begin(), up.end()));
    }
  }
}

TEST_CASE("Taylor engine: a basin of a linear scene has the dense engine's attractors and labels", "[taylor][kinds]") {
  const std::string text = wagg(1.2, R"(run:
  kind: basin
  basin:
    parameters:
      - {path: "initial.x[0]", linspace: [-0.29, 0.6, 8]}
      - {path: "initial.v[0]", linspace: [-0.6, 0.6, 8]}
    max_period: 8
    max_periods: 1000
    tolerance: 1e-8
    match: 1e-5
    seed_stride: 4
)");
  const ResultReader dense(run(text, "basin_dense", "dense"));
  const ResultReader taylor(run(on_taylor(text), "basin_taylor", "taylor"));
  CHECK(taylor.read_integers("/basin/label") == dense.read_integers("/basin/label"));
  CHECK(taylor.read_integers("/basin/periods_used") == dense.read_integers("/basin/periods_used"));
  CHECK(taylor.read_integers("/attractors/period") == dense.read_integers("/attractors/period"));
  CHECK(taylor.read_integers("/attractors/cells") == dense.read_integers("/attractors/cells"));
  CHECK(relative_difference(dense.read("/attractors/x"), taylor.read("/attractors/x")) < kSame);
  CHECK(relative_difference(dense.read("/attractors/v"), taylor.read("/attractors/v")) < kSame);
  CHECK(dense.read_integers("/attractors/period").size() == 2);  // a period-2 and a period-1 orbit coexist
}

// The paper's rising (multi-sliding) bifurcation at Ω ≈ 0.256006, between two grid values: the
// running orbits stick, chatter and impact. Bisection's midpoints depend on the grid alone, so
// the same decisions give the same located value to the bit; the least interior contact force at
// the bracket's ends agrees to the engines' force agreement (~1e-11 of the force scale, ~0.2).
TEST_CASE("Taylor engine: locate on a linear scene finds the dense engine's transition", "[taylor][kinds]") {
  const std::string text = wagg(0.255, R"(run:
  kind: locate
  transient_periods: 200
  locate:
    path: forcing.frequency
    values: [0.2559, 0.2561]
    tolerance: 1e-8
    periodicity: 1e-10
)");
  const ResultReader dense(run(text, "locate_dense", "dense"));
  const ResultReader taylor(run(with_zero_force(text), "locate_taylor", "taylor"));
  REQUIRE(dense.read_integers("/transitions/kind").size() == 1);
  CHECK(dense.attribute_strings("/transitions/kind", "names").at(static_cast<std::size_t>(
            dense.read_integers("/transitions/kind")[0])) == "rising");
  CHECK(taylor.read_integers("/transitions/kind") == dense.read_integers("/transitions/kind"));
  CHECK(taylor.read_integers("/transitions/stop") == dense.read_integers("/transitions/stop"));
  CHECK(taylor.read_integers("/transitions/evaluations") == dense.read_integers("/transitions/evaluations"));
  const double p_dense = dense.read("/transitions/parameter").at(0), p_taylor = taylor.read("/transitions/parameter").at(0);
  CHECK(std::abs(p_taylor - p_dense) <= 1e-12);
  CHECK(std::abs(taylor.read("/transitions/force_limit").at(0) - dense.read("/transitions/force_limit").at(0)) < 1e-10);
  CHECK(taylor.read_integers("/phases/stop") == dense.read_integers("/phases/stop"));
  CHECK(relative_difference(dense.read("/scan/x"), taylor.read("/scan/x")) < kSame);
  CHECK(relative_difference(dense.read("/scan/v"), taylor.read("/scan/v")) < kSame);
  WARN("rising located at Ω = " << p_dense << " (dense), " << p_taylor << " (Taylor)");
}

// A followed sweep recording everything, at two values across the rising: events (impacts,
// chatter limits, sticks, releases), contact intervals, Poincaré points and samples. Event
// times (t ~ 5e3) agree to ~1e-13 relative (measured 5e-14).
TEST_CASE("Taylor engine: a sweep of a linear scene records the dense engine's states and events", "[taylor][kinds]") {
  const std::string text = wagg(0.255, R"(record:
  events: true
  contacts: true
  poincare: true
  samples: {per_period: 400}
run:
  kind: sweep
  transient_periods: 200
  periods: 4
  sweep:
    parameters:
      - {path: forcing.frequency, values: [0.2560, 0.2561]}
    follow: true
)");
  const ResultReader dense(run(text, "sweep_dense", "dense"));
  const ResultReader taylor(run(with_zero_force(text), "sweep_taylor", "taylor"));
  for (const std::string name : {"/events/kind", "/events/stop", "/events/point", "/contacts/stop", "/sweep/status"})
    CHECK(taylor.read_integers(name) == dense.read_integers(name));
  // Counts: impacts, sticks, releases, chatters, segments (the last two columns count the
  // engines' own cached flows).
  const auto cd = dense.read_integers("/sweep/counts"), ct = taylor.read_integers("/sweep/counts");
  REQUIRE(cd.size() == ct.size());
  for (std::size_t i = 0; i < cd.size(); ++i)
    if (i % 7 < 5) CHECK(ct[i] == cd[i]);
  CHECK(relative_difference(dense.read("/events/t"), taylor.read("/events/t")) < 1e-13);
  for (const std::string name : {"/events/v_before", "/events/v_after", "/poincare/x", "/poincare/v", "/samples/x",
                                 "/samples/v", "/sweep/x_end", "/sweep/v_end"}) {
    INFO(name);
    CHECK(relative_difference(dense.read(name), taylor.read(name)) < kSame);
  }
  const auto kinds = dense.read_integers("/events/kind");
  CHECK(std::count(kinds.begin(), kinds.end(), 2) > 0);  // releases: the orbits stick
}

// Continuation of the Duffing impact oscillator's period-1 branch (the `continue` kind: Newton
// shooting on the Taylor engine's maps) locates two folds, the ends of a hysteresis loop (Ω ≈
// 0.8423 and 0.9087). The diagram, by plain runs alone, must jump exactly there: going up it
// follows the two-impact orbit until the upper fold and drops to one impact per period; going
// down it follows the one-impact orbit until the lower fold.
TEST_CASE("Taylor engine: the Duffing impact oscillator's diagram jumps at the folds continuation locates",
          "[taylor][kinds]") {
  const ResultReader cont(run(duffing(0.85, 0.05, R"(run:
  kind: continue
  transient_periods: 60
  continue:
    path: forcing.frequency
    range: [0.83, 0.93]
    step: 0.01
    max_step: 0.02
)"), "fold_continue", "taylor"));
  const std::vector<double> folds = located(cont, "fold");
  REQUIRE(folds.size() == 2);

  const ResultReader diagram(run(duffing(0.83, 0.05, R"(run:
  kind: diagram
  transient_periods: 100
  diagram:
    path: forcing.frequency
    linspace: [0.83, 0.92, 91]
    transient: 60
    points: 8
    directions: both
    max_period: 4
    tolerance: 1e-6
)"), "fold_diagram", "taylor"));
  const std::vector<double> grid = diagram.read("/diagram/parameter");
  // The one place where the impacts per period change, as [grid value before, after] in the
  // direction's order, with the counts either side.
  struct Jump {
    double from, to, before, after;
    int count;
  };
  auto jump = [&](const std::string& d) {
    const std::vector<double> impacts = diagram.read("/diagram/impacts_" + d);
    const auto reached = diagram.read_integers("/diagram/reached_" + d);
    const auto k = diagram.read_integers("/diagram/k_" + d);
    CHECK(std::count(reached.begin(), reached.end(), 1) == static_cast<long>(grid.size()));
    CHECK(std::count(k.begin(), k.end(), 1) == static_cast<long>(grid.size()));  // period 1 throughout
    Jump j{0, 0, 0, 0, 0};
    for (std::size_t g = 0; g + 1 < grid.size(); ++g) {
      const std::size_t a = d == "up" ? g : grid.size() - 1 - g, b = d == "up" ? a + 1 : a - 1;
      if (impacts[a] != impacts[b]) j = {grid[a], grid[b], impacts[a], impacts[b], j.count + 1};
    }
    return j;
  };
  const Jump up = jump("up"), down = jump("down");
  INFO("folds at Ω = " << folds[0] << ", " << folds[1] << "; up: " << up.before << " → " << up.after << " impacts between "
       << up.from << " and " << up.to << "; down: " << down.before << " → " << down.after << " between " << down.from
       << " and " << down.to);
  CHECK(up.count == 1);
  CHECK(up.before == 2.0);
  CHECK(up.after == 1.0);
  CHECK(up.from < folds[1]);
  CHECK(folds[1] < up.to);
  CHECK(down.count == 1);
  CHECK(down.before == 1.0);
  CHECK(down.after == 2.0);
  CHECK(down.to < folds[0]);
  CHECK(folds[0] < down.from);
  WARN("folds at Ω = " << folds[0] << ", " << folds[1] << "; the diagram jumps in [" << down.to << ", " << down.from
       << "] going down and in [" << up.from << ", " << up.to << "] going up");
}

// With lighter damping (c = 0.02) the branch's period-1 orbit doubles at Ω ≈ 0.7138
// (continuation). locate sees a doubling through its running orbits, which converge slowly on
// both sides of it (|μ| → 1), as one `period` transition whose bracket spans the slow stretch
// (running_locate.hpp, merge_doublings): the doubling continuation locates must lie inside it.
TEST_CASE("Taylor engine: locate's period transition of a Duffing impact oscillator holds continuation's doubling",
          "[taylor][kinds]") {
  const ResultReader cont(run(duffing(0.705, 0.02, R"(run:
  kind: continue
  transient_periods: 60
  continue:
    path: forcing.frequency
    range: [0.70, 0.725]
    step: 0.01
    max_step: 0.02
)"), "pd_continue", "taylor"));
  const std::vector<double> pd = located(cont, "period_doubling", 0);
  REQUIRE(pd.size() == 1);

  const ResultReader locate(run(duffing(0.71, 0.02, R"(run:
  kind: locate
  transient_periods: 200
  locate:
    path: forcing.frequency
    values: [0.71, 0.72]
    tolerance: 1e-8
    periodicity: 1e-8
    max_period: 4
    max_periods: 600
)"), "pd_locate", "taylor"));
  const auto tnames = locate.attribute_strings("/transitions/kind", "names");
  const auto tkinds = locate.read_integers("/transitions/kind");
  REQUIRE(tkinds.size() == 1);
  CHECK(tnames.at(static_cast<std::size_t>(tkinds[0])) == "period");
  CHECK(locate.read_integers("/transitions/k_low") == std::vector<std::int64_t>{1});
  CHECK(locate.read_integers("/transitions/k_high") == std::vector<std::int64_t>{2});
  const double lo = locate.read("/transitions/parameter_low").at(0), hi = locate.read("/transitions/parameter_high").at(0);
  INFO("doubling at Ω = " << pd[0] << "; locate's bracket [" << lo << ", " << hi << "]");
  CHECK(lo < pd[0]);
  CHECK(pd[0] < hi);
  WARN("period doubling by continuation at Ω = " << pd[0] << ", inside locate's bracket [" << lo << ", " << hi << "]");
}

// Stopped from outside after the first point (RunRequest::interrupt, the flag SIGINT and SIGTERM
// raise in `vibro run`): the Taylor engine's next run ends at once and the kind writes what it
// has, as on the other engines.
TEST_CASE("Taylor engine: diagram, basin, locate and sweep stop when interrupted", "[taylor][kinds]") {
  const std::vector<std::pair<std::string, std::string>> runs{
      {"diagram", "run:\n  kind: diagram\n  diagram: {path: forcing.frequency, linspace: [0.8, 0.9, 6], points: 8, "
                  "max_period: 4}\n"},
      {"basin", "run:\n  kind: basin\n  basin:\n    parameters:\n      - {path: \"initial.x[0]\", linspace: [-1, 0.5, 4]}\n"
                "      - {path: \"initial.v[0]\", linspace: [-1, 1, 4]}\n    seed_stride: 2\n"},
      {"locate", "run:\n  kind: locate\n  locate: {path: forcing.frequency, linspace: [0.8, 0.9, 6]}\n"},
      {"sweep", "run:\n  kind: sweep\n  periods: 10\n  sweep:\n    parameters:\n      - {path: parameters.beta, "
                "linspace: [0, 1, 6]}\n"},
  };
  for (const auto& [kind, section] : runs) {
    INFO(kind);
    const SceneDocument doc = SceneDocument::parse(duffing(0.85, 0.05, section), kind + ".yaml");
    const Scene scene = doc.build();
    REQUIRE(scene.engine == vibro::io::EngineKind::taylor);
    const std::string out = temp_path("stopped_" + kind + ".h5");
    std::filesystem::remove(out);
    std::atomic<bool> stop{false};
    RunRequest request;
    request.output = out;
    request.threads = 1;
    request.interrupt = &stop;
    request.on_progress = [&stop](double done, double) {
      if (done >= 1.0) stop = true;
    };
    const RunReport report = vibro::io::run_scene(doc, scene, request);
    CAPTURE(report.summary);
    CHECK(report.exit_code == 130);
    if (kind == "sweep") {  // kept as OUT.partial for --resume
      CHECK(std::filesystem::exists(vibro::io::ResultFile::partial_path(out)));
    } else {
      REQUIRE(std::filesystem::exists(out));
      CHECK(ResultReader(out).attribute_string("/meta", "status") == "interrupted");
    }
  }
}
