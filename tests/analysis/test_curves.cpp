/// Tests of two-parameter curves of folds and period doublings (framework/analysis/src/curves.cpp)
/// against brute force: one-parameter continuations in Ω at fixed forcing amplitude A.
///
/// The case: the designed 1-DOF impact oscillator of support/designed_orbit.hpp (x'' + c x' + x =
/// A cos Ωt, upper stop s, r = 0.8), whose period-1 impacting branch has a period doubling at
/// Ω ≈ 0.9898 and a fold at Ω ≈ 1.3390 for the designed A. Each is followed in (Ω, A); at three
/// of the curve's points (p1, p2) an ordinary continuation in Ω at A = p2 exactly locates the
/// fold or the doubling again, and the curve's p1 must agree with it to 1e-8 (both are located
/// to 1e-10 in their line's parameter: the curve point on a line across the curve, the brute
/// force on the line A = p2; the margin covers the slope of the curve between the two lines).
/// The same for a Neimark–Sacker curve of the two-mass oscillator of test_neimark_sacker.cpp.
#include "support/designed_orbit.hpp"
#include "vibro/continuation.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

namespace {

using Eigen::VectorXd;
using vibro::test::DesignedOrbit;

vibro::ImpactSystem designed_system(const DesignedOrbit& d, double omega, double amplitude) {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
  f.cosine(0) = amplitude;
  return vibro::ImpactSystem(vibro::LinearSystem(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, d.c),
                                                 Eigen::MatrixXd::Identity(1, 1), f),
                             {vibro::Stop::upper(0, d.s, d.r)});
}

/// The branch in Ω at amplitude A from the designed orbit's state at Ω = 1.2 (a guess for A ≠ d.A).
vibro::ContinuationResult branch_at(const DesignedOrbit& d, double amplitude, double p_min, double p_max) {
  const vibro::ParameterFamily fam = [d, amplitude](double omega) {
    return vibro::FamilyPoint{designed_system(d, omega, amplitude), vibro::SystemDerivative::frequency_only()};
  };
  vibro::ContinuationOptions o;
  o.p_min = p_min;
  o.p_max = p_max;
  o.step = 0.02;
  o.max_doublings = 0;
  const double t0 = d.t_star + 0.5 * d.T;
  const VectorXd z0 = d.state_after_impact(0.5 * d.T);
  return vibro::continue_orbits(fam, d.omega, t0, z0.head(1), z0.tail(1), o);
}

const vibro::Bifurcation* nearest(const vibro::ContinuationResult& r, vibro::BifurcationKind kind, double near) {
  const vibro::Bifurcation* best = nullptr;
  for (const vibro::Bifurcation& b : r.bifurcations)
    if (b.kind == kind && b.branch == 0 && b.smooth && (!best || std::abs(b.p - near) < std::abs(best->p - near)))
      best = &b;
  return best;
}

vibro::PlaneFamily designed_plane(const DesignedOrbit& d) {
  return [d](double omega, double amplitude) {
    vibro::SystemDerivative da;
    da.cosine = VectorXd::Ones(1);
    return vibro::PlanePoint{designed_system(d, omega, amplitude), vibro::SystemDerivative::frequency_only(), da};
  };
}

