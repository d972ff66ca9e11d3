// `base` in scene files (docs/scenes.md): a shaken chain is its equivalent force form bit for bit
// (on both engines) when no stop rides on the base, and the equivalent force form with the stop
// moving as the base when one does; continuation in the base amplitude against brute force; the
// derivative in Ω with a base; bad input with file:line:col.
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
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;
using Catch::Matchers::Contains;

namespace {

// A two-mass chain between walls (left k 1, c 0.1; right k 0.5, c 0.05), damping 0.1 K
// (proportional: the modal engine takes it), Ω = 0.3.
const std::string kModel = R"(name: base-test
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
    right_wall: {spring: 0.5, damper: 0.05}
)";

std::string stops(const std::string& second) {
  return "stops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}\n"
         "  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2" +
         second + "}\ninitial: {x: [0, 0], v: [0, 0]}\n";
}

struct Trace {
  std::vector<Event> events;
  Eigen::MatrixXd x;
  EngineKind engine;
};

Trace trace_of(const Scene& s, double periods) {
  const double T = s.period();
  std::vector<double> times;
  for (int i = 0; i <= 400; ++i) times.push_back(periods * T * i / 400.0);
  EventLog log;
  Samples samples(times);
  const std::unique_ptr<Engine> engine = make_engine(s);
  const RunSummary summary = engine->run(0.0, s.x0, s.v0, periods * T, {&log, &samples});
  REQUIRE(summary.status == RunStatus::completed);
  return {log.events, samples.x, s.engine};
}

void same(const Trace& a, const Trace& b) {
  CHECK(a.engine == b.engine);
  REQUIRE(a.events.size() == b.events.size());
  for (std::size_t e = 0; e < a.events.size(); ++e) {
    CHECK(a.events[e].t == b.events[e].t);  // bit for bit
    CHECK(a.events[e].stop == b.events[e].stop);
  }
  CHECK((a.x - b.x).cwiseAbs().maxCoeff() == 0.0);
}

std::string num(double v) { return number_text(v); }

SceneError error_of(const std::string& text) {
  try {
    SceneDocument::parse(text, "b.yaml").build();
  } catch (const SceneError& e) {
    return e;
  }
  FAIL("no SceneError for:\n" << text);
  throw;
}

/// A scene that must be refused: its text, the key the error names and a phrase of the problem.
struct BadInput {
  std::string text, path, says;
};

/// Each case refused at its key with file:line:col.
void check_bad_input(const std::vector<BadInput>& cases) {
  for (const BadInput& c : cases) {
    INFO(c.text);
    const SceneError e = error_of(c.text);
    CHECK(e.path() == c.path);
    CHECK(e.line() > 1);
    CHECK(e.column() >= 1);
    CHECK_THAT(std::string(e.what()), Contains("b.yaml:" + std::to_string(e.line()) + ":"));
    if (!c.says.empty()) CHECK_THAT(e.problem(), Contains(c.says));
  }
}

}  // namespace

// x_b = a cos Ωt + b sin Ωt through the left wall (k_L, c_L) and the right wall (k_R, c_R): the
// force is k x_b + c x_b' on the end masses, i.e. cosine k a + c b Ω, sine k b − c a Ω.
TEST_CASE("base: a shaken chain is its equivalent force form, bit for bit, on both engines", "[scene][base]") {
  const double a = 0.08, b = 0.03, W = 0.3;
  for (const char* engine : {"dense", "modal"}) {
    INFO(engine);
    const std::string solver = std::string("solver: {engine: ") + engine + "}\n";
    const std::string based = kModel + "forcing: {frequency: 0.3, cosine: [0.2, 0]}\nbase:\n  displacement: {cosine: " +
                              num(a) + ", sine: " + num(b) + "}\n" + stops("") + solver;
    const double c0 = 0.2 + (1.0 * a + 0.1 * (b * W)), s0 = 0.0 + (1.0 * b - 0.1 * (a * W));
    const double c1 = 0.0 + (0.5 * a + 0.05 * (b * W)), s1 = 0.0 + (0.5 * b - 0.05 * (a * W));
    const std::string forced = kModel + "forcing: {frequency: 0.3, cosine: [" + num(c0) + ", " + num(c1) +
                               "], sine: [" + num(s0) + ", " + num(s1) + "]}\n" + stops("") + solver;
    const Scene x = SceneDocument::parse(based, "a.yaml").build(), y = SceneDocument::parse(forced, "f.yaml").build();
    CHECK(x.engine == (std::string(engine) == "modal" ? EngineKind::modal : EngineKind::dense));
    REQUIRE(x.base);
    const Trace tx = trace_of(x, 30.0), ty = trace_of(y, 30.0);
    CHECK(tx.events.size() > 10);  // it impacts
    same(tx, ty);
  }
}

