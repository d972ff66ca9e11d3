// solver.engine (docs/scenes.md): how `auto` resolves, that a modal scene never builds its dense
// n × n system, and that `vibro run` gives the same events and samples with either engine.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

std::string list(long n, const std::string& value) {
  std::string out = "[";
  for (long i = 0; i < n; ++i) out += (i ? ", " : "") + value;
  return out + "]";
}

struct ChainText {
  long n = 70;
  std::string damper = "0.02";       ///< every link's damper (springs are 1)
  std::string wall = "{spring: 1, damper: 0.02}";
  std::string engine;                ///< solver.engine, or none
  std::string run = "{kind: simulate, transient_periods: 0, periods: 6}";
  std::string record = "{events: true, samples: {per_period: 16}}";
};

/// A uniform chain driven at mass 0, with the four stops of experiments/chains (restitution 0.95).
std::string chain_scene(const ChainText& c) {
  std::string cosine = "[0.6" + std::string(c.n > 1 ? ", " : "") + (c.n > 1 ? list(c.n - 1, "0").substr(1) : "]");
  std::string s = "name: engine-test\nmodel:\n  chain:\n";
  s += "    masses: " + list(c.n, "1") + "\n";
  s += "    springs: " + list(c.n - 1, "1") + "\n";
  s += "    dampers: " + list(c.n - 1, c.damper) + "\n";
  if (!c.wall.empty()) s += "    left_wall: " + c.wall + "\n";
  s += "forcing:\n  frequency: 0.8\n  cosine: " + cosine + "\n";
  s += "stops:\n"
       "  - {mass: 1, side: upper, position: 0.35, restitution: 0.95}\n"
       "  - {mass: 2, side: lower, position: -0.3, restitution: 0.95}\n"
       "  - {between: [3, 4], gap: 0.25, restitution: 0.95}\n"
       "  - {mass: 5, side: upper, position: 0.25, restitution: 0.95}\n";
  if (!c.engine.empty()) s += "solver: {engine: " + c.engine + "}\n";
  s += "record: " + c.record + "\nrun: " + c.run + "\n";
  return s;
}

Scene build(const ChainText& c) { return SceneDocument::parse(chain_scene(c), "engine.yaml").build(); }

/// A file in this test process's own directory (ctest runs every test case in its own process).
std::string temp_path(const std::string& name) {
  static const vibro::test::TempDir dir;
  return dir / name;
}

}  // namespace

TEST_CASE("solver.engine auto picks the modal engine for long proportionally damped chains", "[engine]") {
  ChainText c;
  c.n = kModalAutomaticMinimumDof;
  const Scene at_threshold = build(c);
  CHECK(at_threshold.engine == EngineKind::modal);
  CHECK(at_threshold.engine_choice == EngineChoice::automatic);
  REQUIRE(at_threshold.chain);
  CHECK(at_threshold.chain->dof() == c.n);
  CHECK(at_threshold.chain->rayleigh_stiffness == Approx(0.02).epsilon(1e-14));
  CHECK_THAT(at_threshold.engine_reason, Catch::Contains("proportionally damped chain of 64 masses"));

  c.n = kModalAutomaticMinimumDof - 1;
  const Scene short_chain = build(c);
  CHECK(short_chain.engine == EngineKind::dense);
  CHECK(short_chain.chain);  // banded form kept, the engine is still dense
  CHECK_THAT(short_chain.engine_reason, Catch::Contains("63 masses"));

  c.n = 100;
  c.damper = "0.03";  // the wall's damper stays 0.02: C ≠ βK
  const Scene non_proportional = build(c);
  CHECK(non_proportional.engine == EngineKind::dense);
  CHECK_FALSE(non_proportional.chain);
  CHECK_THAT(non_proportional.engine_reason, Catch::Contains("not proportional"));

  c.damper = "0.02";
  c.wall = "";  // no wall: a rigid-body mode, which the modal engine refuses
  const Scene floating = build(c);
  CHECK(floating.engine == EngineKind::dense);
  CHECK_THAT(floating.engine_reason, Catch::Contains("masses 0…99 tied to no wall"));

  c.wall = "{spring: 1, damper: 0.02}";
  c.engine = "dense";
  CHECK(build(c).engine == EngineKind::dense);
  c.engine = "modal";
  c.n = 8;  // explicit: any n
  CHECK(build(c).engine == EngineKind::modal);

  c.engine = "auto";
  c.n = 100;
  c.run = "{kind: locate, locate: {path: forcing.frequency, linspace: [0.79, 0.81, 2]}}";
  const Scene locating = build(c);  // locate runs on either engine (tests/io/test_locate.cpp)
  CHECK(locating.engine == EngineKind::modal);

  const Scene matrices = SceneDocument::parse("model: {matrices: {mass: [[1]], stiffness: [[1]]}}\n"
                                              "solver: {engine: auto}\n").build();
  CHECK(matrices.engine == EngineKind::dense);
  CHECK_FALSE(matrices.chain);
}

