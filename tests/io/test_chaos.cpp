// The chaos and multistability run kinds (issue 16).
// basin: every grid point's label is the attractor an independent long run from that start ends
// on (run_to_periodic_orbit, a tighter tolerance, no early stop), the attractors are periodic
// orbits, the file is the same for any number of threads, runs stop early, and points that never
// settle are labelled as such.
// diagram, lyapunov and orbit: the files hold what the engine and the library give when called directly
// (to the bit), the detected periods are the orbits' (a period doubling, hysteresis between the
// up and down sweeps), and chaos has a positive exponent.
#include "vibro/io/kinds/basin.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/lyapunov.hpp"
#include "vibro/running_orbit.hpp"
#include "vibro/shooting.hpp"

#include "support/six_mass_chain.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <numeric>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

// The paper's system (Wagg 2004) at Ω = 1.2, where a period-2 and a period-1 orbit coexist
// (experiments/chaos/basin_wagg.yaml; an up sweep stays on the first, a down sweep on the second).
const std::string kWagg = R"(
name: wagg
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
forcing:
  frequency: 1.2
  cosine: [0.5, 0]
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
initial:
  x: [0, 0]
  v: [0, 0]
)";

// A basin over starts of mass 0 on a coarse grid.
const std::string kBasin = kWagg + R"(
run:
  kind: basin
  basin:
    parameters:
      - {path: "initial.x[0]", linspace: [-0.29, 0.6, 10]}
      - {path: "initial.v[0]", linspace: [-0.6, 0.6, 10]}
    seed_stride: 4
)";

// The two-mass chain of experiments/examples/pd_cascade.yaml: its period-1 orbit doubles at
// Ω ≈ 1.682, the period-2 orbit at 1.7336; past Ω∞ ≈ 1.75008 the attractor is chaotic.
const std::string kChain = R"(
name: cascade
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.02]
    left_wall: {spring: 1, damper: 0.02}
forcing:
  frequency: 1.66
  cosine: [0.3, 0]
stops:
  - {mass: 1, side: upper, position: 0, restitution: 0.8, name: s}
initial:
  x: [0, 0]
  v: [0, 0]
solver:
  engine: dense
)";

std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

/// Runs `text` into a file of this test's directory; the run must exit with code 0.
ResultReader run_file(const std::string& text, const std::string& name, int threads = 2) {
  const SceneDocument doc = SceneDocument::parse(text, name + ".yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path(name + ".h5");
  std::filesystem::remove(out);
  RunRequest request;
  request.output = out;
  request.threads = threads;
  const RunReport report = run_scene(doc, scene, request);
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  REQUIRE_FALSE(std::filesystem::exists(ResultFile::partial_path(out)));
  return ResultReader(out);
}

double distance(const Eigen::VectorXd& xa, const Eigen::VectorXd& va, const Eigen::VectorXd& xb,
                const Eigen::VectorXd& vb) {
  return std::max((xa - xb).cwiseAbs().maxCoeff(), (va - vb).cwiseAbs().maxCoeff());
}

}  // namespace

