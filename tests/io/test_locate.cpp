// vibro run with run.kind: locate — the file holds the scan and the located transitions, equal to
// the library (vibro/running_locate.hpp) called directly; bad input leaves no file behind.
#include "vibro/running_locate.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

// The paper's system with a two-point grid around its rising (0.256006…, tests/study).
const std::string kLocate = R"(
name: locate-test
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
forcing:
  frequency: 0.255
  cosine: [0.5, 0]
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
run:
  kind: locate
  transient_periods: 200
  locate:
    path: forcing.frequency
    values: [0.2559, 0.2561]
    tolerance: 1e-8
)";

/// The library called directly (dense engine) on the scene's grid values, 200 transient periods.
ScanResult direct_locate(const SceneDocument& doc, const Scene& scene, const std::vector<double>& grid) {
  ScanOptions options;
  options.orbit.solver = scene.solver;
  options.first_transient = 200;
  options.tolerance = 1e-8;
  const SystemFamily family = [&](double omega) {
    SceneDocument point(doc);
    point.set("forcing.frequency", omega);
    return point.build_point().impact_system();
  };
  return scan_and_locate(family, grid, 0.0, scene.x0, scene.v0, options);
}

/// A file in this test process's own directory (ctest runs every test case in its own process).
std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

}  // namespace

