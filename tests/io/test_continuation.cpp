// vibro run with run.kind: continue — the file holds the branch and the located bifurcations the
// library finds; parameters are refused, with their place in the file, when continuation cannot
// differentiate the system along them.
#include "vibro/continuation.hpp"
#include "vibro/io/kinds/continue.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "support/six_mass_chain.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

// The paper's system continued across its rising (0.256006…, tests/study).
const std::string kContinue = R"(
name: continue-test
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
forcing:
  frequency: 0.2559
  cosine: [0.5, 0]
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, phase: 0.3, name: s2}
initial:
  x: [0, 0]
  v: [0, 0]
run:
  kind: continue
  transient_periods: 200
  continue:
    path: forcing.frequency
    range: [0.2559, 0.2561]
    step: 0.05
    max_step: 0.2
)";

SceneError error_of(const std::string& text) {
  try {
    (void)SceneDocument::parse(text, "c.yaml").build();
  } catch (const SceneError& e) {
    return e;
  }
  FAIL("the scene was accepted");
  throw;
}

std::string with(const std::string& from, const std::string& to) {
  std::string s = kContinue;
  s.replace(s.find(from), from.size(), to);
  return s;
}

}  // namespace

TEST_CASE("a continue run writes the branch and the located rising, as the library finds them", "[runner][continue]") {
  const vibro::test::TempDir dir;
  const SceneDocument doc = SceneDocument::parse(kContinue, "continue.yaml");
  const Scene scene = doc.build();
  const std::string out = dir / "branch.h5";
  const RunReport report = run_scene(doc, scene, {out, 1, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  const ResultReader r(out);
  CHECK(r.attribute_string("/scene", "run_kind") == "continue");
  CHECK(r.attribute_string("/meta", "status") == "completed");
  CHECK(r.attribute_string("/branch", "parameter") == "forcing.frequency");
  const std::vector<double> p = r.read("/branch/p");
  REQUIRE(p.size() >= 3);
  CHECK(*std::min_element(p.begin(), p.end()) == 0.2559);
  CHECK(*std::max_element(p.begin(), p.end()) == 0.2561);
  for (const char* name : {"/branch/x", "/branch/v", "/branch/multipliers_real", "/branch/multipliers_imag",
                           "/branch/sticking_fraction", "/branch/signature", "/branches/k", "/bifurcations/kind"})
    CHECK(r.exists(name));
  CHECK(r.shape("/branch/multipliers_real") == std::vector<std::size_t>{p.size(), 4});
  // Every point is periodic, stable here, with the two structural zeros of sticking.
  for (double res : r.read("/branch/residual")) CHECK(res <= 1e-11);
  for (std::int64_t z : r.read_integers("/branch/structural_zeros")) CHECK(z == 2);
  // The rising, as the library finds it on the same family.
  const std::vector<std::int64_t> kind = r.read_integers("/bifurcations/kind");
  const std::vector<std::string> names = r.attribute_strings("/bifurcations/kind", "names");
  const std::vector<double> at = r.read("/bifurcations/p");
  int rising = -1;
  for (std::size_t i = 0; i < kind.size(); ++i)
    if (names[static_cast<std::size_t>(kind[i])] == "rising") rising = static_cast<int>(i);
  REQUIRE(rising >= 0);
  CHECK(r.read_integers("/bifurcations/stop")[static_cast<std::size_t>(rising)] == 0);
  CHECK(std::abs(at[static_cast<std::size_t>(rising)] - 0.2560063298) < 1e-9);  // tests/study: the reference's
}

TEST_CASE("run.continue.parameter_scale: a run over a narrow range steps as the run over the full range",
          "[runner][continue]") {
  const vibro::test::TempDir dir;
  const auto branch = [&](const std::string& text, const std::string& name) {
    const SceneDocument doc = SceneDocument::parse(text, name + ".yaml");
    const std::string out = dir / (name + ".h5");
    const RunReport report = run_scene(doc, doc.build(), {out, 1, false, false, 0});
    CAPTURE(report.summary);
    REQUIRE(report.exit_code == 0);
    return ResultReader(out).read("/branch/p");
  };
  // The full range [0.2559, 0.2561]; the same start over [0.2559, 0.25605], with and without the
  // full range's width as P.
  const std::vector<double> full = branch(kContinue, "full");
  const std::string narrow = with("range: [0.2559, 0.2561]", "range: [0.2559, 0.25605]");
  // (P as the full run computes it, 0.2561 − 0.2559, to the last bit: 2.0000000000000018e-4.)
  std::ostringstream width;
  width << std::setprecision(17) << 0.2561 - 0.2559;
  const std::vector<double> scaled =
      branch(with("range: [0.2559, 0.2561]", "range: [0.2559, 0.25605]\n    parameter_scale: " + width.str()), "scaled");
  const std::vector<double> own = branch(narrow, "own");
  REQUIRE(full.size() >= 4);
  REQUIRE(scaled.size() >= 3);
  // With P given, every point below the narrow limit is the full run's (the same steps, in the
  // same order, from the same start: the same arithmetic); the last one is placed on the limit.
  // (Points in order of arclength: the limit below the start, the start, then the steps up.)
  for (std::size_t i = 0; i + 1 < scaled.size(); ++i) CHECK(scaled[i] == full[i]);
  CHECK(std::abs(scaled.back() - 0.25605) <= 1e-10);  // placed on the limit to locate_tolerance
  // Without it P is the narrow range's width (1.5e-4): the first step up already differs.
  REQUIRE(own.size() >= 3);
  CHECK(own[1] == full[1]);
  CHECK(std::abs(own[2] - full[2]) > 1e-7);

  // Refused, at its place: a scale that is not > 0.
  for (const char* bad : {"0", "-1e-4"}) {
    const std::string text = with("max_step: 0.2", std::string("max_step: 0.2\n    parameter_scale: ") + bad);
    const SceneError e = error_of(text);
    CHECK(e.path() == "run.continue.parameter_scale");
    CHECK(e.line() == 1 + std::count(text.begin(), text.begin() + static_cast<long>(text.find("parameter_scale")), '\n'));
    CHECK_THAT(e.problem(), Catch::Contains("a scale > 0"));
  }
}

TEST_CASE("continuation parameters: derivatives of the data along a path, and paths refused with their place",
          "[runner][continue]") {
  const SceneDocument doc = SceneDocument::parse(kContinue, "continue.yaml");
  // Affine paths: a constant derivative of the data (here dC/dc of the link damper: [[1, −1], [−1, 1]]).
  const SystemDerivative dc = parameter_derivative(doc, "model.chain.dampers[0]");
  REQUIRE(dc.damping.rows() == 2);
  CHECK(std::abs(dc.damping(0, 0) - 1.0) < 1e-13);
  CHECK(std::abs(dc.damping(0, 1) + 1.0) < 1e-13);
  CHECK(std::abs(dc.damping(1, 1) - 1.0) < 1e-13);
  CHECK(dc.stiffness.cwiseAbs().maxCoeff() == 0.0);
  // A lower stop's position p enters as s0 = −p.
  const SystemDerivative ds = parameter_derivative(doc, "stops[0].position");
  REQUIRE(ds.stops.size() == 2);
  CHECK(std::abs(ds.stops[0].offset + 1.0) < 1e-13);
  // The phase of stop 1 (a = 0 here, so nothing moves) and the frequency: closed forms.
  CHECK(parameter_derivative(doc, "forcing.frequency").frequency == 1.0);
  CHECK(parameter_derivative(doc, "stops[1].phase").stops[1].cosine == 0.0);

  // Refused: a value that does not move the system; a range without the scene's value.
  const SceneError initial = error_of(with("path: forcing.frequency", "path: initial.x[0]"));
  CHECK(initial.path() == "run.continue.path");
  CHECK(initial.line() > 1);
  CHECK(std::string(initial.what()).find("does not change the system") != std::string::npos);
  const SceneError range = error_of(with("range: [0.2559, 0.2561]", "range: [0.26, 0.27]"));
  CHECK(range.path() == "run.continue.range");
  CHECK(std::string(range.what()).find("outside") != std::string::npos);
}

namespace {

// The chain of support/six_mass_chain.hpp (its stop below mass 3 is hit four times per period),
// continued in the position of that stop (a stop's data: the modal engine differentiates along it)
// over [-0.3, -0.2]: 42 points and a Neimark–Sacker bifurcation at -0.27654248064 (dense engine,
// 0.65 s). ENGINE, PATH and RANGE are replaced.
const std::string kChain = std::string("\nname: continue-chain\n") + vibro::test::kSixMassChain + R"(solver: {engine: ENGINE}
run:
  kind: continue
  transient_periods: 100
  continue:
    path: PATH
    range: RANGE
    step: 0.05
)";

std::string chain_scene(const std::string& engine, const std::string& path = "stops[1].position",
                        const std::string& range = "[-0.3, -0.2]") {
  std::string s = kChain;
  for (const auto& [key, value] : {std::pair{std::string("ENGINE"), engine}, {"PATH", path}, {"RANGE", range}})
    s.replace(s.find(key), key.size(), value);
  return s;
}

/// Runs the scene into dir/name and returns the file.
ResultReader run_into(const vibro::test::TempDir& dir, const std::string& text, const std::string& name) {
  const SceneDocument doc = SceneDocument::parse(text, name + ".yaml");
  const Scene scene = doc.build();
  const std::string out = dir / (name + ".h5");
  const RunReport report = run_scene(doc, scene, {out, 1, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  return ResultReader(out);
}

double largest_difference(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

}  // namespace

// Tolerances as in tests/analysis/test_continuation_modal.cpp (the same comparison on the
// library's results): p to 1e-9, states and multipliers to 1e-8 (here absolute: L and V are of
// order 0.1 to 1 in this chain), everything discrete (counts, kinds, stops, signatures) equal.
TEST_CASE("a continue run on the modal engine writes the branch and the bifurcations the dense engine's run writes",
          "[runner][continue][modal]") {
  const vibro::test::TempDir dir;
  const ResultReader dense = run_into(dir, chain_scene("dense"), "dense");
  const ResultReader modal = run_into(dir, chain_scene("modal"), "modal");
  CHECK(modal.attribute_string("/meta", "status") == "completed");
  const std::vector<double> p = dense.read("/branch/p");
  REQUIRE(p.size() >= 5);
  REQUIRE(!dense.read("/bifurcations/p").empty());
  for (const char* name : {"/branch/branch", "/branch/k", "/branch/stable", "/branch/structural_zeros",
                           "/branch/signature", "/branch/located", "/branches/k", "/branches/count", "/bifurcations/kind",
                           "/bifurcations/stop", "/bifurcations/branch", "/bifurcations/smooth"}) {
    INFO(name);
    CHECK(modal.read(name) == dense.read(name));
  }
  for (const char* name : {"/branch/p", "/bifurcations/p"}) {
    INFO(name);
    CHECK(largest_difference(modal.read(name), dense.read(name)) <= 1e-9);
  }
  for (const char* name : {"/branch/x", "/branch/v", "/branch/multipliers_real", "/branch/multipliers_imag",
                           "/bifurcations/x", "/bifurcations/v"}) {
    INFO(name);
    CHECK(largest_difference(modal.read(name), dense.read(name)) <= 1e-8);
  }
  // Not bit for bit: the modal engine's own rounding shows, so it is the modal engine that ran.
  CHECK(largest_difference(modal.read("/branch/x"), dense.read("/branch/x")) > 0.0);
}

TEST_CASE("continuation on the modal engine refuses a parameter that moves M, C or K, at its place",
          "[runner][continue][modal]") {
  // A mass moves M (the damping stays proportional, C = 0.05 K): refused on the modal engine ...
  const SceneError mass = error_of(chain_scene("modal", "model.chain.masses[2]", "[0.9, 1.1]"));
  CHECK(mass.path() == "run.continue.path");
  CHECK(mass.line() == 20);
  CHECK(mass.column() == 11);
  CHECK_THAT(mass.problem(), Catch::Contains("'model.chain.masses[2]' moves the mass matrix, and this scene resolves "
                                             "to the modal engine (solver.engine: modal)"));
  CHECK_THAT(mass.problem(), Catch::Contains("set solver.engine: dense"));
  // ... and accepted on the dense one.
  CHECK_NOTHROW(SceneDocument::parse(chain_scene("dense", "model.chain.masses[2]", "[0.9, 1.1]"), "c.yaml").build());
  // A spring alone makes the damping non-proportional beside its value, which the modal engine
  // cannot run at all: the message says so (it used to blame an off-diagonal matrix entry only).
  const SceneError spring = error_of(chain_scene("modal", "model.chain.springs[2]", "[0.9, 1.1]"));
  CHECK(spring.path() == "run.continue.path");
  CHECK_THAT(spring.problem(), Catch::Contains("beside it the scene is invalid: solver.engine: the modal engine "
                                               "cannot run this scene"));
  CHECK_THAT(spring.problem(), Catch::Contains("not proportional"));
}

namespace {

// The 1-DOF impact oscillator of experiments/examples/impact_oscillator_curves.yaml, its branch cut
// to the fold (Ω ≈ 1.339) and the fold's curve to a few points each way.
const std::string kFoldCurve = R"(
name: fold-curve
model:
  chain:
    masses: [1]
    left_wall: {spring: 1, damper: 0.1}
forcing:
  frequency: 1.2
  cosine: [0.1343234993075181]
stops:
  - {mass: 0, side: upper, position: 0.578984899912866, restitution: 0.8, name: s}
initial:
  time: 3.272492347489368
  x: [-0.6999473964052663]
  v: [-0.075491859219328]
run:
  kind: continue
  transient_periods: 5
  continue:
    path: forcing.frequency
    range: [1.1, 1.45]
    step: 0.02
    max_doublings: 0
    curve:
      path: "forcing.cosine[0]"
      range: [0.12, 0.15]
      step: 0.05
      max_points: 4
      kinds: [fold]
)";

}  // namespace

TEST_CASE("a continue run with curve.kinds: [fold] writes the fold's curves and /codim2, and an unknown kind is "
          "refused at its place", "[runner][continue][curve]") {
  const vibro::test::TempDir dir;
  const ResultReader r = run_into(dir, kFoldCurve, "fold");
  const std::vector<std::int64_t> kind = r.read_integers("/bifurcations/kind");
  const std::vector<std::string> names = r.attribute_strings("/bifurcations/kind", "names");
  int folds = 0;
  for (std::int64_t k : kind) folds += names[static_cast<std::size_t>(k)] == "fold";
  REQUIRE(folds == 1);
  // Two curves (up and down in A), every row a fold, its test function ≈ 0, inside the limits.
  const std::vector<std::int64_t> curve = r.read_integers("/curve/curve");
  REQUIRE(curve.size() >= 4);
  CHECK(curve.front() == 0);
  CHECK(curve.back() == 1);
  const std::vector<std::string> curve_names = r.attribute_strings("/curve/kind", "names");
  for (std::int64_t k : r.read_integers("/curve/kind")) CHECK(curve_names[static_cast<std::size_t>(k)] == "fold");
  for (double v : r.read("/curve/value")) CHECK(std::abs(v) < 1e-8);
  for (double a : r.read("/curve/p2")) CHECK((a >= 0.12 && a <= 0.15));
  CHECK(r.attribute_string("/codim2", "p2") == "forcing.cosine[0]");
  CHECK(r.attribute_strings("/codim2/kind", "names").front() == "fold_flip");
  // No fold–flip on a 1-DOF oscillator (its other multiplier is the positive det/1).
  CHECK(r.read_integers("/codim2/curve").empty());

  std::string cusp = kFoldCurve;
  cusp.replace(cusp.find("kinds: [fold]"), 13, "kinds: [cusp]");
  const SceneError e = error_of(cusp);
  CHECK(e.path() == "run.continue.curve.kinds[0]");
  CHECK_THAT(e.problem(), Catch::Contains("neimark_sacker"));
}
