// Restarts (initial.from): a run started on an orbit saved in a result file — a continuation's
// branch point, a located bifurcation (with branch switching at a period doubling), an orbit
// run's orbit — and the errors of a restart that cannot be made.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

// The three-mass chain of experiments/examples/three_mass_switching.yaml at Ω = 0.67, over
// Ω ∈ [0.665, 0.69]: its period-1 branch doubles at Ω ≈ 0.6753 and 0.6823.
std::string model_text() {
  std::ifstream in(std::string(VIBRO_EXPERIMENTS) + "/examples/three_mass_switching.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  s = s.substr(0, s.find("\ninitial:") + 1);
  const std::string from = "frequency: 1.0", to = "frequency: 0.67";
  if (s.find(from) == std::string::npos) throw std::runtime_error("three_mass_switching.yaml: no '" + from + "'");
  return s.replace(s.find(from), from.size(), to);
}

const std::string kModel = model_text();
const std::string kInitial = "initial: {x: [0, 0, 0], v: [0, 0, 0]}";

std::string continuation(int max_doublings) {
  return kModel + kInitial + R"(
run:
  kind: continue
  transient_periods: 400
  continue:
    path: forcing.frequency
    range: [0.665, 0.69]
    step: 0.01
    max_step: 0.05
    max_points: 2000
    max_doublings: )" + std::to_string(max_doublings) + "\n";
}

struct Run {
  RunReport report;
  ResultReader file;
};

/// Runs `text` as the scene file `dir/name.yaml`, writing `dir/name.h5`.
Run run(const vibro::test::TempDir& dir, const std::string& name, const std::string& text) {
  const SceneDocument doc = SceneDocument::parse(text, dir / (name + ".yaml"));
  const std::string out = dir / (name + ".h5");
  RunReport report = run_scene(doc, doc.build(), {out, 1, false, false, 0});
  return {std::move(report), ResultReader(out)};
}