TEST_CASE("a basin labels every start with the attractor a long run from it ends on", "[runner][basin]") {
  const ResultReader r = run_file(kBasin, "basin", 2);
  CHECK(r.attribute_string("/scene", "run_kind") == "basin");
  CHECK(r.attribute_string("/meta", "status") == "completed");
  CHECK(r.attribute_string("/basin", "p1") == "initial.x[0]");
  REQUIRE(r.shape("/basin/label") == std::vector<std::size_t>{10, 10});
  const auto label = r.read_integers("/basin/label");
  const auto used = r.read_integers("/basin/periods_used");
  const auto period = r.read_integers("/attractors/period");
  const auto first = r.read_integers("/attractors/first");
  const auto cells = r.read_integers("/attractors/cells");
  const Eigen::MatrixXd ax = r.read_matrix("/attractors/x"), av = r.read_matrix("/attractors/v");
  // Both coexisting orbits are found, each the basin of some starts.
  REQUIRE(period.size() == 2);
  CHECK(std::is_permutation(period.begin(), period.end(), std::vector<std::int64_t>{1, 2}.begin()));
  CHECK(std::accumulate(cells.begin(), cells.end(), std::int64_t{0}) == 100);
  CHECK(std::count(label.begin(), label.end(), 0) == cells[0]);
  CHECK(*std::min_element(cells.begin(), cells.end()) > 0);

  const SceneDocument doc = SceneDocument::parse(kBasin, "basin.yaml");
  const Scene scene = doc.build();
  const auto engine = make_engine(scene);
  const double T = scene.period();
  // Each attractor is a periodic orbit: k periods from its first point come back to it.
  for (std::size_t a = 0; a < period.size(); ++a) {
    const Eigen::Index row = first[a];
    const Eigen::VectorXd x = ax.row(row).transpose(), v = av.row(row).transpose();
    const RunSummary s = engine->run(scene.t0, x, v, scene.t0 + static_cast<double>(period[a]) * T);
    CHECK(distance(s.x, s.v, x, v) < 1e-7);
  }
  // Every start, run without early stop to a tighter periodicity, ends on its labelled attractor.
  RunningOrbitOptions options;
  options.tolerance = 1e-11;
  options.max_periods = 5000;
  const auto p1 = r.read("/basin/p1"), p2 = r.read("/basin/p2");
  for (std::size_t i = 0; i < 10; ++i)
    for (std::size_t j = 0; j < 10; ++j) {
      SceneDocument point(doc);
      point.set("initial.x[0]", p1[i]);
      point.set("initial.v[0]", p2[j]);
      const Scene s = point.build_point();
      const RunningOrbit o = run_to_periodic_orbit(*engine, options, s.t0, s.x0, s.v0);
      CAPTURE(i, j, p1[i], p2[j]);
      REQUIRE(o.periodic);
      const std::int64_t l = label[i * 10 + j];
      REQUIRE(l >= 0);
      CHECK(o.k == period[static_cast<std::size_t>(l)]);
      // The orbit's state (at a multiple of T) is one of the labelled attractor's points.
      double best = 1e300;
      for (std::int64_t q = 0; q < period[static_cast<std::size_t>(l)]; ++q) {
        const Eigen::Index row = first[static_cast<std::size_t>(l)] + q;
        best = std::min(best, distance(o.x, o.v, ax.row(row).transpose(), av.row(row).transpose()));
      }
      CHECK(best < 1e-6);
      // Runs stop early: a labelled run stops before the budget, and not later than the long run.
      CHECK(used[i * 10 + j] <= o.periods_run);
    }
}

TEST_CASE("a basin file is the same for one and two threads", "[runner][basin]") {
  const ResultReader one = run_file(kBasin, "basin1", 1);
  const ResultReader two = run_file(kBasin, "basin2", 2);
  for (const char* d : {"/basin/label", "/basin/periods_used", "/attractors/period", "/attractors/cells"})
    CHECK(one.read_integers(d) == two.read_integers(d));
  CHECK(one.read("/attractors/x") == two.read("/attractors/x"));
  CHECK(one.read("/attractors/v") == two.read("/attractors/v"));
}

TEST_CASE("a basin labels starts that do not settle within the budget as not converged", "[runner][basin]") {
  // Ω = 1.75: a period-1 orbit beside a chaotic attractor (no repeat within 300 periods).
  std::string text = kBasin;
  text.replace(text.find("frequency: 1.2"), 14, "frequency: 1.75");
  text.replace(text.find("seed_stride: 4"), 14, "seed_stride: 4\n    max_periods: 300");
  const ResultReader r = run_file(text, "basin_chaos", 2);
  const auto label = r.read_integers("/basin/label");
  const auto used = r.read_integers("/basin/periods_used");
  const auto period = r.read_integers("/attractors/period");
  CHECK(period == std::vector<std::int64_t>{1});
  const auto chaotic = std::count(label.begin(), label.end(), -1);
  CHECK(chaotic > 10);
  CHECK(std::count(label.begin(), label.end(), 0) > 10);
  for (std::size_t g = 0; g < label.size(); ++g) {
    if (label[g] == -1) CHECK(used[g] == 300);
    if (label[g] == 0) CHECK(used[g] < 300);
  }
  CHECK(r.attribute_number("/meta", "points_not_converged") == static_cast<double>(chaotic));
}

