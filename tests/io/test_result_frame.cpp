// `record.frame` (docs/scenes.md, base): a base-excited scene's results written in absolute or
// relative coordinates. The same run written in both frames differs by exactly the base motion,
// x_abs = x_rel + x_b(t), v_abs = v_rel + x_b'(t) (ι = 1 on a chain), state by state (samples,
// Poincaré points, impact map, a sweep's end states, a diagram's points, an orbit), to one
// rounding; a run computed in the other frame agrees to the flows' rounding; the frame is in
// /meta; a followed sweep resumed from a file written in the other frame equals the whole run.
// Each on a chain with and without a stop attached to the base.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"
#include "support/temp_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

using namespace vibro;
using namespace vibro::io;
using Catch::Matchers::Contains;

namespace {

// A two-mass chain between walls, Ω = 0.3, the base moving as a cos Ωt + b sin Ωt, two stops
// (the second one on the base when `attached`).
constexpr double kOmega = 0.3, kA = 0.05, kB = 0.02;

std::string scene(const std::string& base_frame, const std::string& record, bool attached, const std::string& run) {
  return std::string(R"(name: frame-test
model:
  chain:
    masses: [1, 1]
    springs: [1]
    dampers: [0.1]
    left_wall: {spring: 1, damper: 0.1}
    right_wall: {spring: 0.5, damper: 0.05}
forcing: {frequency: 0.3, cosine: [0.4, 0]}
base:
  frame: )") + base_frame + R"(
  displacement: {cosine: 0.05, sine: 0.02}
stops:
  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}
  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2)" +
         (attached ? ", attached: base" : "") + "}\ninitial: {x: [0, 0], v: [0, 0]}\nrecord:\n" + record + run;
}

const std::string kRecord = "  samples: {per_period: 8}\n  poincare: true\n  impact_map: true\n";

/// x_b and x_b' of the scene's base at time t (written out here, not taken from the framework);
/// `a` the first harmonic's cosine (swept in the sweep test).
double xb(double t, double a = kA) { return a * std::cos(kOmega * t) + kB * std::sin(kOmega * t); }
double vb(double t, double a = kA) { return kOmega * (-a * std::sin(kOmega * t) + kB * std::cos(kOmega * t)); }

ResultReader run(const vibro::test::TempDir& dir, const std::string& text, const std::string& name) {
  const SceneDocument doc = SceneDocument::parse(text, name + ".yaml");
  const Scene s = doc.build();
  const RunReport report = run_scene(doc, s, {dir / (name + ".h5"), 1, false, false, 0});
  CAPTURE(report.summary);
  REQUIRE(report.exit_code == 0);
  return ResultReader(dir / (name + ".h5"));
}

/// Rows of `x` (r × n, row-major) of `a` (computed and written in `computed`) and `b` (the same
/// run written in the other frame) at times t: b = a ± (x_b, x_b') to one rounding.
void differ_by_base(const ResultReader& a, const ResultReader& b, const std::string& group, bool a_relative,
                    bool only_point_0 = false) {
  const std::string times = "t";
  // A diagram's impact map: only the rows of its first value (Ω = 0.3; `point` 0).
  const std::vector<std::int64_t> point = only_point_0 ? a.read_integers(group + "/point") : std::vector<std::int64_t>{};
  const std::vector<double> t = a.read(group + "/" + times), xa = a.read(group + "/x"), va = a.read(group + "/v"),
                            xr = b.read(group + "/x"), vr = b.read(group + "/v");
  REQUIRE(t == b.read(group + "/" + times));
  REQUIRE(!t.empty());
  REQUIRE(xa.size() == 2 * t.size());
  REQUIRE(xr.size() == xa.size());
  const double sign = a_relative ? 1.0 : -1.0;
  double worst = 0.0, largest = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i)
    for (std::size_t q = 0; q < 2 && (point.empty() || point[i] == 0); ++q) {
      const std::size_t at = 2 * i + q;
      // One rounding of the sum: |error| ≤ ε/2 of the result (plus that of x_b, computed here
      // with the same formula but its own rounding: a few ε of |x_b|).
      worst = std::max({worst, std::abs(xr[at] - (xa[at] + sign * xb(t[i]))) / (std::abs(xr[at]) + std::abs(xb(t[i]))),
                        std::abs(vr[at] - (va[at] + sign * vb(t[i]))) / (std::abs(vr[at]) + std::abs(vb(t[i])))});
      largest = std::max(largest, std::abs(xb(t[i])));
    }
  INFO(group << ": largest relative difference " << worst);
  CHECK(worst <= 8 * 2.2e-16);
  // The frames do differ at these times (|x_b| ≤ 0.054 here; a section's crossings fall at a few
  // forcing phases, where |x_b| may be smaller, but far above the one rounding checked above).
  CHECK(largest > (group == "section" ? 1e-3 : 0.01));
}