/// The error a scene's parsing or building gives ("" if none).
std::string error_of(const vibro::test::TempDir& dir, const std::string& text) {
  try {
    (void)SceneDocument::parse(text, dir / "bad.yaml").build();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

long row_of_kind(const ResultReader& f, const std::string& kind, double near) {
  const std::vector<std::string> names = f.attribute_strings("/bifurcations/kind", "names");
  const std::vector<std::int64_t> kinds = f.read_integers("/bifurcations/kind");
  const std::vector<double> p = f.read("/bifurcations/p");
  for (std::size_t i = 0; i < kinds.size(); ++i)
    if (names[static_cast<std::size_t>(kinds[i])] == kind && std::abs(p[i] - near) < 1e-3) return static_cast<long>(i);
  return -1;
}

}  // namespace

TEST_CASE("an orbit run restarted from a continuation's branch point starts on that orbit", "[runner][restart]") {
  const vibro::test::TempDir dir;
  const Run a = run(dir, "branch", continuation(0));
  REQUIRE(a.report.exit_code == 0);
  const std::vector<std::int64_t> ids = a.file.read_integers("/branch/branch");
  const std::vector<double> p = a.file.read("/branch/p"), t0 = a.file.read("/branch/t0");
  const Eigen::MatrixXd x = a.file.read_matrix("/branch/x"), v = a.file.read_matrix("/branch/v");
  REQUIRE(std::count(ids.begin(), ids.end(), 0) > 10);
  const Run b = run(dir, "orbit", kModel + "initial:\n  from: {file: branch.h5, branch: 0, point: 10}\nrun: {kind: orbit}\n");
  CAPTURE(b.report.summary);
  REQUIRE(b.report.exit_code == 0);
  CHECK(b.file.attribute_string("/scene", "restart") == "branch.h5: branch 0, point 10 (row 10 of /branch)");
  // The scene was put at the point's Ω, and its guess is the saved orbit: it closes to the
  // continuation's tolerance (1e-11) before any Newton step, and shooting keeps it.
  CHECK(b.file.attribute_number("/scene", "frequency") == p[10]);
  const std::vector<double> residuals = b.file.read("/orbit/residuals");
  REQUIRE(!residuals.empty());
  CHECK(residuals.front() <= 1e-11);
  CHECK(std::abs(std::stod(b.file.attribute_string("/orbit", "t0")) - t0[10]) <= 1e-12 * t0[10]);
  const Eigen::VectorXd xo = b.file.read_matrix("/orbit/x").col(0), vo = b.file.read_matrix("/orbit/v").col(0);
  const double L = x.cwiseAbs().maxCoeff(), V = v.cwiseAbs().maxCoeff();
  CHECK((xo - x.row(10).transpose()).cwiseAbs().maxCoeff() <= 1e-11 * L);
  CHECK((vo - v.row(10).transpose()).cwiseAbs().maxCoeff() <= 1e-11 * V);
  // An orbit run's file as the start: its orbit again, at the scene's own Ω (an orbit file
  // carries no continuation parameter; the scene above is at the point's Ω only through `from`).
  const Run c = run(dir, "again", kModel + "initial:\n  from: {file: orbit.h5}\nrun: {kind: orbit}\n");
  REQUIRE(c.report.exit_code == 0);
  CHECK(c.file.attribute_string("/scene", "restart") == "orbit.h5: the orbit");
  CHECK(c.file.attribute_number("/scene", "frequency") == 0.67);
  // The last point of the branch, counted from its end (the range's end, Ω = 0.69).
  const Run e = run(dir, "last", kModel + "initial:\n  from: {file: branch.h5, branch: 0, point: -1}\nrun: {kind: orbit}\n");
  REQUIRE(e.report.exit_code == 0);
  CHECK(e.file.read("/orbit/residuals").front() <= 1e-11);
  const long last = static_cast<long>(std::count(ids.begin(), ids.end(), 0)) - 1;
  CHECK(e.file.attribute_number("/scene", "frequency") == p[static_cast<std::size_t>(last)]);
}

TEST_CASE("a continuation restarted at a located period doubling follows the doubled branch", "[runner][restart]") {
  const vibro::test::TempDir dir;
  // The reference: one run that switches at its doublings itself.
  const Run whole = run(dir, "whole", continuation(1));
  REQUIRE(whole.report.exit_code == 0);
  const long pd = row_of_kind(whole.file, "period_doubling", 0.6753);
  REQUIRE(pd >= 0);
  const std::vector<std::int64_t> from = whole.file.read_integers("/branches/bifurcation");
  const auto doubled = std::find(from.begin(), from.end(), pd) - from.begin();
  REQUIRE(static_cast<std::size_t>(doubled) < from.size());
  // The restart: from that located doubling, only the doubled branch.
  std::string text = continuation(1);
  text.replace(text.find(kInitial), kInitial.size(),
               "initial:\n  from: {file: whole.h5, bifurcation: " + std::to_string(pd) + "}");
  text += "    switch: period_doubling\n";
  const Run r = run(dir, "restart", text);
  CAPTURE(r.report.summary);
  REQUIRE(r.report.exit_code == 0);
  const std::vector<std::int64_t> k = r.file.read_integers("/branches/k");
  REQUIRE(k.size() >= 2);
  CHECK(k[0] == 1);
  CHECK(r.file.read_integers("/branches/count")[0] == 1);  // the start orbit alone
  CHECK(k[1] == 2);
  // The doubled branch covers the range of the one the whole run switched onto, and every
  // bifurcation located on that one is located on it, to well inside the location tolerance
  // (1e-10): both start from the same located doubling. The steps are not the same — a branch's
  // step scales come from the orbit its run started on (Ω = 0.67 there, the doubling here) — so
  // the restart may locate more than the whole run did where that one stepped past a change
  // (here a grazing at Ω ≈ 0.66504, next to the range's end).
  const auto d = static_cast<std::size_t>(doubled);
  const std::vector<double> lo = whole.file.read("/branches/p_min"), hi = whole.file.read("/branches/p_max");
  CHECK(r.file.read("/branches/p_min")[1] <= lo[d] + 1e-8);
  CHECK(std::abs(r.file.read("/branches/p_max")[1] - hi[d]) <= 1e-8);
  auto located_on = [](const ResultReader& f, std::int64_t branch) {
    const std::vector<std::int64_t> b = f.read_integers("/bifurcations/branch"), kind = f.read_integers("/bifurcations/kind");
    const std::vector<double> p = f.read("/bifurcations/p");
    std::vector<std::pair<std::int64_t, double>> out;
    for (std::size_t i = 0; i < b.size(); ++i)
      if (b[i] == branch) out.emplace_back(kind[i], p[i]);
    return out;
  };
  const auto ref = located_on(whole.file, static_cast<std::int64_t>(d)), got = located_on(r.file, 1);
  REQUIRE(!ref.empty());
  for (const auto& located : ref) {  // (no structured binding: clang does not capture one in a lambda)
    CAPTURE(located.first, located.second);
    CHECK(std::any_of(got.begin(), got.end(), [&located](const auto& g) {
      return g.first == located.first && std::abs(g.second - located.second) <= 1e-8;
    }));
  }
  // A start that is not a period doubling is refused with the reason.
  std::string plain = continuation(0);
  plain.replace(plain.find(kInitial), kInitial.size(),
                "initial:\n  from: {file: whole.h5, branch: 0, point: 3}");
  plain += "    switch: period_doubling\n";
  const SceneDocument doc = SceneDocument::parse(plain, dir / "plain.yaml");
  try {
    (void)run_scene(doc, doc.build(), {dir / "plain.h5", 1, false, false, 0});
    FAIL("a start without a multiplier at −1 was switched at");
  } catch (const SceneError& e) {
    CHECK(std::string(e.what()).find("needs a start orbit at a period doubling") != std::string::npos);
  }
}

TEST_CASE("a restart that cannot be made is refused at its key", "[runner][restart][scene-errors]") {
  const vibro::test::TempDir dir;
  const Run a = run(dir, "saved", continuation(0));
  REQUIRE(a.report.exit_code == 0);
  const std::string run_orbit = "run: {kind: orbit}\n";
  auto with_from = [&](const std::string& from) { return kModel + "initial:\n  from: " + from + "\n" + run_orbit; };
  CHECK(error_of(dir, with_from("{file: missing.h5}")).find("initial.from.file: cannot read the result file") !=
        std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5}")).find("has no /orbit") != std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, branch: 7, point: 0}")).find("has no branch 7") != std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, branch: 0}")).find("initial.from.point: missing") != std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, branch: 0, point: 100000}")).find("initial.from.point") !=
        std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, bifurcation: 1000}")).find("initial.from.bifurcation") !=
        std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, bifurcation: 0, branch: 0, point: 1}")).find("not both") !=
        std::string::npos);
  CHECK(error_of(dir, with_from("{file: saved.h5, brunch: 0}")).find("did you mean 'branch'") != std::string::npos);
  // The state is the saved orbit's: giving it as well is an error at the key, with its line.
  const std::string both = kModel + "initial:\n  x: [0, 0, 0]\n  from: {file: saved.h5, branch: 0, point: 1}\n" + run_orbit;
  const std::string e = error_of(dir, both);
  CHECK(e.find("initial.x") != std::string::npos);
  CHECK(e.find("give either `from` or the state") != std::string::npos);
  CHECK(e.rfind(dir / "bad.yaml:", 0) == 0);
}
