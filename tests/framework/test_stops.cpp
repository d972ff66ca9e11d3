/// Tests of vibro::Stop and vibro::ImpactSystem (framework/src/stops.cpp).
///
/// What is checked, and against what:
///  1. validation: every rejected input throws vibro::InvalidInput whose message names the stop
///     ("stops[j] (name)"), the quantity and the rule (STYLE.md, point 7); valid edge cases pass;
///  2. the canonical form g_j = w_jᵀ x - s_j(t) of every kind (upper, lower, between, each fixed
///     and moving): normals(), gaps() and gap_rates() against the physical formulas written out
///     below by hand, s(t) = p + a cos(Ωt + φ) with the sign flipped for a lower stop;
///  3. check_admissible names the violated stop and prints the violation, which is re-read from
///     the message and compared with the hand value.
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace {

using Catch::Contains;
using vibro::HarmonicForcing;
using vibro::ImpactSystem;
using vibro::InvalidInput;
using vibro::LinearSystem;
using vibro::Stop;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A valid 3-DOF system (M = diag(1, 2, 0.5), a spring chain tied to a left wall) forced at Ω.
LinearSystem three_dof(double omega) {
  Eigen::MatrixXd M = Eigen::Vector3d(1.0, 2.0, 0.5).asDiagonal();
  Eigen::MatrixXd K(3, 3);
  K << 3.0, -1.0, 0.0,  //
      -1.0, 2.0, -1.0,  //
      0.0, -1.0, 1.0;
  Eigen::MatrixXd C = 0.05 * K;
  HarmonicForcing f = HarmonicForcing::zero(3, omega);
  f.cosine(0) = 0.4;
  return LinearSystem(std::move(M), std::move(C), std::move(K), std::move(f));
}

/// The message of the InvalidInput that building the scene throws ("<no exception>" if none;
/// any other exception type escapes and fails the test).
std::string rejection(std::vector<Stop> stops, double omega = 1.0) {
  try {
    (void)ImpactSystem(three_dof(omega), std::move(stops));
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "<no exception>";
}

/// The number printed right after `label` in `message` (NaN if absent).
double number_after(const std::string& message, const std::string& label) {
  const auto at = message.find(label);
  if (at == std::string::npos) return kNaN;
  return std::stod(message.substr(at + label.size()));
}

/// The physical position of a stop at time t, written from its definition (not from the
/// library's s0/s_cos/s_sin): p + a cos(Ωt + φ).
double physical_position(const Stop& s, double omega, double t) {
  return s.position + s.amplitude * std::cos(omega * t + s.phase);
}
double physical_velocity(const Stop& s, double omega, double t) {
  return -s.amplitude * omega * std::sin(omega * t + s.phase);
}

}  // namespace

// =============================================================================================
// 1. Validation
// =============================================================================================

TEST_CASE("stops: restitution outside [0, 1] is rejected naming the stop and the value",
          "[stops]") {
  for (double r : {-0.1, 1.5, kNaN}) {
    CAPTURE(r);
    const std::vector<Stop> stops{Stop::upper(0, 0.1, 0.5), Stop::lower(1, -0.2, r)};
    REQUIRE_THROWS_AS(ImpactSystem(three_dof(1.0), stops), InvalidInput);
    REQUIRE_THROWS_WITH(ImpactSystem(three_dof(1.0), stops),
                        Contains("stops[1]") && Contains("(lower x1)") && Contains("restitution") &&
                            Contains("[0, 1]"));
  }
  // The value itself is printed (full precision): re-read it.
  CHECK(number_after(rejection({Stop::upper(0, 0.1, 0.5), Stop::lower(1, -0.2, -0.1)}),
                     "restitution is ") == -0.1);
  CHECK(number_after(rejection({Stop::upper(0, 0.1, 0.5), Stop::lower(1, -0.2, 1.5)}),
                     "restitution is ") == 1.5);
  // The bounds themselves are valid (r = 0: plastic, r = 1: elastic).
  CHECK(rejection({Stop::upper(0, 0.1, 0.0), Stop::lower(1, -0.2, 1.0)}) == "<no exception>");
}

TEST_CASE("stops: a mass index out of range is rejected with the index and the range", "[stops]") {
  REQUIRE_THROWS_WITH(
      ImpactSystem(three_dof(1.0), {Stop::upper(0, 0.1, 0.5), Stop::upper(3, 0.1, 0.5)}),
      Contains("stops[1]") && Contains("mass index 3") && Contains("[0, 2]"));
  REQUIRE_THROWS_WITH(ImpactSystem(three_dof(1.0), {Stop::lower(-1, 0.1, 0.5)}),
                      Contains("stops[0]") && Contains("mass index -1"));
  REQUIRE_THROWS_WITH(ImpactSystem(three_dof(1.0), {Stop::between(0, 7, 0.1, 0.5)}),
                      Contains("stops[0]") && Contains("other mass index 7") && Contains("[0, 2]"));
}

TEST_CASE("stops: a stop between a mass and itself is rejected", "[stops]") {
  REQUIRE_THROWS_WITH(
      ImpactSystem(three_dof(1.0), {Stop::upper(0, 0.1, 0.5), Stop::between(2, 2, 0.1, 0.5)}),
      Contains("stops[1]") && Contains("two different masses") && Contains("2 twice"));
}

TEST_CASE("stops: duplicate stops (same coordinate, same side) are rejected naming both",
          "[stops]") {
  // Same side, different positions: one of the two is redundant, still rejected.
  REQUIRE_THROWS_WITH(
      ImpactSystem(three_dof(1.0),
                   {Stop::upper(1, 0.1, 0.5), Stop::lower(0, -0.1, 0.5), Stop::upper(1, 0.3, 0.9)}),
      Contains("stops[2]") && Contains("duplicates stops[0]") && Contains("same side"));
  // A between stop written twice with the same orientation.
  REQUIRE_THROWS_WITH(
      ImpactSystem(three_dof(1.0), {Stop::between(0, 1, 0.1, 0.5), Stop::between(0, 1, 0.2, 0.5)}),
      Contains("stops[1]") && Contains("duplicates stops[0]"));
  // Opposite sides of the same coordinate with room between them are fine.
  CHECK(rejection({Stop::between(0, 1, 0.1, 0.5), Stop::between(1, 0, 0.2, 0.5)}) ==
        "<no exception>");
}

TEST_CASE("stops: upper and lower stops leaving no room are rejected with the clearance",
          "[stops]") {
  // Upper at 0.1 below lower at 0.2 on one mass: 0.2 ≤ x0 ≤ 0.1 is empty; clearance -0.1.
  const std::string msg = rejection({Stop::upper(0, 0.1, 0.5), Stop::lower(0, 0.2, 0.5)});
  CHECK_THAT(msg, Contains("stops[0] (upper x0)") && Contains("stops[1] (lower x0)") &&
                      Contains("leave no room"));
  // Clearance printed = 0.1 - 0.2 (one rounding of the subtraction allowed: 1 ulp of 0.2).
  CHECK(std::abs(number_after(msg, "clearance ") - (0.1 - 0.2)) <= 3e-17);
  // Zero clearance (upper and lower at the same place) also leaves no room.
  CHECK_THAT(rejection({Stop::lower(2, 0.3, 0.5), Stop::upper(2, 0.3, 0.5)}),
             Contains("leave no room"));
  // Clearance 0.15 eaten by stops moving in antiphase: 0.15 − 2·0.1 < 0 at Ωt = π.
  const std::string antiphase = rejection({Stop::upper(0, 0.1, 0.5).moving(0.1, std::numbers::pi),
                                           Stop::lower(0, -0.05, 0.5).moving(0.1, 0.0)});
  CHECK_THAT(antiphase, Contains("leave no room") && Contains("stop amplitudes"));
  CHECK(std::abs(number_after(antiphase, "least clearance while they move ") - (0.15 - 0.2)) < 1e-15);
  // ... but the same amplitudes one radian apart leave room: the clearance is
  // 0.15 + 0.1 (cos Ωt − cos(Ωt + 1)) ≥ 0.15 − 0.2 sin ½ = 0.054 (the amplitudes summed would
  // refuse it), and stops moving together keep their clearance whatever they move by.
  CHECK(rejection({Stop::upper(0, 0.1, 0.5).moving(0.1, 0.0),
                   Stop::lower(0, -0.05, 0.5).moving(0.1, 1.0)}) == "<no exception>");
  CHECK(rejection({Stop::upper(0, 0.1, 0.5).moving(0.5, 0.3),
                   Stop::lower(0, -0.05, 0.5).moving(0.5, 0.3)}) == "<no exception>");
  // Two between stops x0 - x1 ≤ 0.1 and x1 - x0 ≤ -0.2 (x0 - x1 ≥ 0.2): no room either.
  CHECK_THAT(rejection({Stop::between(0, 1, 0.1, 0.5), Stop::between(1, 0, -0.2, 0.5)}),
             Contains("leave no room"));
}

TEST_CASE("stops: a moving stop needs a forcing frequency", "[stops]") {
  REQUIRE_THROWS_WITH(
      ImpactSystem(three_dof(0.0), {Stop::upper(0, 0.1, 0.5).moving(0.01, 0.0)}),
      Contains("stops[0]") && Contains("moving stop") && Contains("forcing frequency"));
  // A fixed stop without a forcing frequency is fine.
  CHECK(rejection({Stop::upper(0, 0.1, 0.5)}, 0.0) == "<no exception>");
}

TEST_CASE("stops: non-finite positions, phases and negative amplitudes are rejected", "[stops]") {
  CHECK_THAT(rejection({Stop::upper(0, kNaN, 0.5)}), Contains("stops[0]") && Contains("position"));
  CHECK_THAT(rejection({Stop::upper(0, 0.1, 0.5),
                        Stop::upper(1, std::numeric_limits<double>::infinity(), 0.5)}),
             Contains("stops[1]") && Contains("position") && Contains("finite"));
  CHECK_THAT(rejection({Stop::upper(0, 0.1, 0.5).moving(-0.01, 0.0)}),
             Contains("stops[0]") && Contains("amplitude"));
  CHECK_THAT(rejection({Stop::upper(0, 0.1, 0.5).moving(0.01, kNaN)}),
             Contains("stops[0]") && Contains("phase"));
}

TEST_CASE("stops: default names say kind and masses, user names are kept", "[stops]") {
  std::vector<Stop> stops{Stop::upper(0, 0.3, 0.5), Stop::lower(1, -0.2, 0.5),
                          Stop::between(2, 0, 0.15, 0.5), Stop::upper(2, 0.5, 0.5)};
  stops[3].name = "right wall";
  const ImpactSystem scene(three_dof(1.0), stops);
  CHECK(scene.stops()[0].name == "upper x0");
  CHECK(scene.stops()[1].name == "lower x1");
  CHECK(scene.stops()[2].name == "between x2-x0");
  CHECK(scene.stops()[3].name == "right wall");
  CHECK(scene.stop_count() == 4);
  CHECK(scene.dof() == 3);
}

// =============================================================================================
// 2. Canonical form: normals, gaps, gap rates
// =============================================================================================

TEST_CASE("stops: normals, gaps and gap rates of every kind, fixed and moving, by hand",
          "[stops]") {
  const double omega = 1.7;
  const std::vector<Stop> stops{
      Stop::upper(0, 0.3, 0.5),                          // x0 ≤ 0.3
      Stop::lower(1, -0.2, 0.5),                         // x1 ≥ -0.2
      Stop::between(2, 0, 0.15, 0.5),                    // x2 - x0 ≤ 0.15
      Stop::upper(2, 0.5, 0.5).moving(0.1, 0.4),         // x2 ≤ 0.5 + 0.1 cos(Ωt + 0.4)
      Stop::lower(0, -0.6, 0.5).moving(0.05, -1.1),      // x0 ≥ -0.6 + 0.05 cos(Ωt - 1.1)
      Stop::between(1, 2, 0.25, 0.5).moving(0.02, 2.0),  // x1 - x2 ≤ 0.25 + 0.02 cos(Ωt + 2)
  };
  const ImpactSystem scene(three_dof(omega), stops);

  // Normals w_j: columns of ±e_i, e_i - e_k.
  Eigen::MatrixXd W_expected(3, 6);
  W_expected << 1, 0, -1, 0, -1, 0,  //
      0, -1, 0, 0, 0, 1,             //
      0, 0, 1, 1, 0, -1;
  CHECK(scene.normals() == W_expected);  // exact: entries are 0 and ±1

  // Tolerance: each gap is a sum of ≤ 4 terms of size ≤ 1 evaluated with a few roundings
  // (the library splits cos(Ωt + φ) into cos φ cos Ωt - sin φ sin Ωt), so the difference to the
  // direct formula is ≲ 10 ε ≈ 2e-15; 1e-14 leaves margin while a wrong sign or a dropped
  // amplitude/frequency factor is ≥ 1e-3.
  constexpr double kTolerance = 1e-14;
  double worst = 0.0;
  const Eigen::Vector3d xs[] = {{0.1, -0.05, 0.2}, {-0.7, 0.4, 0.9}, {0.3, -0.2, 0.45}};
  const Eigen::Vector3d vs[] = {{0.5, -1.0, 0.25}, {-2.0, 0.3, 1.1}, {0.0, 0.0, 0.0}};
  for (int sample = 0; sample < 3; ++sample) {
    for (double t : {0.0, 0.37, 1.9, 12.25, -3.0}) {
      const Eigen::Vector3d& x = xs[sample];
      const Eigen::Vector3d& v = vs[sample];
      const Eigen::VectorXd g = scene.gaps(t, x);
      const Eigen::VectorXd gd = scene.gap_rates(t, v);
      REQUIRE(g.size() == 6);
      REQUIRE(gd.size() == 6);
      const auto pos = [&](int j) {
        return physical_position(stops[static_cast<std::size_t>(j)], omega, t);
      };
      const auto vel = [&](int j) {
        return physical_velocity(stops[static_cast<std::size_t>(j)], omega, t);
      };
      // Upper: x_i - s(t). Lower: s(t) - x_i. Between: x_i - x_k - gap(t).
      const double g_hand[6] = {x(0) - pos(0), pos(1) - x(1), x(2) - x(0) - pos(2),
                                x(2) - pos(3), pos(4) - x(0), x(1) - x(2) - pos(5)};
      const double gd_hand[6] = {v(0) - vel(0), vel(1) - v(1), v(2) - v(0) - vel(2),
                                 v(2) - vel(3), vel(4) - v(0), v(1) - v(2) - vel(5)};
      for (int j = 0; j < 6; ++j) {
        CAPTURE(sample, t, j);
        CHECK(std::abs(g(j) - g_hand[j]) <= kTolerance);
        CHECK(std::abs(gd(j) - gd_hand[j]) <= kTolerance);
        worst = std::max({worst, std::abs(g(j) - g_hand[j]), std::abs(gd(j) - gd_hand[j])});
      }
    }
  }
  // The moving stops do move: at t = 0.37 the gap of stop 3 differs from its fixed value.
  CHECK(std::abs(scene.gaps(0.37, xs[0])(3) - (xs[0](2) - 0.5)) > 1e-2);
  // Measured worst difference: 2.2e-16.
  CHECK(worst <= kTolerance);
}

TEST_CASE("stops: s(t) coefficients of a moving lower stop carry the flipped sign", "[stops]") {
  // s(t) = -(p + a cos(Ωt + φ)) = -p - a cos φ cos Ωt + a sin φ sin Ωt.
  const Stop s = Stop::lower(0, -0.6, 0.5).moving(0.05, -1.1);
  CHECK(s.s0() == 0.6);
  CHECK(std::abs(s.s_cos() - (-0.05 * std::cos(-1.1))) <= 1e-17);
  CHECK(std::abs(s.s_sin() - (0.05 * std::sin(-1.1))) <= 1e-17);
  const Stop u = Stop::upper(0, 0.6, 0.5).moving(0.05, -1.1);
  CHECK(u.s0() == 0.6);
  CHECK(std::abs(u.s_cos() - 0.05 * std::cos(-1.1)) <= 1e-17);
  CHECK(std::abs(u.s_sin() - (-0.05 * std::sin(-1.1))) <= 1e-17);
}

TEST_CASE("stops: length_scale is the largest offset, amplitude or extra", "[stops]") {
  const ImpactSystem scene(three_dof(1.0), {Stop::upper(0, 0.3, 0.5), Stop::lower(1, -0.45, 0.5),
                                            Stop::upper(2, 0.1, 0.5).moving(0.2, 0.0)});
  CHECK(scene.length_scale() == 0.45);
  CHECK(scene.length_scale(-2.0) == 2.0);
  const ImpactSystem at_zero(three_dof(1.0), {Stop::upper(0, 0.0, 0.5)});
  CHECK(at_zero.length_scale() == 1e-300);
}

// =============================================================================================
// 3. check_admissible
// =============================================================================================

TEST_CASE("stops: check_admissible names the violated stop and the violation", "[stops]") {
  const double omega = 2.0;
  std::vector<Stop> stops{Stop::upper(0, 0.3, 0.5), Stop::lower(1, -0.2, 0.5),
                          Stop::between(2, 0, 0.3, 0.5), Stop::upper(2, 0.5, 0.5).moving(0.1, 0.0)};
  stops[1].name = "left wall";
  const ImpactSystem scene(three_dof(omega), stops);
  const double tol = 1e-12;
  const auto message = [&](double t, const Eigen::Vector3d& x) {
    try {
      scene.check_admissible(t, x, tol);
    } catch (const InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("<no exception>");
  };

  // Inside every stop, and on a stop within the tolerance: accepted.
  CHECK(message(0.0, Eigen::Vector3d(0.0, 0.0, 0.1)) == "<no exception>");
  CHECK(message(0.0, Eigen::Vector3d(0.3 + 5e-13, 0.0, 0.1)) == "<no exception>");

  // The violation is printed with 17 digits and re-read; it is one subtraction of numbers
  // ≤ 0.6 in double (a few roundings for the moving stop), so it matches the hand value to
  // 1e-16 (resp. 1e-15); a wrong stop, sign or position would be off by ≥ 0.05.
  // Upper stop 0 violated by 0.35 - 0.3.
  std::string msg = message(0.0, Eigen::Vector3d(0.35, 0.0, 0.4));
  CHECK_THAT(msg, Contains("violates stops[0] (upper x0)"));
  CHECK(std::abs(number_after(msg, " by ") - 0.05) <= 1e-16);
  // Lower stop 1 ("left wall"): x1 = -0.25 below -0.2 by 0.05.
  msg = message(0.0, Eigen::Vector3d(0.0, -0.25, 0.1));
  CHECK_THAT(msg, Contains("violates stops[1] (left wall)"));
  CHECK(std::abs(number_after(msg, " by ") - 0.05) <= 1e-16);
  // Between stop 2: x2 - x0 = 0.45 - 0.1 = 0.35 > 0.3 by 0.05.
  msg = message(0.0, Eigen::Vector3d(0.1, 0.0, 0.45));
  CHECK_THAT(msg, Contains("violates stops[2] (between x2-x0)"));
  CHECK(std::abs(number_after(msg, " by ") - 0.05) <= 1e-16);
  // Moving stop 3: x2 = 0.55 is admissible at t = 0 (s = 0.6) but violates it by 0.15 at
  // t = π/Ω (s = 0.5 + 0.1 cos π = 0.4). x0 = 0.28 keeps stops 0 and 2 satisfied.
  CHECK(message(0.0, Eigen::Vector3d(0.28, 0.0, 0.55)) == "<no exception>");
  msg = message(std::numbers::pi / omega, Eigen::Vector3d(0.28, 0.0, 0.55));
  CHECK_THAT(msg, Contains("violates stops[3] (upper x2)"));
  CHECK(std::abs(number_after(msg, " by ") - 0.15) <= 1e-15);
  CHECK(std::abs(number_after(msg, "at t = ") - std::numbers::pi / omega) <= 1e-15);
}

TEST_CASE("stops: validated_stops checks as ImpactSystem does, without the n × m normals",
          "[stops]") {
  // Two conflicts: stops[1] and [2] are opposite stops on x1 - x2 with no room between them, and
  // stops[3] duplicates stops[0]. All pairs (j, k), j < k, checked in order meet (0, 3) first.
  const std::vector<Stop> stops{Stop::upper(0, 0.1, 0.5), Stop::between(1, 2, 0.2, 0.5),
                                Stop::between(2, 1, -0.3, 0.5), Stop::upper(0, 0.5, 0.5)};
  for (const std::size_t n : {3, 100000}) {  // the key-based check costs nothing per mass
    INFO("n = " << n);
    const auto e = static_cast<Eigen::Index>(n);
    CHECK_THROWS_WITH(vibro::validated_stops(stops, e, 1.0),
                      Contains("stops[3] (upper x0): duplicates stops[0] (upper x0)"));
    std::vector<Stop> rest(stops.begin(), stops.begin() + 3);
    CHECK_THROWS_WITH(vibro::validated_stops(rest, e, 1.0),
                      Contains("stops[1] (between x1-x2) and stops[2] (between x2-x1) leave no room"));
    rest[2].position = -0.1;  // clearance 0.2 - 0.1 > 0
    const std::vector<Stop> ok = vibro::validated_stops(rest, e, 1.0);
    CHECK(ok[2].name == "between x2-x1");
  }
  // The same messages as the dense ImpactSystem, which uses it.
  CHECK_THROWS_WITH(ImpactSystem(three_dof(1.0), stops),
                    Contains("stops[3] (upper x0): duplicates stops[0] (upper x0)"));
  // And the O(1)-per-stop gap agrees with the dense gaps() for every kind, moving ones included
  // (the same sums in another order: values ≤ 0.5, so 1e-15 is a few ulps).
  std::vector<Stop> kinds{Stop::upper(0, 0.4, 0.5).moving(0.1, 0.3), Stop::lower(1, -0.2, 0.5),
                          Stop::between(2, 0, 0.3, 0.5).moving(0.05, -1.0)};
  const ImpactSystem dense(three_dof(1.3), kinds);
  const Eigen::Vector3d x(0.1, -0.05, 0.2);
  const Eigen::VectorXd g = dense.gaps(0.7, x);
  for (std::size_t j = 0; j < kinds.size(); ++j)
    CHECK(vibro::stop_gap(dense.stops()[j], 1.3, 0.7, x) == Approx(g(static_cast<Eigen::Index>(j))).margin(1e-15));
}