double max_abs_difference(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

}  // namespace

TEST_CASE("record.frame: a simulation's states in both frames differ by the base motion", "[scene][base][frame]") {
  for (bool attached : {false, true})
    for (const std::string computed : {"relative", "absolute"}) {
      const std::string other = computed == "relative" ? "absolute" : "relative";
      INFO("attached " << attached << ", computed " << computed);
      const vibro::test::TempDir dir;
      const std::string runs = "run: {periods: 30, transient_periods: 10}\n";
      // With a section too: its hyperplane (x_1 = 0.02) is in the coordinates computed in, so both
      // runs cross it at the same times; the states written differ by the base motion.
      const std::string record = kRecord + "  section: {coordinate: 1, value: 0.02}\n";
      const ResultReader own = run(dir, scene(computed, record, attached, runs), "own");
      const ResultReader mapped = run(dir, scene(computed, record + "  frame: " + other + "\n", attached, runs), "mapped");
      CHECK(own.attribute_string("/meta", "frame") == computed);  // the default: the frame computed in
      CHECK(mapped.attribute_string("/meta", "frame") == other);
      REQUIRE(own.read("/impact_map/t").size() >= 10);  // it impacts
      for (const char* group : {"samples", "poincare", "impact_map", "section"})
        differ_by_base(own, mapped, group, computed == "relative");
      // Event data is the same in both frames (gap rates), and so is /scene (what was integrated).
      CHECK(own.read("/impact_map/velocity") == mapped.read("/impact_map/velocity"));
      CHECK(own.read("/scene/forcing_cosine") == mapped.read("/scene/forcing_cosine"));

      // Computed in the other frame (its initial state mapped: at t = 0, x_b = a, x_b' = Ω b),
      // the run agrees with `mapped` to the flows' rounding: over 40 periods with ~60 impacts the
      // two formulations differ by 1e-13 of the clearance (tests/framework/test_base_excitation.cpp).
      const double sign = computed == "relative" ? 1.0 : -1.0;
      std::string text = scene(other, kRecord, attached, runs);
      const std::string x0 = "initial: {x: [0, 0], v: [0, 0]}";
      text.replace(text.find(x0), x0.size(),
                   "initial: {x: [" + number_text(sign * kA) + ", " + number_text(sign * kA) + "], v: [" +
                       number_text(sign * kOmega * kB) + ", " + number_text(sign * kOmega * kB) + "]}");
      const ResultReader direct = run(dir, text, "direct");
      CHECK(direct.attribute_string("/meta", "frame") == other);
      for (const char* group : {"samples", "poincare", "impact_map"}) {
        INFO(group);
        CHECK(direct.read(std::string("/") + group + "/t").size() == mapped.read(std::string("/") + group + "/t").size());
        const double dx = max_abs_difference(direct.read(std::string("/") + group + "/x"), mapped.read(std::string("/") + group + "/x")),
                     dv = max_abs_difference(direct.read(std::string("/") + group + "/v"), mapped.read(std::string("/") + group + "/v"));
        INFO("dx " << std::scientific << dx << " dv " << dv);
        // Samples and Poincaré points at fixed times: the flows' rounding. The impact map's
        // states are taken at the located event times, which the two formulations place a few
        // triggers apart: |Δx| ≈ |v| |Δt| (measured 1.2e-11 … 4.5e-11 here).
        const double tolerance = std::string(group) == "impact_map" ? 1e-10 : 1e-11;
        CHECK(dx <= tolerance);
        CHECK(dv <= tolerance);
      }
    }
}