TEST_CASE("a basin labels starts outside a stop -4 and runs the others as without them", "[runner][basin]") {
  // Rows x0 = -0.5 and -0.4 lie below the lower stop of mass 0 (at -0.3): inadmissible starts.
  auto basin = [](const std::string& rows) {
    return kWagg + "run:\n  kind: basin\n  basin:\n    parameters:\n      - {path: \"initial.x[0]\", values: " + rows +
           "}\n      - {path: \"initial.v[0]\", values: [-0.6, 0.0, 0.6]}\n    seed_stride: 1\n";
  };
  const std::string text = basin("[-0.5, -0.4, -0.2, 0.0, 0.3, 0.6]");
  const SceneDocument doc = SceneDocument::parse(text, "basin_outside.yaml");
  const Scene scene = doc.build();  // the grid's inadmissible starts do not refuse the scene
  RunRequest request;
  request.output = temp_path("basin_outside.h5");
  request.threads = 2;
  const RunReport report = run_scene(doc, scene, request);
  CAPTURE(report.summary);
  CHECK(report.exit_code == 0);
  CHECK(report.summary.find("6 starts outside a stop, not run (label -4)") != std::string::npos);
  const ResultReader r(request.output);
  CHECK(r.attribute_string("/meta", "status") == "completed");
  CHECK(r.attribute_number("/meta", "points_inadmissible") == 6.0);
  const auto label = r.read_integers("/basin/label"), used = r.read_integers("/basin/periods_used");
  REQUIRE(label.size() == 18);
  for (std::size_t g = 0; g < 6; ++g) {
    CHECK(label[g] == -4);
    CHECK(used[g] == 0);
  }
  // The admissible starts: as a basin of those rows alone (seeds in the same order).
  const ResultReader alone = run_file(basin("[-0.2, 0.0, 0.3, 0.6]"), "basin_inside", 2);
  CHECK(std::vector<std::int64_t>(label.begin() + 6, label.end()) == alone.read_integers("/basin/label"));
  CHECK(std::vector<std::int64_t>(used.begin() + 6, used.end()) == alone.read_integers("/basin/periods_used"));
  CHECK(r.read("/attractors/x") == alone.read("/attractors/x"));
  CHECK(alone.attribute_number("/meta", "points_inadmissible") == 0.0);

  // Any other invalid grid value still refuses the scene, naming the value.
  std::string bad = kWagg + R"(
run:
  kind: basin
  basin:
    parameters:
      - {path: "stops[0].restitution", values: [0.5, 1.5]}
      - {path: "initial.v[0]", values: [-0.6, 0.6]}
)";
  CHECK_THROWS_WITH(SceneDocument::parse(bad, "bad.yaml").build(),
                    Catch::Matchers::Contains("stops[0].restitution = 1.5 makes the scene invalid"));
}

TEST_CASE("a diagram records the followed attractor, its period and its impacts", "[runner][diagram]") {
  const std::string text = kChain + R"(
run:
  kind: diagram
  transient_periods: 300
  diagram:
    path: forcing.frequency
    values: [1.70, 1.66]
    transient: 300
    points: 8
    max_period: 4
)";
  const ResultReader r = run_file(text, "diagram");
  CHECK(r.attribute_string("/scene", "run_kind") == "diagram");
  CHECK(r.attribute_string("/diagram", "parameter") == "forcing.frequency");
  CHECK(r.read("/diagram/parameter") == std::vector<double>{1.66, 1.70});  // sorted
  REQUIRE(r.shape("/diagram/x_up") == std::vector<std::size_t>{2, 8, 2});
  // Below the first doubling one impact per period on the period-1 orbit, above it period 2.
  CHECK(r.read_integers("/diagram/k_up") == std::vector<std::int64_t>{1, 2});
  CHECK(r.read_integers("/diagram/k_down") == std::vector<std::int64_t>{1, 2});
  CHECK(r.read("/diagram/impacts_up").at(0) == 1.0);
  CHECK(r.read_integers("/diagram/reached_down") == std::vector<std::int64_t>{1, 1});

  // The up sweep's first point is 300 + 8 periods from rest at Ω = 1.66: the engine directly.
  const SceneDocument doc = SceneDocument::parse(text, "diagram.yaml");
  SceneDocument at(doc);
  at.set("forcing.frequency", 1.66);
  const Scene scene = at.build_point();
  const auto engine = make_engine(scene);
  const double T = scene.period();
  RunSummary s = engine->run(0.0, scene.x0, scene.v0, 300 * T);
  const std::vector<double> x = r.read("/diagram/x_up"), v = r.read("/diagram/v_up");
  for (int i = 1; i <= 8; ++i) {
    s = engine->run(300 * T + (i - 1) * T, s.x, s.v, 300 * T + i * T);
    for (int j = 0; j < 2; ++j) {
      CHECK(x.at(static_cast<std::size_t>((i - 1) * 2 + j)) == s.x(j));
      CHECK(v.at(static_cast<std::size_t>((i - 1) * 2 + j)) == s.v(j));
    }
  }
}

