/// Friction in scene files and result files (docs/scenes.md `friction`, docs/results.md):
///  1. experiments/examples/stick_slip.yaml loads as its comment says: one contact on a moving
///     surface, run on the dense engine (auto says why);
///  2. its simulation through the scene's engine writes friction-stick, -slip and -reversal
///     events, named in /events/kind, with the friction force, and the contacts in /scene;
///  3. a scene without friction writes no friction datasets and the four rigid event kinds.
/// The refusals (μ_s < μ_k, negative or infinite loads, NaN, indices out of range, unknown keys,
/// nonlinear forces or the modal engine with friction) are files of
/// tests/io/malformed/friction_*.yaml.
#include "vibro/io/result_file.hpp"
#include "vibro/io/results.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace {

const std::string kStickSlip = std::string(VIBRO_EXPERIMENTS) + "/examples/stick_slip.yaml";

}  // namespace

TEST_CASE("the stick-slip example loads with a frictional contact on the dense engine", "[friction]") {
  const vibro::io::Scene s = vibro::io::SceneDocument::load(kStickSlip).build();
  REQUIRE(s.friction.size() == 1);
  const vibro::FrictionContact& c = s.friction[0];
  CHECK(c.kind == vibro::FrictionContact::Kind::surface);
  CHECK(c.mass == 0);
  CHECK(c.normal_load == 1.0);
  CHECK(c.static_coefficient == 0.5);
  CHECK(c.kinetic_coefficient == 0.3);
  CHECK(c.amplitude == 0.5);
  CHECK(c.phase == 0.3);
  CHECK(c.name == "belt");
  CHECK(s.stops.empty());
  CHECK(s.engine == vibro::io::EngineKind::dense);
  CHECK_THAT(s.engine_reason, Catch::Contains("friction"));
}

TEST_CASE("friction switches are recorded as friction-stick, -slip and -reversal events", "[friction]") {
  const vibro::test::TempDir dir;
  const std::string path = dir / "stick_slip.h5";
  const vibro::io::Scene scene = vibro::io::SceneDocument::load(kStickSlip).build();
  const std::unique_ptr<vibro::Engine> engine = vibro::io::make_engine(scene);
  const double t_start = scene.t0 + scene.run.transient_periods * scene.period();
  const vibro::RunSummary transient = engine->run(scene.t0, scene.x0, scene.v0, t_start);
  REQUIRE(transient.status == vibro::RunStatus::completed);
  vibro::io::Recording rec = vibro::io::Recording::for_scene(scene, t_start);
  rec.summary = engine->run(t_start, transient.x, transient.v, rec.t_end, rec.observers());
  REQUIRE(rec.summary.status == vibro::RunStatus::completed);
  const std::vector<vibro::Event>& ev = rec.events->events;
  REQUIRE(ev.size() >= 20);  // a stick and a slip in each half period, 10 periods recorded
  const double limit_static = 0.5, limit_kinetic = 0.3;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    CHECK(ev[i].stop == 0);
    CHECK(std::abs(ev[i].v_before) < 1e-12);  // the relative velocity is zero at every switch
    if (ev[i].kind == vibro::EventKind::friction_stick) {
      CHECK(std::abs(ev[i].force) <= limit_static + 1e-12);
      if (i + 1 < ev.size()) CHECK(ev[i + 1].kind == vibro::EventKind::friction_slip);
    } else {
      REQUIRE((ev[i].kind == vibro::EventKind::friction_slip || ev[i].kind == vibro::EventKind::friction_reversal));
      CHECK(std::abs(std::abs(ev[i].force) - limit_kinetic) < 1e-15);  // slipping: −μ_k N sign(u)
    }
  }
  CHECK(rec.summary.sticks > 0);
  vibro::io::ResultFile file = vibro::io::ResultFile::create(path, scene, vibro::io::current_meta(1));
  file.write_simulation(rec);
  file.finish(vibro::io::current_meta(1));
  const vibro::io::ResultReader r(path);
  CHECK(r.attribute_strings("/events/kind", "names") ==
        std::vector<std::string>{"impact", "stick", "release", "chatter-limit", "engage", "disengage", "friction-stick",
                                 "friction-slip", "friction-reversal"});
  CHECK(r.read_integers("/events/kind").front() == static_cast<std::int64_t>(ev.front().kind));
  CHECK(r.read("/events/force").size() == ev.size());
  CHECK(r.read("/scene/friction_static") == std::vector<double>{0.5});
  CHECK(r.read("/scene/friction_kinetic") == std::vector<double>{0.3});
  CHECK(r.read("/scene/friction_amplitude") == std::vector<double>{0.5});
  CHECK(r.read_integers("/scene/friction_mass") == std::vector<std::int64_t>{0});
}