TEST_CASE("a locate run writes the scan and the transitions the library finds", "[runner][locate]") {
  const SceneDocument doc = SceneDocument::parse(kLocate, "locate.yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path("rising.h5");
  std::filesystem::remove(out);
  const RunReport report = run_scene(doc, scene, {out, 2, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  REQUIRE(std::filesystem::exists(out));
  REQUIRE_FALSE(std::filesystem::exists(ResultFile::partial_path(out)));

  // The library, called directly with the same settings.
  const ScanResult direct = direct_locate(doc, scene, {0.2559, 0.2561});
  REQUIRE(direct.transitions.size() == 1);

  const ResultReader r(out);
  CHECK(r.attribute_string("/scene", "run_kind") == "locate");
  CHECK(r.attribute_string("/meta", "status") == "completed");
  CHECK(r.attribute_string("/scan", "parameter") == "forcing.frequency");
  CHECK(r.read("/scan/parameter") == std::vector<double>{0.2559, 0.2561});
  CHECK(r.read("/scan/periodic") == std::vector<double>{1, 1});
  const auto names = r.attribute_strings("/transitions/kind", "names");
  const auto kinds = r.read_integers("/transitions/kind");
  REQUIRE(kinds.size() == 1);
  CHECK(names.at(static_cast<std::size_t>(kinds[0])) == "rising");
  CHECK(r.read_integers("/transitions/stop") == std::vector<std::int64_t>{0});
  // Same computation, same numbers, to the bit (the bisection is deterministic).
  CHECK(r.read("/transitions/parameter") == std::vector<double>{direct.transitions[0].p});
  CHECK(r.read("/transitions/force_limit") == std::vector<double>{direct.transitions[0].force_limit});
  // Phases: one of stop 0 at the first point, two (split) at the second.
  const auto point = r.read_integers("/phases/point");
  const auto stop = r.read_integers("/phases/stop");
  int before = 0, after = 0;
  for (std::size_t i = 0; i < point.size(); ++i)
    if (stop[i] == 0) (point[i] == 0 ? before : after) += 1;
  CHECK(before == 1);
  CHECK(after == 2);
  std::filesystem::remove(out);
}

TEST_CASE("the modal engine locates the paper's rising where the dense engine does", "[runner][locate]") {
  // The same locate run with solver.engine: modal (the paper's chain is proportionally damped,
  // C = 0.1 K, and tied to a wall): the two engines evaluate the exact flows differently (modal
  // coordinates and reduced chains vs the dense augmented generator), agreeing to ~1e-10 in event
  // times (tests/framework/test_modal.cpp), so the bisection must end in the same bracket or a
  // neighbouring one: the located rising agrees to the bracket width 1e-8, and its least
  // interior force, ~linear in Ω there (slope ~3 per unit Ω), to ~3e-8 + rounding.
  std::string text = kLocate;
  text.replace(text.find("run:\n"), 5, "solver: {engine: modal}\nrun:\n");
  const SceneDocument doc = SceneDocument::parse(text, "locate-modal.yaml");
  const Scene scene = doc.build();
  REQUIRE(scene.engine == EngineKind::modal);
  const std::string out = temp_path("rising_modal.h5");
  std::filesystem::remove(out);
  const RunReport report = run_scene(doc, scene, {out, 2, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const ResultReader r(out);
  CHECK(r.attribute_string("/meta", "engine") == "modal");
  const auto kinds = r.read_integers("/transitions/kind");
  REQUIRE(kinds.size() == 1);
  CHECK(r.attribute_strings("/transitions/kind", "names").at(static_cast<std::size_t>(kinds[0])) == "rising");
  CHECK(r.read_integers("/transitions/stop") == std::vector<std::int64_t>{0});

  const SceneDocument dense_doc = SceneDocument::parse(kLocate, "locate.yaml");
  const ScanResult dense = direct_locate(dense_doc, dense_doc.build(), {0.2559, 0.2561});
  REQUIRE(dense.transitions.size() == 1);
  const double located = r.read("/transitions/parameter").at(0);
  CHECK(std::abs(located - dense.transitions[0].p) <= 1e-8);
  CHECK(std::abs(r.read("/transitions/force_limit").at(0) - dense.transitions[0].force_limit) <= 5e-8);
  std::filesystem::remove(out);
}

TEST_CASE("a locate run over a scene without stops compares periodic orbits and finds no transition", "[runner][locate]") {
  // Found by fuzz_run: both ends of a grid interval periodic and no stop, the largest jump of
  // the stops' sticking fractions was taken over an empty vector (an Eigen assertion; a read
  // through a null pointer in a release build).
  std::string text = kLocate;
  text.erase(text.find("stops:"), text.find("run:") - text.find("stops:"));
  const SceneDocument doc = SceneDocument::parse(text, "locate.yaml");
  const Scene scene = doc.build();
  REQUIRE(scene.stops.empty());
  const std::string out = temp_path("no_stops.h5");
  std::filesystem::remove(out);
  const RunReport report = run_scene(doc, scene, {out, 1, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const ResultReader r(out);
  CHECK(r.attribute_string("/meta", "status") == "completed");
  CHECK(r.read("/scan/periodic") == std::vector<double>{1, 1});
  CHECK(r.read_integers("/transitions/kind").empty());
  std::filesystem::remove(out);
}

TEST_CASE("a locate grid value that makes the scene invalid is refused before any file exists", "[runner][locate]") {
  std::string text = kLocate;
  text.replace(text.find("values: [0.2559, 0.2561]"), 24, "values: [0.2559, -0.25]");
  const std::string out = temp_path("invalid.h5");
  std::filesystem::remove(out);
  REQUIRE_THROWS_AS(SceneDocument::parse(text, "locate.yaml").build(), SceneError);
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK_FALSE(std::filesystem::exists(ResultFile::partial_path(out)));
}

TEST_CASE("a locate run reports the period doublings of the three-mass clearance chain as changes of "
          "period, with the doubling in the bracket", "[runner][locate]") {
  // three_mass_chain.yaml's system from its period-1 orbit at Ω = 0.31 (on the running method's
  // path down from Ω = 0.7, at forcing phase 0). Continuation (continue, from Ω = 0.7 down) finds
  // the period-1 orbit doubling at 0.305288088182 and 0.301781374772. Near each a multiplier near
  // −1 keeps the runs from closing within 2000 periods on both sides, and the bisection used to
  // return two "not periodic" brackets around it instead.
  const std::string text = R"(
name: locate-doubling
model:
  chain:
    masses: [1, 1, 1]
    springs: [1, 1]
    dampers: [0.05, 0.05]
    left_wall: {spring: 1, damper: 0.05}
forcing:
  frequency: 0.31
  cosine: [0.2, 0, 0]
stops:
  - {between: [1, 2], gap: 0.05, restitution: 0.6, name: m1-m2 clearance}
  - {mass: 2, side: upper, position: 0.4, restitution: 0.8, name: right wall}
initial:
  x: [0.3128226553488964, 0.3864012467213644, 0.38474367192712233]
  v: [0.011645924049693574, 0.003575868877863314, -0.03429715474678856]
run:
  kind: locate
  transient_periods: 20
  locate:
    path: forcing.frequency
    values: [0.31, 0.307, 0.304, 0.301]
    tolerance: 1e-8
)";
  const SceneDocument doc = SceneDocument::parse(text, "doubling.yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path("doubling.h5");
  std::filesystem::remove(out);
  const RunReport report = run_scene(doc, scene, {out, 2, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const ResultReader r(out);
  const auto names = r.attribute_strings("/transitions/kind", "names");
  const auto kinds = r.read_integers("/transitions/kind");
  const auto low = r.read("/transitions/parameter_low"), high = r.read("/transitions/parameter_high");
  const auto k_low = r.read_integers("/transitions/k_low"), k_high = r.read_integers("/transitions/k_high");
  for (const double doubling : {0.305288088182, 0.301781374772}) {
    CAPTURE(doubling);
    int found = 0;
    for (std::size_t i = 0; i < kinds.size(); ++i) {
      if (!(low[i] <= doubling && doubling <= high[i])) continue;
      ++found;
      CHECK(names.at(static_cast<std::size_t>(kinds[i])) == "period");
      CHECK(k_low[i] == 2);   // the doubled orbit below it in Ω
      CHECK(k_high[i] == 1);
      CHECK(high[i] - low[i] < 1e-4);
    }
    CHECK(found == 1);
  }
  std::filesystem::remove(out);
}