// With s2 on the base it moves as x_b: the scene is the equivalent force form with s2 given
// amplitude A = |x_b| and phase φ = atan2(−b, a) (A cos(Ωt + φ) = a cos Ωt + b sin Ωt), bit for
// bit; and it differs from the scene whose s2 stands still.
TEST_CASE("base: a stop attached to the base is the force form with the stop moving as the base", "[scene][base]") {
  const double a = 0.08, b = 0.03, W = 0.3;
  const std::string based = kModel + "forcing: {frequency: 0.3, cosine: [0.2, 0]}\nbase:\n  displacement: {cosine: " +
                            num(a) + ", sine: " + num(b) + "}\n" + stops(", attached: base");
  const double c0 = 0.2 + (1.0 * a + 0.1 * (b * W)), s0 = 0.0 + (1.0 * b - 0.1 * (a * W));
  const double c1 = 0.0 + (0.5 * a + 0.05 * (b * W)), s1 = 0.0 + (0.5 * b - 0.05 * (a * W));
  const std::string force = kModel + "forcing: {frequency: 0.3, cosine: [" + num(c0) + ", " + num(c1) + "], sine: [" +
                            num(s0) + ", " + num(s1) + "]}\n";
  const std::string moving = force + stops(", amplitude: " + num(std::hypot(a, b)) + ", phase: " + num(std::atan2(-b, a)));
  const Scene x = SceneDocument::parse(based, "a.yaml").build();
  const Scene y = SceneDocument::parse(moving, "m.yaml").build();
  const Scene fixed = SceneDocument::parse(force + stops(""), "s.yaml").build();
  const Trace tx = trace_of(x, 30.0);
  same(tx, trace_of(y, 30.0));
  const Trace tf = trace_of(fixed, 30.0);
  CHECK((tx.x - tf.x).cwiseAbs().maxCoeff() > 1e-3);
}

TEST_CASE("base: higher harmonics run on both engines, and with a stop on the base on the dense one", "[scene][base]") {
  const std::string base = "base:\n  displacement:\n    cosine: 0.05\n    harmonics:\n      - {order: 2, cosine: 0.01}\n";
  const Scene s = SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\n" + base + stops(""), "h.yaml").build();
  CHECK(s.engine == EngineKind::dense);  // two masses: auto chooses as without harmonics
  CHECK_THAT(s.engine_reason, Contains("2 masses"));
  const Scene modal =
      SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\n" + base + stops("") + "solver: {engine: modal}\n", "m.yaml")
          .build();
  CHECK(modal.engine == EngineKind::modal);
  REQUIRE(modal.chain);
  REQUIRE(modal.chain->forcing.harmonics.size() == 1);
  CHECK(modal.chain->forcing.harmonics[0].cosine(0) == 0.01);
  REQUIRE(s.forcing().harmonics.size() == 1);
  CHECK(s.forcing().harmonics[0].order == 2);
  // k x_b for the 2nd harmonic on mass 0: 1 · 0.01, and its dashpot's sine −c a 2Ω.
  CHECK(s.forcing().harmonics[0].cosine(0) == 0.01);
  CHECK(s.forcing().harmonics[0].sine(0) == -(0.1 * (0.01 * 0.6)));
  // A stop on the base moves with both harmonics: auto chooses as without them (two masses: the
  // dense engine), and the modal engine runs it too, on a chain holding the order-2 slot.
  const Scene on = SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\n" + base + stops(", attached: base"), "a.yaml")
                       .build();
  CHECK(on.engine == EngineKind::dense);
  CHECK_THAT(on.engine_reason, Contains("2 masses"));
  REQUIRE(on.stops[1].harmonics.size() == 1);
  CHECK(on.stops[1].harmonics[0].order == 2);
  CHECK(on.stops[1].harmonics[0].cosine == 0.01);
  const Scene on_modal = SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\n" + base + stops(", attached: base") +
                                                  "solver: {engine: modal}\n",
                                              "am.yaml")
                             .build();
  CHECK(on_modal.engine == EngineKind::modal);
  // A stop moving on its own with the same motion as the attached one is the same scene, bit for bit.
  const Scene own = SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\n" + base +
                                             stops(", amplitude: 0.05, harmonics: [{order: 2, cosine: 0.01}]"),
                                         "o.yaml")
                        .build();
  same(trace_of(on, 10.0), trace_of(own, 10.0));
}

