/// Tests of continuation and bifurcation location (framework/analysis, continuation.hpp).
///
/// The engineered case: the designed 1-DOF impact oscillator of support/designed_orbit.hpp with
/// its stop s and amplitude A fixed, continued in Ω. Its period-1 impacting orbits solve two
/// closed-form equations G(u, t*, Ω) = 0, so the fold (∂G/∂(u, t*) singular) and the period
/// doubling (a multiplier −1 of the closed-form monodromy matrix) are located independently by
/// Newton on those equations; its non-impacting orbit is the linear response of amplitude
/// A/√((1 − Ω²)² + c²Ω²), which grazes the stop where that equals s — a quadratic in Ω².
/// Along Ω ∈ [0.8, 1.45] the branch is: non-impacting, grazing (0.8863), impacting and stable,
/// period doubling (0.9898), a fold (1.3390), unstable impacting back down to a grazing corner
/// (1.0975) where the non-impacting branch takes over. The doubled branch grazes and turns at
/// 0.99021, then doubles again.
#include "support/analysis_helpers.hpp"
#include "support/designed_orbit.hpp"
#include "support/symmetric_orbit.hpp"
#include "vibro/continuation.hpp"
#include "vibro/models/chain.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <numbers>
#include <utility>

namespace {

using Eigen::VectorXd;
using vibro::test::DesignedOrbit;

/// The designed 1-DOF system (s, A from the orbit at Ω = 1.2) as a family in Ω.
vibro::ParameterFamily designed_family(const DesignedOrbit& d) {
  return [d](double omega) {
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
    f.cosine(0) = d.A;
    vibro::ImpactSystem sys(vibro::LinearSystem(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, d.c),
                                                Eigen::MatrixXd::Identity(1, 1), f),
                            {vibro::Stop::upper(0, d.s, d.r)});
    return vibro::FamilyPoint{std::move(sys), vibro::SystemDerivative::frequency_only()};
  };
}

}  // namespace


namespace {

/// Newton on the closed-form equations [G(u, t*, Ω); condition(u, t*, Ω)] = 0 for (u, t*, Ω),
/// with a central-difference Jacobian (it only steers the iteration: the root is where the
/// residual, evaluated in closed form, vanishes).
Eigen::Vector3d solve_closed_form(const DesignedOrbit& d, Eigen::Vector3d y,
                                  const std::function<double(const DesignedOrbit&, double, double, double)>& condition) {
  auto F = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector2d g = d.G(q(0), q(1), q(2));
    return Eigen::Vector3d(g(0), g(1), condition(d, q(0), q(1), q(2)));
  };
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix3d J;
    for (int i = 0; i < 3; ++i) {
      Eigen::Vector3d h = Eigen::Vector3d::Zero();
      h(i) = 1e-7;
      J.col(i) = (F(y + h) - F(y - h)) / 2e-7;
    }
    const Eigen::Vector3d step = J.fullPivLu().solve(F(y));
    y -= step;
    if (step.cwiseAbs().maxCoeff() < 1e-15) break;
  }
  REQUIRE(F(y).cwiseAbs().maxCoeff() < 1e-13);
  return y;
}

const vibro::Bifurcation* find(const vibro::ContinuationResult& r, vibro::BifurcationKind kind, double near,
                               int branch = 0) {
  const vibro::Bifurcation* best = nullptr;
  for (const vibro::Bifurcation& b : r.bifurcations)
    if (b.kind == kind && b.branch == branch && (!best || std::abs(b.p - near) < std::abs(best->p - near))) best = &b;
  return best;
}

vibro::ContinuationResult designed_branch() {
  const DesignedOrbit d(0.125);
  vibro::ContinuationOptions o;
  o.p_min = 0.8;
  o.p_max = 1.45;
  o.step = 0.02;
  const double t0 = d.t_star + 0.5 * d.T;
  const VectorXd z0 = d.state_after_impact(0.5 * d.T);
  return vibro::continue_orbits(designed_family(d), d.omega, t0, z0.head(1), z0.tail(1), o);
}

}  // namespace

TEST_CASE("continuation: the designed oscillator's fold, period doubling and two grazings are "
          "located to 1e-10 of their closed-form values",
          "[continuation][closed-form]") {
  const DesignedOrbit d(0.125);
  const vibro::ContinuationResult r = designed_branch();
  REQUIRE_FALSE(r.branches.empty());
  const vibro::Branch& main = r.branches[0];
  INFO("branch: " << main.end);
  // The whole range is covered, both ends at the limits, through the fold and the corner.
  CHECK(main.end.find("reached p_min") != std::string::npos);
  CHECK(main.end.find("reached p_max") != std::string::npos);

  // Fold: ∂G/∂(u, t*) singular.
  const Eigen::Vector3d fold = solve_closed_form(d, {0.62, 1.27, 1.339},
      [](const DesignedOrbit& o, double u, double ts, double w) { return o.dG(u, ts, w).determinant(); });
  // Period doubling: tr M + 1 + det M = 0.
  const Eigen::Vector3d pd = solve_closed_form(d, {0.19, 0.42, 0.99}, [](const DesignedOrbit& o, double u, double ts, double w) {
    const Eigen::Matrix2d M = o.monodromy(u, ts, w);
    return M.trace() + 1.0 + M.determinant();
  });
  // Grazing of the linear response: A² = s² ((1 − Ω²)² + c²Ω²), a quadratic in Ω².
  const double b = 2.0 - d.c * d.c, disc = std::sqrt(b * b - 4.0 * (1.0 - d.A * d.A / (d.s * d.s)));
  const double graze_high = std::sqrt(0.5 * (b + disc)), graze_low = std::sqrt(0.5 * (b - disc));

  struct Expect {
    vibro::BifurcationKind kind;
    double p;
  };
  for (const Expect& e : {Expect{vibro::BifurcationKind::fold, fold(2)}, Expect{vibro::BifurcationKind::period_doubling, pd(2)},
                          Expect{vibro::BifurcationKind::grazing, graze_high}, Expect{vibro::BifurcationKind::grazing, graze_low}}) {
    const vibro::Bifurcation* found = find(r, e.kind, e.p);
    INFO(vibro::to_string(e.kind) << " expected at " << e.p);
    REQUIRE(found != nullptr);
    INFO("located at " << found->p << " (bracket " << found->p_low << " … " << found->p_high << ", value " << found->value << ")");
    CHECK(found->smooth);
    CHECK(std::abs(found->p - e.p) <= 1e-10);
    CHECK(found->p_high - found->p_low <= 1e-10);
    if (e.kind == vibro::BifurcationKind::grazing) CHECK(found->stop == 0);
  }
  // Nothing else on the period-1 branch.
  int on_main = 0;
  for (const vibro::Bifurcation& b : r.bifurcations) on_main += b.branch == 0;
  CHECK(on_main == 4);
  // The test functions vanish at the located points (in their own scales: t_p, the product
  // Π(1 + μ), the gap in units of s).
  CHECK(std::abs(find(r, vibro::BifurcationKind::fold, fold(2))->value) < 1e-8);
  CHECK(std::abs(find(r, vibro::BifurcationKind::period_doubling, pd(2))->value) < 1e-8);
  CHECK(std::abs(find(r, vibro::BifurcationKind::grazing, graze_low)->value) < 1e-9 * d.s);
  // Stability along the branch (the order is from p_min up, over the fold and back down):
  // non-impacting orbits are stable; the impacting ones coming up from the low grazing are
  // unstable (a multiplier below −1, growing like 1/u towards the grazing) until the period
  // doubling, stable from there to the fold, unstable (a multiplier above 1) beyond it.
  for (const vibro::BranchPoint& p : main.points) {
    if (p.located) continue;
    INFO("p = " << p.p << ", dp/ds " << p.tangent_p << ", largest multiplier " << p.multipliers.spectral_radius);
    const bool impacting = p.signature.impacts[0] > 0, rising = p.tangent_p > 0.0;
    if (!impacting) CHECK(p.multipliers.stable);
    else if (rising && p.p < pd(2) - 1e-6) CHECK_FALSE(p.multipliers.stable);
    else if (rising && p.p > pd(2) + 1e-6 && p.p < fold(2) - 1e-6) CHECK(p.multipliers.stable);
    else if (!rising && p.p < fold(2) - 1e-6) CHECK_FALSE(p.multipliers.stable);
  }
}