TEST_CASE("a bad solver.engine names the key, the place and why", "[engine]") {
  ChainText c;
  c.engine = "banded";
  try {
    (void)build(c);
    FAIL("no SceneError");
  } catch (const SceneError& e) {
    CHECK(e.path() == "solver.engine");
    CHECK(e.line() == 16);
    CHECK(e.column() == 18);
    CHECK_THAT(e.problem(), Catch::Contains("expected one of auto, dense, modal, taylor, found 'banded'"));
  }
  c.engine = "modal";
  c.damper = "0.03";
  try {
    (void)build(c);
    FAIL("no SceneError");
  } catch (const SceneError& e) {
    CHECK(e.path() == "solver.engine");
    CHECK_THAT(e.problem(), Catch::Contains("the modal engine cannot run this scene") &&
                                Catch::Contains("not proportional"));
  }
}

TEST_CASE("a sweep whose values change the automatic engine is refused at the value", "[engine]") {
  ChainText c;
  c.n = 100;
  c.run = "{kind: sweep, sweep: {parameters: [{path: 'model.chain.dampers[7]', values: [0.02, 0.05]}]}}";
  try {
    (void)build(c);
    FAIL("no SceneError");
  } catch (const SceneError& e) {
    CHECK(e.path() == "run.sweep.parameters[0].values[1]");
    CHECK_THAT(e.problem(), Catch::Contains("runs with the dense engine, the base scene with the modal engine"));
  }
  c.engine = "dense";
  CHECK(build(c).engine == EngineKind::dense);  // explicit: every point is dense
}

TEST_CASE("a modal scene is loaded, checked and written without its dense matrices", "[engine]") {
  // 10 000 masses, a stop on every tenth: dense, M, C, K would take 3 × 800 MB.
  const SceneDocument doc = SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/chains/chain_10000_every10.yaml");
  const Scene scene = doc.build();
  CHECK(scene.engine == EngineKind::modal);
  CHECK(scene.dof() == 10000);
  CHECK(scene.stops.size() == 1000);
  CHECK(scene.stops[999].name == "lower x9990");  // named without the dense ImpactSystem
  CHECK_FALSE(scene.dense.built());
  // Stops checked in O(m log m): a duplicate among 1000 is still found.
  SceneDocument dup = doc;
  dup.set("stops[500].mass", 20);  // stops[500] (upper x5000) becomes a twin of stops[2], upper x20
  try {
    (void)dup.build();
    FAIL("no SceneError");
  } catch (const SceneError& e) {
    CHECK(e.path() == "stops[500]");
    CHECK_THAT(e.problem(), Catch::Contains("duplicates stops[2] (upper x20)"));
  }
}

