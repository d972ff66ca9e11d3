// Stops along general normals in scene files (docs/scenes.md, stops: normal): how they load,
// which engine they resolve to, what bad input says (file:line:col and key), what the result
// file holds (docs/results.md, stop_normal), and the pitch–plunge example.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <string>

namespace {

using namespace vibro;
using namespace vibro::io;
using Catch::Matchers::Contains;

/// A pitch–plunge section (h, α) with a stop at the tip, h + 0.6 α ≤ 0.2; `stop` replaces the
/// stop's line, `extra` is appended.
std::string scene_text(const std::string& stop, const std::string& extra = "") {
  return "model:\n"
         "  matrices:\n"
         "    mass: [[1, 0.25], [0.25, 0.5]]\n"
         "    stiffness: [[1, 0], [0, 2.5]]\n"
         "    damping: [[0.02, 0], [0, 0.03]]\n"
         "forcing:\n"
         "  frequency: 1.1\n"
         "  cosine: [0.35, 0.1]\n"
         "stops:\n" +
         stop + "\n" + extra;
}

SceneError scene_error(const std::string& text) {
  try {
    (void)SceneDocument::parse(text, "general.yaml").build();
  } catch (const SceneError& e) {
    return e;
  }
  FAIL("no SceneError was thrown");
  throw std::logic_error("unreachable");
}

}  // namespace

TEST_CASE("a stop along a general normal loads from a scene", "[general-stops]") {
  const Scene s = SceneDocument::parse(scene_text(
                                           "  - {normal: [1, 0.6], position: 0.2, restitution: 0.75, amplitude: 0.01,"
                                           " phase: 0.5, name: tip freeplay}"))
                      .build();
  REQUIRE(s.stops.size() == 1);
  const Stop& st = s.stops[0];
  CHECK(st.kind == Stop::Kind::normal);
  CHECK(st.direction == Eigen::Vector2d(1.0, 0.6));
  CHECK(st.position == 0.2);
  CHECK(st.restitution == 0.75);
  CHECK(st.amplitude == 0.01);
  CHECK(st.phase == 0.5);
  CHECK(st.name == "tip freeplay");
  CHECK(s.impact_system().normals() == Eigen::MatrixXd(Eigen::Vector2d(1.0, 0.6)));
  // Unnamed: a name from the normal.
  const Scene u = SceneDocument::parse(scene_text("  - {normal: [1, -0.6], position: 0.2, restitution: 0.75}")).build();
  CHECK(u.stops[0].name == "normal 1·x0 - 0.59999999999999998·x1");
}

TEST_CASE("a chain with a general stop runs on the dense engine", "[general-stops]") {
  // 70 masses would go to the modal engine on auto; the general stop sends them to the dense one.
  std::string masses = "[1", springs = "[1", dampers = "[0.01";
  for (int i = 1; i < 70; ++i) masses += ", 1";
  for (int i = 1; i < 69; ++i) springs += ", 1";
  for (int i = 1; i < 69; ++i) dampers += ", 0.01";
  masses += "]";
  springs += "]";
  dampers += "]";
  std::string normal = "[1, 0.5";
  for (int i = 2; i < 70; ++i) normal += ", 0";
  normal += "]";
  const std::string chain = "model:\n  chain: {masses: " + masses + ", springs: " + springs +
                            ", dampers: " + dampers + ", left_wall: {spring: 1, damper: 0.01}}\n";
  const std::string text = "forcing: {frequency: 0.5}\nstops:\n  - {normal: " + normal + ", position: 0.3, restitution: 0.5}\n";
  const SceneDocument plain = SceneDocument::parse(chain + text);
  const Scene s = plain.build();
  CHECK(s.engine == EngineKind::dense);
  CHECK_THAT(s.engine_reason, Contains("auto: stops[0] has a general normal (the modal engine runs a stop along a "
                                       "general normal through free flight, impacts and chatter but does not hold one"));
  // Given explicitly, the modal engine runs it (a rigid one; a compliant one is refused at its law).
  const Scene modal = SceneDocument::parse(chain + text + "solver: {engine: modal}\n").build();
  CHECK(modal.engine == EngineKind::modal);
  std::string soft = text;
  soft.replace(soft.find("restitution: 0.5"), 16, "law: compliant, stiffness: 2, damping: 0.02");
  const SceneError e = scene_error(chain + soft + "solver: {engine: modal}\n");
  CHECK(e.path() == "stops[0].law");
  CHECK_THAT(e.problem(), Contains("compliant stop along a general normal"));
}

