/// Tests of the scene loader vibro::io::SceneDocument / vibro::io::Scene (framework/io/src/scene.cpp).
///
/// What is checked, and against what:
///  1. the Wagg (2004) fig. 2 scene (experiments/wagg2004/fig2_sticking_orbit.yaml) resolves to
///     the paper's section-3 system: M = I, K = k E, C = c E with E = [[2,-1],[-1,1]], k = 1,
///     c = 0.1, Ω = 0.255, f = (A1, A2) cos Ωt = (0.5, 0) cos Ωt, s1 = -0.3 below mass 1 (our
///     mass 0), s2 = 0.1 above mass 2 (our mass 1), r = 0.7 — written out by hand below, and
///     compared with models::wagg2004(), the C++ builder of the same system;
///  2. paths: SceneDocument::set / set_assignment / get change exactly the named value, reject
///     a missing key, an index out of range, a non-numeric target, a malformed path or
///     assignment with a message naming the path; a copied document is independent;
///  3. the malformed suite: every file in tests/io/malformed/ is a scene with one mistake. Its
///     first line states what the loader must say:
///         # expect: LINE:COL PATH | FRAGMENT
///     PATH is the key path of the error ("-" for none); FRAGMENT must occur in the problem text
///     (a trailing '$' anchors it at the end). Adding a case needs no C++;
///  4. the newcomer's examples in experiments/examples/ load and say what their comments say.
#include "vibro/io/scene.hpp"
#include "vibro/models/chain.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using Catch::Contains;
using vibro::Stop;
using vibro::io::Scene;
using vibro::io::SceneDocument;
using vibro::io::SceneError;

const std::string kFig2 = std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml";
const std::string kMalformed = std::string(VIBRO_TEST_DATA) + "/malformed";

/// Runs `f`, which must throw SceneError, and returns the error.
template <class F>
SceneError scene_error(F&& f) {
  try {
    f();
  } catch (const SceneError& e) {
    return e;
  }
  FAIL("no SceneError was thrown");
  throw std::logic_error("unreachable");
}

/// The expectation on the first line of a malformed scene.
struct Expectation {
  int line = 0, column = 0;
  std::string path, fragment;
  bool anchored = false;  ///< fragment must end the problem text
};

/// Parses "# expect: LINE:COL PATH | FRAGMENT"; returns false if the line is not of that form.
bool parse_expectation(const std::string& first_line, Expectation& out) {
  out = Expectation{};
  const std::string tag = "# expect: ";
  if (first_line.rfind(tag, 0) != 0) return false;
  const std::string rest = first_line.substr(tag.size());
  const std::size_t bar = rest.find(" | ");
  if (bar == std::string::npos) return false;
  const std::string where = rest.substr(0, bar);
  out.fragment = rest.substr(bar + 3);
  if (!out.fragment.empty() && out.fragment.back() == '$') {
    out.fragment.pop_back();
    out.anchored = true;
  }
  const std::size_t colon = where.find(':');
  const std::size_t space = where.find(' ');
  if (colon == std::string::npos || space == std::string::npos || colon > space) return false;
  try {
    out.line = std::stoi(where.substr(0, colon));
    out.column = std::stoi(where.substr(colon + 1, space - colon - 1));
  } catch (const std::exception&) {
    return false;
  }
  out.path = where.substr(space + 1);
  if (out.path == "-") out.path.clear();
  return !out.fragment.empty() && out.line > 0 && out.column > 0;
}

std::vector<std::filesystem::path> malformed_files() {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(kMalformed))
    if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

// --- 1. The paper's system --------------------------------------------------------------------