TEST_CASE("a diagram's up and down sweeps show the hysteresis of coexisting orbits", "[runner][diagram]") {
  const ResultReader r = run_file(kWagg + R"(
run:
  kind: diagram
  transient_periods: 200
  diagram:
    path: forcing.frequency
    values: [1.12, 1.2, 1.28]
    transient: 300
    points: 16
    max_period: 8
)",
                                  "hysteresis");
  // Up from Ω = 1.12 the period-2 orbit persists to 1.2; down from 1.28 the period-1 orbit does.
  CHECK(r.read_integers("/diagram/k_up") == std::vector<std::int64_t>{2, 2, 1});
  CHECK(r.read_integers("/diagram/k_down") == std::vector<std::int64_t>{2, 1, 1});
  CHECK(r.read("/diagram/x_up").at(16 * 2) != r.read("/diagram/x_down").at(16 * 2));
}

TEST_CASE("a lyapunov run writes the library's spectrum, along a parameter from point to point",
          "[runner][lyapunov]") {
  const std::string text = kChain + R"(
run:
  kind: lyapunov
  transient_periods: 200
  lyapunov:
    path: forcing.frequency
    values: [1.66, 1.77]
    transient: 100
    align: 20
    periods: 300
)";
  const ResultReader r = run_file(text, "lyapunov");
  CHECK(r.attribute_string("/scene", "run_kind") == "lyapunov");
  REQUIRE(r.shape("/lyapunov/exponents") == std::vector<std::size_t>{2, 4});
  const std::vector<double> e = r.read("/lyapunov/exponents");
  const std::vector<std::int64_t> finite = r.read_integers("/lyapunov/finite");

  // The library directly: the first point from rest, the second from where the first ended.
  const SceneDocument doc = SceneDocument::parse(text, "lyapunov.yaml");
  SceneDocument at(doc);
  LyapunovOptions o;
  o.transient = 300;
  o.align = 20;
  o.periods = 300;
  at.set("forcing.frequency", 1.66);
  const Scene first = at.build_point();
  const LyapunovResult a = lyapunov_spectrum(first.impact_system(), first.solver, 0.0, first.x0, first.v0, o);
  for (int i = 0; i < 4; ++i) CHECK(e.at(static_cast<std::size_t>(i)) == a.exponents(i));
  // On the stable period-1 orbit every exponent is negative (and finite: no stop is held).
  for (std::size_t i = 0; i < 4; ++i) {
    CHECK(finite.at(i) == 1);
    CHECK(e.at(i) < 0.0);
  }
  o.transient = 100;
  at.set("forcing.frequency", 1.77);
  const Scene second = at.build_point();
  const LyapunovResult b = lyapunov_spectrum(second.impact_system(), second.solver, 0.0, a.x_end, a.v_end, o);
  for (int i = 0; i < 4; ++i) {
    const double want = b.exponents(i);
    CHECK(finite.at(static_cast<std::size_t>(4 + i)) == (std::isfinite(want) ? 1 : 0));
    CHECK(e.at(static_cast<std::size_t>(4 + i)) == (std::isfinite(want) ? want : 0.0));
  }
  // Past the cascade: chaos, a positive largest exponent.
  CHECK(e.at(4) > 0.05);
  CHECK(r.read_integers("/lyapunov/structural").at(1) == b.structural);
}

TEST_CASE("a lyapunov run without a grid gives the spectrum at the scene's values", "[runner][lyapunov]") {
  const ResultReader r = run_file(kChain + R"(
run:
  kind: lyapunov
  lyapunov: {transient: 200, align: 20, periods: 200, count: 2}
)",
                                  "lyapunov_single");
  CHECK_FALSE(r.exists("/lyapunov/parameter"));
  REQUIRE(r.shape("/lyapunov/exponents") == std::vector<std::size_t>{1, 2});
  const std::vector<double> e = r.read("/lyapunov/exponents");
  CHECK(e[0] >= e[1]);
  CHECK(e[0] < 0.0);
}

