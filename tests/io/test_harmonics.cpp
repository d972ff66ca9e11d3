// forcing.harmonics in scene files (docs/scenes.md): the first harmonic given there is the scene
// with forcing.cosine/sine bit for bit; higher orders reach the system, /scene and both engines
// (the same events on each); continuation in a harmonic's amplitude against brute-force simulation.
#include "vibro/io/kinds/continue.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

const std::string kBase = R"(
name: harmonics-test
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}
initial:
  x: [0, 0]
  v: [0, 0]
)";

std::string with_forcing(const std::string& forcing, const std::string& run = "") { return kBase + forcing + run; }

/// Events and dense samples of a dense run of the scene, for a bit-for-bit comparison.
struct Trace {
  std::vector<Event> events;
  Eigen::MatrixXd x;
};

Trace trace_of(const Scene& s, double periods) {
  const double T = s.period();
  std::vector<double> times;
  for (int i = 0; i <= 400; ++i) times.push_back(periods * T * i / 400.0);
  EventLog log;
  Samples samples(times);
  const ImpactSystem system = s.impact_system();  // the simulator keeps a reference
  Simulator sim(system, s.solver);
  const RunSummary summary = sim.run(0.0, s.x0, s.v0, periods * T, {&log, &samples});
  REQUIRE(summary.status == RunStatus::completed);
  return {log.events, samples.x};
}

bool same_events(const std::vector<Event>& a, const std::vector<Event>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].t != b[i].t || a[i].stop != b[i].stop || a[i].kind != b[i].kind || a[i].v_before != b[i].v_before ||
        a[i].v_after != b[i].v_after)
      return false;
  return true;
}

}  // namespace

TEST_CASE("forcing.harmonics: order 1 given there is the scene with forcing.cosine and sine, bit for bit",
          "[scene][harmonics]") {
  const std::string plain = R"(forcing:
  frequency: 0.2559
  cosine: [0.5, 0]
  sine: [0, 0.05]
)";
  const std::string listed = R"(forcing:
  frequency: 0.2559
  harmonics:
    - {order: 1, cosine: [0.5, 0], sine: [0, 0.05]}
)";
  const Scene a = SceneDocument::parse(with_forcing(plain), "a.yaml").build();
  const Scene b = SceneDocument::parse(with_forcing(listed), "b.yaml").build();
  CHECK(b.forcing().harmonics.empty());
  CHECK(a.forcing().cosine == b.forcing().cosine);
  CHECK(a.forcing().sine == b.forcing().sine);
  CHECK(a.engine == b.engine);
  const Trace ta = trace_of(a, 20.0), tb = trace_of(b, 20.0);
  CHECK(ta.events.size() > 20);
  CHECK(same_events(ta.events, tb.events));
  CHECK(ta.x == tb.x);

  // The result files too: the same datasets (tools/dev/same_results.py compares whole files).
  const vibro::test::TempDir dir;
  const std::string run = "record: {events: true}\nrun: {kind: simulate, periods: 10}\n";
  const SceneDocument da = SceneDocument::parse(with_forcing(plain, run), "a.yaml");
  const SceneDocument db = SceneDocument::parse(with_forcing(listed, run), "b.yaml");
  REQUIRE(run_scene(da, da.build(), {dir / "a.h5", 1, false, false, 0}).exit_code == 0);
  REQUIRE(run_scene(db, db.build(), {dir / "b.h5", 1, false, false, 0}).exit_code == 0);
  const ResultReader ra(dir / "a.h5"), rb(dir / "b.h5");
  for (const char* name : {"/scene/forcing_cosine", "/scene/forcing_sine", "/events/t", "/events/v_before", "/events/v_after"}) {
    INFO(name);
    REQUIRE(ra.exists(name));
    CHECK(ra.read(name) == rb.read(name));
  }
  CHECK(!rb.exists("/scene/harmonic_order"));
}

TEST_CASE("forcing.harmonics: higher orders reach the system, /scene, and the engine auto chooses as without them",
          "[scene][harmonics]") {
  const std::string forcing = R"(forcing:
  frequency: 0.2559
  cosine: [0.5, 0]
  harmonics:
    - {order: 3, sine: [0, 0.02]}
    - {order: 2, cosine: [0.1, 0], sine: [0.05, 0]}
solver: {engine: auto}
)";
  const std::string run = "record: {events: true, poincare: true, samples: {per_period: 50}}\nrun: {kind: simulate, periods: 5}\n";
  const SceneDocument doc = SceneDocument::parse(with_forcing(forcing, run), "h.yaml");
  const Scene s = doc.build();
  REQUIRE(s.forcing().harmonics.size() == 2);
  CHECK(s.forcing().harmonics[0].order == 3);
  CHECK(s.forcing().harmonics[1].order == 2);
  CHECK(s.forcing().harmonics[1].sine(0) == 0.05);
  CHECK(s.system().forcing().harmonics.size() == 2);  // the chain's dense system carries them
  CHECK(s.engine == EngineKind::dense);  // two masses: below the modal engine's threshold
  CHECK(s.engine_reason.find("2 masses") != std::string::npos);
  // --set reaches a harmonic's amplitude by its place in the list.
  SceneDocument edited(doc);
  edited.set("forcing.harmonics[1].cosine[0]", 0.25);
  CHECK(edited.build().forcing().harmonics[1].cosine(0) == 0.25);
  const vibro::test::TempDir dir;
  REQUIRE(run_scene(doc, s, {dir / "h.h5", 1, false, false, 0}).exit_code == 0);
  const ResultReader r(dir / "h.h5");
  CHECK(r.read_integers("/scene/harmonic_order") == std::vector<std::int64_t>{3, 2});
  CHECK(r.shape("/scene/harmonic_cosine") == std::vector<std::size_t>{2, 2});
  CHECK(r.read("/scene/harmonic_cosine") == std::vector<double>{0.0, 0.0, 0.1, 0.0});
  CHECK(r.read("/scene/harmonic_sine") == std::vector<double>{0.0, 0.02, 0.05, 0.0});
  const std::vector<std::size_t> section = r.shape("/poincare/x");  // one state per period
  REQUIRE(section.size() == 2);
  CHECK(section[0] >= 5);
  CHECK(section[1] == 2);
}