TEST_CASE("friction scenes run as orbits and continuations: structural zeros and the onset of sticking", "[friction]") {
  const vibro::test::TempDir dir;
  auto run = [&](vibro::io::SceneDocument doc, const std::string& name) {
    const vibro::io::Scene scene = doc.build();
    vibro::io::RunRequest request;
    request.output = dir / name;
    request.threads = 1;
    const vibro::io::RunReport report = vibro::io::run_scene(doc, scene, request);
    CAPTURE(report.summary);
    REQUIRE(report.exit_code == 0);
    return vibro::io::ResultReader(dir / name);
  };
  // The stick-slip example as a periodic orbit: it sticks once per period, so one multiplier is
  // a structural zero.
  vibro::io::SceneDocument orbit = vibro::io::SceneDocument::load(kStickSlip);
  orbit.replace("run", "{kind: orbit, transient_periods: 20}");
  orbit.replace("record", "");
  const vibro::io::ResultReader o = run(orbit, "orbit.h5");
  CHECK(o.attribute_string("/orbit", "status") == "converged");
  CHECK(o.attribute_string("/orbit", "structural_zeros") == "1");
  CHECK(o.attribute_string("/orbit", "stability") == "stable");
  // Den Hartog's oscillator continued in Ω through the onset of sticking and, lower, the birth of a
  // slip inside a stick (the numbers are checked against his closed form and against the engine's
  // switch counts in tests/analysis/test_friction_analysis.cpp).
  const vibro::io::ResultReader c =
      run(vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/friction/den_hartog_continuation.yaml"),
          "continuation.h5");
  const std::vector<std::string> names = c.attribute_strings("/bifurcations/kind", "names");
  const std::vector<std::int64_t> kinds = c.read_integers("/bifurcations/kind");
  const std::vector<double> p = c.read("/bifurcations/p");
  int onsets = 0, adding = 0;
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    CHECK(names.at(static_cast<std::size_t>(kinds[i])) == "rising");
    onsets += std::abs(p[i] - 0.6007) < 1e-3;
    adding += std::abs(p[i] - 0.18496) < 1e-4;
  }
  CHECK(kinds.size() == 2);
  CHECK(onsets == 1);
  CHECK(adding == 1);
  // With stiction: the symmetric orbit's branch point, located, with the crossing branch switched
  // onto both ways (checked against the half-period map in tests/analysis/test_friction_analysis.cpp).
  const vibro::io::ResultReader s = run(
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/friction/den_hartog_stiction_continuation.yaml"),
      "stiction.h5");
  const std::vector<std::string> s_names = s.attribute_strings("/bifurcations/kind", "names");
  const std::vector<std::int64_t> s_kinds = s.read_integers("/bifurcations/kind");
  const std::vector<double> s_p = s.read("/bifurcations/p");
  const std::vector<std::int64_t> s_smooth = s.read_integers("/bifurcations/smooth");
  int branch_points = 0;
  for (std::size_t i = 0; i < s_kinds.size(); ++i)
    if (s_names.at(static_cast<std::size_t>(s_kinds[i])) == "branch_point") {
      ++branch_points;
      CHECK(std::abs(s_p[i] - 0.522467) < 1e-6);
      CHECK(s_smooth[i] == 1);
    }
  CHECK(branch_points == 1);
  const std::vector<std::int64_t> parents = s.read_integers("/branches/parent");
  REQUIRE(parents.size() == 3);
  CHECK(parents[1] == 0);
  CHECK(parents[2] == 0);
}

TEST_CASE("a scene with friction and a rigid stop runs as an orbit: impacts, stick-slip, a structural zero",
          "[friction]") {
  // The stick-slip example with a rigid stop at x = 1 (r = 0.7): each period it sticks to the
  // belt twice and strikes the stop once (tests/analysis/test_friction_stops_analysis.cpp checks
  // the tangent map of this orbit against differences of the map).
  const vibro::test::TempDir dir;
  vibro::io::SceneDocument doc = vibro::io::SceneDocument::load(kStickSlip);
  doc.replace("stops", "[{mass: 0, side: upper, position: 1, restitution: 0.7}]");
  doc.replace("run", "{kind: orbit, transient_periods: 200}");
  doc.replace("record", "");
  const vibro::io::Scene scene = doc.build();
  vibro::io::RunRequest request;
  request.output = dir / "orbit.h5";
  request.threads = 1;
  const vibro::io::RunReport report = vibro::io::run_scene(doc, scene, request);
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const vibro::io::ResultReader o(dir / "orbit.h5");
  CHECK(o.attribute_string("/orbit", "status") == "converged");
  CHECK(o.attribute_string("/orbit", "structural_zeros") == "1");
  CHECK(o.attribute_string("/orbit", "stability") == "stable");
}

TEST_CASE("a scene with friction and a compliant stop runs on the friction engine with stops", "[friction]") {
  // experiments/friction/two_mass_compliant_friction.yaml: mass 0 rubs on a fixed surface, mass 1
  // strikes a compliant stop; its engine records both laws' events.
  const vibro::io::Scene s =
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/friction/two_mass_compliant_friction.yaml").build();
  REQUIRE(s.friction.size() == 1);
  REQUIRE(s.stops.size() == 1);
  CHECK(s.stops[0].is_compliant());
  CHECK(s.engine == vibro::io::EngineKind::dense);
  const std::unique_ptr<vibro::Engine> engine = vibro::io::make_engine(s);
  CHECK(engine->stop_count() == 1);
  vibro::EventLog log;
  const vibro::RunSummary r = engine->run(s.t0, s.x0, s.v0, s.t0 + 20 * s.period(), {&log});
  REQUIRE(r.status == vibro::RunStatus::completed);
  int engages = 0, sticks = 0, slips = 0;
  for (const vibro::Event& e : log.events) {
    engages += e.kind == vibro::EventKind::engage;
    sticks += e.kind == vibro::EventKind::friction_stick;
    slips += e.kind == vibro::EventKind::friction_slip;
    if (e.kind == vibro::EventKind::friction_stick) CHECK(std::abs(e.force) <= 0.3 * (1 + 1e-9));  // μ_s N
  }
  CHECK(engages >= 20);  // 3 per period at Ω = 0.3 in the sweep's diagram
  CHECK(sticks >= 20);
  CHECK(slips >= 20);
}