TEST_CASE("bad normals in a scene name the file, the line, the column and the key", "[general-stops]") {
  struct Case {
    std::string stop;
    int line, column;
    std::string path, fragment;
  };
  const Case cases[] = {
      {"  - {normal: [1, 0.6, 2], position: 0.2, restitution: 0.5}", 10, 14, "stops[0].normal",
       "expected a list of 2 numbers (one coefficient per degree of freedom), found 3"},
      {"  - {normal: [0, 0], position: 0.2, restitution: 0.5}", 10, 14, "stops[0].normal",
       "expected a nonzero normal n of nᵀx ≤ position, found all zeros"},
      {"  - {normal: [1, a], position: 0.2, restitution: 0.5}", 10, 18, "stops[0].normal[1]", "expected a number, found 'a'"},
      {"  - {normal: [1, .nan], position: 0.2, restitution: 0.5}", 10, 18, "stops[0].normal[1]", "expected a number, found '.nan'"},
      {"  - {normal: [.inf, 1], position: 0.2, restitution: 0.5}", 10, 15, "stops[0].normal[0]", "expected a number, found '.inf'"},
      {"  - {normal: 1, position: 0.2, restitution: 0.5}", 10, 14, "stops[0].normal", "expected a list of numbers"},
      {"  - {normal: [1, 0.6], restitution: 0.5}", 10, 5, "stops[0].position", "missing: the stop's offset p"},
      {"  - {normal: [1, 0.6], mass: 0, position: 0.2, restitution: 0.5}", 10, 30, "stops[0].mass",
       "a stop along a normal takes 'normal' and 'position' (nᵀx ≤ position), not 'mass'"},
      {"  - {normal: [1, 0.6], between: [0, 1], gap: 0.2, restitution: 0.5}", 10, 33, "stops[0].between",
       "not 'between'"},
      {"  - {normal: [1, 0.6], position: 0.2, restitution: 0.5}\n  - {normal: [2, 1.2], position: 0.1, restitution: 0.5}",
       11, 5, "stops[1]", "duplicates stops[0]"},
      {"  - {normal: [1, 0.6], position: 0.2, restitution: 0.5}\n  - {normal: [-2, -1.2], position: -0.5, restitution: 0.5}",
       10, 5, "stops[0]", "leave no room between them"},
      {"  - {normal: [1, 0.6], position: 0.2, restitution: 0.5, side: upper}", 10, 63, "stops[0].side", "not 'side'"},
      {"  - {normals: [1, 0.6], position: 0.2, restitution: 0.5}", 10, 6, "stops[0].normals", "did you mean 'normal'?"},
  };
  for (const Case& c : cases) {
    INFO(c.stop);
    const SceneError e = scene_error(scene_text(c.stop));
    INFO(e.what());
    CHECK(e.file() == "general.yaml");
    CHECK(e.line() == c.line);
    CHECK(e.column() == c.column);
    CHECK(e.path() == c.path);
    CHECK_THAT(e.problem(), Contains(c.fragment));
  }
}

TEST_CASE("a result file holds the normals of general stops", "[general-stops]") {
  const vibro::test::TempDir dir;
  const std::string out = dir / "general.h5";
  const SceneDocument doc = SceneDocument::parse(
      scene_text("  - {normal: [1, 0.6], position: 0.2, restitution: 0.75}\n  - {mass: 0, side: lower, position: -0.4, "
                 "restitution: 0.5}",
                 "record: {events: true}\nrun: {kind: simulate, periods: 3}\n"));
  const Scene scene = doc.build();
  REQUIRE(run_scene(doc, scene, {out, 1, false, false}).exit_code == 0);
  const ResultReader r(out);
  CHECK(r.read_integers("/scene/stop_kind") == std::vector<std::int64_t>{3, 1});
  CHECK(r.attribute_strings("/scene/stop_kind", "names") ==
        std::vector<std::string>{"upper", "lower", "between", "normal"});
  CHECK(r.shape("/scene/stop_normal") == std::vector<std::size_t>{2, 2});
  CHECK(r.read("/scene/stop_normal") == std::vector<double>{1.0, 0.6, -1.0, 0.0});
  CHECK(r.read_integers("/scene/stop_mass") == std::vector<std::int64_t>{-1, 0});
  CHECK(r.read("/events/t").size() > 0);
}

TEST_CASE("the pitch–plunge freeplay example runs and impacts its tip stop", "[general-stops]") {
  const vibro::test::TempDir dir;
  const std::string out = dir / "pitch_plunge.h5";
  const SceneDocument doc = SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/pitch_plunge_freeplay.yaml");
  const Scene scene = doc.build();
  REQUIRE(scene.stops.size() == 2);
  CHECK(scene.stops[0].kind == Stop::Kind::normal);
  CHECK(scene.engine == EngineKind::dense);
  REQUIRE(run_scene(doc, scene, {out, 1, false, false}).exit_code == 0);
  const ResultReader r(out);
  CHECK(r.read("/events/t").size() > 10);
}
