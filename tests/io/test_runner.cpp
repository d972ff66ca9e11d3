// vibro run end to end: scene → run → file read back equals the library called directly; sweeps
// give the same data on 1 and 2 threads; an interrupted and resumed sweep equals an
// uninterrupted one; bad sweep input leaves no file behind.
#include "vibro/io/result_file.hpp"
#include "vibro/io/recorded_gaps.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <string>

using namespace vibro;
using namespace vibro::io;
using Catch::Contains;

namespace {

const std::string kScene = R"(
name: runner-test
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
  contacts: true
  statistics: true
  poincare: true
  impact_map: true
  samples: {per_period: 50}
run:
  kind: simulate
  transient_periods: 3
  periods: 2
)";

std::string sweep_scene(bool follow) {
  std::string s = kScene;
  s.replace(s.find("kind: simulate"), 14, "kind: sweep");
  s += "  sweep:\n    parameters:\n      - path: forcing.frequency\n        linspace: [0.25, 0.27, 6]\n";
  s += follow ? "    follow: true\n" : "    follow: false\n";
  return s;
}

/// A file in this test process's own directory: ctest runs every test case in its own process,
/// so no two tests (and no two test runs at once) share a name.
std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

/// Every dataset of two files is identical (the /meta attributes, with wall times, may differ).
void require_same_data(const std::string& a, const std::string& b) {
  const ResultReader ra(a), rb(b);
  const auto objects = ra.objects();
  REQUIRE(objects == rb.objects());
  for (const std::string& o : objects) {
    if (!ra.is_dataset(o)) continue;
    INFO(o);
    if (ra.type(o) == "str") {
      CHECK(ra.read_strings(o) == rb.read_strings(o));
    } else {
      CHECK(ra.read(o) == rb.read(o));  // bit for bit
    }
  }
}

}  // namespace