// The same scene on both engines: the modal engine's matrix-free frames give the dense engine's
// spectrum (unit masses: the same numbers up to the maps' rounding; library test in
// tests/analysis/test_modal_tangent.cpp, where the 1e-9 is justified).
TEST_CASE("a lyapunov run on the modal engine writes the dense engine's spectrum", "[runner][lyapunov]") {
  auto scene = [](const std::string& engine) {
    return std::string("\n") + vibro::test::kSixMassChain + R"(initial:
  x: [0, 0, 0, 0, 0, 0]
  v: [0, 0, 0, 0, 0, 0]
solver:
  engine: )" + engine + R"(
run:
  kind: lyapunov
  lyapunov: {transient: 3, align: 2, periods: 6}
)";
  };
  const ResultReader dense = run_file(scene("dense"), "lyapunov_dense");
  const ResultReader modal = run_file(scene("modal"), "lyapunov_modal");
  CHECK(modal.attribute_string("/meta", "engine") == "modal");
  const std::vector<double> a = dense.read("/lyapunov/exponents"), b = modal.read("/lyapunov/exponents");
  REQUIRE(a.size() == 12);
  REQUIRE(b.size() == a.size());
  for (std::size_t i = 0; i < a.size(); ++i) CHECK(std::abs(a[i] - b[i]) <= 1e-9);
  CHECK(dense.read_integers("/lyapunov/finite") == modal.read_integers("/lyapunov/finite"));
  CHECK(dense.read_integers("/lyapunov/structural") == modal.read_integers("/lyapunov/structural"));
}

TEST_CASE("a lyapunov grid without follow runs every point from the initial state, in parallel",
          "[runner][lyapunov]") {
  const std::string text = kChain + R"(
run:
  kind: lyapunov
  transient_periods: 100
  lyapunov:
    path: forcing.frequency
    values: [1.66, 1.70, 1.77]
    follow: false
    transient: 100
    align: 20
    periods: 200
)";
  const ResultReader r = run_file(text, "lyapunov_parallel");
  const std::vector<double> e = r.read("/lyapunov/exponents");
  const std::vector<std::int64_t> finite = r.read_integers("/lyapunov/finite");
  SceneDocument at(SceneDocument::parse(text, "lyapunov_parallel.yaml"));
  LyapunovOptions o;
  o.transient = 200;  // run.transient_periods + transient at every point
  o.align = 20;
  o.periods = 200;
  const std::vector<double> grid{1.66, 1.70, 1.77};
  for (std::size_t g = 0; g < grid.size(); ++g) {
    at.set("forcing.frequency", grid[g]);
    const Scene s = at.build_point();
    const LyapunovResult want = lyapunov_spectrum(s.impact_system(), s.solver, 0.0, s.x0, s.v0, o);
    for (std::size_t i = 0; i < 4; ++i) {
      const double w = want.exponents(static_cast<Eigen::Index>(i));
      CHECK(finite.at(g * 4 + i) == (std::isfinite(w) ? 1 : 0));
      CHECK(e.at(g * 4 + i) == (std::isfinite(w) ? w : 0.0));
    }
  }
}

TEST_CASE("an interrupted basin is written with its points not run labelled -3 and exit code 130",
          "[runner][basin]") {
  const SceneDocument doc = SceneDocument::parse(kBasin, "basin_stopped.yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path("basin_stopped.h5");
  std::filesystem::remove(out);
  std::atomic<bool> stop{true};  // raised before the run: no point runs
  RunRequest request;
  request.output = out;
  request.threads = 2;
  request.interrupt = &stop;
  const RunReport report = run_scene(doc, scene, request);
  CAPTURE(report.summary);
  CHECK(report.exit_code == 130);
  const ResultReader r(out);
  CHECK(r.attribute_string("/meta", "status") == "interrupted");
  const auto label = r.read_integers("/basin/label");
  CHECK(std::count(label.begin(), label.end(), -3) == 100);
  CHECK(r.read_integers("/attractors/period").empty());
}

namespace {

/// A chain of ten unit masses (dampers 0.2, the wall too), 0.5 cos 0.3t on mass 0, stops under
/// mass 0 and above mass 9 (bench_continuation's chain): a stable period-1 orbit with impacts.
std::string orbit_scene(const std::string& engine, const std::string& orbit = "{period: 1}") {
  return R"(
model:
  chain:
    masses: [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]
    springs: [1, 1, 1, 1, 1, 1, 1, 1, 1]
    dampers: [0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2]
    left_wall: {spring: 1, damper: 0.2}
forcing:
  frequency: 0.3
  cosine: [0.5, 0, 0, 0, 0, 0, 0, 0, 0, 0]
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 9, side: upper, position: 0.5, restitution: 0.7}
initial:
  x: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
  v: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
solver:
  engine: )" + engine + R"(
run:
  kind: orbit
  transient_periods: 5
  orbit: )" + orbit + "\n";
}

}  // namespace