TEST_CASE("stops[j].harmonics: the first harmonic as amplitude and phase, bad input with file:line:col", "[scene][base]") {
  const std::string head = kModel + "forcing: {frequency: 0.3}\n";
  // order 1 written as a harmonic is amplitude and phase: c cos Ωt + s sin Ωt = A cos(Ωt + φ).
  const Scene s = SceneDocument::parse(head + stops(", harmonics: [{order: 1, cosine: 0.03, sine: -0.04}, {order: 3, sine: 0.01}]"),
                                       "h.yaml")
                      .build();
  CHECK(s.stops[1].amplitude == std::hypot(0.03, -0.04));
  CHECK(s.stops[1].phase == std::atan2(0.04, 0.03));
  REQUIRE(s.stops[1].harmonics.size() == 1);
  CHECK(s.stops[1].harmonics[0].order == 3);
  CHECK(s.stops[1].harmonics[0].cosine == 0.0);
  CHECK(s.stops[1].harmonics[0].sine == 0.01);
  const std::vector<BadInput> cases{
      {head + stops(", harmonics: [{order: 0, cosine: 0.1}]"), "stops[1].harmonics[0].order", "whole number"},
      {head + stops(", harmonics: [{order: -2, cosine: 0.1}]"), "stops[1].harmonics[0].order", "whole number"},
      {head + stops(", harmonics: [{order: 2.5, cosine: 0.1}]"), "stops[1].harmonics[0].order", "whole number"},
      {head + stops(", harmonics: [{order: 2, cosine: .nan}]"), "stops[1].harmonics[0].cosine", ""},
      {head + stops(", harmonics: [{order: 2, sine: .inf}]"), "stops[1].harmonics[0].sine", ""},
      {head + stops(", harmonics: [{order: 2}, {order: 2, sine: 0.1}]"), "stops[1].harmonics[1].order", "given twice"},
      {head + stops(", amplitude: 0.1, harmonics: [{order: 1, sine: 0.1}]"), "stops[1].harmonics[0].order", "one place"},
      {head + stops(", harmonics: {order: 2}"), "stops[1].harmonics", "a list"},
      {head + stops(", harmonics: [{order: 2, cos: 0.1}]"), "stops[1].harmonics[0].cos", "cosine"},
      {kModel + stops(", harmonics: [{order: 2, cosine: 0.1}]"), "stops[1].harmonics", "forcing.frequency > 0"},
  };
  check_bad_input(cases);
}

TEST_CASE("base: bad input names file, line, column and key", "[scene][base]") {
  const std::string head = kModel + "forcing: {frequency: 0.3}\n";
  const std::vector<BadInput> cases{
      {head + "base:\n  displacement:\n    harmonics: [{order: 0, cosine: 0.1}]\n" + stops(""),
       "base.displacement.harmonics[0].order", "whole number"},
      {head + "base:\n  displacement:\n    harmonics: [{order: 1.5, cosine: 0.1}]\n" + stops(""),
       "base.displacement.harmonics[0].order", "whole number"},
      {head + "base:\n  displacement:\n    cosine: 0.1\n    harmonics: [{order: 1, cosine: 0.1}]\n" + stops(""),
       "base.displacement.harmonics[0].order", "given twice"},
      {head + "base:\n  displacement: {cosine: .nan}\n" + stops(""), "base.displacement.cosine", ""},
      {head + "base:\n  displacement: {sine: .inf}\n" + stops(""), "base.displacement.sine", ""},
      {head + "base:\n  displacement: {cosine: 0.1}\n  influence: [1, 1]\n" + stops(""), "base.influence", "walls"},
      {head + "base:\n  displacement: {cosine: 0.1}\n  frame: lab\n" + stops(""), "base.frame", "absolute, relative"},
      {head + "base:\n  displacement: {}\n" + stops(""), "base.displacement", "at least one"},
      {head + stops(", attached: base"), "stops[1].attached", "needs a base section"},
      {head + stops(", attached: shaker"), "stops[1].attached", "base, laboratory"},
      {kModel + "base:\n  displacement: {cosine: 0.1}\n" + stops(""), "base", "forcing.frequency > 0"},
      {"model:\n  chain: {masses: [1, 1], springs: [1]}\nforcing: {frequency: 0.3}\nbase:\n  displacement: {cosine: 0.1}\n" +
           stops(""),
       "base", "reaches no mass"},
      {"model:\n  matrices: {mass: [[1, 0], [0, 1]], stiffness: [[2, -1], [-1, 1]]}\nforcing: {frequency: 0.3}\n"
       "base:\n  displacement: {cosine: 0.1}\n  influence: [1, 1, 1]\n" + stops(""),
       "base.influence", "list of 2 numbers"},
      {"model:\n  matrices: {mass: [[1, 0], [0, 1]], stiffness: [[2, -1], [-1, 1]]}\nforcing: {frequency: 0.3}\n"
       "base:\n  displacement: {cosine: 0.1}\n" + stops(""),
       "base.influence", "missing"},
  };
  check_bad_input(cases);
}