TEST_CASE("forcing.harmonics: solver.engine: modal runs them, with the dense engine's events", "[scene][harmonics]") {
  // The two engines agree to rounding on a drive with harmonics (tests/framework/
  // test_modal_harmonics.cpp gives the bound 1e-10 of T and V and its reasons).
  const std::string forcing = R"(forcing:
  frequency: 0.2559
  cosine: [0.5, 0]
  harmonics:
    - {order: 3, sine: [0, 0.02]}
    - {order: 2, cosine: [0.1, 0], sine: [0.05, 0]}
)";
  const std::string run = "record: {events: true}\nrun: {kind: simulate, periods: 20}\n";
  const vibro::test::TempDir dir;
  std::vector<ResultReader> results;
  for (const char* engine : {"dense", "modal"}) {
    const SceneDocument doc =
        SceneDocument::parse(with_forcing(forcing, run) + "solver: {engine: " + engine + "}\n", std::string(engine) + ".yaml");
    const Scene s = doc.build();
    CHECK(s.engine == (std::string(engine) == "modal" ? EngineKind::modal : EngineKind::dense));
    REQUIRE(run_scene(doc, s, {dir / (std::string(engine) + ".h5"), 1, false, false, 0}).exit_code == 0);
    results.emplace_back(dir / (std::string(engine) + ".h5"));
  }
  const std::vector<double> td = results[0].read("/events/t"), tm = results[1].read("/events/t");
  REQUIRE(td.size() >= 10);
  REQUIRE(tm.size() == td.size());
  CHECK(results[0].read_integers("/events/stop") == results[1].read_integers("/events/stop"));
  const double T = 2.0 * std::numbers::pi / 0.2559;
  double dt = 0.0;
  for (std::size_t e = 0; e < td.size(); ++e) dt = std::max(dt, std::abs(td[e] - tm[e]));
  CHECK(dt <= 1e-10 * T);
}

TEST_CASE("forcing.harmonics: the parameter derivative of a harmonic's amplitude", "[scene][harmonics][continue]") {
  const std::string forcing = R"(forcing:
  frequency: 0.2559
  cosine: [0.5, 0]
  harmonics:
    - {order: 2, cosine: [0.1, 0], sine: [0, 0.05]}
)";
  const SceneDocument doc = SceneDocument::parse(with_forcing(forcing), "d.yaml");
  const SystemDerivative d = parameter_derivative(doc, "forcing.harmonics[0].sine[1]");
  REQUIRE(d.harmonic_sine.size() == 1);
  CHECK(std::abs(d.harmonic_sine[0](1) - 1.0) < 1e-13);
  CHECK(d.harmonic_sine[0](0) == 0.0);
  CHECK(d.harmonic_cosine[0].cwiseAbs().maxCoeff() == 0.0);
  CHECK(d.cosine.cwiseAbs().maxCoeff() == 0.0);
  CHECK(d.frequency == 0.0);
}