// The file holds what the library's shooting gives from the same guess (dense engine: the same
// calls, so the same numbers to rounding of the output, 1e-14); the modal engine's Newton–Krylov
// orbit and leading multiplier equal those to 1e-9 (library test: 1e-8 of L, V on other chains,
// tests/analysis/test_modal_tangent.cpp; here L ≈ 0.6, V ≈ 0.2).
TEST_CASE("an orbit run writes the library's periodic orbit and multipliers, on both engines", "[runner][orbit]") {
  const ResultReader dense = run_file(orbit_scene("dense"), "orbit_dense");
  const ResultReader modal = run_file(orbit_scene("modal"), "orbit_modal");
  const SceneDocument doc = SceneDocument::parse(orbit_scene("dense"), "orbit.yaml");
  const Scene scene = doc.build();
  const vibro::ImpactSystem system = scene.impact_system();
  vibro::Simulator sim(system, scene.solver);
  const double T = 2.0 * std::numbers::pi / 0.3;
  const auto guess = sim.run(0.0, scene.x0, scene.v0, 5.0 * T);
  vibro::ShootingOptions o;
  o.solver = scene.solver;
  const vibro::ShootingResult want = vibro::shoot(system, o, guess.t, guess.x, guess.v);
  REQUIRE(want.converged());
  CHECK(dense.attribute_string("/orbit", "status") == "converged");
  CHECK(modal.attribute_string("/orbit", "status") == "converged");
  CHECK(modal.attribute_string("/orbit", "leading_only") == "true");
  const std::vector<double> xd = dense.read("/orbit/x"), xm = modal.read("/orbit/x"), vm = modal.read("/orbit/v");
  REQUIRE(xd.size() == 10);
  for (std::size_t i = 0; i < 10; ++i) {
    CHECK(std::abs(xd[i] - want.x(static_cast<Eigen::Index>(i))) <= 1e-14);
    CHECK(std::abs(xm[i] - want.x(static_cast<Eigen::Index>(i))) <= 1e-9);
    CHECK(std::abs(vm[i] - want.v(static_cast<Eigen::Index>(i))) <= 1e-9);
  }
  const std::vector<double> re = dense.read("/orbit/multipliers_real"), im = dense.read("/orbit/multipliers_imag");
  REQUIRE(re.size() == 20);
  CHECK(std::hypot(re[0], im[0]) == Approx(want.multipliers.spectral_radius).epsilon(1e-14));
  CHECK(std::abs(std::stod(modal.attribute_string("/orbit", "spectral_radius")) - want.multipliers.spectral_radius) <= 1e-9);
  CHECK(modal.read("/orbit/multipliers_real").size() == 6);
  CHECK(dense.attribute_string("/orbit", "stable") == (want.multipliers.stable ? "true" : "false"));
  CHECK(dense.attribute_string("/orbit", "stability") == (want.multipliers.stable ? "stable" : "unstable"));
}

TEST_CASE("an orbit run that does not converge writes its last iterate and why, exit 1", "[runner][orbit]") {
  // Two Newton iterations cannot reach 1e-11 from a 5-period guess (four are needed).
  const SceneDocument doc = SceneDocument::parse(orbit_scene("dense", "{period: 1, max_iterations: 2}"), "orbit_nc.yaml");
  const std::string out = temp_path("orbit_nc.h5");
  RunRequest request;
  request.output = out;
  const RunReport report = run_scene(doc, doc.build(), request);
  CHECK(report.exit_code == 1);
  CHECK_THAT(report.summary, Catch::Contains("No periodic orbit"));
  const ResultReader r(out);
  CHECK(r.attribute_string("/meta", "status") == "not_converged");
  CHECK(r.attribute_string("/orbit", "status") == "not converged");
  CHECK(r.read("/orbit/x").size() == 10);
  CHECK(r.read("/orbit/multipliers_real").empty());
  CHECK(r.read("/orbit/residuals").size() == 3);
}