TEST_CASE("the modal and dense engines give the same run of a 70-mass chain", "[engine]") {
  // 70 masses, restitution 0.95, six periods: impacts only (no sticking, no chatter), so both
  // engines compute the same exact piecewise-linear motion, each from its own closed form.
  ChainText c;
  c.record = "{events: true, statistics: true, poincare: true, samples: {per_period: 16}}";
  c.engine = "modal";
  const std::string modal_text = chain_scene(c);
  c.engine = "dense";
  const std::string dense_text = chain_scene(c);
  const SceneDocument modal_doc = SceneDocument::parse(modal_text, "modal.yaml");
  const SceneDocument dense_doc = SceneDocument::parse(dense_text, "dense.yaml");
  const Scene modal = modal_doc.build(), dense = dense_doc.build();
  REQUIRE(modal.engine == EngineKind::modal);
  REQUIRE(dense.engine == EngineKind::dense);

  const std::string out_modal = temp_path("modal.h5"), out_dense = temp_path("dense.h5");
  REQUIRE(run_scene(modal_doc, modal, {out_modal, 1, false, false}).exit_code == 0);
  REQUIRE(run_scene(dense_doc, dense, {out_dense, 1, false, false}).exit_code == 0);
  CHECK_FALSE(modal.dense.built());  // the modal run never assembled M, C, K

  const ResultReader a(out_modal), b(out_dense);
  CHECK(a.attribute_string("/meta", "engine") == "modal");
  CHECK(b.attribute_string("/meta", "engine") == "dense");
  CHECK(a.attribute_string("/meta", "status") == "completed");
  CHECK(b.attribute_string("/meta", "status") == "completed");
  CHECK(a.exists("/scene/mass_diagonal"));
  CHECK_FALSE(a.exists("/scene/mass"));
  CHECK(b.exists("/scene/mass"));

  // Same events: count, stops, kinds exactly; times to 1e-9 T. Both engines locate each impact
  // to a few ulps of t in their own arithmetic (events.hpp, modal.hpp); the two flows (dense
  // eigen-/exponential, modal closed form) differ by rounding of order 1e-13 relative per
  // segment, which a few dozen impacts amplify (restitution 0.95, nearby grazing) to well below
  // 1e-9 T (measured: 2e-14 T for times, 1.2e-13 L for samples). A wrong event (missed,
  // spurious, other stop) moves times by O(T) or changes counts.
  const double T = 2 * std::numbers::pi / 0.8;
  const std::vector<double> ta = a.read("/events/t"), tb = b.read("/events/t");
  REQUIRE(ta.size() == tb.size());
  REQUIRE(ta.size() >= 10);  // the run has impacts to compare (22 in six periods)
  CHECK(a.read("/events/stop") == b.read("/events/stop"));
  CHECK(a.read("/events/kind") == b.read("/events/kind"));
  for (std::size_t i = 0; i < ta.size(); ++i) CHECK(std::abs(ta[i] - tb[i]) <= 1e-9 * T);
  const std::vector<double> kinds = a.read("/events/kind");
  CHECK(std::all_of(kinds.begin(), kinds.end(), [](double k) { return k == 0.0; }));  // impacts only

  // Same samples to 1e-9 of the length scale L (the largest stop offset, 0.35 here), for the
  // reason above: both are exact solutions, differing by rounding amplified through the impacts.
  const Eigen::MatrixXd xa = a.read_matrix("/samples/x"), xb = b.read_matrix("/samples/x");
  REQUIRE(xa.rows() == xb.rows());
  REQUIRE(xa.cols() == 70);
  CHECK((xa - xb).cwiseAbs().maxCoeff() <= 1e-9 * 0.35);

  // The other observers see the same motion: impacts per period and stop exactly, Poincaré
  // points (one per period) to 1e-9 L as the samples.
  CHECK(a.read("/stats/impacts") == b.read("/stats/impacts"));
  const Eigen::MatrixXd pa = a.read_matrix("/poincare/x"), pb = b.read_matrix("/poincare/x");
  REQUIRE(pa.rows() == pb.rows());
  REQUIRE(pa.rows() >= 6);  // one per period begun (6 periods recorded)
  CHECK((pa - pb).cwiseAbs().maxCoeff() <= 1e-9 * 0.35);
  std::filesystem::remove(out_modal);
  std::filesystem::remove(out_dense);
}