TEST_CASE("the fig. 2 scene is the system of Wagg (2004), section 3", "[scene]") {
  const Scene s = SceneDocument::load(kFig2).build();

  CHECK(s.file == kFig2);
  CHECK(s.name == "wagg2004-fig2");
  REQUIRE(s.system().dof() == 2);

  // m1 = m2 = 1, k1 = k2 = 1 (k1 the left-wall spring, k2 the link), c1 = c2 = 0.1.
  const Eigen::Matrix2d E = (Eigen::Matrix2d() << 2.0, -1.0, -1.0, 1.0).finished();
  CHECK(s.system().mass() == Eigen::MatrixXd(Eigen::Matrix2d::Identity()));
  CHECK(s.system().stiffness() == Eigen::MatrixXd(1.0 * E));
  CHECK(s.system().damping() == Eigen::MatrixXd(0.1 * E));

  // f(t) = (A1, A2) cos Ωt with A1 = 0.5, A2 = 0, Ω = 0.255.
  const vibro::HarmonicForcing& f = s.system().forcing();
  CHECK(f.frequency == 0.255);
  CHECK(f.cosine == Eigen::VectorXd(Eigen::Vector2d(0.5, 0.0)));
  CHECK(f.sine == Eigen::VectorXd(Eigen::Vector2d::Zero()));
  CHECK(f.constant == Eigen::VectorXd(Eigen::Vector2d::Zero()));
  CHECK(s.period() == Approx(2.0 * std::numbers::pi / 0.255).epsilon(1e-15));

  // s1 = -0.3 below the paper's mass 1 (mass 0), s2 = 0.1 above mass 2 (mass 1), r = 0.7.
  REQUIRE(s.stops.size() == 2);
  CHECK(s.stops[0].kind == Stop::Kind::lower);
  CHECK(s.stops[0].mass == 0);
  CHECK(s.stops[0].position == -0.3);
  CHECK(s.stops[0].restitution == 0.7);
  CHECK(s.stops[0].amplitude == 0.0);
  CHECK(s.stops[0].name == "s1");
  CHECK(s.stops[1].kind == Stop::Kind::upper);
  CHECK(s.stops[1].mass == 1);
  CHECK(s.stops[1].position == 0.1);
  CHECK(s.stops[1].restitution == 0.7);
  CHECK(s.stops[1].amplitude == 0.0);
  CHECK(s.stops[1].name == "s2");

  // At rest at the origin, default solver, recording and run as written.
  CHECK(s.t0 == 0.0);
  CHECK(s.x0 == Eigen::VectorXd(Eigen::Vector2d::Zero()));
  CHECK(s.v0 == Eigen::VectorXd(Eigen::Vector2d::Zero()));
  const vibro::SimulatorOptions defaults;
  CHECK(s.solver.trigger == defaults.trigger);
  CHECK(s.solver.max_events == defaults.max_events);
  CHECK(s.record.events);
  CHECK(s.record.contacts);
  CHECK(s.record.statistics);
  CHECK(s.record.poincare);
  CHECK(s.record.samples_per_period == 400);
  CHECK(s.record.sample_times.empty());
  CHECK(s.run.kind == vibro::io::RunSpec::Kind::simulate);
  CHECK(s.run.transient_periods == 200.0);
  CHECK(s.run.periods == 4.0);
  CHECK(s.run.axes.empty());

  // The same system as the C++ builder of the paper's parameters.
  const vibro::ImpactSystem paper = vibro::models::wagg2004();
  CHECK(s.system().mass() == paper.system().mass());
  CHECK(s.system().damping() == paper.system().damping());
  CHECK(s.system().stiffness() == paper.system().stiffness());
  CHECK(s.impact_system().normals() == paper.normals());
  for (std::size_t j = 0; j < 2; ++j) {
    CHECK(s.stops[j].s0() == paper.stops()[j].s0());
    CHECK(s.stops[j].restitution == paper.stops()[j].restitution);
  }
}