/// Follows `kind` (near Ω = near on the designed branch) in A both ways and checks three of its
/// points against brute-force continuations in Ω.
void check_against_brute_force(vibro::BifurcationKind kind, double near) {
  const DesignedOrbit d(0.125);
  const vibro::ContinuationResult r = branch_at(d, d.A, 0.8, 1.45);
  const vibro::Bifurcation* start = nearest(r, kind, near);
  REQUIRE(start != nullptr);
  vibro::CurveOptions co;
  co.p1_min = 0.8;
  co.p1_max = 1.6;
  co.p2_min = 0.85 * d.A;
  co.p2_max = 1.15 * d.A;
  co.step = 0.05;
  co.max_points = 8;
  co.branch.max_doublings = 0;
  std::vector<vibro::CurvePoint> points;
  double seconds = 0.0, worst = 0.0;
  for (const int dir : {1, -1}) {
    co.direction = dir;
    const auto t0 = std::chrono::steady_clock::now();
    const vibro::Curve curve = vibro::follow_curve(designed_plane(d), *start, d.A, co);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    INFO(vibro::to_string(kind) << " curve " << (dir > 0 ? "up" : "down") << ": " << curve.points.size() << " points in "
                                << seconds << " s, end: " << curve.end);
    REQUIRE(curve.points.size() >= 4);
    CHECK(curve.kind == kind);
    // It moves in A.
    CHECK(dir * (curve.points.back().p2 - curve.points.front().p2) > 0.05 * d.A);
    // Every point is a located point of the kind: its test function vanishes there.
    for (const vibro::CurvePoint& q : curve.points) CHECK(std::abs(q.value) < 1e-8);
    points.push_back(curve.points[curve.points.size() / 2]);
    if (dir > 0) points.push_back(curve.points.back());
  }
  for (const vibro::CurvePoint& q : points) {
    // Brute force at A = q.p2 exactly: a branch in Ω through the designed orbit's neighbourhood.
    const double lo = std::min(d.omega, q.p1) - 0.05, hi = std::max(d.omega, q.p1) + 0.05;
    const vibro::ContinuationResult b = branch_at(d, q.p2, lo, hi);
    const vibro::Bifurcation* found = nearest(b, kind, q.p1);
    INFO(vibro::to_string(kind) << " at A = " << q.p2 << ": curve Ω = " << q.p1);
    REQUIRE(found != nullptr);
    INFO("brute force Ω = " << found->p << " (bracket " << found->p_high - found->p_low << "), difference "
                            << found->p - q.p1);
    CHECK(std::abs(found->p - q.p1) <= 1e-8);
    worst = std::max(worst, std::abs(found->p - q.p1));
  }
  WARN(vibro::to_string(kind) << " curves: " << seconds << " s; largest |Ω_brute − Ω_curve| at three amplitudes "
                              << worst);
}

}  // namespace

TEST_CASE("curves: the designed oscillator's fold curve in (Ω, A) passes through the folds located by "
          "continuations in Ω at three amplitudes, to 1e-8",
          "[continuation][curve][fold]") {
  check_against_brute_force(vibro::BifurcationKind::fold, 1.339);
}

TEST_CASE("curves: the designed oscillator's period-doubling curve in (Ω, A) passes through the doublings "
          "located by continuations in Ω at three amplitudes, to 1e-8",
          "[continuation][curve][doubling]") {
  check_against_brute_force(vibro::BifurcationKind::period_doubling, 0.9898);
}

TEST_CASE("curves: the designed oscillator's period-doubling curve, followed down in A, ends where its orbit "
          "grazes, on the closed-form grazing curve A = s √((1 − Ω²)² + c²Ω²)",
          "[continuation][curve][codim2]") {
  const DesignedOrbit d(0.125);
  const vibro::ContinuationResult r = branch_at(d, d.A, 0.8, 1.45);
  const vibro::Bifurcation* start = nearest(r, vibro::BifurcationKind::period_doubling, 0.9898);
  REQUIRE(start != nullptr);
  vibro::CurveOptions co;
  co.p1_min = 0.8;
  co.p1_max = 1.2;
  co.p2_min = 0.03;
  co.p2_max = 0.15;
  co.step = 0.05;
  co.max_points = 60;
  co.direction = -1;
  co.branch.max_doublings = 0;
  const vibro::Curve curve = vibro::follow_curve(designed_plane(d), *start, d.A, co);
  INFO(curve.points.size() << " points, end: " << curve.end);
  REQUIRE(curve.special.size() == 1);
  const vibro::CodimTwoPoint& g = curve.special.front();
  INFO(vibro::to_string(g.kind) << " at (" << g.p1 << ", " << g.p2 << "): " << g.note);
  CHECK(g.kind == vibro::CodimTwoKind::grazing);
  CHECK(g.stop == 0);
  CHECK(g.after == static_cast<int>(curve.points.size()) - 1);
  // The non-impacting orbit's amplitude at the point equals the stop's distance (the grazing
  // curve in closed form). The point is the last curve point, whose slowest impact is below
  // 1e-3 V: the orbit is within O(u²/|g''|) ≈ 1e-6 L of grazing, so A within ~1e-6 of the curve.
  const double w = g.p1;
  const double grazing_amplitude = d.s * std::sqrt((1.0 - w * w) * (1.0 - w * w) + d.c * d.c * w * w);
  INFO("closed-form grazing amplitude " << grazing_amplitude << ", difference " << g.p2 - grazing_amplitude);
  CHECK(std::abs(g.p2 - grazing_amplitude) <= 1e-5 * d.A);
  WARN("period-doubling curve ends at a grazing: (" << g.p1 << ", " << g.p2 << "), |A − A_grazing| "
                                                    << std::abs(g.p2 - grazing_amplitude));
}