TEST_CASE("a sweep runs with the modal engine", "[engine]") {
  ChainText c;
  c.engine = "modal";
  c.run = "{kind: sweep, periods: 1, sweep: {parameters: [{path: forcing.frequency, values: [0.78, 0.8]}]}}";
  c.record = "{events: true, samples: {per_period: 4}}";
  const SceneDocument doc = SceneDocument::parse(chain_scene(c), "modal-sweep.yaml");
  const Scene scene = doc.build();
  c.engine = "dense";
  const SceneDocument dense_doc = SceneDocument::parse(chain_scene(c), "dense-sweep.yaml");
  const std::string out = temp_path("sweep_modal.h5"), out_dense = temp_path("sweep_dense.h5");
  for (const std::string& o : {out, out_dense}) std::filesystem::remove(ResultFile::partial_path(o));
  REQUIRE(run_scene(doc, scene, {out, 2, false, false}).exit_code == 0);
  REQUIRE(run_scene(dense_doc, dense_doc.build(), {out_dense, 2, false, false}).exit_code == 0);
  const ResultReader a(out), b(out_dense);
  CHECK(a.attribute_string("/meta", "engine") == "modal");
  CHECK(a.read("/sweep/status") == std::vector<double>{0.0, 0.0});
  CHECK(a.read("/events/point") == b.read("/events/point"));
  const std::vector<double> ta = a.read("/events/t"), tb = b.read("/events/t");
  REQUIRE(ta.size() == tb.size());
  const double T = 2 * std::numbers::pi / 0.78;  // the longer period: 1e-9 T as above
  for (std::size_t i = 0; i < ta.size(); ++i) CHECK(std::abs(ta[i] - tb[i]) <= 1e-9 * T);
  const Eigen::MatrixXd xa = a.read_matrix("/samples/x"), xb = b.read_matrix("/samples/x");
  REQUIRE(xa.size() == xb.size());
  CHECK((xa - xb).cwiseAbs().maxCoeff() <= 1e-9 * 0.35);
  std::filesystem::remove(out);
  std::filesystem::remove(out_dense);
}

TEST_CASE("run.kind locate with solver.engine modal builds a modal scene", "[engine]") {
  ChainText c;
  c.engine = "modal";
  c.run = "{kind: locate, locate: {path: forcing.frequency, linspace: [0.79, 0.81, 2]}}";
  const Scene scene = build(c);
  CHECK(scene.engine == EngineKind::modal);
  CHECK(scene.run.kind == RunSpec::Kind::locate);
}

TEST_CASE("every sticking phase starts with one stick or chatter-limit row, and /meta counts agree", "[engine]") {
  // docs/results.md, /events. At Ω = 0.2561 on the paper's system every phase follows chatter
  // (945 sticks over 200 periods, no `stick` row), so the rule, not a coincidence, makes them agree.
  const std::string fig2 = std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml";
  for (const char* engine : {"dense", "modal"}) {
    INFO(engine);
    SceneDocument doc = SceneDocument::parse(SceneDocument::load(fig2).text() + "solver: {engine: " + engine + "}\n",
                                             "fig2.yaml");
    doc.set("forcing.frequency", 0.2561);
    doc.set("run.transient_periods", 20);
    doc.set("run.periods", 40);
    const Scene scene = doc.build();
    const std::string out = temp_path(std::string("counts_") + engine + ".h5");
    REQUIRE(run_scene(doc, scene, {out, 1, false, false}).exit_code == 0);
    const ResultReader file(out);
    const std::vector<std::int64_t> kind = file.read_integers("/events/kind");
    auto rows = [&](EventKind k) {
      return static_cast<double>(std::count(kind.begin(), kind.end(), static_cast<std::int64_t>(k)));
    };
    CHECK(rows(EventKind::chatter_limit) > 0);
    CHECK(file.attribute_number("/meta", "sticks") == rows(EventKind::stick) + rows(EventKind::chatter_limit));
    CHECK(file.attribute_number("/meta", "chatters") == rows(EventKind::chatter_limit));
    CHECK(file.attribute_number("/meta", "impacts") == rows(EventKind::impact));
    CHECK(file.attribute_number("/meta", "releases") == rows(EventKind::release));
    // One contact interval per phase start, starting at that row's time.
    const std::vector<double> t = file.read("/events/t"), t_start = file.read("/contacts/t_start");
    std::vector<double> starts;
    for (std::size_t i = 0; i < kind.size(); ++i)
      if (kind[i] == static_cast<std::int64_t>(EventKind::stick) ||
          kind[i] == static_cast<std::int64_t>(EventKind::chatter_limit))
        starts.push_back(t[i]);
    std::sort(starts.begin(), starts.end());
    std::vector<double> sorted_start = t_start;
    std::sort(sorted_start.begin(), sorted_start.end());
    CHECK(starts == sorted_start);
  }
}
