// vibro run with run.kind: continue — the file holds the branch and the located bifurcations the
// library finds; parameters are refused, with their place in the file, when continuation cannot
// differentiate the system along them.
#include "vibro/continuation.hpp"
#include "vibro/io/continuation.hpp"
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
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

/// A fresh directory of this test's own (removed at the end).
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "vibro_continue_XXXXXX").string();
    REQUIRE(mkdtemp(pattern.data()) != nullptr);
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

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
  const TempDir dir;
  const SceneDocument doc = SceneDocument::parse(kContinue, "continue.yaml");
  const Scene scene = doc.build();
  const std::string out = (dir.path / "branch.h5").string();
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

  // Refused: a value that does not move the system; an off-diagonal entry alone; the modal engine.
  const SceneError initial = error_of(with("path: forcing.frequency", "path: initial.x[0]"));
  CHECK(initial.path() == "run.continue.path");
  CHECK(initial.line() > 1);
  CHECK(std::string(initial.what()).find("does not change the system") != std::string::npos);
  const SceneError range = error_of(with("range: [0.2559, 0.2561]", "range: [0.26, 0.27]"));
  CHECK(range.path() == "run.continue.range");
  CHECK(std::string(range.what()).find("outside") != std::string::npos);
  const SceneError modal = error_of(with("initial:", "solver: {engine: modal}\ninitial:"));
  CHECK(modal.path() == "run.kind");
  CHECK(std::string(modal.what()).find("dense engine") != std::string::npos);
}