TEST_CASE("continuation: branch switching at the period doubling gives a period-2 branch whose "
          "orbits have minimal period 2, it grazes, turns and doubles again",
          "[continuation][doubling]") {
  const DesignedOrbit d(0.125);
  const vibro::ContinuationResult r = designed_branch();
  REQUIRE(r.branches.size() >= 2);
  const vibro::Branch& doubled = r.branches[1];
  CHECK(doubled.k == 2);
  CHECK(doubled.parent == 0);
  REQUIRE(doubled.points.size() >= 4);
  // Its points away from the PD point are genuine period-2 orbits: shooting with k = 2 from one
  // converges there with minimal period 2.
  const vibro::BranchPoint& q = doubled.points[3];
  vibro::ShootingOptions so;
  so.period = 2;
  so.phase = q.phase;
  so.free_section = false;
  const vibro::ShootingResult s = vibro::shoot(designed_family(d)(q.p).system, so, q.t0, q.x, q.v);
  REQUIRE(s.converged());
  CHECK(s.minimal_k == 2);
  CHECK((vibro::test::stack(s.x, s.v) - vibro::test::stack(q.x, q.v)).cwiseAbs().maxCoeff() < 1e-9);
  // The doubled branch's grazing corner and its own period doubling.
  CHECK(find(r, vibro::BifurcationKind::grazing, 0.9902, 1) != nullptr);
  CHECK(find(r, vibro::BifurcationKind::period_doubling, 0.9762, 1) != nullptr);
  bool period_four = false;
  for (const vibro::Branch& b : r.branches) period_four |= b.k == 4;
  CHECK(period_four);
}

namespace {

vibro::FamilyPoint paper_at(double omega) {
  vibro::models::Wagg2004 p;
  p.frequency = omega;
  return vibro::FamilyPoint{vibro::models::wagg2004(p), vibro::SystemDerivative::frequency_only()};
}

}  // namespace

TEST_CASE("continuation: the paper's system near Ω = 0.2637: mass 1 loses an impact per period at "
          "a grazing corner and the impacting branch folds just above it, in between two stable "
          "orbits coexist, each attracting a run started on it",
          "[continuation][wagg2004]") {
  vibro::models::Wagg2004 p;
  p.frequency = 0.2634;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  vibro::Simulator sim(sys);
  const double T = 2.0 * std::numbers::pi / p.frequency;
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 200.0 * T);
  vibro::ContinuationOptions o;
  o.p_min = 0.2634;
  o.p_max = 0.2640;
  o.step = 0.02;
  const vibro::ContinuationResult r = vibro::continue_orbits(paper_at, p.frequency, 200.0 * T, warm.x, warm.v, o);
  const vibro::Bifurcation* fold = find(r, vibro::BifurcationKind::fold, 0.26378);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.26373);
  REQUIRE(fold != nullptr);
  REQUIRE(graze != nullptr);
  CHECK(graze->stop == 0);
  CHECK(graze->smooth);
  CHECK(graze->p < fold->p);
  CHECK(std::abs(graze->value) < 1e-12);  // the gap maximum there, length units (L = 0.3)
  // Between the corner and the fold: the impacting orbit (one impact of mass 1 per period) is
  // stable below the fold, and the orbit without that impact stable above the corner.
  const double mid = 0.5 * (graze->p + fold->p);
  const vibro::BranchPoint* with = nullptr;
  const vibro::BranchPoint* without = nullptr;
  for (const vibro::BranchPoint& q : r.branches[0].points) {
    if (q.located || !q.multipliers.stable) continue;
    const vibro::BranchPoint*& slot = q.signature.impacts[0] == 1 ? with : without;
    if (!slot || std::abs(q.p - mid) < std::abs(slot->p - mid)) slot = &q;
  }
  REQUIRE(with != nullptr);
  REQUIRE(without != nullptr);
  // Both orbits at Ω = mid, by shooting from those branch points; each is stable and a run from
  // it stays on it for 100 periods (two attractors at one Ω).
  const vibro::ImpactSystem at_mid = paper_at(mid).system;
  std::vector<VectorXd> found;
  for (const vibro::BranchPoint* q : {with, without}) {
    vibro::ShootingOptions so;
    so.phase = q->phase;
    so.free_section = false;
    const vibro::ShootingResult orbit = vibro::shoot(at_mid, so, q->t0, q->x, q->v);
    REQUIRE(orbit.converged());
    CHECK(orbit.multipliers.stable);
    vibro::Simulator run(at_mid);
    VectorXd z = vibro::test::stack(orbit.x, orbit.v);
    z(2) += 1e-7;  // a small push: it must come back
    const double Tm = 2.0 * std::numbers::pi / mid;
    const vibro::RunSummary s = run.run(orbit.t0, z.head(2), z.tail(2), orbit.t0 + 100.0 * Tm);
    CHECK((vibro::test::stack(s.x, s.v) - vibro::test::stack(orbit.x, orbit.v)).cwiseAbs().maxCoeff() < 1e-9);
    // Compared at phase 0 (the sections may differ).
    found.push_back(vibro::test::engine_map(at_mid, {}, orbit.t0, vibro::test::stack(orbit.x, orbit.v), Tm * std::ceil(orbit.t0 / Tm + 1.0)));
  }
  CHECK((found[0] - found[1]).cwiseAbs().maxCoeff() > 1e-3);  // two different orbits
}