TEST_CASE("record.frame: a followed sweep's states, its end states and a resumed sweep", "[scene][base][frame]") {
  const std::string sweep = R"(run:
  kind: sweep
  periods: 4
  transient_periods: 10
  sweep:
    follow: true
    parameters:
      - {path: base.displacement.cosine, values: [0.03, 0.04, 0.05, 0.06]}
)";
  for (bool attached : {false, true}) {
    INFO("attached " << attached);
    const vibro::test::TempDir dir;
    const std::string rec = "  samples: {per_period: 4}\n";
    const ResultReader own = run(dir, scene("relative", rec, attached, sweep), "own");
    const std::string text = scene("relative", rec + "  frame: absolute\n", attached, sweep);
    const ResultReader mapped = run(dir, text, "mapped");
    CHECK(mapped.attribute_string("/meta", "frame") == "absolute");
    // End states: point p at t_end with its own amplitude a_p.
    const std::vector<double> a = own.read("/sweep/values"), t = own.read("/sweep/t_end"), x = own.read("/sweep/x_end"),
                              v = own.read("/sweep/v_end"), xm = mapped.read("/sweep/x_end"),
                              vm = mapped.read("/sweep/v_end");
    REQUIRE(a.size() == 4);
    for (std::size_t p = 0; p < 4; ++p)
      for (std::size_t q = 0; q < 2; ++q) {
        CHECK(std::abs(xm[2 * p + q] - (x[2 * p + q] + xb(t[p], a[p]))) <= 4e-16);  // one rounding (values < 1)
        CHECK(std::abs(vm[2 * p + q] - (v[2 * p + q] + vb(t[p], a[p]))) <= 4e-16);
      }
    // The samples stack points as rows (point, time): each point's own amplitude.
    const std::vector<double> st = own.read("/samples/t"), sx = own.read("/samples/x"), sm = mapped.read("/samples/x");
    const std::vector<std::size_t> shape = own.shape("/samples/t");
    REQUIRE(shape.size() == 2);
    for (std::size_t p = 0; p < shape[0]; ++p)
      for (std::size_t i = 0; i < shape[1]; ++i) {
        const std::size_t row = p * shape[1] + i;
        CHECK(std::abs(sm[2 * row] - (sx[2 * row] + xb(st[row], a[p]))) <= 4e-16);
      }

    // Interrupted after two points and resumed: the third starts from the second's end state,
    // read back from the file (in the absolute frame) and mapped to the relative one, which is
    // the computed state to one rounding of the map there and back (not bit for bit): measured
    // 1e-14 after the two points that follow.
    const std::string parts = dir / "parts.h5";
    const SceneDocument doc = SceneDocument::parse(text, "parts.yaml");
    const Scene s = doc.build();
    RunRequest first{parts, 1, false, false};
    first.interrupt_after = 2;
    CHECK(run_scene(doc, s, first).exit_code == 130);
    REQUIRE(run_scene(doc, s, {parts, 1, true, false}).exit_code == 0);
    const ResultReader resumed(parts);
    for (const char* d : {"/sweep/x_end", "/sweep/v_end", "/samples/x", "/samples/v"}) {
      INFO(d);
      const double difference = max_abs_difference(resumed.read(d), mapped.read(d));
      INFO("max difference " << std::scientific << difference);
      CHECK(difference <= 1e-12);
    }
  }
}

