/// Compliant stops in scene files and result files (docs/scenes.md, docs/results.md):
///  1. experiments/examples/soft_impact.yaml loads as its comment says: one compliant stop with
///     its stiffness, damping and preload, run on the dense engine (auto picks it, and says why);
///  2. its simulation writes engage and disengage events, named in /events/kind, alternating,
///     and the stops' laws in /scene;
///  3. a compliant stop's stiffness, damping and preload as continuation paths: the parameter
///     derivative moves that entry of that stop and nothing else.
/// The refusals (bad k_s, c_s, F_p, unknown law, restitution on a compliant stop, stiffness on a
/// rigid one, the modal engine) are files of tests/io/malformed/compliant_*.yaml.
#include "vibro/io/kinds/continue.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/results.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/simulator.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace {

const std::string kSoftImpact = std::string(VIBRO_EXPERIMENTS) + "/examples/soft_impact.yaml";

}  // namespace

TEST_CASE("the soft-impact example loads with a compliant stop on the dense engine", "[compliant]") {
  const vibro::io::Scene s = vibro::io::SceneDocument::load(kSoftImpact).build();
  REQUIRE(s.stops.size() == 1);
  const vibro::Stop& stop = s.stops[0];
  CHECK(stop.law == vibro::Stop::Law::compliant);
  CHECK(stop.stiffness == 25.0);
  CHECK(stop.damping == 0.1);
  CHECK(stop.preload == 0.0);
  CHECK(stop.position == 1.0);
  CHECK(s.engine == vibro::io::EngineKind::dense);
  CHECK_THAT(s.engine_reason, Catch::Contains("compliant"));
}

TEST_CASE("a compliant stop's switches are recorded as engage and disengage events", "[compliant]") {
  const vibro::test::TempDir dir;
  const std::string path = dir / "soft.h5";
  const vibro::io::Scene scene = vibro::io::SceneDocument::load(kSoftImpact).build();
  const vibro::ImpactSystem system = scene.impact_system();
  vibro::Simulator simulator(system, scene.solver);
  const double t_start = scene.t0 + scene.run.transient_periods * scene.period();
  const vibro::RunSummary transient = simulator.run(scene.t0, scene.x0, scene.v0, t_start);
  vibro::io::Recording rec = vibro::io::Recording::for_scene(scene, t_start);
  rec.summary = simulator.run(t_start, transient.x, transient.v, rec.t_end, rec.observers());
  REQUIRE(rec.summary.status == vibro::RunStatus::completed);
  const std::vector<vibro::Event>& ev = rec.events->events;
  REQUIRE(ev.size() >= 10);  // the orbit engages the stop every period (10 recorded)
  for (std::size_t i = 0; i < ev.size(); ++i) {
    CHECK((ev[i].kind == vibro::EventKind::engage || ev[i].kind == vibro::EventKind::disengage));
    if (i > 0) CHECK(ev[i].kind != ev[i - 1].kind);  // one stop: engage and disengage alternate
    if (ev[i].kind == vibro::EventKind::engage) CHECK(ev[i].v_before > 0.0);  // the gap rises
  }
  vibro::io::ResultFile file = vibro::io::ResultFile::create(path, scene, vibro::io::current_meta(1));
  file.write_simulation(rec);
  file.finish(vibro::io::current_meta(1));
  const vibro::io::ResultReader r(path);
  CHECK(r.attribute_strings("/events/kind", "names") ==
        std::vector<std::string>{"impact", "stick", "release", "chatter-limit", "engage", "disengage"});
  CHECK(r.read_integers("/events/kind").front() == static_cast<std::int64_t>(ev.front().kind));
  CHECK(r.read_integers("/scene/stop_law") == std::vector<std::int64_t>{1});
  CHECK(r.read("/scene/stop_stiffness") == std::vector<double>{25.0});
}