TEST_CASE("continuation: a grazing point followed in a second parameter stays on the closed-form "
          "grazing curve A(Ω) = s √((1 − Ω²)² + c²Ω²)",
          "[continuation][curve]") {
  const DesignedOrbit d(0.125);
  // Locate the low grazing (0.8863) in Ω first, on a short stretch of the branch below it.
  vibro::ContinuationOptions o;
  o.p_min = 0.85;
  o.p_max = 0.95;
  o.step = 0.05;
  o.max_doublings = 0;
  const vibro::ParameterFamily fam = designed_family(d);
  // Start on the non-impacting orbit at Ω = 0.86 (the linear response): a short run from rest.
  const vibro::FamilyPoint start = fam(0.86);
  vibro::Simulator sim(start.system);
  const double T = 2.0 * std::numbers::pi / 0.86;
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(1), VectorXd::Zero(1), 100.0 * T);
  const vibro::ContinuationResult r = vibro::continue_orbits(fam, 0.86, 100.0 * T, warm.x, warm.v, o);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.8863);
  REQUIRE(graze != nullptr);
  REQUIRE(graze->smooth);
  // The plane (Ω, A).
  const vibro::PlaneFamily plane = [d](double omega, double amplitude) {
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
    f.cosine(0) = amplitude;
    vibro::ImpactSystem sys(vibro::LinearSystem(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, d.c),
                                                Eigen::MatrixXd::Identity(1, 1), f),
                            {vibro::Stop::upper(0, d.s, d.r)});
    vibro::SystemDerivative da;
    da.cosine = VectorXd::Ones(1);
    return vibro::PlanePoint{std::move(sys), vibro::SystemDerivative::frequency_only(), da};
  };
  vibro::CurveOptions co;
  co.p1_min = 0.7;
  co.p1_max = 1.0;
  co.p2_min = 0.8 * d.A;
  co.p2_max = 1.2 * d.A;
  co.step = 0.05;
  co.max_points = 8;
  co.branch = o;
  const vibro::Curve curve = vibro::follow_curve(plane, *graze, d.A, co);
  INFO(curve.end);
  REQUIRE(curve.points.size() >= 5);
  double worst = 0.0;
  for (const vibro::CurvePoint& q : curve.points) {
    const double w = q.p1;
    const double exact = d.s * std::sqrt((1.0 - w * w) * (1.0 - w * w) + d.c * d.c * w * w);
    worst = std::max(worst, std::abs(q.p2 - exact));
  }
  // Each curve point is located (to 1e-10 in the line's parameter) on a line across the curve.
  INFO("curve points " << curve.points.size() << ", worst distance from the closed form " << worst);
  CHECK(worst <= 1e-9);
  // It moved along the curve, not on the spot.
  CHECK(std::abs(curve.points.back().p2 - curve.points.front().p2) > 0.05 * d.A);
}

TEST_CASE("continuation: a flight that starts at a release has no gap peak at its start (the rounding "
          "of the released gap rate once posed as a grazing of the paper's branch)",
          "[continuation][wagg2004]") {
  // At Ω = 0.2592 mass 1's nearest approach in free flight is 4.9e-4 below its stop (the bounce
  // after its release); the release itself starts a flight on the stop with the gap rate zero up
  // to rounding, which once gave a "peak" 4e-8 into that flight with value ~1e-16: the largest gap
  // peak, the grazing test function, was then ~0 whatever the bounces did, and six grazings of the
  // fold cascade were located where their orbits stay 1e-7 from the stop.
  vibro::models::Wagg2004 p;
  p.frequency = 0.2592;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  const double T = 2.0 * std::numbers::pi / p.frequency;
  vibro::Simulator sim(sys);
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 400.0 * T);
  vibro::LinearisationOptions lo;
  lo.jacobian = false;
  lo.features = true;
  const vibro::TangentMap m = vibro::linearise(sys, {}, 400.0 * T, warm.x, warm.v, 401.0 * T, lo);
  double largest = -std::numeric_limits<double>::infinity();
  for (const vibro::GapPeak& g : m.gap_peaks)
    if (g.stop == 0) largest = std::max(largest, g.value);
  INFO("largest gap peak of s1: " << largest);
  CHECK(largest < -4e-4);
  CHECK(largest > -6e-4);
}

namespace {

/// The three-mass chain of experiments/examples/three_mass_continuation.yaml at Ω.
vibro::FamilyPoint three_mass_at(double omega) {
  vibro::models::Chain c;
  c.masses = {1.0, 1.0, 1.0};
  c.springs = {1.0, 1.0};
  c.dampers = {0.1, 0.1};
  c.left_spring = 1.0;
  c.left_damper = 0.1;
  c.force_cosine = {0.5, 0.0, 0.0};
  c.frequency = omega;
  vibro::ImpactSystem sys(vibro::models::build_chain(c), {vibro::Stop::lower(0, -0.3, 0.7), vibro::Stop::upper(2, 0.1, 0.7)});
  return vibro::FamilyPoint{std::move(sys), vibro::SystemDerivative::frequency_only()};
}

}  // namespace