TEST_CASE("record.frame: a diagram's points and an orbit in both frames", "[scene][base][frame]") {
  const std::string diagram = R"(run:
  kind: diagram
  transient_periods: 20
  diagram: {path: forcing.frequency, values: [0.3, 0.31], transient: 10, points: 4, max_period: 2}
)";
  const std::string orbit = "run: {kind: orbit, transient_periods: 40, orbit: {period: 1}}\n";
  for (bool attached : {false, true}) {
    INFO("attached " << attached);
    const vibro::test::TempDir dir;
    const ResultReader own = run(dir, scene("relative", "  impact_map: true\n", attached, diagram), "own");
    const ResultReader mapped = run(dir, scene("relative", "  impact_map: true\n  frame: absolute\n", attached, diagram), "mapped");
    differ_by_base(own, mapped, "impact_map", true, true);
    // x_up[0, i] (Ω = 0.3, the first value up): the state at t0 + (20 + extra + i + 1) T (the
    // transient, the periods added while it settles, then the recorded periods).
    const double T = 2.0 * M_PI / kOmega;
    const std::vector<double> x = own.read("/diagram/x_up"), xm = mapped.read("/diagram/x_up"),
                              v = own.read("/diagram/v_up"), vm = mapped.read("/diagram/v_up");
    const double extra = own.read("/diagram/extra_periods_up")[0];
    REQUIRE(x.size() == 16);
    for (std::size_t i = 0; i < 4; ++i) {
      const double t = (20.0 + extra + static_cast<double>(i) + 1.0) * T;
      for (std::size_t q = 0; q < 2; ++q) {
        CHECK(std::abs(xm[2 * i + q] - (x[2 * i + q] + xb(t))) <= 4e-16);
        CHECK(std::abs(vm[2 * i + q] - (v[2 * i + q] + vb(t))) <= 4e-16);
      }
    }

    const ResultReader o = run(dir, scene("relative", "  events: false\n", attached, orbit), "orbit");
    const ResultReader om = run(dir, scene("relative", "  frame: absolute\n", attached, orbit), "orbit_mapped");
    REQUIRE(o.attribute_string("/orbit", "status") == "converged");
    const double t0 = std::stod(o.attribute_string("/orbit", "t0"));
    const std::vector<double> ox = o.read("/orbit/x"), ov = o.read("/orbit/v"), mx = om.read("/orbit/x"),
                              mv = om.read("/orbit/v");
    for (std::size_t q = 0; q < 2; ++q) {
      CHECK(std::abs(mx[q] - (ox[q] + xb(t0))) <= 4e-16);
      CHECK(std::abs(mv[q] - (ov[q] + vb(t0))) <= 4e-16);
    }
    // initial.from that orbit: its state is in the absolute frame, so the scene must compute in it.
    const std::string x0 = "initial: {x: [0, 0], v: [0, 0]}", from = "initial: {from: {file: orbit_mapped.h5}}";
    std::string restart = scene("relative", "  events: false\n", attached, "run: {kind: simulate, periods: 1}\n");
    restart.replace(restart.find(x0), x0.size(), from);
    try {
      SceneDocument::parse(restart, dir / "r.yaml").build();
      FAIL("a state in another frame accepted");
    } catch (const SceneError& e) {
      CHECK_THAT(std::string(e.what()), Contains("initial.from") && Contains("set base.frame: absolute"));
    }
    std::string absolute = scene("absolute", "  events: false\n", attached, "run: {kind: simulate, periods: 1}\n");
    absolute.replace(absolute.find(x0), x0.size(), from);
    const Scene s = SceneDocument::parse(absolute, dir / "r.yaml").build();
    CHECK(s.x0(0) == mx[0]);
    CHECK(s.v0(1) == mv[1]);
  }
}

TEST_CASE("record.frame: bad input", "[scene][base][frame]") {
  auto error_of = [](const std::string& text) {
    try {
      SceneDocument::parse(text, "f.yaml").build();
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    FAIL("no error");
    return std::string();
  };
  const std::string simulate = "run: {periods: 1}\n";
  CHECK_THAT(error_of(scene("relative", "  frame: laboratory\n", false, simulate)), Contains("f.yaml:18:") && Contains("record.frame"));
  std::string no_base = scene("relative", "  frame: absolute\n", false, simulate);
  no_base.erase(no_base.find("base:"), no_base.find("stops:") - no_base.find("base:"));
  CHECK_THAT(error_of(no_base), Contains("record.frame") && Contains("no base section"));
  CHECK_THAT(error_of(scene("relative", "  frame: absolute\n", false,
                            "run:\n  kind: continue\n  continue: {path: forcing.frequency, range: [0.3, 0.4]}\n")),
             Contains("f.yaml:18:") && Contains("run.kind continue"));
  // The frame the scene computes in may always be named.
  CHECK_NOTHROW(SceneDocument::parse(scene("relative", "  frame: relative\n", false,
                                           "run:\n  kind: continue\n  continue: {path: forcing.frequency, range: [0.3, 0.4]}\n"),
                                     "f.yaml")
                    .build());
}