// model.matrices with an influence vector: the drive is K ι x_b + C ι x_b' (absolute). The same
// chain written as matrices with ι = 1 is the chain scene (same forcing, to rounding of K ι).
TEST_CASE("base: model.matrices with an influence vector drives as K ι x_b + C ι x_b'", "[scene][base]") {
  const std::string m = "model:\n  matrices:\n    mass: [[1, 0], [0, 1]]\n    damping: [[0.2, -0.1], [-0.1, 0.15]]\n"
                        "    stiffness: [[2, -1], [-1, 1.5]]\nforcing: {frequency: 0.3}\nbase:\n  displacement: {cosine: 0.08, "
                        "sine: 0.03}\n  influence: [1, 1]\n" + stops("");
  const Scene s = SceneDocument::parse(m, "m.yaml").build();
  const Scene c = SceneDocument::parse(kModel + "forcing: {frequency: 0.3}\nbase:\n  displacement: {cosine: 0.08, sine: 0.03}\n" +
                                           stops(""),
                                       "c.yaml")
                      .build();
  CHECK((s.forcing().cosine - c.forcing().cosine).cwiseAbs().maxCoeff() <= 1e-16);
  CHECK((s.forcing().sine - c.forcing().sine).cwiseAbs().maxCoeff() <= 1e-16);
  CHECK(std::abs(s.forcing().cosine(0) - (1.0 * 0.08 + 0.1 * 0.03 * 0.3)) <= 1e-16);
}

// d/dΩ with a base: the derivative continuation uses must be the central difference of the
// scene's forcing in Ω (the base's drive is at most quadratic in Ω, so the difference is exact
// to rounding), in both frames.
TEST_CASE("base: the derivative in the forcing frequency follows the base's drive", "[scene][base][continue]") {
  for (const char* frame : {"absolute", "relative"}) {
    INFO(frame);
    const std::string text = kModel + "forcing: {frequency: 0.3}\nbase:\n  frame: " + frame +
                             "\n  displacement:\n    cosine: 0.08\n    sine: 0.03\n    harmonics: [{order: 2, sine: 0.01}]\n" +
                             "initial: {x: [0, 0], v: [0, 0]}\n";  // no stops: none may move with a 2nd harmonic
    const SceneDocument doc = SceneDocument::parse(text, "d.yaml");
    const SystemDerivative d = parameter_derivative(doc, "forcing.frequency");
    CHECK(d.frequency == 1.0);
    const double h = 1e-3;
    SceneDocument plus(doc), minus(doc);
    plus.set("forcing.frequency", 0.3 + h);
    minus.set("forcing.frequency", 0.3 - h);
    const Scene p = plus.build_point(), q = minus.build_point();
    const Eigen::VectorXd dc = (p.forcing().cosine - q.forcing().cosine) / (2 * h);
    const Eigen::VectorXd ds = (p.forcing().sine - q.forcing().sine) / (2 * h);
    REQUIRE(d.cosine.size() == 2);
    CHECK((d.cosine - dc).cwiseAbs().maxCoeff() <= 1e-12);
    CHECK((d.sine - ds).cwiseAbs().maxCoeff() <= 1e-12);
    REQUIRE(d.harmonic_sine.size() == 1);
    const Eigen::VectorXd dh = (p.forcing().harmonics[0].cosine - q.forcing().harmonics[0].cosine) / (2 * h);
    CHECK((d.harmonic_cosine[0] - dh).cwiseAbs().maxCoeff() <= 1e-12);
    CHECK(d.cosine.cwiseAbs().maxCoeff() + d.sine.cwiseAbs().maxCoeff() > 0.0);
  }
}