TEST_CASE("continuation: past a grazing corner whose two parts lie on the same side in Ω, the branch "
          "leaves the corner (the three-mass chain at Ω ≈ 0.180626, where it once walked back into it "
          "and stopped)",
          "[continuation][three-mass]") {
  // The orbit with three free impacts of s3 per period, stable at Ω = 0.180566 (a point of the
  // scene's branch, kept to 17 digits: shooting from it converges at once). Up from it the branch
  // folds at 0.1807322 and comes back down, unstable, to the grazing of s3 at 0.1806264, where
  // the orbit with two impacts takes over and rises in Ω, stable. The step that crosses the corner
  // lands on that orbit between the last three-impact point and the grazing in Ω: oriented along
  // the step in Ω, its tangent pointed back into the grazing, where no orbit lies beyond.
  const double p0 = 0.18056607808771738;
  VectorXd x(3), v(3);
  x << 0.31211263810559026, 0.15632541169677808, 0.09021442517545247;
  v << 0.10377505196359062, 0.0595516096713064, 0.061648112483887615;
  vibro::ContinuationOptions o;
  o.p_min = 0.1805;
  o.p_max = 0.1810;
  o.step = 0.01;
  o.max_step = 0.02;
  o.parameter_scale = 0.025;  // the scene's range, so that the steps are the scene's
  const auto start = std::chrono::steady_clock::now();
  const vibro::ContinuationResult r = vibro::continue_orbits(three_mass_at, p0, 0.0, x, v, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  REQUIRE_FALSE(r.branches.empty());
  const vibro::Branch& b = r.branches[0];
  INFO("branch: " << b.end << " (" << seconds << " s)");
  CHECK(b.end.find("reached p_min") != std::string::npos);
  CHECK(b.end.find("reached p_max") != std::string::npos);
  const vibro::Bifurcation* fold = find(r, vibro::BifurcationKind::fold, 0.1807322);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.1806264);
  REQUIRE(fold != nullptr);
  REQUIRE(graze != nullptr);
  CHECK(std::abs(fold->p - 0.180732192) < 1e-8);
  CHECK(graze->stop == 1);
  CHECK(graze->smooth);
  CHECK(std::abs(graze->p - 0.180626398) < 1e-8);
  // Beyond the corner: two impacts of s3, stable, Ω rising to the limit.
  const vibro::BranchPoint& last = b.points.back();
  CHECK(last.p == Approx(o.p_max).margin(1e-12));
  CHECK(last.signature.impacts[1] == 2);
  CHECK(last.multipliers.stable);
  CHECK(last.tangent_p > 0.0);
}

namespace {

/// The newcomer's three-mass chain (experiments/examples/three_mass_chain.yaml): unit masses and
/// springs from a wall, dampers 0.05, 0.2 cos Ωt on mass 0, a clearance of 0.05 between masses 1
/// and 2 (r = 0.6) and a wall at 0.4 above mass 2 (r = 0.8).
vibro::FamilyPoint clearance_chain_at(double omega) {
  vibro::models::Chain c;
  c.masses = {1.0, 1.0, 1.0};
  c.springs = {1.0, 1.0};
  c.dampers = {0.05, 0.05};
  c.left_spring = 1.0;
  c.left_damper = 0.05;
  c.force_cosine = {0.2, 0.0, 0.0};
  c.frequency = omega;
  vibro::ImpactSystem sys(vibro::models::build_chain(c),
                          {vibro::Stop::between(1, 2, 0.05, 0.6), vibro::Stop::upper(2, 0.4, 0.8)});
  return vibro::FamilyPoint{std::move(sys), vibro::SystemDerivative::frequency_only()};
}

}  // namespace

TEST_CASE("continuation: through a grazing that adds an impact, onto the unstable orbits beyond it, "
          "round their fold and on to chatter and sticking (the three-mass clearance chain down from "
          "Ω = 0.7)",
          "[continuation][three-mass][grazing]") {
  // The orbit at Ω = 0.7 strikes the clearance twice per period, nothing held. Down in Ω it grazes
  // the clearance at 0.6874399307 (a third impact is born); the orbits with three impacts leave the
  // grazing upwards in Ω, unstable (a multiplier from −∞), to a fold at 0.6895773127 and come back
  // down stable. Newton from the side without the impact cannot see it: the steps used to shrink
  // against the grazing until "step below min_step". The fold's value is the one the same scene's
  // branch reaches from below (from Ω = 0.5, up), where no grazing is crossed before it.
  const double p0 = 0.7;
  VectorXd x(3), v(3);
  x << 0.01758951153595281, -0.1517587032492654, -0.1854217681805984;
  v << -0.059502736248966244, 0.006082666124027866, 0.05106996248742386;
  vibro::ContinuationOptions o;
  o.p_min = 0.61;
  o.p_max = 0.7;
  o.direction = -1;
  o.step = 0.01;
  o.max_step = 0.02;
  o.max_doublings = 0;
  const auto start = std::chrono::steady_clock::now();
  const vibro::ContinuationResult r = vibro::continue_orbits(clearance_chain_at, p0, 0.0, x, v, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  REQUIRE_FALSE(r.branches.empty());
  const vibro::Branch& b = r.branches[0];
  INFO("branch: " << b.end << " (" << seconds << " s)");
  CHECK(b.end.find("step below min_step") == std::string::npos);
  CHECK(b.end.find("reached p_min") != std::string::npos);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.68744);
  const vibro::Bifurcation* fold = find(r, vibro::BifurcationKind::fold, 0.68958);
  REQUIRE(graze != nullptr);
  REQUIRE(fold != nullptr);
  CHECK(graze->stop == 0);
  CHECK(graze->smooth);
  CHECK(std::abs(graze->p - 0.6874399307) < 1e-9);
  CHECK(std::abs(fold->p - 0.6895773127) < 1e-9);
  // Between them the orbits with three impacts, unstable; after the fold the same, stable.
  bool unstable_three = false, stable_three = false, held = false;
  for (const vibro::BranchPoint& q : b.points) {
    if (q.signature.impacts[0] == 3 && q.p > 0.68745 && q.p < 0.68957) {
      unstable_three |= !q.multipliers.stable;
      stable_three |= q.multipliers.stable && q.tangent_p < 0.0;
    }
    held |= q.signature.phases[0] > 0;
  }
  CHECK(unstable_three);
  CHECK(stable_three);
  // Further down, chatter of the clearance ends in sticking: the branch follows the sticking orbits.
  CHECK(held);
  CHECK(b.points.back().p == Approx(o.p_min).margin(1e-12));
}

