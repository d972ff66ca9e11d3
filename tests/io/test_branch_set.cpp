// Continuation with branch switching: a doubled branch met again from a second period doubling is
// recognised and not followed again; the run's summary of its branches (in the result file and
// the printed report); its budget; and every point's state at the fixed phase.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;

namespace {

// experiments/examples/three_mass_switching.yaml over Ω ∈ [0.655, 0.69]: the period-1 branch
// doubles at Ω ≈ 0.6753, 0.6823 and 0.6611; the period-2 branch from 0.6753 comes down to the
// doubling at 0.6611 (and through it, onto its own orbits shifted by one period), so the
// switching at 0.6611 meets it again.
const std::string kSwitching = R"(
name: switching-test
model:
  chain:
    masses: [1, 1, 1]
    springs: [1, 1]
    dampers: [0.05, 0.05]
    left_wall: {spring: 1, damper: 0.05}
forcing:
  frequency: 0.67
  cosine: [0, 0, 0.3]
stops:
  - {mass: 0, side: lower, position: -0.1, restitution: 0.8, name: below m0}
  - {between: [1, 2], gap: 0.05, restitution: 0.8, name: m1-m2 clearance}
initial:
  x: [0, 0, 0]
  v: [0, 0, 0]
run:
  kind: continue
  transient_periods: 400
  continue:
    path: forcing.frequency
    range: [0.655, 0.69]
    step: 0.01
    max_step: 0.05
    max_points: 2000
    max_doublings: 1
    max_branches: 64
    max_total_points: 40000
)";

std::string with(const std::string& from, const std::string& to) {
  std::string s = kSwitching;
  s.replace(s.find(from), from.size(), to);
  return s;
}

struct Run {
  RunReport report;
  ResultReader file;
};

Run run(const vibro::test::TempDir& dir, const std::string& text) {
  const SceneDocument doc = SceneDocument::parse(text, "switching.yaml");
  const std::string out = dir / "branches.h5";
  RunReport report = run_scene(doc, doc.build(), {out, 1, false, false, 0});
  return {std::move(report), ResultReader(out)};
}

}  // namespace

TEST_CASE("branch switching recognises a doubled branch already followed and follows each branch once",
          "[runner][continue][branches]") {
  const vibro::test::TempDir dir;
  const Run r = run(dir, kSwitching);
  CAPTURE(r.report.summary);
  REQUIRE(r.report.exit_code == 0);
  const ResultReader& f = r.file;
  const std::vector<std::int64_t> k = f.read_integers("/branches/k"), parent = f.read_integers("/branches/parent"),
                                  from = f.read_integers("/branches/bifurcation");
  const std::vector<double> lo = f.read("/branches/p_min"), hi = f.read("/branches/p_max");
  const std::vector<double> bif_p = f.read("/bifurcations/p");
  const std::vector<std::int64_t> bif_kind = f.read_integers("/bifurcations/kind"), bif_branch = f.read_integers("/bifurcations/branch");
  const std::vector<std::string> names = f.attribute_strings("/bifurcations/kind", "names");
  // The period doublings of the period-1 branch: three, at 0.6611, 0.6753 and 0.6823.
  std::vector<std::size_t> doublings;
  for (std::size_t i = 0; i < bif_kind.size(); ++i)
    if (names[static_cast<std::size_t>(bif_kind[i])] == "period_doubling" && bif_branch[i] == 0) doublings.push_back(i);
  REQUIRE(doublings.size() == 3);
  // Each is either the start of one period-2 branch or recognised as a branch already followed,
  // never both, and each period-2 branch is started once.
  const std::vector<std::int64_t> rec_from = f.read_integers("/recognised/bifurcation"),
                                  rec_known = f.read_integers("/recognised/known"), rec_k = f.read_integers("/recognised/k");
  REQUIRE(rec_from.size() == 1);  // the doubling at 0.6611: the branch from 0.6753 reaches it
  CHECK(std::abs(bif_p[static_cast<std::size_t>(rec_from[0])] - 0.6611) < 1e-3);
  CHECK(rec_k[0] == 2);
  const auto known = static_cast<std::size_t>(rec_known[0]);
  REQUIRE(known < k.size());
  CHECK(k[known] == 2);
  CHECK(parent[known] == 0);
  // The branch it was recognised as spans both doublings it joins.
  CHECK(lo[known] <= bif_p[static_cast<std::size_t>(rec_from[0])] + 1e-6);
  CHECK(std::abs(bif_p[static_cast<std::size_t>(from[known])] - 0.6753) < 1e-3);
  for (std::size_t d : doublings) {
    int started = 0, recognised = 0;
    for (std::int64_t b : from) started += b == static_cast<std::int64_t>(d);
    for (std::int64_t b : rec_from) recognised += b == static_cast<std::int64_t>(d);
    CAPTURE(d, bif_p[d]);
    CHECK(started + recognised == 1);
  }
  // Distinct branches: one period-1 and two period-2 (from 0.6753 and from 0.6823).
  REQUIRE(k.size() == 3);
  CHECK(k == std::vector<std::int64_t>{1, 2, 2});
  CHECK(parent == std::vector<std::int64_t>{-1, 0, 0});
  CHECK(f.read_integers("/recognised/parent") == std::vector<std::int64_t>{0});
  CHECK(f.read("/recognised/distance")[0] <= 1e3 * 1e-11);  // the default tolerance's scale
  // The summary: parameter ranges, starts and ends, the bifurcations located on each.
  // (the ends placed on the scan limits to locate_tolerance, 1e-10)
  CHECK(std::abs(lo[0] - 0.655) <= 1e-10);
  CHECK(std::abs(hi[0] - 0.69) <= 1e-10);
  const std::vector<std::string> start = f.read_strings("/branches/start");
  CHECK(start[0].find("shot at p = 0.67") != std::string::npos);
  CHECK(start[1].find("period doubling at p = 0.675") != std::string::npos);
  const std::vector<std::int64_t> located = f.read_integers("/branches/bifurcations");
  for (std::size_t b = 0; b < k.size(); ++b) {
    std::int64_t count = 0;
    for (std::int64_t x : bif_branch) count += x == static_cast<std::int64_t>(b);
    CHECK(located[b] == count);
  }
  CHECK(f.attribute_string("/branches", "budget").empty());
  CHECK(r.report.summary.find("is branch " + std::to_string(known) + ", already followed") != std::string::npos);
  CHECK(f.read_integers("/branches/joins").size() == 3);
}