TEST_CASE("a compliant stop's stiffness, damping and preload are continuation parameters", "[compliant][continue]") {
  // A soft-impact oscillator with all three (a value at 0 has an invalid side: c_s, F_p ≥ 0).
  const vibro::io::SceneDocument doc = vibro::io::SceneDocument::parse(R"(
model:
  chain:
    masses: [1]
    left_wall: {spring: 1, damper: 0.02}
forcing:
  frequency: 0.9
  cosine: [0.5]
stops:
  - {mass: 0, side: upper, position: 1, law: compliant, stiffness: 25, damping: 0.1, preload: 0.05}
)",
                                                                       "soft.yaml");
  for (const char* key : {"stiffness", "damping", "preload"}) {
    INFO(key);
    const vibro::SystemDerivative d = vibro::io::parameter_derivative(doc, std::string("stops[0].") + key);
    REQUIRE(d.stops.size() == 1);
    const vibro::StopDerivative& s = d.stops[0];
    // The law's values enter the scene's data as they are: their central difference is 1 to
    // rounding (ε p / h with the step h = 1e-2 p: ~1e-14).
    const double moved = std::string(key) == "stiffness" ? s.stiffness : (std::string(key) == "damping" ? s.damping : s.preload);
    CHECK(std::abs(moved - 1.0) < 1e-12);
    CHECK(s.stiffness * s.damping == 0.0);
    CHECK(s.damping * s.preload == 0.0);
    CHECK(s.offset == 0.0);
    CHECK(s.restitution == 0.0);
    CHECK(d.stiffness.cwiseAbs().maxCoeff() == 0.0);
    CHECK(d.damping.cwiseAbs().maxCoeff() == 0.0);
    CHECK(d.frequency == 0.0);
  }
}

// The modal engine's share of compliant stops (docs/scenes.md, solver.engine): a long chain
// (64 masses, C = βK, β = 0.05) with compliant stops on one mass and between neighbours whose
// dashpots are β k_s runs on the modal engine under auto, for every run kind (orbit included: the
// modal tangent map takes compliant switches); a dashpot that is not β k_s sends auto to the dense
// engine and says why. Continuation in such a stop's stiffness is an error on the modal engine.
TEST_CASE("auto runs proportional compliant stops of a long chain on the modal engine", "[compliant][modal]") {
  auto scene = [](const std::string& damping, const std::string& run) {
    std::string masses, springs, dampers, cosine;
    for (int i = 0; i < 64; ++i) {
      masses += std::string(i ? ", " : "") + "1";
      cosine += std::string(i ? ", " : "") + (i ? "0" : "1");
      if (i < 63) {
        springs += std::string(i ? ", " : "") + "1";
        dampers += std::string(i ? ", " : "") + "0.05";
      }
    }
    const std::string text = "model:\n  chain:\n    masses: [" + masses + "]\n    springs: [" + springs +
                             "]\n    dampers: [" + dampers + "]\n    left_wall: {spring: 1, damper: 0.05}\n" +
                             "forcing:\n  frequency: 0.3\n  cosine: [" + cosine + "]\nstops:\n" +
                             "  - {mass: 0, side: upper, position: 0.5, law: compliant, stiffness: 4, damping: 0.2, "
                             "preload: 0.1}\n" +
                             "  - {between: [10, 11], gap: 0.2, law: compliant, stiffness: 2, damping: " + damping +
                             "}\n" + run;
    return vibro::io::SceneDocument::parse(text, "long.yaml").build();
  };
  const vibro::io::Scene proportional = scene("0.1", "");
  CHECK(proportional.engine == vibro::io::EngineKind::modal);
  const vibro::io::Scene other = scene("0.3", "");
  CHECK(other.engine == vibro::io::EngineKind::dense);
  CHECK_THAT(other.engine_reason, Catch::Contains("stops[1]") && Catch::Contains("is not β k_s = 0.1"));
  for (const char* kind : {"orbit", "lyapunov"}) {
    const vibro::io::Scene run = scene("0.1", std::string("run:\n  kind: ") + kind + "\n");
    CHECK(run.engine == vibro::io::EngineKind::modal);
  }
  const vibro::io::Scene preload =
      scene("0.1", "run:\n  kind: continue\n  continue:\n    path: stops[0].preload\n    range: [0.1, 0.3]\n");
  CHECK(preload.engine == vibro::io::EngineKind::modal);
  CHECK_THROWS_WITH(scene("0.1", "run:\n  kind: continue\n  continue:\n    path: stops[0].stiffness\n    range: [4, 6]\n"),
                    Catch::Contains("run.continue.path") && Catch::Contains("stiffness or damping of compliant stops[0]") &&
                        Catch::Contains("solver.engine: dense"));
}