namespace {

/// Continues `doc` (a `run.kind: continue` scene in `path`) and compares the branch with brute
/// force: at up to five points (stable, period 1, p ≤ p_max), the orbit's state at its phase t0
/// must be where a simulation from rest at that parameter settles after 400 periods on `brute`
/// (the dense engine, or the scene's own). Returns how many points were compared.
int continuation_against_brute_force(const SceneDocument& doc, const std::string& path, double p_max,
                                     EngineKind continued, EngineKind brute) {
  const vibro::test::TempDir dir;
  const Scene scene = doc.build();
  CHECK(scene.engine == continued);
  const RunReport report = run_scene(doc, scene, {dir / "c.h5", 1, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const ResultReader r(dir / "c.h5");
  const std::vector<double> p = r.read("/branch/p"), t0 = r.read("/branch/t0"), x = r.read("/branch/x"),
                            v = r.read("/branch/v"), residual = r.read("/branch/residual");
  const std::vector<std::int64_t> k = r.read_integers("/branch/k"), stable = r.read_integers("/branch/stable");
  REQUIRE(p.size() >= 3);
  int compared = 0;
  for (std::size_t i = 0; i < p.size(); i += std::max<std::size_t>(1, p.size() / 5)) {
    if (k[i] != 1 || stable[i] != 1 || p[i] > p_max) continue;
    CHECK(residual[i] <= 1e-10);
    SceneDocument at(doc);
    at.set(path, p[i]);
    Scene s = at.build_point();
    s.engine = brute;
    const double t_end = t0[i] + 400.0 * s.period();
    const std::unique_ptr<Engine> engine = make_engine(s);
    Samples end(std::vector<double>{t_end});
    const RunSummary summary = engine->run(0.0, Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(2), t_end, {&end});
    REQUIRE(summary.status == RunStatus::completed);
    INFO(path << " = " << p[i]);
    // A stable orbit attracts at its largest multiplier (|μ| ≤ 0.2 here, measured): 400 periods
    // leave nothing of the start (0.2^400); what remains is the corrector's residual (≤ 1e-10
    // above), rounding, and, across engines, their agreement (1e-10 of T in event times,
    // tests/framework/test_modal_harmonics.cpp), all far below 1e-8.
    for (Eigen::Index q = 0; q < 2; ++q) {
      CHECK(std::abs(end.x(q, 0) - x[2 * i + static_cast<std::size_t>(q)]) <= 1e-8);
      CHECK(std::abs(end.v(q, 0) - v[2 * i + static_cast<std::size_t>(q)]) <= 1e-8);
    }
    ++compared;
  }
  return compared;
}

// The two-mass chain with an impacting period-1 orbit at Ω = 0.3 and a second harmonic.
const std::string kTwoTone = R"(forcing:
  frequency: 0.3
  cosine: [0.5, 0]
  harmonics:
    - {order: 2, cosine: [0.0, 0], sine: [0, 0.02]}
)";

std::string continue_in(const std::string& path, double lo, double hi, double step) {
  return "run:\n  kind: continue\n  transient_periods: 200\n  continue:\n    path: " + path + "\n    range: [" +
         number_text(lo) + ", " + number_text(hi) + "]\n    step: " + number_text(step) +
         "\n    max_step: " + number_text(step) + "\n";
}

}  // namespace

TEST_CASE("forcing.harmonics: continuation in a second harmonic's amplitude matches brute-force simulation",
          "[scene][harmonics][continue]") {
  // The second harmonic's cosine on mass 0 is continued over [0, 0.04]. Beyond p ≈ 0.0239 the
  // branch folds back (two stable orbits coexist there, and a run from rest may settle on
  // either): the comparison keeps to p ≤ 0.02, where the orbit is unique.
  const std::string path = "forcing.harmonics[0].cosine[0]";
  const SceneDocument doc = SceneDocument::parse(with_forcing(kTwoTone, continue_in(path, 0, 0.04, 0.01)), "c.yaml");
  CHECK(continuation_against_brute_force(doc, path, 0.02, EngineKind::dense, EngineKind::dense) >= 2);
}

TEST_CASE("forcing.harmonics: on the modal engine, continuation in a second harmonic's amplitude matches brute force "
          "on both engines",
          "[scene][harmonics][continue][modal]") {
  // The same scene and branch as above, continued on the modal engine (its parameter derivatives
  // carry one particular solution per harmonic); its points are checked against runs on the
  // modal engine and on the dense one.
  const std::string path = "forcing.harmonics[0].cosine[0]";
  const SceneDocument doc = SceneDocument::parse(
      with_forcing(kTwoTone, continue_in(path, 0, 0.04, 0.01)) + "solver: {engine: modal}\n", "c.yaml");
  CHECK(continuation_against_brute_force(doc, path, 0.02, EngineKind::modal, EngineKind::modal) >= 2);
  CHECK(continuation_against_brute_force(doc, path, 0.02, EngineKind::modal, EngineKind::dense) >= 2);
}

TEST_CASE("forcing.harmonics: continuation in a second harmonic's quadrature part (its phase) matches brute force "
          "on both engines",
          "[scene][harmonics][continue][modal]") {
  // The second harmonic's sine on mass 1 turns the harmonic's phase as it grows (the cosine on
  // mass 0 held at 0.01): continued over [0, 0.04] on each engine, checked against the dense engine.
  const std::string path = "forcing.harmonics[0].sine[1]";
  const std::string forcing = R"(forcing:
  frequency: 0.3
  cosine: [0.5, 0]
  harmonics:
    - {order: 2, cosine: [0.01, 0], sine: [0, 0.0]}
)";
  for (const char* engine : {"dense", "modal"}) {
    INFO("engine " << engine);
    const SceneDocument doc = SceneDocument::parse(
        with_forcing(forcing, continue_in(path, 0, 0.04, 0.01)) + "solver: {engine: " + engine + "}\n", "c.yaml");
    const EngineKind kind = std::string(engine) == "modal" ? EngineKind::modal : EngineKind::dense;
    CHECK(continuation_against_brute_force(doc, path, 0.04, kind, EngineKind::dense) >= 2);
  }
}