TEST_CASE("continuation: a fold of the orbits with the impact just beside the grazing that ends them "
          "is not stepped over (the three-mass clearance chain at Ω ≈ 0.34057)",
          "[continuation][three-mass][grazing]") {
  // Down in Ω, the unstable orbits with three impacts on the clearance turn at a fold at
  // 0.3405746067 and go back up to the grazing at 0.3406846563 that ends them (a corner: the
  // orbits with two impacts leave it downwards). The first step from this point (one of the
  // scene's branch points, kept to 17 digits), of 0.02 at the scene's parameter scale, lands on
  // the two-impact orbits below both: the step across the grazing saw no turn in Ω (both ends
  // travel down), and the fold was lost. The tangent of the three-impact orbits at the grazing
  // (leaving it downwards, into the fold) shows the turn, and the step is cut.
  const double p0 = 0.34227002384989125, t0 = 3.877695945534333;
  VectorXd x(3), v(3);
  x << 0.10311075158037762, 0.06792461761963765, 0.08288308455598971;
  v << -0.05341092523855251, -0.11836966090314052, -0.123544509393987;
  vibro::ContinuationOptions o;
  o.p_min = 0.338;
  o.p_max = 0.343;
  o.direction = -1;
  o.step = 0.02;
  o.max_step = 0.02;
  o.parameter_scale = 0.4;  // the scene's range [0.3, 0.7]
  o.max_doublings = 0;
  const vibro::ContinuationResult r = vibro::continue_orbits(clearance_chain_at, p0, t0, x, v, o);
  REQUIRE_FALSE(r.branches.empty());
  INFO("branch: " << r.branches[0].end);
  const vibro::Bifurcation* fold = find(r, vibro::BifurcationKind::fold, 0.3405746);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.3406847);
  REQUIRE(fold != nullptr);
  REQUIRE(graze != nullptr);
  CHECK(fold->smooth);
  CHECK(std::abs(fold->p - 0.3405746067) < 1e-9);
  CHECK(graze->smooth);
  CHECK(std::abs(graze->p - 0.3406846563) < 1e-9);
  // The fold lies on the orbits with three impacts (the grazing's impacting side).
  CHECK(fold->point.signature.impacts[0] == 3);
}

TEST_CASE("continuation: a branch switched onto at a period doubling goes on through a grazing whose "
          "impacting orbits leave it at a small angle to the part followed (the three-mass clearance "
          "chain's doubled branch at Ω ≈ 0.5673813)",
          "[continuation][three-mass][grazing][doubling]") {
  // The period-1 orbit with 15 impacts on the clearance doubles at Ω = 0.5673807122 (the scene's
  // located doubling, its orbit kept to 17 digits). On the doubled branch one half has lost the
  // last impact (29 per 2T), stable; up in Ω that half grazes the clearance again at 0.5673813049,
  // where the orbits with 30 impacts turn back down in Ω, unstable, 3° from the part followed
  // (a non-smooth fold), back to the doubling. The corner's predictor along their tangent
  // kept the gap maximum at the grazing to first order only, short of the stop: its corrector
  // landed on the part already followed, and the branch ended with "step below min_step
  // (corrector stalled …)" at 0.5673813048.
  const double p0 = 0.5673807121760062, t0 = 7.345573247940974;
  VectorXd x(3), v(3);
  x << -0.39808954122032075, -0.6266651439329597, -0.6317415612247173;
  v << -0.05842049422928531, 0.02880638994258305, -0.07223308238207306;
  vibro::ContinuationOptions o;
  o.p_min = 0.566;
  o.p_max = 0.569;
  o.phase = 4.167736580757769;
  o.step = 0.01;
  o.max_step = 0.02;
  o.parameter_scale = 0.4;  // the scene's range [0.3, 0.7]
  o.max_doublings = 1;
  o.switch_at_start = true;
  const vibro::ContinuationResult r = vibro::continue_orbits(clearance_chain_at, p0, t0, x, v, o);
  REQUIRE(r.branches.size() == 2);
  const vibro::Branch& b = r.branches[1];
  INFO("doubled branch: " << b.end);
  CHECK(b.k == 2);
  CHECK(b.end.find("step below min_step") == std::string::npos);
  // It comes back to the doubling: onto the period-1 orbits, or onto its own orbits shifted by a
  // period (the part of the doubled branch between the doubling and the first point switched onto).
  CHECK((b.end.find("merged into the period-1T branch") != std::string::npos ||
         b.end.find("closes on itself") != std::string::npos));
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.5673813049, 1);
  REQUIRE(graze != nullptr);
  CHECK(graze->stop == 0);
  CHECK(graze->smooth);
  CHECK(std::abs(graze->p - 0.5673813049) < 1e-9);
  // Both parts of the corner: stable orbits with 29 impacts, unstable ones with 30 beyond it.
  bool stable_29 = false, unstable_30 = false;
  for (const vibro::BranchPoint& q : b.points) {
    stable_29 |= q.signature.impacts[0] == 29 && q.multipliers.stable;
    unstable_30 |= q.signature.impacts[0] == 30 && !q.multipliers.stable && q.tangent_p < 0.0;
  }
  CHECK(stable_29);
  CHECK(unstable_30);
}