TEST_CASE("the scene keeps its file's text verbatim", "[scene]") {
  std::ifstream in(kFig2, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const SceneDocument doc = SceneDocument::load(kFig2);
  CHECK(doc.text() == text);
  CHECK(doc.file() == kFig2);
  CHECK(doc.build().yaml_text == text);
}

TEST_CASE("a missing scene file is a SceneError naming the file", "[scene]") {
  const SceneError e = scene_error([] { (void)SceneDocument::load(kMalformed + "/no-such-scene.yaml"); });
  CHECK(e.file() == kMalformed + "/no-such-scene.yaml");
  CHECK_THAT(e.problem(), Contains("cannot open"));
}

// --- 2. Paths --------------------------------------------------------------------------------

TEST_CASE("set and get change exactly the value a path names", "[scene]") {
  SceneDocument doc = SceneDocument::load(kFig2);
  CHECK(doc.get("forcing.frequency") == 0.255);
  CHECK(doc.get("stops[1].position") == 0.1);
  CHECK(doc.get("model.chain.masses[1]") == 1.0);
  CHECK(doc.get("model.chain.left_wall.spring") == 1.0);
  CHECK(doc.get("record.samples.per_period") == 400.0);

  doc.set("forcing.frequency", 0.26);
  doc.set("stops[1].position", 0.12);
  doc.set("model.chain.masses[1]", 2.0);
  doc.set_assignment("forcing.cosine[0]=0.45");
  doc.set_assignment("model.chain.left_wall.damper=1e-1");
  doc.set_assignment("stops[0].restitution=0.6");
  CHECK(doc.get("forcing.frequency") == 0.26);
  CHECK(doc.get("stops[1].position") == 0.12);
  CHECK(doc.get("forcing.cosine[0]") == 0.45);

  const Scene s = doc.build();
  CHECK(s.system().forcing().frequency == 0.26);
  CHECK(s.system().forcing().cosine(0) == 0.45);
  CHECK(s.stops[1].position == 0.12);
  CHECK(s.stops[0].restitution == 0.6);
  CHECK(s.stops[1].restitution == 0.7);  // untouched
  CHECK(s.system().mass()(1, 1) == 2.0);
  CHECK(s.system().mass()(0, 0) == 1.0);
  CHECK(s.system().damping()(0, 0) == 0.2);
}

TEST_CASE("set, get and set_assignment reject bad paths and values", "[scene]") {
  SceneDocument doc = SceneDocument::load(kFig2);

  SECTION("a missing key names the deepest existing path and the key") {
    const SceneError e = scene_error([&] { doc.set("forcing.frequncy", 0.26); });
    CHECK(e.file() == kFig2);
    CHECK(e.path() == "forcing");
    CHECK_THAT(e.problem(), Contains("has no key 'frequncy'"));
    CHECK(e.line() == 13);  // the forcing mapping
    const SceneError g = scene_error([&] { (void)doc.get("solver.trigger"); });  // no solver section
    CHECK(g.path().empty());
    CHECK_THAT(g.problem(), Contains("has no key 'solver'"));
  }
  SECTION("an index out of range names the list and its length") {
    const SceneError e = scene_error([&] { doc.set("stops[2].position", 0.1); });
    CHECK(e.path() == "stops");
    CHECK_THAT(e.problem(), Contains("has no element [2] (a list of 2)"));
    const SceneError m = scene_error([&] { (void)doc.get("model.chain.masses[7]"); });
    CHECK(m.path() == "model.chain.masses");
    CHECK_THAT(m.problem(), Contains("has no element [7]"));
    const SceneError k = scene_error([&] { (void)doc.get("forcing[0]"); });  // a mapping, no index
    CHECK(k.path() == "forcing");
    CHECK_THAT(k.problem(), Contains("(a mapping)"));
  }
  SECTION("a non-numeric target says what is there") {
    CHECK_THAT(scene_error([&] { doc.set("name", 1.0); }).problem(),
               Contains("expected a number, found 'wagg2004-fig2'"));
    CHECK_THAT(scene_error([&] { doc.set("stops[0]", 1.0); }).problem(),
               Contains("expected a number, found a mapping"));
    CHECK_THAT(scene_error([&] { doc.set("forcing.cosine", 1.0); }).problem(),
               Contains("expected a number, found a list of 2"));
    CHECK_THAT(scene_error([&] { doc.set("stops[0].side", 1.0); }).problem(),
               Contains("expected a number, found 'lower'"));
    CHECK(scene_error([&] { doc.set("stops[0].side", 1.0); }).path() == "stops[0].side");
    CHECK(doc.build().stops[0].kind == Stop::Kind::lower);  // nothing was changed
  }
  SECTION("a malformed path") {
    CHECK_THAT(scene_error([&] { (void)doc.get("stops[first].position"); }).problem(),
               Contains("malformed path: index 'first' is not a whole number"));
    CHECK_THAT(scene_error([&] { (void)doc.get("stops[0.position"); }).problem(),
               Contains("malformed path: unclosed '['"));
    CHECK_THAT(scene_error([&] { (void)doc.get(""); }).problem(), Contains("malformed path: empty path"));
  }
  SECTION("a malformed assignment") {
    const SceneError no_equals = scene_error([&] { doc.set_assignment("forcing.frequency"); });
    CHECK(no_equals.file() == "--set");
    CHECK_THAT(no_equals.problem(), Contains("expected PATH=VALUE"));
    CHECK_THAT(scene_error([&] { doc.set_assignment("=0.26"); }).problem(), Contains("expected PATH=VALUE"));
    for (const char* bad : {"forcing.frequency=", "forcing.frequency=fast", "forcing.frequency=0.26x",
                            "forcing.frequency=inf", "forcing.frequency=nan"}) {
      INFO(bad);
      const SceneError e = scene_error([&] { doc.set_assignment(bad); });
      CHECK(e.file() == "--set");
      CHECK(e.path() == "forcing.frequency");
      CHECK_THAT(e.problem(), Contains("expected a finite number"));
    }
    CHECK_THAT(scene_error([&] { doc.set_assignment("forcing.frequncy=0.26"); }).problem(),
               Contains("has no key 'frequncy'"));
    CHECK(doc.get("forcing.frequency") == 0.255);  // nothing was changed
  }
  SECTION("errors in an assignment carry the --set position prefix (docs/scenes.md, Errors)") {
    // The K-th --set, column C of its text: the path at 1, the value after '='.
    CHECK(std::string(scene_error([&] { doc.set_assignment("forcing.frequency=fast", 3); }).what()) ==
          "--set:3:19: forcing.frequency: expected a finite number, found 'fast'");
    CHECK_THAT(scene_error([&] { doc.set_assignment("forcing.cosine[99999999999999999999]=1", 2); }).what(),
               Catch::StartsWith("--set:2:1: forcing.cosine[99999999999999999999]: malformed path: index "
                                 "'99999999999999999999' is too large"));
    CHECK_THAT(scene_error([&] { doc.set_assignment("forcing.frequency"); }).what(),
               Catch::StartsWith("--set:1:1: forcing.frequency: expected PATH=VALUE"));
    // Numbers as the file reads them: a subnormal is a number, an underflow to 0 is refused.
    doc.set_assignment("forcing.cosine[1]=1e-308");
    CHECK(doc.get("forcing.cosine[1]") == 1e-308);
    CHECK_THAT(scene_error([&] { doc.set_assignment("forcing.cosine[1]=1e-400"); }).problem(),
               Contains("below the smallest double"));
  }
  SECTION("a value set out of range fails at build with the value's path") {
    doc.set_assignment("forcing.frequency=-1");
    const SceneError e = scene_error([&] { (void)doc.build(); });
    CHECK(e.path() == "forcing.frequency");
    CHECK(e.line() == 13);
    CHECK_THAT(e.problem(), Contains("found -1"));
  }
}

TEST_CASE("a copied document is independent of the original", "[scene]") {
  const SceneDocument original = SceneDocument::load(kFig2);
  SceneDocument copy = original;
  copy.set("forcing.frequency", 0.26);
  copy.set("stops[0].position", -0.25);
  CHECK(original.get("forcing.frequency") == 0.255);
  CHECK(original.get("stops[0].position") == -0.3);
  CHECK(copy.get("forcing.frequency") == 0.26);
  CHECK(original.build().system().forcing().frequency == 0.255);
  CHECK(copy.build().system().forcing().frequency == 0.26);

  SceneDocument assigned = SceneDocument::parse("model: {chain: {masses: [1]}}\n");
  assigned = copy;
  assigned.set("forcing.frequency", 0.3);
  CHECK(copy.get("forcing.frequency") == 0.26);
  CHECK(assigned.get("forcing.frequency") == 0.3);
  CHECK(assigned.file() == kFig2);
  CHECK(assigned.text() == original.text());
}

TEST_CASE("a copied document reports errors at the same source positions", "[scene]") {
  // Sweeps edit copies of the document; their errors must still point into the file.
  for (const char* name : {"frequency_negative.yaml", "stop_side_left.yaml", "sweep_path_missing.yaml"}) {
    INFO(name);
    const SceneDocument original = SceneDocument::load(kMalformed + "/" + name);
    const SceneDocument copy = original;
    const SceneError a = scene_error([&] { (void)original.build(); });
    const SceneError b = scene_error([&] { (void)copy.build(); });
    CHECK(b.path() == a.path());
    CHECK(b.problem() == a.problem());
    CHECK(b.line() == a.line());
    CHECK(b.column() == a.column());
  }
}

TEST_CASE("a scene parsed from text is named <string> in errors", "[scene]") {
  const SceneError e = scene_error([] {
    (void)SceneDocument::parse("model:\n  chain:\n    masses: [1, -2]\n").build();
  });
  CHECK(e.file() == "<string>");
  CHECK(std::string(e.what()) == "<string>:3:17: model.chain.masses[1]: expected a mass > 0, found -2");
}

// --- 3. The malformed suite ------------------------------------------------------------------

TEST_CASE("every malformed scene is rejected with the expected position, path and message", "[scene]") {
  const std::vector<std::filesystem::path> files = malformed_files();
  CHECK(files.size() >= 30);
  for (const std::filesystem::path& file : files) {
    INFO("scene: " << file.filename().string());
    std::ifstream in(file);
    std::string first;
    std::getline(in, first);
    Expectation want;
    INFO("first line: " << first);
    REQUIRE(parse_expectation(first, want));

    try {
      (void)SceneDocument::load(file.string()).build();
      FAIL_CHECK("accepted, but should fail at " << want.line << ":" << want.column << " "
                                                 << want.path << " | " << want.fragment);
      continue;
    } catch (const SceneError& e) {
      INFO("error: " << e.what());
      CHECK(e.file() == file.string());
      CHECK(e.line() == want.line);
      CHECK(e.column() == want.column);
      CHECK(e.path() == want.path);
      CHECK_THAT(e.problem(), Contains(want.fragment));
      if (want.anchored) CHECK(e.problem().size() >= want.fragment.size());
      if (want.anchored && e.problem().size() >= want.fragment.size())
        CHECK(e.problem().substr(e.problem().size() - want.fragment.size()) == want.fragment);
      // what() is "file:line:col: path: problem" (no "path: " when there is no path).
      const std::string prefix = file.string() + ":" + std::to_string(e.line()) + ":" +
                                 std::to_string(e.column()) + ": ";
      CHECK(std::string(e.what()) == prefix + (e.path().empty() ? "" : e.path() + ": ") + e.problem());
    } catch (const std::exception& e) {
      FAIL_CHECK("threw something other than SceneError: " << e.what());
    }
  }
}

TEST_CASE("the expectation lines of the malformed suite parse", "[scene]") {
  Expectation e;
  REQUIRE(parse_expectation("# expect: 12:5 stops[1].position | missing: where$", e));
  CHECK(e.line == 12);
  CHECK(e.column == 5);
  CHECK(e.path == "stops[1].position");
  CHECK(e.fragment == "missing: where");
  CHECK(e.anchored);
  REQUIRE(parse_expectation("# expect: 5:12 - | YAML syntax error", e));
  CHECK(e.path.empty());
  CHECK_FALSE(e.anchored);
  CHECK_FALSE(parse_expectation("# expected: 5:12 - | x", e));
  CHECK_FALSE(parse_expectation("# expect: 5 - | x", e));
  CHECK_FALSE(parse_expectation("# expect: 5:12 path", e));
}

// --- 4. The examples -------------------------------------------------------------------------

TEST_CASE("a filled list is the list written out", "[scene]") {
  const Scene written = SceneDocument::parse(R"(
model:
  chain: {masses: [2, 2, 2, 2], springs: [1, 1, 1], dampers: [0.1, 0.1, 0.1], left_wall: {spring: 1}}
forcing: {frequency: 1, cosine: [0.5, 0.5, 0.5, 0.5]}
initial: {x: [0.01, 0.01, 0.01, 0.01]}
)").build();
  const Scene filled = SceneDocument::parse(R"(
model:
  chain: {masses: {fill: 2, count: 4}, springs: {fill: 1, count: 3}, dampers: {fill: 0.1, count: 3}, left_wall: {spring: 1}}
forcing: {frequency: 1, cosine: {fill: 0.5, count: 4}}
initial: {x: {fill: 0.01, count: 4}}
)").build();
  CHECK(filled.system().mass() == written.system().mass());
  CHECK(filled.system().damping() == written.system().damping());
  CHECK(filled.system().stiffness() == written.system().stiffness());
  CHECK(filled.system().forcing().cosine == written.system().forcing().cosine);
  CHECK(filled.x0 == written.x0);
  // A long chain in one line reads without a YAML node per mass; a million masses are read to
  // their count, then refused, as no engine could hold their n × n modes (25 TB).
  const Scene big = SceneDocument::parse(
      "model:\n  chain: {masses: {fill: 1, count: 5000}, springs: {fill: 1, count: 4999}}\n").build();
  CHECK(big.dof() == 5000);
  CHECK_THROWS_WITH(
      SceneDocument::parse("model:\n  chain: {masses: {fill: 1, count: 1000000}, springs: {fill: 1, count: 999999}}\n")
          .build(),
      Catch::Matchers::Contains("a chain of 1000000 masses (every engine holds n × n modes or matrices) needs about 25 TB"));
  // An entry of a filled list is not a path: write the list out to vary one entry.
  SceneDocument doc = SceneDocument::parse("model:\n  chain: {masses: {fill: 1, count: 3}}\n");
  CHECK_THROWS_AS(doc.set("model.chain.masses[1]", 2.0), SceneError);
}

TEST_CASE("the three-mass chain example loads as described", "[scene]") {
  const Scene s = SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/three_mass_chain.yaml").build();
  REQUIRE(s.system().dof() == 3);
  Eigen::Matrix3d K;
  K << 2, -1, 0, -1, 2, -1, 0, -1, 1;
  CHECK(s.system().stiffness() == Eigen::MatrixXd(K));
  CHECK(s.system().damping() == Eigen::MatrixXd(0.05 * K));
  CHECK(s.system().forcing().frequency == 0.5);
  CHECK(s.system().forcing().cosine == Eigen::VectorXd(Eigen::Vector3d(0.2, 0.0, 0.0)));  // mass 0 only
  REQUIRE(s.stops.size() == 2);
  CHECK(s.stops[0].kind == Stop::Kind::between);
  CHECK(s.stops[0].mass == 1);
  CHECK(s.stops[0].other == 2);
  CHECK(s.stops[0].position == 0.05);
  CHECK(s.stops[1].kind == Stop::Kind::upper);
  CHECK(s.stops[1].mass == 2);
  CHECK(s.run.kind == vibro::io::RunSpec::Kind::simulate);
}

TEST_CASE("the three-mass sweep example sweeps Ω over 41 points, following", "[scene]") {
  const std::string path = std::string(VIBRO_EXPERIMENTS) + "/examples/three_mass_sweep.yaml";
  const Scene s = SceneDocument::load(path).build();
  const Scene chain =
      SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/three_mass_chain.yaml").build();
  CHECK(s.system().mass() == chain.system().mass());
  CHECK(s.system().stiffness() == chain.system().stiffness());
  CHECK(s.system().damping() == chain.system().damping());
  CHECK(s.stops.size() == chain.stops.size());
  CHECK(s.run.kind == vibro::io::RunSpec::Kind::sweep);
  CHECK(s.run.follow);
  CHECK_FALSE(s.run.reverse);
  REQUIRE(s.run.axes.size() == 1);
  const vibro::io::SweepAxis& axis = s.run.axes[0];
  CHECK(axis.path == "forcing.frequency");
  REQUIRE(axis.values.size() == 41);
  CHECK(axis.values.front() == 0.3);
  CHECK(axis.values.back() == 0.7);
  for (std::size_t i = 0; i < axis.values.size(); ++i)
    CHECK(axis.values[i] == Approx(0.3 + 0.01 * static_cast<double>(i)).margin(1e-15));

  // Each point is the scene with the path set to the value: it must build.
  SceneDocument doc = SceneDocument::load(path);
  for (const double w : {axis.values.front(), axis.values[20], axis.values.back()}) {
    doc.set(axis.path, w);
    CHECK(doc.build().system().forcing().frequency == w);
  }
}