TEST_CASE("curves: a kind other than grazing, rising, fold, period doubling and Neimark–Sacker is refused by name",
          "[continuation][curve]") {
  const DesignedOrbit d(0.125);
  vibro::Bifurcation b;
  b.kind = vibro::BifurcationKind::phase_change;
  vibro::CurveOptions co;
  co.p1_min = 0.8;
  co.p1_max = 1.6;
  co.p2_min = 0.5;
  co.p2_max = 1.5;
  CHECK_THROWS_WITH(vibro::follow_curve(designed_plane(d), b, 1.0, co), Catch::Contains("not phase_change"));
}

namespace {

/// The two-mass oscillator of test_neimark_sacker.cpp (unit masses, springs 1, dashpots 0.02 K,
/// mass 0 forced by A cos Ωt and stopped from above at 0.2, r = 0.8) in (Ω, A).
vibro::ImpactSystem two_masses(double omega, double amplitude) {
  Eigen::MatrixXd K(2, 2);
  K << 2.0, -1.0, -1.0, 1.0;
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(2, omega);
  f.cosine(0) = amplitude;
  return vibro::ImpactSystem(vibro::LinearSystem(Eigen::MatrixXd::Identity(2, 2), 0.02 * K, K, f),
                             {vibro::Stop::upper(0, 0.2, 0.8)});
}

vibro::ContinuationResult two_mass_branch(double amplitude, double p_min, double p_max) {
  const vibro::ParameterFamily fam = [amplitude](double omega) {
    return vibro::FamilyPoint{two_masses(omega, amplitude), vibro::SystemDerivative::frequency_only()};
  };
  // The stable orbit at Ω = 1.38 (below the first Neimark–Sacker point), from rest.
  const vibro::ImpactSystem start = two_masses(1.38, amplitude);
  vibro::Simulator sim(start);
  const double T = 2.0 * std::numbers::pi / 1.38;
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 400.0 * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  vibro::ContinuationOptions o;
  o.p_min = p_min;
  o.p_max = p_max;
  o.step = 0.02;
  o.max_doublings = 0;
  return vibro::continue_orbits(fam, 1.38, 400.0 * T, warm.x, warm.v, o);
}

}  // namespace

TEST_CASE("curves: the two-mass oscillator's Neimark–Sacker curve in (Ω, A) passes through the points "
          "located by continuations in Ω at two amplitudes, to 1e-8",
          "[continuation][curve][torus]") {
  const vibro::ContinuationResult r = two_mass_branch(1.0, 1.38, 1.45);
  const vibro::Bifurcation* start = nearest(r, vibro::BifurcationKind::neimark_sacker, 1.41768);
  REQUIRE(start != nullptr);
  const vibro::PlaneFamily plane = [](double omega, double amplitude) {
    vibro::SystemDerivative da;
    da.cosine = VectorXd::Zero(2);
    da.cosine(0) = 1.0;
    return vibro::PlanePoint{two_masses(omega, amplitude), vibro::SystemDerivative::frequency_only(), da};
  };
  vibro::CurveOptions co;
  co.p1_min = 1.3;
  co.p1_max = 1.6;
  co.p2_min = 0.9;
  co.p2_max = 1.1;
  co.step = 0.1;
  co.max_points = 5;
  co.branch.max_doublings = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const vibro::Curve curve = vibro::follow_curve(plane, *start, 1.0, co);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  INFO("torus curve: " << curve.points.size() << " points in " << seconds << " s, end: " << curve.end);
  REQUIRE(curve.points.size() >= 3);
  for (const vibro::CodimTwoPoint& c : curve.special)
    UNSCOPED_INFO(vibro::to_string(c.kind) << " at (" << c.p1 << ", " << c.p2 << "), located " << c.located);
  for (const vibro::CurvePoint& q : curve.points) CHECK(std::abs(q.value) < 1e-8);
  double worst = 0.0;
  for (const std::size_t i : {curve.points.size() / 2, curve.points.size() - 1}) {
    const vibro::CurvePoint& q = curve.points[i];
    const vibro::ContinuationResult b = two_mass_branch(q.p2, 1.38, std::max(1.45, q.p1 + 0.02));
    const vibro::Bifurcation* found = nearest(b, vibro::BifurcationKind::neimark_sacker, q.p1);
    INFO("A = " << q.p2 << ": curve Ω = " << q.p1);
    REQUIRE(found != nullptr);
    INFO("brute force Ω = " << found->p << ", difference " << found->p - q.p1);
    CHECK(std::abs(found->p - q.p1) <= 1e-8);
    worst = std::max(worst, std::abs(found->p - q.p1));
  }
  WARN("torus curve: " << curve.points.size() << " points in " << seconds << " s; largest |Ω_brute − Ω_curve| " << worst);
}