TEST_CASE("continuation: a period doubling between a stable impacting orbit and the grazing that ends "
          "the impact is located where a corrector fails on the chord of its bracket (the three-mass "
          "clearance chain at Ω ≈ 0.5677196 and 0.5677131)",
          "[continuation][three-mass][doubling]") {
  // Down in Ω from this point (one of the scene's branch points, 22 impacts on the clearance, kept
  // to 17 digits) the orbits lose their last slow impacts one by one at grazings; between each
  // stable impacting stretch and its grazing a multiplier passes −1 (it tends to −∞ as the
  // impact's speed goes to 0), within 5e-8 of the grazing in Ω. In the scene's own run (from
  // Ω = 0.7, tools/bench/clearance_doublings.sh) the corrector from the chord through a bracket's
  // first end failed there and these two were reported unlocated (brackets 1.2e-8 and 2.1e-8);
  // the Illinois iteration now retries from the bracket ends' orbits. From this point the chord's
  // corrector does not fail (this case passes without the retry too): it checks the location
  // against the values independently found. Their values, by shooting
  // at Ω ± 1e-11 (tools/figures/clearance_doublings.py's finite-difference check brackets them
  // too): the multiplier nearest −1 changes side between 0.56771961985 and …962, and between
  // 0.56771306634 and …636.
  const double p0 = 0.5677220428099354, t0 = 7.341156880450848;
  VectorXd x(3), v(3);
  x << -0.3978014335809019, -0.6273726319881558, -0.6324051109355068;
  v << -0.05868336418823873, 0.02830317529996571, -0.07219518143220434;
  vibro::ContinuationOptions o;
  o.p_min = 0.5677;
  o.p_max = 0.56773;
  o.phase = 4.167736580757769;
  o.direction = -1;
  o.step = 0.01;
  o.max_step = 0.02;
  o.max_doublings = 0;
  const vibro::ContinuationResult r = vibro::continue_orbits(clearance_chain_at, p0, t0, x, v, o);
  REQUIRE_FALSE(r.branches.empty());
  INFO("branch: " << r.branches[0].end);
  for (const double expected : {0.5677196199, 0.5677130664}) {
    const vibro::Bifurcation* pd = find(r, vibro::BifurcationKind::period_doubling, expected);
    REQUIRE(pd != nullptr);
    INFO("doubling near " << expected << " at " << pd->p << " (" << pd->note << ")");
    CHECK(pd->smooth);
    // Located to the options' tolerance (1e-10) around the value the shooting brackets (±1e-11).
    CHECK(std::abs(pd->p - expected) < 1e-10);
    CHECK(pd->p_high - pd->p_low <= 1e-10);
  }
}

TEST_CASE("continuation: a grazing corner reached by short steps is located from the side without the "
          "impact although it lies far beyond the two points in Ω (the three-mass chain at Ω ≈ 0.17979)",
          "[continuation][three-mass][grazing]") {
  // Past the vanishing of s3's split phase the branch follows the bounces lost one grazing at a
  // time; each grazing is a corner where the branch turns back in Ω. From this orbit with seven
  // impacts of s3 (a point of the scene's branch) the steps cross the corners at 0.1797894388
  // (eight impacts / seven) and 0.1798412768 (seven / six) between points a few 1e-7 apart, while
  // the corner lies 8 … 20 times that distance beyond the point without the impact: the secant
  // from that side must be let reach it.
  const double p0 = 0.17984281124250473;
  VectorXd x(3), v(3);
  x << 0.3203801898123175, 0.15999506626516288, 0.09077985607243874;
  v << 0.10763994481686039, 0.06761474942522078, 0.06448766075081086;
  vibro::ContinuationOptions o;
  o.p_min = 0.17970;
  o.p_max = 0.17990;
  o.step = 0.01;
  o.max_step = 0.02;
  o.parameter_scale = 0.025;  // the scene's range, so that the steps are the scene's
  o.max_points = 60;
  const vibro::ContinuationResult r = vibro::continue_orbits(three_mass_at, p0, 0.0, x, v, o);
  REQUIRE_FALSE(r.branches.empty());
  for (const double at : {0.179789438829, 0.179841276770}) {
    const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, at);
    REQUIRE(graze != nullptr);
    INFO("grazing near " << at << ": " << graze->p << " (" << graze->note << ")");
    CHECK(graze->smooth);
    CHECK(std::abs(graze->p - at) < 1e-9);
    CHECK(std::abs(graze->value) < 1e-9);
  }
}

namespace {

/// One direction of a brute-force bifurcation diagram of the paper's system (run.kind: diagram,
/// done here with the simulator): at every Ω of `grid`, in order, `periods` forcing periods from
/// the previous value's final state (the time restarting at 0, so every state is at forcing
/// phase 0); the state reached at each value, and the last one in *end.
std::vector<VectorXd> diagram_sweep(const std::vector<double>& grid, VectorXd x, VectorXd v, int periods,
                                    VectorXd* end) {
  std::vector<VectorXd> out;
  for (const double omega : grid) {
    const vibro::ImpactSystem sys = paper_at(omega).system;
    vibro::Simulator sim(sys);
    const vibro::RunSummary s = sim.run(0.0, x, v, periods * 2.0 * std::numbers::pi / omega);
    REQUIRE(s.status == vibro::RunStatus::completed);
    x = s.x;
    v = s.v;
    out.push_back(vibro::test::stack(x, v));
  }
  *end = vibro::test::stack(x, v);
  return out;
}

}  // namespace

TEST_CASE("continuation: on the paper's system past the vanishing of mass 1's split sticking phase, "
          "every Ω interval where the up and down diagrams differ (two stable orbits coexist) is "
          "bounded by a fold or grazing continuation locates",
          "[continuation][wagg2004][hysteresis]") {
  // Started at lo, not where the scene starts, so its steps differ from the scene's: the steps
  // jump across the grazings beside the upper ends of the windows at 0.257470, 0.257485 and
  // 0.257498 from stable orbits with the grazing impact, and each such fold is located on the
  // impacting orbits by short steps from the last point before the jump. About 9 s (CPU) on an
  // idle machine.
  // The diagram: up from the orbit reached from rest at lo, then down from where the up sweep
  // ends, on a grid of `count` values; where the two states differ at a grid value the two
  // sweeps sit on different attractors there.
  const double lo = 0.25744, hi = 0.25756;
  const int count = 121;
  std::vector<double> grid;
  for (int i = 0; i < count; ++i) grid.push_back(lo + (hi - lo) * i / (count - 1));
  const double T = 2.0 * std::numbers::pi / lo;
  const vibro::ImpactSystem start_sys = paper_at(lo).system;
  vibro::Simulator sim(start_sys);
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 200.0 * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  VectorXd end;
  const std::vector<VectorXd> up = diagram_sweep(grid, warm.x, warm.v, 100, &end);
  std::vector<double> reversed(grid.rbegin(), grid.rend());
  std::vector<VectorXd> down = diagram_sweep(reversed, end.head(2), end.tail(2), 100, &end);
  std::reverse(down.begin(), down.end());
  // The windows: maximal runs of grid values where the sweeps differ. (Runs that converge to one
  // orbit agree to far below 1e-6; the two orbits of a window differ by ≥ 1e-5.)
  std::vector<std::pair<int, int>> windows;
  for (int i = 0; i < count; ++i) {
    const bool differ = (up[i] - down[i]).cwiseAbs().maxCoeff() > 1e-6;
    if (!differ) continue;
    if (!windows.empty() && windows.back().second == i - 1) windows.back().second = i;
    else windows.push_back({i, i});
  }
  // The two windows, at 0.257470 and 0.257545, lie in [lo, hi].
  CHECK(windows.size() >= 2);
  // Continuation from the orbit the up sweep starts on.
  vibro::ContinuationOptions o;
  o.p_min = lo;
  o.p_max = hi;
  o.step = 0.01;
  o.max_step = 0.02;
  o.parameter_scale = 0.04;  // as on the scene's range [0.24, 0.28]
  o.max_points = 800;
  const vibro::ContinuationResult r = vibro::continue_orbits(paper_at, lo, 200.0 * T, warm.x, warm.v, o);
  REQUIRE_FALSE(r.branches.empty());
  INFO("branch: " << r.branches[0].end << ", " << r.branches[0].points.size() << " points");
  CHECK(r.branches[0].end.find("reached p_max") != std::string::npos);
  // Each end of a window lies between its last agreeing grid value and the first differing one:
  // there an attractor ceases (a fold, or a grazing corner where the branch turns back).
  const auto bounded = [&](double a, double b) {
    for (const vibro::Bifurcation& f : r.bifurcations)
      if ((f.kind == vibro::BifurcationKind::fold || f.kind == vibro::BifurcationKind::grazing ||
           f.kind == vibro::BifurcationKind::period_doubling) &&
          f.smooth && f.p > std::min(a, b) && f.p < std::max(a, b))
        return true;
    return false;
  };
  for (const auto& [first, last] : windows) {
    INFO("window " << grid[static_cast<std::size_t>(first)] << " … " << grid[static_cast<std::size_t>(last)]);
    REQUIRE(first > 0);
    REQUIRE(last + 1 < count);
    CHECK(bounded(grid[static_cast<std::size_t>(first - 1)], grid[static_cast<std::size_t>(first)]));
    CHECK(bounded(grid[static_cast<std::size_t>(last)], grid[static_cast<std::size_t>(last + 1)]));
  }
}