TEST_CASE("a diagram extends a value's transient until it settles, and says which values did not", "[runner][diagram]") {
  // Above, 50 periods from rest at Ω = 1.66 are not enough for the period-1 orbit (residual 3e-4):
  // the extension records blocks of 8 more periods until the period test holds.
  const auto diagram = [](const std::string& values, int transient, const std::string& settle) {
    return kChain + "run:\n  kind: diagram\n  transient_periods: " + std::to_string(transient) +
           "\n  diagram:\n    path: forcing.frequency\n    values: " + values +
           "\n    transient: 0\n    points: 8\n    max_period: 4\n    directions: up\n" + settle;
  };
  const ResultReader fixed = run_file(diagram("[1.66, 1.67]", 50, "    settle: 0\n"), "unsettled");
  CHECK(fixed.read_integers("/diagram/k_up") == std::vector<std::int64_t>{0, 0});
  CHECK(fixed.read_integers("/diagram/verdict_up") == std::vector<std::int64_t>{1, 1});  // not periodic
  CHECK(fixed.read_integers("/diagram/extra_periods_up") == std::vector<std::int64_t>{0, 0});
  CHECK(fixed.read("/diagram/residual_up").at(0) > 1e-6);

  const std::string text = diagram("[1.66, 1.67]", 50, "");  // the default: settle up to 1000 periods
  const ResultReader r = run_file(text, "settled");
  CHECK(r.read_integers("/diagram/k_up") == std::vector<std::int64_t>{1, 1});
  CHECK(r.read_integers("/diagram/verdict_up") == std::vector<std::int64_t>{0, 0});
  const std::vector<std::int64_t> extra = r.read_integers("/diagram/extra_periods_up");
  for (std::int64_t e : extra) CHECK((e > 0 && e % 8 == 0));
  for (double residual : r.read("/diagram/residual_up")) CHECK(residual <= 1e-6);  // the tolerance
  CHECK(r.attribute_number("/meta", "points_not_settled") == 0);
  // The recorded points are those 50 + extra + 1 … 8 periods from rest: the engine directly.
  SceneDocument at(SceneDocument::parse(text, "settled.yaml"));
  at.set("forcing.frequency", 1.66);
  const Scene scene = at.build_point();
  const auto engine = make_engine(scene);
  const double T = scene.period();
  const long first = 50 + extra.at(0);
  const auto period = [&](long block, long i) {  // the i-th period of a block, timed as the run times it
    const double t1 = static_cast<double>(block) * T;
    return std::pair<double, double>{t1 + static_cast<double>(i - 1) * T, t1 + static_cast<double>(i) * T};
  };
  RunSummary s = engine->run(0.0, scene.x0, scene.v0, 50 * T);
  for (long block = 50; block < first; block += 8)
    for (long i = 1; i <= 8; ++i) s = engine->run(period(block, i).first, s.x, s.v, period(block, i).second);
  const std::vector<double> x = r.read("/diagram/x_up");
  for (long i = 1; i <= 8; ++i) {
    s = engine->run(period(first, i).first, s.x, s.v, period(first, i).second);
    for (int j = 0; j < 2; ++j) CHECK(x.at(static_cast<std::size_t>((i - 1) * 2 + j)) == s.x(j));
  }

  // A cap too low for the approach: the residual still falls when it is reached.
  const ResultReader capped = run_file(diagram("[1.66, 1.67]", 50, "    settle: 16\n"), "capped");
  CHECK(capped.read_integers("/diagram/verdict_up") == std::vector<std::int64_t>{2, 2});  // not settled
  CHECK(capped.read_integers("/diagram/extra_periods_up") == std::vector<std::int64_t>{16, 16});
  CHECK(capped.attribute_number("/meta", "points_not_settled") == 2);
  CHECK(capped.attribute_number("/meta", "points_not_periodic") == 0);

  // Past the cascade (Ω∞ ≈ 1.75008) the attractor is chaotic: no approach, so the extension
  // ends after `patience` periods (a quarter of settle) without a new least residual, well
  // before the cap, and the values are reported not periodic.
  const ResultReader chaos = run_file(diagram("[1.76, 1.77]", 300, ""), "chaotic");
  CHECK(chaos.read_integers("/diagram/verdict_up") == std::vector<std::int64_t>{1, 1});
  for (std::int64_t e : chaos.read_integers("/diagram/extra_periods_up")) CHECK((e >= 250 && e < 1000));
  for (double residual : chaos.read("/diagram/residual_up")) CHECK(residual > 0.1);
}