// Continuation in base.displacement.cosine with a stop on the base: at a few branch points the
// orbit's state must be where a long simulation from rest at that amplitude settles (stable
// orbits, as in the harmonics' continuation test).
// Continued on the dense engine (the scene's choice) and on the modal one (solver.engine: modal),
// each point checked against brute force on the dense engine.
namespace {

void base_continuation_against_brute_force(EngineKind kind, double upper,
                                           const std::string& base = "base:\n  displacement: {cosine: 0.02}\n",
                                           const std::string& path = "base.displacement.cosine", double start = 0.02) {
  const std::string run = "run:\n  kind: continue\n  transient_periods: 200\n  continue:\n    path: " + path + "\n"
                          "    range: [" + num(start) + ", " + num(upper) + "]\n    step: 0.02\n    max_step: 0.02\n";
  {
    const vibro::test::TempDir dir;
    const std::string text = kModel + "forcing: {frequency: 0.3, cosine: [0.4, 0]}\n" + base +
                             stops(", attached: base") + run +
                             (kind == EngineKind::modal ? "solver: {engine: modal}\n" : "");
    const SceneDocument doc = SceneDocument::parse(text, "c.yaml");
    const Scene scene = doc.build();
    CHECK(scene.engine == kind);
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
      if (k[i] != 1 || stable[i] != 1) continue;
      CHECK(residual[i] <= 1e-10);
      SceneDocument at(doc);
      at.set(path, p[i]);
      Scene s = at.build_point();
      s.engine = EngineKind::dense;
      const double t_end = t0[i] + 400.0 * s.period();
      const std::unique_ptr<Engine> engine = make_engine(s);
      Samples end(std::vector<double>{t_end});
      const RunSummary summary = engine->run(0.0, Eigen::VectorXd::Zero(2), Eigen::VectorXd::Zero(2), t_end, {&end});
      REQUIRE(summary.status == RunStatus::completed);
      INFO("p = " << p[i]);
      // 400 periods of a stable orbit leave nothing of the start; what remains is the corrector's
      // residual (≤ 1e-10 above), rounding and, for the modal branch, the engines' agreement
      // (1e-10 of T in event times, tests/framework/test_modal_harmonics.cpp), all far below 1e-8.
      for (Eigen::Index q = 0; q < 2; ++q) {
        CHECK(std::abs(end.x(q, 0) - x[2 * i + static_cast<std::size_t>(q)]) <= 1e-8);
        CHECK(std::abs(end.v(q, 0) - v[2 * i + static_cast<std::size_t>(q)]) <= 1e-8);
      }
      ++compared;
    }
    CHECK(compared >= 2);
  }
}

}  // namespace

TEST_CASE("base: continuation in the base amplitude matches brute-force simulation", "[scene][base][continue]") {
  // Over [0.02, 0.06], as on the modal engine: above 0.079 the branch enters a cascade of
  // chatter and period-doubled branches that costs ~12 s of CPU (minutes under the sanitizers)
  // and adds no point this comparison can use (its stable period-1 points are sampled).
  base_continuation_against_brute_force(EngineKind::dense, 0.06);
}