TEST_CASE("continuation: the vanishing of mass 1's split sticking phase moves with the chatter rule's "
          "height and lies inside the independent computation's bracket at chatter_height 1e-10",
          "[continuation][wagg2004][chatter]") {
  // The vanishing is where the chatter rule stops catching the bounces before the contact force
  // turns: not a smooth condition, bracketed by bisection, and displaced by the rule's cut-off.
  // The independent computation (exact bounces, no chatter rule) puts it in
  // [0.25745569, 0.25745575]. Measured (this set-up, p in [0.2573, 0.2576], steps of the scene):
  // 0.2574559335 at chatter_height 1e-9 (the default: 1.8e-7 above the bracket), 0.2574557475 at
  // 1e-10, 0.2574556984 at 1e-11, 0.2574556832 at 1e-12 (the displacement shrinks about 4 × per
  // decade of the height, ~height^0.6). Checked here: the default lies above the bracket, 1e-10
  // inside it.
  vibro::models::Wagg2004 p;
  p.frequency = 0.2574;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  vibro::Simulator sim(sys);
  const double T = 2.0 * std::numbers::pi / p.frequency;
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 200.0 * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  for (const double height : {1e-9, 1e-10}) {
    vibro::ContinuationOptions o;
    o.p_min = 0.2573;
    o.p_max = 0.2576;
    o.step = 0.01;
    o.max_step = 0.02;
    o.max_points = 40;
    o.solver.chatter_height = height;
    const vibro::ContinuationResult r = vibro::continue_orbits(paper_at, p.frequency, 200.0 * T, warm.x, warm.v, o);
    const vibro::Bifurcation* vanish = find(r, vibro::BifurcationKind::phase_change, 0.2574557);
    REQUIRE(vanish != nullptr);
    INFO("chatter_height " << height << ": vanishing at " << vanish->p << " in [" << vanish->p_low << ", "
                           << vanish->p_high << "]");
    CHECK_FALSE(vanish->smooth);
    if (height == 1e-9) {
      CHECK(vanish->p_low > 0.25745575 + 1e-7);
    } else {
      CHECK(vanish->p_low > 0.25745569);
      CHECK(vanish->p_high < 0.25745575);
    }
  }
}

