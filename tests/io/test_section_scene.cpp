// record.section (docs/scenes.md, docs/results.md /section): the scene's errors at file:line:col,
// a simulation's /section equal to the Section observer run by hand and every other group equal
// to the same scene without a section, bit for bit; a diagram's /section with the parameter of
// each row.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/section.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;
using Catch::Contains;

namespace {

const std::string kScene = R"(name: section-test
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
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7}
record:
  events: true
  samples: {per_period: 40}
  SECTION
run:
  kind: simulate
  transient_periods: 3
  periods: 6
)";

std::string with_section(const std::string& section) {
  std::string s = kScene;
  s.replace(s.find("SECTION"), 7, section);
  return s;
}

std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

SceneError scene_error(const std::string& text) {
  try {
    (void)SceneDocument::parse(text, "section.yaml").build();
  } catch (const SceneError& e) {
    return e;
  }
  FAIL("no SceneError was thrown");
  throw std::logic_error("unreachable");
}

}  // namespace

TEST_CASE("record.section: bad hyperplanes are refused at file:line:col", "[scene][section]") {
  struct Case {
    std::string section, path, message;
  };
  const std::vector<Case> cases{
      {"section: {coordinate: 2}", "record.section.coordinate", "expected a whole number in [0, 1], found 2"},
      {"section: {coordinate: -1}", "record.section.coordinate", "expected a whole number in [0, 1]"},
      {"section: {normal: [0, 0]}", "record.section.normal", "the normal is zero"},
      {"section: {normal: [1, 0, 0]}", "record.section.normal", "expected a list of 2 numbers"},
      {"section: {coordinate: 0, direction: upward}", "record.section.direction",
       "expected one of up, down, both, found 'upward'"},
      {"section: {coordinate: 0, value: .nan}", "record.section.value", ""},
      {"section: {normal: [1, .nan]}", "record.section.normal[1]", ""},
      {"section: {coordinate: 0, normal: [1, 0]}", "record.section", "either coordinate"},
      {"section: {value: 0.1}", "record.section", "needs coordinate"},
      {"section: {coordinate: 0, valu: 0.1}", "record.section.valu", "did you mean 'value'?"},
  };
  for (const Case& c : cases) {
    INFO(c.section);
    const SceneError e = scene_error(with_section(c.section));
    CHECK(e.file() == "section.yaml");
    CHECK(e.line() == 17);
    CHECK(e.column() > 2);
    CHECK(e.path() == c.path);
    CHECK_THAT(e.problem(), Contains(c.message));
  }
  // The Taylor engine (nonlinear forces) does not locate sections: refused, naming the key.
  std::string taylor = with_section("section: {coordinate: 0}");
  taylor.replace(taylor.find("record:"), 7, "parameters: {beta: 0.5}\nforces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\nrecord:");
  const SceneError e = scene_error(taylor);
  CHECK(e.path() == "record.section");
  CHECK_THAT(e.problem(), Contains("Taylor engine"));
}

TEST_CASE("record.section: a simulation's /section is the observer's, and the rest is unchanged", "[runner][section]") {
  const SceneDocument with = SceneDocument::parse(with_section("section: {normal: [-0.5, 1], value: 0.02}"), "a.yaml");
  const SceneDocument without = SceneDocument::parse(with_section(""), "b.yaml");
  const Scene scene = with.build();
  REQUIRE(scene.record.section);
  const std::string a = temp_path("with.h5"), b = temp_path("without.h5");
  REQUIRE(run_scene(with, scene, {a, 1, false, false}).exit_code == 0);
  REQUIRE(run_scene(without, without.build(), {b, 1, false, false}).exit_code == 0);
  const ResultReader ra(a), rb(b);
  for (const std::string& o : rb.objects()) {
    if (!rb.is_dataset(o) || o.rfind("/scene", 0) == 0 || rb.type(o) == "str") continue;
    INFO(o);
    CHECK(ra.read(o) == rb.read(o));  // bit for bit
  }

  const ImpactSystem impact = scene.impact_system();
  Simulator sim(impact, scene.solver);
  const double T = scene.period();
  const RunSummary transient = sim.run(0.0, scene.x0, scene.v0, 3 * T);
  Eigen::VectorXd n(2);
  n << -0.5, 1.0;
  Section section(Hyperplane{n, 0.02});
  sim.run(3 * T, transient.x, transient.v, 9 * T, {&section});
  REQUIRE(section.t.size() >= 6);
  CHECK(ra.read("/section/t") == section.t);
  CHECK(ra.read("/section/phase") == section.phase);
  const std::vector<std::int64_t> dirs = ra.read_integers("/section/direction");
  REQUIRE(dirs.size() == section.crossing.size());
  for (std::size_t k = 0; k < dirs.size(); ++k) CHECK(dirs[k] == section.crossing[k]);
  const Eigen::MatrixXd x = ra.read_matrix("/section/x");
  REQUIRE(x.rows() == static_cast<Eigen::Index>(section.t.size()));
  for (std::size_t k = 0; k < section.t.size(); ++k) CHECK(x.row(static_cast<Eigen::Index>(k)).transpose() == section.x[k]);
}

TEST_CASE("record.section: a diagram writes every value's crossings with the parameter", "[runner][section]") {
  std::string text = with_section("section: {coordinate: 1, direction: up}");
  text.replace(text.find("  kind: simulate"), 16,
               "  kind: diagram\n  diagram:\n    path: forcing.frequency\n    values: [0.25, 0.26, 0.27]\n    "
               "points: 4\n    max_period: 2\n    transient: 5");
  text.replace(text.find("  events: true\n  samples: {per_period: 40}\n"), 43, "");
  const SceneDocument doc = SceneDocument::parse(text, "diagram.yaml");
  const std::string out = temp_path("diagram.h5");
  REQUIRE(run_scene(doc, doc.build(), {out, 1, false, false}).exit_code == 0);
  const ResultReader r(out);
  const std::vector<double> t = r.read("/section/t"), p = r.read("/section/parameter");
  const std::vector<std::int64_t> point = r.read_integers("/section/point"), dir = r.read_integers("/section/direction");
  const std::vector<double> grid = r.read("/diagram/parameter");
  REQUIRE(!t.empty());
  REQUIRE(p.size() == t.size());
  for (std::size_t k = 0; k < t.size(); ++k) {
    CHECK(p[k] == grid[static_cast<std::size_t>(point[k])]);
    CHECK(dir[k] == 1);
  }
  const Eigen::MatrixXd v = r.read_matrix("/section/v"), x = r.read_matrix("/section/x");
  for (Eigen::Index k = 0; k < v.rows(); ++k) {
    CHECK(v(k, 1) > 0.0);
    CHECK(std::abs(x(k, 1)) <= 1e-12);
  }
}