// The base's second harmonic moves the attached stop with two harmonics: continuation in that
// harmonic's amplitude (the drive and the stop's motion both move with it), its derivative
// against the central difference of the scene's data, and its orbits against brute force.
TEST_CASE("base: continuation in the base's second harmonic with a stop on the base matches brute force",
          "[scene][base][continue]") {
  const std::string base = "base:\n  displacement:\n    cosine: 0.02\n    harmonics: [{order: 2, cosine: 0.005}]\n";
  const std::string path = "base.displacement.harmonics[0].cosine";
  const SceneDocument doc =
      SceneDocument::parse(kModel + "forcing: {frequency: 0.3, cosine: [0.4, 0]}\n" + base + stops(", attached: base"), "d.yaml");
  const SystemDerivative d = parameter_derivative(doc, path);
  // x_b gains cos 2Ωt per unit: the attached upper stop on mass 1 (c = 1) by the same.
  REQUIRE(d.stop_harmonic_cosine.size() == 2);
  REQUIRE(d.stop_harmonic_cosine[1].size() == 1);
  CHECK(std::abs(d.stop_harmonic_cosine[1][0] - 1.0) <= 1e-12);
  CHECK(d.stop_harmonic_cosine[0].empty());
  REQUIRE(d.harmonic_cosine.size() == 1);
  CHECK(std::abs(d.harmonic_cosine[0](0) - 1.0) <= 1e-12);  // k_left ι_0 = 1
  // A stop's own harmonic is a continuation parameter too (a lower stop: s = −p).
  const SceneDocument own = SceneDocument::parse(
      kModel + "forcing: {frequency: 0.3}\nstops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, "
               "harmonics: [{order: 3, sine: 0.01}]}\n",
      "o.yaml");
  const SystemDerivative ds = parameter_derivative(own, "stops[0].harmonics[0].sine");
  REQUIRE(ds.stop_harmonic_sine.size() == 1);
  REQUIRE(ds.stop_harmonic_sine[0].size() == 1);
  CHECK(std::abs(ds.stop_harmonic_sine[0][0] + 1.0) <= 1e-12);
  base_continuation_against_brute_force(EngineKind::dense, 0.045, base, path, 0.005);
}

TEST_CASE("base: continuation in the base amplitude on the modal engine matches brute force on the dense engine",
          "[scene][base][continue][modal]") {
  // Over [0.02, 0.06] only: the modal engine's continuation of this scene (a stop moving with the
  // base) takes ~75 s of CPU over [0.02, 0.1], too long for the suite's time limit under load.
  base_continuation_against_brute_force(EngineKind::modal, 0.06);
}

// The shaken impact oscillator of experiments/shaken continued in Ω: the base's drive m Ω² x_b
// depends on Ω, and the fold continuation locates (where the impacting orbit ends) must be where
// brute force sees it end. From the fold's orbit, a run at Ω_fold − δ stays on an impacting orbit
// and one at Ω_fold + δ leaves it for the free one (no impacts in the last 20 periods of 1500).
// δ = 1e-3 of Ω: near a fold the orbit's distance grows as √δ and the escape takes ∝ 1/√δ
// periods (a few hundred here), both within reach of the run.
TEST_CASE("base: the fold of a continuation in Ω is where brute force loses the impacting orbit",
          "[scene][base][continue]") {
  const vibro::test::TempDir dir;
  const SceneDocument doc = SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/shaken/continuation.yaml");
  const Scene scene = doc.build();
  const RunReport report = run_scene(doc, scene, {dir / "w.h5", 1, false, false, 0});
  REQUIRE(report.exit_code == 0);
  const ResultReader r(dir / "w.h5");
  const std::vector<std::int64_t> kind = r.read_integers("/bifurcations/kind");
  const std::vector<double> p = r.read("/bifurcations/p"), t0 = r.read("/bifurcations/t0"),
                            x = r.read("/bifurcations/x"), v = r.read("/bifurcations/v");
  int folds = 0;
  for (std::size_t i = 0; i < kind.size(); ++i) {
    if (kind[i] != 0) continue;  // 0: fold
    ++folds;
    INFO("fold at Ω = " << p[i]);
    for (double side : {-1.0, 1.0}) {
      SceneDocument at(doc);
      at.set("forcing.frequency", p[i] + side * 1e-3);
      const Scene s = at.build_point();
      const double T = s.period();
      const std::unique_ptr<Engine> engine = make_engine(s);
      EventLog log;
      const double t_end = t0[i] + 1500.0 * T;
      const RunSummary summary = engine->run(t0[i], Eigen::VectorXd::Constant(1, x[i]), Eigen::VectorXd::Constant(1, v[i]),
                                             t_end, {&log});
      REQUIRE(summary.status == RunStatus::completed);
      int late = 0;
      for (const Event& e : log.events) late += e.kind == EventKind::impact && e.t > t_end - 20.0 * T;
      INFO("side " << side << ": impacts in the last 20 periods " << late);
      CHECK((side < 0 ? late >= 20 : late == 0));
    }
  }
  CHECK(folds == 1);
}