TEST_CASE("continuation: a grazing corner whose orbits without the impact are first met where the lost "
          "impact's flight has no gap maximum is solved at the corner (the paper's system at Ω ≈ "
          "0.2574626)",
          "[continuation][wagg2004][grazing]") {
  // Past the vanishing of mass 1's split phase the branch loses its bounces one grazing at a time.
  // From this stable orbit with 15 impacts of s1 (a point of the scene's branch, kept to 17
  // digits), with the step the scene's run takes there, the branch turns at a fold at 0.2574627888
  // and comes back down, unstable, to the grazing corner at 0.2574626340, where the orbits with 14
  // impacts leave upwards. The step past the corner lands on a 14-impact orbit 1.4e-6 above it
  // whose flight of the lost impact has no gap maximum: its largest gap maximum is another
  // flight's (−0.44 L), flat in Ω, and the grazing used to be bracketed by the landing point
  // instead (0.2574644489 in the scene). The corner, solved on its own by Newton on the grazing
  // condition from the 14-impact side near it: 0.2574626340 (test function 5.6e-14).
  const double p0 = 0.25746276592783146;
  VectorXd x(2), v(2);
  x << 0.291379641461578, 0.07708840629395695;
  v << 0.14891914464512584, 0.007625906388432056;
  vibro::ContinuationOptions o;
  o.p_min = 0.24;
  o.p_max = 0.28;
  o.step = 6.862153e-05;  // the scene's step at this point
  o.max_step = 0.02;
  o.max_points = 6;
  o.max_doublings = 0;
  const auto start = std::chrono::steady_clock::now();
  const vibro::ContinuationResult r = vibro::continue_orbits(paper_at, p0, 0.0, x, v, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  REQUIRE_FALSE(r.branches.empty());
  INFO("branch: " << r.branches[0].end << " (" << seconds << " s)");
  for (const vibro::Bifurcation& b : r.bifurcations)
    UNSCOPED_INFO(vibro::to_string(b.kind) << " at " << b.p << (b.smooth ? " solved" : " bracketed") << " (" << b.note << ")");
  const vibro::Bifurcation* fold = find(r, vibro::BifurcationKind::fold, 0.2574627888);
  const vibro::Bifurcation* graze = find(r, vibro::BifurcationKind::grazing, 0.2574626340);
  REQUIRE(fold != nullptr);
  REQUIRE(graze != nullptr);
  CHECK(std::abs(fold->p - 0.2574627888) < 1e-9);
  CHECK(graze->stop == 0);
  CHECK(graze->smooth);
  // Within 1e-9 of the independent solve (its 10 digits), touching the stop to 1e-9 L.
  CHECK(std::abs(graze->p - 0.2574626340) < 1e-9);
  CHECK(std::abs(graze->value) < 1e-9);
  CHECK(graze->point.signature.impacts[0] == 14);
}

namespace {

/// x'' + 0.05 x' + x = 2 cos Ωt between rigid stops at x = ±1 (r = 0.8): unchanged by x → −x,
/// t → t + T/2, so H(z) = −z(T/2) of the run from (0, z) maps the section t ≡ 0 (mod T) onto
/// itself; a symmetric orbit is a fixed point of H, its period map H∘H, and its multipliers
/// the squares of H's: where it loses its symmetry, a multiplier of H passes −1.
vibro::ImpactSystem two_sided(double omega) {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
  f.cosine(0) = 2.0;
  return vibro::ImpactSystem(vibro::LinearSystem(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, 0.05),
                                                 Eigen::MatrixXd::Identity(1, 1), f),
                             {vibro::Stop::upper(0, 1.0, 0.8), vibro::Stop::lower(0, -1.0, 0.8)});
}

VectorXd two_sided_half_map(double omega, const VectorXd& z) {
  const vibro::ImpactSystem sys = two_sided(omega);
  vibro::Simulator sim(sys);
  const vibro::RunSummary s = sim.run(0.0, z.head(1), z.tail(1), std::numbers::pi / omega);
  REQUIRE(s.status == vibro::RunStatus::completed);
  VectorXd out(2);
  out << -s.x(0), -s.v(0);
  return out;
}

/// The symmetric orbit at Ω and H's multiplier nearest −1 (symmetric_orbit.hpp), step 1e-5: the
/// runs' rounding, ~1e-14 amplified through the impacts, gives ~1e-9 in the multiplier, the
/// truncation h²|H'''|/6 ~1e-10.
std::pair<VectorXd, double> symmetric_impacting_orbit(double omega, const VectorXd& z) {
  return vibro::test::symmetric_fixed_point([omega](const VectorXd& y) { return two_sided_half_map(omega, y); }, z,
                                            1e-5);
}

}  // namespace

TEST_CASE("continuation: a branch point where a symmetric impacting orbit loses its symmetry, located against the "
          "half-period map, and the crossing branch switched onto",
          "[continuation]") {
  // The symmetric orbit (one impact on each stop per period) is stable at Ω = 1 and loses its
  // symmetry at Ω_b ≈ 1.02358: a multiplier passes +1 while its branch goes straight on in Ω.
  // Reference: H's multiplier passing −1, bracketed by bisection on its sign (the differences'
  // ~1e-9 over its slope, ≈ −5.9 per unit of Ω, place it to a few 1e-10).
  const double W = 1.0, T = 2.0 * std::numbers::pi / W;
  const vibro::ImpactSystem start = two_sided(W);
  vibro::Simulator sim(start);
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(1), VectorXd::Zero(1), 300.0 * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  VectorXd z(2);
  z << warm.x(0), warm.v(0);
  double lo = 1.0, hi = 1.04;
  auto [z_lo, mu_lo] = symmetric_impacting_orbit(lo, z);
  REQUIRE(mu_lo > -1.0);
  REQUIRE(symmetric_impacting_orbit(hi, z_lo).second < -1.0);
  for (int i = 0; i < 26; ++i) {
    const double mid = 0.5 * (lo + hi);
    const auto [z_mid, mu_mid] = symmetric_impacting_orbit(mid, z_lo);
    if (mu_mid > -1.0) lo = mid, z_lo = z_mid;
    else hi = mid;
  }
  const double reference = 0.5 * (lo + hi);

  vibro::ContinuationOptions o;
  o.p_min = 0.9;
  o.p_max = 1.1;
  o.max_doublings = 0;
  const vibro::ParameterFamily family = [](double omega) {
    return vibro::FamilyPoint{two_sided(omega), vibro::SystemDerivative::frequency_only()};
  };
  const vibro::ContinuationResult r = vibro::continue_orbits(family, W, 300.0 * T, warm.x, warm.v, o);
  const vibro::Bifurcation* bp = find(r, vibro::BifurcationKind::branch_point, 1.0236);
  REQUIRE(bp != nullptr);
  WARN(std::setprecision(15) << "branch point: Ω = " << bp->p << " (half-period map's bracket [" << lo << ", " << hi
                             << "], difference " << bp->p - reference << "), smooth " << bp->smooth);
  CHECK(bp->smooth);
  // The reference to a few 1e-10, the location to its tolerance 1e-10.
  CHECK(std::abs(bp->p - reference) < 1e-9);
  CHECK(r.branches.front().points.front().p == Approx(0.9).margin(1e-12));
  CHECK(r.branches.front().points.back().p == Approx(1.1).margin(1e-12));
  // A branch switched onto there whose orbits, checked by plain runs, are periodic and not
  // symmetric.
  int asymmetric = 0;
  for (std::size_t i = 1; i < r.branches.size(); ++i) {
    const vibro::Branch& s = r.branches[i];
    INFO("branch " << i << ": " << s.start << " … " << s.end);
    CHECK(s.parent == 0);
    if (s.points.size() < 5) continue;
    const vibro::BranchPoint& q = s.points[4];
    const double Tq = 2.0 * std::numbers::pi / q.p;
    const vibro::ImpactSystem sq = two_sided(q.p);
    vibro::Simulator run(sq);
    const vibro::RunSummary one = run.run(q.t0, q.x, q.v, q.t0 + Tq);
    REQUIRE(one.status == vibro::RunStatus::completed);
    CHECK(std::max(std::abs(one.x(0) - q.x(0)), std::abs(one.v(0) - q.v(0))) < 1e-9);
    vibro::Simulator half(sq);
    const vibro::RunSummary h = half.run(q.t0, q.x, q.v, q.t0 + Tq / 2);
    REQUIRE(h.status == vibro::RunStatus::completed);
    asymmetric += std::abs(h.x(0) + q.x(0)) + std::abs(h.v(0) + q.v(0)) > 1e-4;
  }
  CHECK(asymmetric >= 1);
}