TEST_CASE("a simulation's file holds exactly what the library computes", "[runner]") {
  const SceneDocument doc = SceneDocument::parse(kScene, "runner-test.yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path("simulate.h5");
  const RunReport report = run_scene(doc, scene, {out, 1, false, false});
  REQUIRE(report.exit_code == 0);
  REQUIRE(std::filesystem::exists(out));
  REQUIRE_FALSE(std::filesystem::exists(out + ".partial"));

  // The same run, by hand.
  const ImpactSystem impact = scene.impact_system();
  Simulator sim(impact, scene.solver);
  const double T = scene.period();
  const RunSummary transient = sim.run(0.0, scene.x0, scene.v0, 3 * T);
  EventLog events;
  Samples samples([&] {
    std::vector<double> t;
    for (int i = 0; i < 100; ++i) t.push_back(3 * T + i * T / 50);
    return t;
  }());
  const RunSummary recorded = sim.run(3 * T, transient.x, transient.v, 5 * T, {&events, &samples});
  REQUIRE(recorded.status == RunStatus::completed);

  const ResultReader file(out);
  const std::vector<double> t = file.read("/events/t");
  REQUIRE(t.size() == events.events.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    CHECK(t[i] == events.events[i].t);
    CHECK(file.read("/events/v_before")[i] == events.events[i].v_before);
  }
  const Eigen::MatrixXd x = file.read_matrix("/samples/x");
  REQUIRE(x.rows() == samples.x.cols());
  for (Eigen::Index i = 0; i < x.rows(); ++i) CHECK(x.row(i).transpose() == samples.x.col(i));
  CHECK(file.attribute_string("/scene", "yaml") == kScene);
  // Counts are the recorded run's, as the recorded events are (docs/results.md): the transient's
  // impacts (3 periods of chatter here) are not in them.
  REQUIRE(transient.impacts > 0);
  CHECK(file.attribute_number("/meta", "impacts") == static_cast<double>(recorded.impacts));
  CHECK(file.attribute_number("/meta", "sticks") == static_cast<double>(recorded.sticks));
  CHECK(file.attribute_string("/meta", "chatter_rule") == "third_order");  // the default
  std::filesystem::remove(out);
}

TEST_CASE("a scene that records nothing writes no data groups", "[runner]") {
  std::string text = kScene;
  text.replace(text.find("record:"), text.find("run:") - text.find("record:"), "");
  const SceneDocument doc = SceneDocument::parse(text, "quiet.yaml");
  const std::string out = temp_path("quiet.h5");
  REQUIRE(run_scene(doc, doc.build(), {out, 1, false, false}).exit_code == 0);
  const ResultReader file(out);
  for (const char* group : {"/events", "/contacts", "/samples", "/poincare", "/stats"}) CHECK_FALSE(file.exists(group));
  CHECK(file.exists("/scene"));
  CHECK(file.exists("/meta"));
  std::filesystem::remove(out);
}

TEST_CASE("a sweep gives the same data on 1 and 2 threads", "[runner]") {
  const SceneDocument doc = SceneDocument::parse(sweep_scene(false), "sweep.yaml");
  const Scene scene = doc.build();
  const std::string one = temp_path("sweep1.h5"), two = temp_path("sweep2.h5");
  REQUIRE(run_scene(doc, scene, {one, 1, false, false}).exit_code == 0);
  REQUIRE(run_scene(doc, scene, {two, 2, false, false}).exit_code == 0);
  require_same_data(one, two);
  const ResultReader file(one);
  CHECK(file.shape("/sweep/values") == std::vector<std::size_t>{6, 1});
  CHECK(file.shape("/poincare/x")[0] == 6);
  std::filesystem::remove(one);
  std::filesystem::remove(two);
}

TEST_CASE("an interrupted sweep resumed with --resume equals an uninterrupted one", "[runner]") {
  for (bool follow : {false, true}) {
    INFO("follow " << follow);
    const SceneDocument doc = SceneDocument::parse(sweep_scene(follow), "sweep.yaml");
    const Scene scene = doc.build();
    const std::string whole = temp_path("whole.h5"), parts = temp_path("parts.h5");
    REQUIRE(run_scene(doc, scene, {whole, 2, false, false}).exit_code == 0);

    RunRequest first{parts, 2, false, false};
    first.interrupt_after = 2;
    const RunReport stopped = run_scene(doc, scene, first);
    CHECK(stopped.exit_code == 130);
    CHECK_FALSE(std::filesystem::exists(parts));
    REQUIRE(std::filesystem::exists(parts + ".partial"));
    const RunReport resumed = run_scene(doc, scene, {parts, 2, true, false});
    REQUIRE(resumed.exit_code == 0);
    CHECK_THAT(resumed.summary, Catch::Contains("resumed"));
    CHECK_FALSE(std::filesystem::exists(parts + ".partial"));
    require_same_data(whole, parts);
    std::filesystem::remove(whole);
    std::filesystem::remove(parts);
  }
}

TEST_CASE("a sweep value that makes the scene invalid is refused before any file exists", "[runner]") {
  std::string text = sweep_scene(false);
  text.replace(text.find("path: forcing.frequency"), 23, "path: stops[0].position");
  text.replace(text.find("linspace: [0.25, 0.27, 6]"), 25, "values: [-0.3, 0.2]");  // 0.2: x0 = 0 violates it
  const std::string out = temp_path("invalid.h5");
  const SceneDocument doc = SceneDocument::parse(text, "invalid.yaml");
  REQUIRE_THROWS_AS(doc.build(), SceneError);
  CHECK_FALSE(std::filesystem::exists(out));
  CHECK_FALSE(std::filesystem::exists(out + ".partial"));
}

TEST_CASE("sample times past one sweep value's recorded span are refused before the sweep starts", "[runner]") {
  // Two periods: a span of 50.3 at Ω = 0.25, 46.5 at Ω = 0.27; a sample at 47 fits every value but the last
  // (it made a worker thread throw, and the process abort, mid-sweep).
  std::string text = sweep_scene(false);
  text.replace(text.find("samples: {per_period: 50}"), 25, "samples: {times: [0.5, 47]}");
  const SceneDocument doc = SceneDocument::parse(text, "times.yaml");
  try {
    (void)doc.build();
    FAIL("not refused");
  } catch (const SceneError& e) {
    CHECK_THAT(e.what(), Contains("forcing.frequency = 0.27") && Contains("makes the scene invalid") &&
                             Contains("record.samples.times[1]") && Contains("must lie in the recorded span"));
  }
  text.replace(text.find("[0.5, 47]"), 9, "[0.5, 46]");
  CHECK_NOTHROW(SceneDocument::parse(text, "times.yaml").build());
}

TEST_CASE("a recorded state past a stop beyond the gap tolerance fails the run before it is written", "[runner]") {
  const Scene scene = SceneDocument::parse(kScene, "gaps.yaml").build();
  Recording rec = Recording::for_scene(scene, 0.0);
  rec.summary = make_engine(scene)->run(0.0, scene.x0, scene.v0, rec.t_end, rec.observers());
  REQUIRE(rec.summary.status == RunStatus::completed);
  REQUIRE(rec.samples->t.size() > 10);
  Recording checked = rec;
  check_recorded_gaps(scene, checked);
  CHECK(checked.summary.status == RunStatus::completed);  // the engine's own states pass
  // One sample moved past stop 1 (upper, mass 1) by 1e-6 L, far beyond trigger × L = 1e-13 L.
  const Stop& stop = scene.stops[1];
  const double t = rec.samples->t[7];
  rec.samples->x(stop.mass, 7) = stop.position + 1e-6 * rec.summary.length_scale;
  check_recorded_gaps(scene, rec);
  CHECK(rec.summary.status == RunStatus::numerical_failure);
  CHECK_THAT(rec.summary.message, Contains("past stop 1") && Contains("at t = " + number_text(t)));
}

TEST_CASE("a sweep point that would run for days is recorded as stopped early, and the others run", "[runner]") {
  // A damper of 1e20 at mass 0: about 1e21 steps of the event search for that point alone.
  std::string text = sweep_scene(false);
  text.replace(text.find("path: forcing.frequency"), 23, "path: 'model.chain.dampers[0]'");
  text.replace(text.find("linspace: [0.25, 0.27, 6]"), 25, "values: [0.1, 1e20, 0.2]");
  const SceneDocument doc = SceneDocument::parse(text, "stiff_point.yaml");
  const Scene scene = doc.build();
  const std::string out = temp_path("stiff_point.h5");
  const RunReport report = run_scene(doc, scene, {out, 1, false, false});
  CHECK(report.exit_code == 1);  // finished, with a point stopped early
  const ResultReader file(out);
  CHECK(file.read("/sweep/status") == std::vector<double>{0, 2, 0});
  const std::vector<std::string> messages = file.read_strings("/sweep/message");
  REQUIRE(messages.size() == 3);
  CHECK(messages[0].empty());
  CHECK_THAT(messages[1], Contains("not run: this run needs about") &&
                              Contains("steps of the certified event search") && Contains("damping of mass 0"));
  CHECK(messages[2].empty());
  std::filesystem::remove(out);
}