TEST_CASE("a continuation run's budget ends the switching and says so", "[runner][continue][branches]") {
  const vibro::test::TempDir dir;
  SECTION("branches") {
    const Run r = run(dir, with("max_branches: 64", "max_branches: 2"));
    CAPTURE(r.report.summary);
    REQUIRE(r.report.exit_code == 0);
    CHECK(r.file.read_integers("/branches/k").size() == 2);
    const std::string budget = r.file.attribute_string("/branches", "budget");
    CHECK(budget.find("max_branches (2) reached: ") != std::string::npos);
    CHECK(budget.find("not switched at") != std::string::npos);
    CHECK(r.report.summary.find("budget: max_branches (2) reached") != std::string::npos);
    CHECK(r.file.attribute_string("/meta", "message").find("max_branches") != std::string::npos);
  }
  SECTION("points") {
    const Run r = run(dir, with("max_total_points: 40000", "max_total_points: 60"));
    CAPTURE(r.report.summary);
    REQUIRE(r.report.exit_code == 0);
    const std::vector<std::int64_t> count = r.file.read_integers("/branches/count");
    std::int64_t total = 0;
    for (std::int64_t c : count) total += c;
    CHECK(total <= 60);
    CHECK(r.file.attribute_string("/branches", "budget").find("max_total_points (60) reached") != std::string::npos);
  }
}

TEST_CASE("every branch point is also stored at the fixed phase, on its orbit", "[runner][continue][branches]") {
  const vibro::test::TempDir dir;
  const Run r = run(dir, with("max_doublings: 1", "max_doublings: 1\n    phase: 1.0"));
  REQUIRE(r.report.exit_code == 0);
  const ResultReader& f = r.file;
  const double theta = std::stod(f.attribute_string("/branch", "fixed_phase"));
  CHECK(theta == 1.0);
  const std::vector<double> p = f.read("/branch/p"), t0 = f.read("/branch/t0"), phase = f.read("/branch/phase");
  const Eigen::MatrixXd x = f.read_matrix("/branch/x"), xf = f.read_matrix("/branch/x_fixed"),
                        vf = f.read_matrix("/branch/v_fixed");
  const std::vector<std::int64_t> k = f.read_integers("/branch/k"), ok = f.read_integers("/branch/fixed_ok");
  const SceneDocument doc = SceneDocument::parse(kSwitching, "switching.yaml");
  // Every tenth point: the state at the fixed phase returns to itself after its period, run
  // independently from the fixed phase's time (2πm + θ)/Ω; and where the section lies at that
  // phase it is the section's state itself.
  for (std::size_t i = 0; i < p.size(); i += 10) {
    CAPTURE(i, p[i], phase[i]);
    REQUIRE(ok[i] == 1);
    if (phase[i] == theta) CHECK(xf.row(static_cast<Eigen::Index>(i)) == x.row(static_cast<Eigen::Index>(i)));
    SceneDocument at(doc);
    at.set("forcing.frequency", p[i]);
    const Scene s = at.build_point();
    const double T = 2.0 * std::numbers::pi / p[i];
    const double t = (theta + 2.0 * std::numbers::pi * std::ceil((p[i] * t0[i] - theta) / (2.0 * std::numbers::pi) - 1e-12)) / p[i];
    const RunSummary run = make_engine(s)->run(t, xf.row(static_cast<Eigen::Index>(i)).transpose(),
                                               vf.row(static_cast<Eigen::Index>(i)).transpose(), t + k[i] * T);
    REQUIRE(run.status == RunStatus::completed);
    CHECK((run.x - xf.row(static_cast<Eigen::Index>(i)).transpose()).cwiseAbs().maxCoeff() < 1e-8);
    CHECK((run.v - vf.row(static_cast<Eigen::Index>(i)).transpose()).cwiseAbs().maxCoeff() < 1e-8);
  }
}
