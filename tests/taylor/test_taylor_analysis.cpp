// The analysis layer on the Taylor engine (nonlinear forces): tangent maps from the variational
// equations and the saltation matrices of the nonlinear field (vibro/linearisation.hpp), shooting
// and Floquet multipliers, continuation with its bifurcations.
#include "vibro/continuation.hpp"
#include "vibro/family_engine.hpp"
#include "vibro/io/kinds/continue.hpp"
#include "vibro/io/scene.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/lyapunov.hpp"
#include "vibro/shooting.hpp"
#include "vibro/simulator.hpp"
#include "vibro/taylor_simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

/// x'' + 0.05 x' + x + β x³ = 0.8 cos Ω t, a rigid stop at x = 0.6 with r = 0.8
/// (experiments/examples/duffing_impact.yaml).
std::string duffing(double omega, double beta = 0.5, const std::string& extra = "") {
  return "model:\n  chain:\n    masses: [1]\n    left_wall: {spring: 1, damper: 0.05}\n"
         "forcing:\n  frequency: " + std::to_string(omega) + "\n  cosine: [0.8]\n"
         "stops:\n  - {mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop}\n"
         "parameters: {beta: " + std::to_string(beta) + "}\n"
         "forces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n"
         "initial: {x: [0], v: [0]}\n" + extra;
}

/// The seed paper's two-mass oscillator at its sticking orbit (Wagg 2004, fig. 2; Ω = 0.255,
/// experiments/wagg2004/fig2_sticking_orbit.yaml), with `extra` scene text appended.
std::string two_mass(const std::string& extra = "") {
  return "model:\n  chain:\n    masses: [1, 1]\n    springs: [1]\n    dampers: [0.1]\n"
         "    left_wall: {spring: 1, damper: 0.1}\n"
         "forcing:\n  frequency: 0.255\n  cosine: [0.5, 0]\n"
         "stops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}\n"
         "  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}\n"
         "initial: {x: [0, 0], v: [0, 0]}\n" + extra;
}

VectorXd stacked(const VectorXd& x, const VectorXd& v) {
  VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// A converged period-k orbit from the state after `periods` forcing periods from rest.
vibro::ShootingResult orbit(const vibro::ImpactSystem& sys, const vibro::NonlinearForces& f,
                            const vibro::SimulatorOptions& solver, double T, int k = 1, int periods = 60) {
  vibro::TaylorSimulator sim(sys, f, solver);
  const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(sys.dof()), VectorXd::Zero(sys.dof()), periods * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  o.solver = solver;
  o.period = k;
  vibro::ShootingResult r = vibro::shoot(sys, f, o, warm.t, warm.x, warm.v);
  INFO(r.message);
  REQUIRE(r.converged());
  return r;
}

// Where the branch of duffing() has its fold (from the continuation's exploration; the test
// locates it itself and checks it by runs).
constexpr double kFoldStart = 1.3;
constexpr double kFoldRange[2] = {0.8, 1.4};
constexpr double kFoldDelta = 2e-3;
constexpr int kFoldPeriods = 400;
constexpr int kDoublingPeriods = 1500;

}  // namespace

// The map's Jacobian against central differences of the period map itself (plain runs of the
// Taylor engine from perturbed states), on the period-1 impacting orbit of the Duffing impact
// oscillator. Every perturbed run keeps the orbit's impacts (checked), so P is smooth there. A
// central difference with step h errs by h² |P'''|/6 (truncation) plus ε_run/h (the runs' own
// rounding, ε_run ~ 1e-14 of the scales after a period with an impact): with h = 1e-5 of the
// scales both are ~1e-9 to 1e-10, so 1e-7 of the Jacobian's size is a safe bound that a wrong
// saltation matrix (an O(1) error in a term) or a wrong flow Jacobian cannot meet.
TEST_CASE("Taylor engine: the period map's Jacobian and multipliers against central differences", "[taylor][analysis]") {
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(duffing(1.3)).build();
  const vibro::ImpactSystem sys = scene.impact_system();
  const double T = scene.period();
  const vibro::ShootingResult r = orbit(sys, scene.forces, scene.solver, T);
  const vibro::TangentMap& m = r.map;
  REQUIRE(m.summary.impacts > 0);
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  const VectorXd z0 = stacked(r.x, r.v);
  const double t1 = r.t0 + r.k * T;
  auto P = [&](const VectorXd& z, long* impacts) {
    vibro::TaylorSimulator sim(sys, scene.forces, scene.solver);
    const vibro::RunSummary s = sim.run(r.t0, z.head(1), z.tail(1), t1);
    REQUIRE(s.status == vibro::RunStatus::completed);
    *impacts = s.impacts;
    return stacked(s.x, s.v);
  };
  MatrixXd fd(2, 2);
  for (int i = 0; i < 2; ++i) {
    const double h = 1e-5 * (i == 0 ? L : V);
    VectorXd zp = z0, zm = z0;
    zp(i) += h;
    zm(i) -= h;
    long ip = 0, im = 0;
    fd.col(i) = (P(zp, &ip) - P(zm, &im)) / (2.0 * h);
    CHECK(ip == m.summary.impacts);
    CHECK(im == m.summary.impacts);
  }
  const double size = std::max(1.0, m.jacobian.cwiseAbs().maxCoeff());
  const double error = (m.jacobian - fd).cwiseAbs().maxCoeff() / size;
  INFO("J = " << m.jacobian << "\nFD = " << fd << "\nrelative difference " << error);
  CHECK(error < 1e-7);
  const Eigen::VectorXcd mu = fd.eigenvalues();
  for (int i = 0; i < 2; ++i) {  // each multiplier of the differences has one of the map's beside it
    double nearest = 1e300;
    for (int k = 0; k < 2; ++k) nearest = std::min(nearest, std::abs(mu(i) - r.multipliers.values(k)));
    CHECK(nearest < 1e-7 * size);
  }
  WARN("Duffing impact oscillator, Ω = 1.3: |J − J_fd| / max(1, |J|) = " << error << ", multipliers "
       << r.multipliers.values.transpose());
}

// The parameter column ∂P/∂p at fixed t0, t1 (the lifted variational equation of
// taylor_tangent.cpp) against central differences of runs at p ± h, for Ω (the drive moves) and
// for β (a named parameter of the forces). Same error budget as above.
TEST_CASE("Taylor engine: the map's derivative in Ω and in a parameter of the forces against central differences",
          "[taylor][analysis]") {
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(duffing(1.3)).build();
  const double T = scene.period();
  const vibro::ShootingResult r = orbit(scene.impact_system(), scene.forces, scene.solver, T);
  const double t1 = r.t0 + T;
  struct Case {
    std::string path;
    double value;
  };
  for (const Case& c : {Case{"forcing.frequency", 1.3}, Case{"parameters.beta", 0.5}}) {
    const vibro::io::SceneDocument doc = vibro::io::SceneDocument::parse(duffing(1.3));
    vibro::LinearisationOptions o;
    o.parameter = vibro::io::parameter_derivative(doc, c.path);
    const vibro::TangentMap m =
        vibro::linearise(scene.impact_system(), scene.forces, scene.solver, r.t0, r.x, r.v, t1, o);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    auto run_at = [&](double p) {
      vibro::io::SceneDocument d(doc);
      d.set(c.path, p);
      const vibro::io::Scene s = d.build_point();
      const vibro::ImpactSystem sys = s.impact_system();
      vibro::TaylorSimulator sim(sys, s.forces, s.solver);
      const vibro::RunSummary e = sim.run(r.t0, r.x, r.v, t1);
      REQUIRE(e.status == vibro::RunStatus::completed);
      REQUIRE(e.impacts == m.summary.impacts);
      return stacked(e.x, e.v);
    };
    const double h = 1e-5 * c.value;
    const VectorXd fd = (run_at(c.value + h) - run_at(c.value - h)) / (2.0 * h);
    const double size = std::max(1.0, m.parameter.cwiseAbs().maxCoeff());
    const double error = (m.parameter - fd).cwiseAbs().maxCoeff() / size;
    INFO(c.path << ": analytic " << m.parameter.transpose() << ", central differences " << fd.transpose());
    CHECK(error < 1e-7);
    WARN("d/d " << c.path << ": relative difference " << error);
  }
}

// A linear scene (no forces) run through the Taylor engine: its tangent map (variational
// equations of the Taylor core, saltation from the same reset) against the dense engine's exact
// one (matrix exponentials), on the same orbit. Both are exact to rounding; the orbits agree to
// ~1e-13 of the scales (tests/taylor/test_taylor_engine.cpp), so J and the multipliers agree to
// ~1e-12 relative; 1e-10 leaves room without admitting a wrong term.
// The same with the stop moving at orders 1, 2 and 3 (its velocity and acceleration enter the
// saltation matrices, its motion the gap's peaks, on both engines in closed form).
TEST_CASE("Taylor engine: multipliers of a linear scene equal the dense engine's", "[taylor][analysis]") {
  for (const std::string motion : {"", ", amplitude: 0.02, harmonics: [{order: 2, cosine: 0.01}, {order: 3, sine: 0.005}]"}) {
    INFO("stop motion: '" << motion << "'");
    const std::string text =
        "model:\n  chain:\n    masses: [1]\n    left_wall: {spring: 1, damper: 0.05}\n"
        "forcing:\n  frequency: 1.3\n  cosine: [0.8]\n"
        "stops:\n  - {mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop" + motion + "}\n"
        "initial: {x: [0], v: [0]}\n";
    const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
    const vibro::ImpactSystem sys = scene.impact_system();
    const double T = scene.period();
    const vibro::ShootingResult taylor = orbit(sys, {}, scene.solver, T);
    vibro::ShootingOptions o;
    o.solver = scene.solver;
    o.phase = taylor.phase;  // the same section
    o.free_section = false;
    const vibro::ShootingResult dense = vibro::shoot(sys, o, taylor.t0, taylor.x, taylor.v);
    REQUIRE(dense.converged());
    REQUIRE(taylor.map.summary.impacts > 0);
    REQUIRE(std::abs(dense.t0 - taylor.t0) < 1e-12 * T);
    const double size = std::max(1.0, dense.map.jacobian.cwiseAbs().maxCoeff());
    const double dj = (dense.map.jacobian - taylor.map.jacobian).cwiseAbs().maxCoeff() / size;
    const double dmu = (dense.multipliers.values - taylor.multipliers.values).cwiseAbs().maxCoeff();
    CHECK(dj < 1e-10);
    CHECK(dmu < 1e-10);
    WARN("linear scene" << (motion.empty() ? "" : ", moving stop") << ": |J_taylor − J_dense| / max(1, |J|) = " << dj
                        << ", multipliers differ by " << dmu);
  }
}

// Lyapunov exponents (the orthonormal frame carried by the variational equations, re-orthonormalised
// at every impact) of the same linear scene on both engines, over 40 periods after 40 of
// transient and 10 of alignment on its stable impacting orbit: each period's growth agrees to ~1e-12 relative (the
// maps' agreement above), so the averaged exponents agree to ~1e-12/T; held to 1e-10.
TEST_CASE("Taylor engine: Lyapunov exponents of a linear scene equal the dense engine's", "[taylor][analysis]") {
  const std::string text =
      "model:\n  chain:\n    masses: [1]\n    left_wall: {spring: 1, damper: 0.05}\n"
      "forcing:\n  frequency: 1.3\n  cosine: [0.8]\n"
      "stops:\n  - {mass: 0, side: upper, position: 0.6, restitution: 0.8, name: stop}\n"
      "initial: {x: [0], v: [0]}\n";
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
  const vibro::ImpactSystem sys = scene.impact_system();
  vibro::LyapunovOptions o;
  o.transient = 40;
  o.align = 10;
  o.periods = 40;
  const vibro::LyapunovResult dense = vibro::lyapunov_spectrum(sys, scene.solver, 0.0, scene.x0, scene.v0, o);
  const vibro::LyapunovResult taylor = vibro::lyapunov_spectrum(sys, {}, scene.solver, 0.0, scene.x0, scene.v0, o);
  REQUIRE(dense.status == vibro::RunStatus::completed);
  REQUIRE(taylor.status == vibro::RunStatus::completed);
  const double d = (dense.exponents - taylor.exponents).cwiseAbs().maxCoeff();
  INFO("dense " << dense.exponents.transpose() << ", Taylor " << taylor.exponents.transpose());
  CHECK(d < 1e-10);
  WARN("Lyapunov exponents, linear scene: engines differ by " << d);
}

// Continuation in Ω of the Duffing impact oscillator's branch (the Taylor engine's maps and their
// derivative in Ω) locates a fold; two long runs on either side of it, started on the branch's
// stable orbit next to the fold, bracket it independently: on the branch's side (δ inside) the
// run stays on the orbit; beyond it (δ outside) there is no orbit to stay on and the run leaves
// for another attractor, O(1) away. The located Ω is thereby confirmed to within δ.
TEST_CASE("Taylor engine: a fold of the Duffing impact oscillator's branch, located and bracketed by runs",
          "[taylor][analysis]") {
  const double omega0 = kFoldStart;
  const vibro::io::SceneDocument doc = vibro::io::SceneDocument::parse(duffing(omega0));
  const vibro::io::Scene scene = doc.build();
  const vibro::ContinuationFamily family =
      vibro::io::continuation_family(doc, "forcing.frequency", vibro::io::EngineKind::taylor, scene.solver);
  vibro::ContinuationOptions o;
  o.p_min = kFoldRange[0];
  o.p_max = kFoldRange[1];
  o.step = 0.01;
  o.max_step = 0.02;
  o.max_doublings = 0;
  o.solver = scene.solver;
  const vibro::ImpactSystem sys = scene.impact_system();  // outlives the simulator
  vibro::TaylorSimulator sim(sys, scene.forces, scene.solver);
  const double T0 = scene.period();
  const vibro::RunSummary warm = sim.run(0.0, scene.x0, scene.v0, 60.0 * T0);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  const vibro::ContinuationResult r = vibro::continue_orbits(family, omega0, warm.t, warm.x, warm.v, o);
  REQUIRE(!r.branches.empty());
  // A fold with no other bifurcation within 5δ (a fold right beside a grazing would mix the two
  // in the runs' bracket).
  const double delta = kFoldDelta;
  const vibro::Bifurcation* fold = nullptr;
  int folds = 0;
  for (const vibro::Bifurcation& b : r.bifurcations) {
    if (b.kind != vibro::BifurcationKind::fold || b.branch != 0) continue;
    ++folds;
    bool alone = true;
    for (const vibro::Bifurcation& c : r.bifurcations)
      if (&c != &b && std::abs(c.p - b.p) < 5.0 * delta) alone = false;
    if (alone && !fold) fold = &b;
  }
  CHECK(folds == 2);  // the hysteresis loop of the resonance (measured: Ω ≈ 0.8423 and 0.9087)
  REQUIRE(fold != nullptr);
  const double pf = fold->p;
  // The stable orbit of the branch next to the fold, and the side the branch lies on.
  const vibro::BranchPoint* q = nullptr;
  for (const vibro::BranchPoint& b : r.branches[0].points)
    if (b.multipliers.stable && (!q || std::abs(b.p - pf) < std::abs(q->p - pf))) q = &b;
  REQUIRE(q != nullptr);
  const double side = q->p < pf ? -1.0 : 1.0;
  REQUIRE(std::abs(q->p - pf) < 0.05);
  // From q's state, the state at the fold orbit's section after about `periods` forcing periods
  // at Ω = p, and its distance from the fold orbit's state (in units of the run's L and V).
  const vibro::BranchPoint& f = fold->point;
  auto distance_after = [&](double p, int periods) {
    vibro::io::SceneDocument d(doc);
    d.set("forcing.frequency", p);
    const vibro::io::Scene s = d.build_point();
    const vibro::ImpactSystem at = s.impact_system();
    vibro::TaylorSimulator run(at, s.forces, s.solver);
    const double T = s.period();
    const vibro::RunSummary e = run.run(q->t0, q->x, q->v, f.t0 + periods * T);
    REQUIRE(e.status == vibro::RunStatus::completed);
    return std::max((e.x - f.x).cwiseAbs().maxCoeff() / e.length_scale,
                    (e.v - f.v).cwiseAbs().maxCoeff() / e.velocity_scale);
  };
  const double inside = distance_after(pf + side * delta, kFoldPeriods);
  const double outside = distance_after(pf - side * delta, kFoldPeriods);
  const double inside4 = distance_after(pf + side * delta / 4.0, kFoldPeriods);
  const double outside4 = distance_after(pf - side * delta / 4.0, kFoldPeriods);
  INFO("fold at Ω = " << pf << " (branch on the " << (side < 0 ? "low" : "high") << " side); distance after "
       << kFoldPeriods << " periods: δ inside " << inside << ", outside " << outside << "; δ/4 inside " << inside4
       << ", outside " << outside4);
  // Beyond the fold the run leaves for the other attractor of the hysteresis loop, O(1) away.
  CHECK(outside > 0.3);
  CHECK(outside4 > 0.3);
  // Inside, it settles on the stable orbit, which at a saddle-node lies ~ c √δ from the fold's
  // orbit: a quarter of δ halves the distance (0.5, within the O(√δ) correction of the normal form).
  CHECK(inside < outside / 4.0);
  CHECK(inside4 / inside > 0.4);
  CHECK(inside4 / inside < 0.6);
  WARN("fold located at Ω = " << pf << "; runs at δ = " << delta << " either side: inside " << inside
       << " from the fold orbit, outside " << outside << "; at δ/4: " << inside4 << ", " << outside4);
}

// With lighter damping (c = 0.02) the period-1 branch has a period-doubling bubble: continuation
// locates its two period doublings, and long runs check them. Between them the period-1 orbit is
// unstable (μ < −1) and a run started on it settles on a period-2 orbit (its stroboscopic state
// returns after two periods, not after one); just above the upper doubling the run settles on the
// period-1 orbit again.
TEST_CASE("Taylor engine: the period doublings of a Duffing impact oscillator's branch, checked by runs",
          "[taylor][analysis]") {
  const double omega0 = 0.78;
  std::string text = duffing(omega0);
  text.replace(text.find("damper: 0.05"), 12, "damper: 0.02");
  const vibro::io::SceneDocument doc = vibro::io::SceneDocument::parse(text);
  const vibro::io::Scene scene = doc.build();
  const vibro::ContinuationFamily family =
      vibro::io::continuation_family(doc, "forcing.frequency", vibro::io::EngineKind::taylor, scene.solver);
  vibro::ContinuationOptions o;
  o.p_min = 0.69;
  o.p_max = 0.80;
  o.step = 0.01;
  o.max_step = 0.02;
  o.max_doublings = 0;
  o.solver = scene.solver;
  const vibro::ImpactSystem sys = scene.impact_system();
  vibro::TaylorSimulator sim(sys, scene.forces, scene.solver);
  const vibro::RunSummary warm = sim.run(0.0, scene.x0, scene.v0, 60.0 * scene.period());
  REQUIRE(warm.status == vibro::RunStatus::completed);
  const vibro::ContinuationResult r = vibro::continue_orbits(family, omega0, warm.t, warm.x, warm.v, o);
  std::vector<const vibro::Bifurcation*> pd;
  for (const vibro::Bifurcation& b : r.bifurcations)
    if (b.kind == vibro::BifurcationKind::period_doubling && b.branch == 0) pd.push_back(&b);
  REQUIRE(pd.size() == 2);
  if (pd[0]->p > pd[1]->p) std::swap(pd[0], pd[1]);
  // Stroboscopic distances |z(N+1) − z(N)| and |z(N+2) − z(N)| (in units of L and V) of a run at
  // Ω = p from the upper doubling's orbit.
  const vibro::BranchPoint& start = pd[1]->point;
  auto returns = [&](double p, int periods) {
    vibro::io::SceneDocument d(doc);
    d.set("forcing.frequency", p);
    const vibro::io::Scene s = d.build_point();
    const vibro::ImpactSystem at = s.impact_system();
    vibro::TaylorSimulator run(at, s.forces, s.solver);
    const double T = s.period();
    std::vector<VectorXd> z;
    double L = 1.0, V = 1.0;
    vibro::RunSummary e = run.run(start.t0, start.x, start.v, start.t0 + periods * T);
    for (int k = 0; k < 3; ++k) {
      REQUIRE(e.status == vibro::RunStatus::completed);
      z.push_back(stacked(e.x, e.v));
      L = e.length_scale;
      V = e.velocity_scale;
      e = run.run(e.t, e.x, e.v, e.t + T);
    }
    auto dist = [&](const VectorXd& a, const VectorXd& b) {
      return std::max(std::abs(a(0) - b(0)) / L, std::abs(a(1) - b(1)) / V);
    };
    return std::pair{dist(z[1], z[0]), dist(z[2], z[0])};
  };
  const double mid = 0.5 * (pd[0]->p + pd[1]->p);
  const auto [one_mid, two_mid] = returns(mid, kDoublingPeriods);
  const auto [one_above, two_above] = returns(pd[1]->p + 0.01, kDoublingPeriods);
  INFO("doublings at Ω = " << pd[0]->p << ", " << pd[1]->p << "; between: |P z − z| = " << one_mid
       << ", |P² z − z| = " << two_mid << "; above: " << one_above << ", " << two_above);
  CHECK(one_mid > 1e-3);
  CHECK(two_mid < 1e-3 * one_mid);
  CHECK(one_above < 1e-6);
  WARN("period doublings located at Ω = " << pd[0]->p << " and " << pd[1]->p << "; runs between: |Pz − z| = "
       << one_mid << ", |P²z − z| = " << two_mid << "; above: |Pz − z| = " << one_above);
}

// The seed paper's sticking orbit (Wagg 2004, fig. 2: two masses, a stop on each, r = 0.7,
// Ω = 0.255; experiments/wagg2004/fig2_sticking_orbit.yaml), a linear scene run through the Taylor
// engine: its map crosses chatter (the accumulation rule), sticking (the held flow's variational
// equations, the saltation at its start) and release (the force's sign change). Both engines'
// maps are exact to rounding; their orbits agree to ~1e-13 of the scales (the engines' agreement,
// tests/taylor/test_taylor_engine.cpp), and J is a continuous function of the orbit, with
// derivatives of the size of J itself, so J and the multipliers agree to ~1e-12 relative: 1e-10
// leaves a factor 100 without admitting a wrong term (a missing nonlinear part of a held
// segment, a wrong saltation, would be O(1)).
TEST_CASE("Taylor engine: the seed paper's sticking orbit has the dense engine's multipliers", "[taylor][analysis]") {
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(two_mass()).build();
  const vibro::ImpactSystem sys = scene.impact_system();
  const double T = scene.period();
  vibro::Simulator warm_sim(sys, scene.solver);  // the transient on the dense engine
  const vibro::RunSummary warm = warm_sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 60.0 * T);
  REQUIRE(warm.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  o.solver = scene.solver;
  const vibro::ShootingResult taylor = vibro::shoot(sys, vibro::NonlinearForces{}, o, warm.t, warm.x, warm.v);
  INFO(taylor.message);
  REQUIRE(taylor.converged());
  REQUIRE(taylor.map.summary.impacts > 0);
  bool sticks = false;
  for (const vibro::SaltationRecord& s : taylor.map.saltations) sticks = sticks || !s.held_after.empty();
  REQUIRE(sticks);
  o.phase = taylor.phase;  // the same section
  o.free_section = false;
  const vibro::ShootingResult dense = vibro::shoot(sys, o, taylor.t0, taylor.x, taylor.v);
  REQUIRE(dense.converged());
  REQUIRE(std::abs(std::remainder(dense.t0 - taylor.t0, T)) < 1e-12 * T);  // the same section (mod T)
  const double size = std::max(1.0, dense.map.jacobian.cwiseAbs().maxCoeff());
  const double dj = (dense.map.jacobian - taylor.map.jacobian).cwiseAbs().maxCoeff() / size;
  const double dmu = (dense.multipliers.values - taylor.multipliers.values).cwiseAbs().maxCoeff();
  INFO("J_taylor =\n" << taylor.map.jacobian << "\nJ_dense =\n" << dense.map.jacobian);
  CHECK(dj < 1e-10);
  CHECK(dmu < 1e-10);
  // A release's saltation is the identity (λ = 0 there, so f⁺ = f⁻): its guard's rate −λ̇ (the
  // held system's force series on the Taylor engine, the force rows on the dense one) is checked
  // on its own, to the orbits' agreement.
  REQUIRE(dense.map.saltations.size() == taylor.map.saltations.size());
  int releases = 0;
  for (std::size_t i = 0; i < dense.map.saltations.size(); ++i) {
    const vibro::SaltationRecord& a = dense.map.saltations[i];
    const vibro::SaltationRecord& b = taylor.map.saltations[i];
    if (a.impact || a.released.empty()) continue;
    ++releases;
    CHECK(std::abs(a.guard_rate - b.guard_rate) < 1e-10 * std::max(1.0, std::abs(a.guard_rate)));
  }
  CHECK(releases > 0);
  WARN("Wagg (2004) sticking orbit: |J_taylor − J_dense| / max(1, |J|) = " << dj << ", multipliers differ by " << dmu
       << " (" << dense.multipliers.values.transpose() << ")");
}

namespace {

/// The seed paper's two-mass oscillator (above) with cubic springs, on mass 0 (which enters the
/// contact force of its stop) and between the masses (which couples the free mass to the held
/// one): while a stop holds, the other mass moves under nonlinear forces.
std::string sticking_duffing(double beta = 0.3) {
  return two_mass("parameters: {beta: " + std::to_string(beta) + "}\n"
                  "forces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n"
                  "  - {cubic_spring: {between: [0, 1], coefficient: beta}}\n");
}

/// Central differences of f with steps h and h/2 combined by Richardson's rule: the h² terms
/// cancel, leaving O(h⁴) truncation and ~ε_run/h rounding (ε_run ~ 1e-14 of the scales).
template <class F>
VectorXd richardson(const F& f, double h) {
  const VectorXd d1 = (f(h) - f(-h)) / (2.0 * h);
  const VectorXd d2 = (f(0.5 * h) - f(-0.5 * h)) / h;
  return (4.0 * d2 - d1) / 3.0;
}

/// How far the tangent map of a periodic orbit lies from differences of runs (relative to its size).
struct MapGap {
  double jacobian = 0.0, parameter = 0.0;  ///< the Jacobian's; the largest of the parameter columns'
};

/// The tangent map m of the scene `text` over one forcing period from (t0, x, v): its Jacobian, and
/// its derivative in each of `parameters` (path, value), against Richardson-extrapolated central
/// differences of runs that keep the map's events (checked), with h = 1e-4 of the scales
/// (truncation ~h⁴|P⁽⁵⁾| ~ 1e-16, the runs' rounding ε_run/h ~ 1e-10): both held to `tolerance`
/// (default 1e-8) of their sizes. With `multipliers`, each multiplier of the differences has one of
/// them within the tolerance of the size.
MapGap map_against_differences(const std::string& text, double t0, const VectorXd& x, const VectorXd& v,
                               const vibro::TangentMap& m,
                               const std::vector<std::pair<std::string, double>>& parameters,
                               const Eigen::VectorXcd* multipliers = nullptr, double tolerance = 1e-8) {
  const vibro::io::SceneDocument doc = vibro::io::SceneDocument::parse(text);
  const vibro::io::Scene scene = doc.build();
  const vibro::ImpactSystem sys = scene.impact_system();
  const Eigen::Index n = sys.dof();
  const long events = static_cast<long>(m.events.size());
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  const VectorXd z0 = stacked(x, v);
  const double t1 = t0 + scene.period();
  auto P = [&](const vibro::ImpactSystem& s, const vibro::NonlinearForces& f, const VectorXd& z) {
    vibro::TaylorSimulator sim(s, f, scene.solver);
    vibro::EventLog log;
    const vibro::RunSummary e = sim.run(t0, z.head(n), z.tail(n), t1, {&log});
    REQUIRE(e.status == vibro::RunStatus::completed);
    REQUIRE(static_cast<long>(log.events.size()) == events);
    return stacked(e.x, e.v);
  };
  MapGap gap;
  MatrixXd fd(2 * n, 2 * n);
  for (Eigen::Index i = 0; i < 2 * n; ++i) {
    const double scale = i < n ? L : V;
    fd.col(i) = richardson(
        [&](double h) {
          VectorXd z = z0;
          z(i) += h;
          return P(sys, scene.forces, z);
        },
        1e-4 * scale);
  }
  const double size = std::max(1.0, m.jacobian.cwiseAbs().maxCoeff());
  gap.jacobian = (m.jacobian - fd).cwiseAbs().maxCoeff() / size;
  INFO("J = " << m.jacobian << "\nFD = " << fd << "\nrelative difference " << gap.jacobian);
  CHECK(gap.jacobian < tolerance);
  if (multipliers) {
    const Eigen::VectorXcd mu = fd.eigenvalues();
    for (Eigen::Index i = 0; i < 2 * n; ++i) {
      double nearest = 1e300;
      for (Eigen::Index k = 0; k < 2 * n; ++k) nearest = std::min(nearest, std::abs(mu(i) - (*multipliers)(k)));
      CHECK(nearest < tolerance * size);
    }
  }
  for (const auto& [key, at] : parameters) {
    const std::string path = key;  // copies: clang before 16 cannot capture a structured binding in a lambda
    const double value = at;
    vibro::LinearisationOptions o;
    o.parameter = vibro::io::parameter_derivative(doc, path);
    const vibro::TangentMap mp = vibro::linearise(sys, scene.forces, scene.solver, t0, x, v, t1, o);
    REQUIRE(mp.summary.status == vibro::RunStatus::completed);
    const VectorXd dp = richardson(
        [&](double h) {
          vibro::io::SceneDocument d(doc);
          d.set(path, value + h);
          const vibro::io::Scene sp = d.build_point();
          return P(sp.impact_system(), sp.forces, z0);
        },
        1e-4 * value);
    const double psize = std::max(1.0, mp.parameter.cwiseAbs().maxCoeff());
    const double perror = (mp.parameter - dp).cwiseAbs().maxCoeff() / psize;
    INFO(path << ": analytic " << mp.parameter.transpose() << ", differences " << dp.transpose());
    CHECK(perror < tolerance);
    gap.parameter = std::max(gap.parameter, perror);
  }
  return gap;
}

/// The same for the period map P of the scene `text` at its period-1 orbit r, with its multipliers.
MapGap map_against_differences(const std::string& text, const vibro::ShootingResult& r,
                               const std::vector<std::pair<std::string, double>>& parameters) {
  return map_against_differences(text, r.t0, r.x, r.v, r.map, parameters, &r.multipliers.values);
}

}  // namespace

// The period map of a nonlinear scene through sticking: the Duffing impact oscillator with a
// plastic stop, on its periodic orbit (each period an impact, sticking, a release at the contact
// force's sign change). Its Jacobian and its derivatives in Ω (the drive) and β (the cubic
// spring, which moves the held flow's contact force) against Richardson-extrapolated central
// differences of runs. Each perturbed run keeps the orbit's events (checked), so P is smooth
// there. With h = 1e-4 of the scales the truncation is ~h⁴ |P⁽⁵⁾| ~ 1e-16 and the runs' rounding
// ε_run/h ~ 1e-10: 1e-8 of the sizes bounds both, which a wrong held-flow Jacobian, saltation or
// release guard (O(1) terms) cannot meet.
TEST_CASE("Taylor engine: the period map through sticking against central differences", "[taylor][analysis]") {
  const std::string text = sticking_duffing();
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
  const vibro::ShootingResult r = orbit(scene.impact_system(), scene.forces, scene.solver, scene.period(), 1, 40);
  bool sticks = false, releases = false;
  for (const vibro::SaltationRecord& s : r.map.saltations) {
    sticks = sticks || !s.held_after.empty();
    releases = releases || (!s.held_before.empty() && s.held_after.empty());
  }
  REQUIRE(sticks);
  REQUIRE(releases);
  const MapGap g = map_against_differences(text, r, {{"forcing.frequency", 0.255}, {"parameters.beta", 0.3}});
  WARN("sticking Duffing impact oscillator: |J − J_fd| / max(1, |J|) = " << g.jacobian << ", multipliers "
       << r.multipliers.values.transpose() << "; d/dΩ, d/dβ: relative difference " << g.parameter);
}

// Shooting asks for runs of zero length (the section at the guess's own time): the Taylor engine
// takes no step and returns the state it was given.
TEST_CASE("Taylor engine: a run of zero length returns its start", "[taylor][analysis]") {
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(duffing(0.78)).build();
  const vibro::ImpactSystem sys = scene.impact_system();
  vibro::TaylorSimulator sim(sys, scene.forces, scene.solver);
  const VectorXd x = VectorXd::Constant(1, 0.3), v = VectorXd::Constant(1, -0.2);
  const vibro::RunSummary s = sim.run(7.5, x, v, 7.5);
  REQUIRE(s.status == vibro::RunStatus::completed);
  CHECK(s.t == 7.5);
  CHECK(s.x == x);
  CHECK(s.v == v);
}

namespace {

/// A Duffing oscillator (β = 0.5) against a preloaded spring-dashpot stop at 0.6 (k_s = 20,
/// c_s = 0.3, F_p = 0.2: the vector field jumps at each switch), `extra` stops appended.
std::string soft_duffing(double omega, const std::string& extra_stops = "") {
  return "model:\n  chain:\n    masses: [1]\n    left_wall: {spring: 1, damper: 0.05}\n"
         "forcing:\n  frequency: " + std::to_string(omega) + "\n  cosine: [0.8]\n"
         "stops:\n  - {mass: 0, side: upper, position: 0.6, law: compliant, stiffness: 20, damping: 0.3, preload: 0.2,"
         " name: soft}\n" + extra_stops +
         "parameters: {beta: 0.5}\n"
         "forces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n"
         "initial: {x: [0], v: [0]}\n";
}

}  // namespace

// The period map of a nonlinear scene through a compliant stop's switches: the soft-impact
// Duffing oscillator on its period-1 orbit (an engagement and a disengagement each period, the
// vector field jumping by c_s g' + F_p at both, so the saltation matrices are not the identity),
// and the same with a rigid stop behind the spring (a two-stage stop: impacts while the spring is
// engaged). Its Jacobian and its derivatives in Ω, β and the compliant stop's law (k_s, c_s, F_p,
// which act in the engaged flow only) against Richardson-extrapolated central differences of
// runs, each keeping the orbit's events (checked). Error budget as the sticking test's above
// (h = 1e-4 of the scales: truncation ~1e-16, rounding ~1e-10): 1e-8 of the sizes, which a
// saltation matrix left at the identity (an O(c_s g' + F_p) term) or an engaged flow without the
// stop's spring cannot meet.
TEST_CASE("Taylor engine: the period map through a compliant stop's switches against central differences",
          "[taylor][analysis][compliant]") {
  for (const std::string rigid : {"", "  - {mass: 0, side: upper, position: 0.66, restitution: 0.7, name: behind}\n"}) {
    INFO("rigid stop behind the spring: '" << rigid << "'");
    const std::string text = soft_duffing(1.1, rigid);
    const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
    REQUIRE(scene.engine == vibro::io::EngineKind::taylor);
    const vibro::ShootingResult r = orbit(scene.impact_system(), scene.forces, scene.solver, scene.period(), 1, 60);
    long engagements = 0;
    for (const vibro::Event& e : r.map.events) engagements += e.kind == vibro::EventKind::engage;
    REQUIRE(engagements > 0);
    if (!rigid.empty()) REQUIRE(r.map.summary.impacts > 0);
    const MapGap g = map_against_differences(text, r,
                                             {{"forcing.frequency", 1.1}, {"parameters.beta", 0.5},
                                              {"stops[0].stiffness", 20.0}, {"stops[0].damping", 0.3},
                                              {"stops[0].preload", 0.2}});
    WARN("soft-impact Duffing" << (rigid.empty() ? "" : " (two-stage)") << ": |J − J_fd| / max(1, |J|) = "
                               << g.jacobian << ", parameters " << g.parameter << "; multipliers "
                               << r.multipliers.values.transpose());
  }
}

namespace {

/// Two unit masses coupled by a spring and a damper (1, 0.1), the first on the wall (1, 0.1),
/// pressed by a constant force 3.5 against a rigid stop at x0 = 1 (r = 0.5) and shaken off it once
/// a period by 0.8 cos t: each period a release, a flight, a few bounces whose chatter the rule
/// ends (chatter_height 1e-3), and sticking. A hardening cubic spring β x0³ (β = 2) takes 2 of
/// the pressing force at the stop, so the contact force at the chatter's capture is a small part
/// of what the linear forces alone would give.
std::string pressed_duffing(const std::string& rule) {
  return "model:\n  chain:\n    masses: [1, 1]\n    springs: [1]\n    dampers: [0.1]\n"
         "    left_wall: {spring: 1, damper: 0.1}\n"
         "forcing:\n  frequency: 1\n  constant: [3.5, 0]\n  cosine: [0.8, 0]\n"
         "stops:\n  - {mass: 0, side: upper, position: 1, restitution: 0.5, name: stop}\n"
         "parameters: {beta: 2}\n"
         "forces:\n  - {cubic_spring: {mass: 0, coefficient: beta}}\n"
         "solver: {chatter_height: 1e-3, chatter_rule: " + rule + "}\n"
         "initial: {x: [0, 0], v: [0, 0]}\n";
}

}  // namespace

// The map through a chatter ended by its rule, on a scene with nonlinear forces. The second- and
// third-order rules move the state at the capture by the skipped bounces' mean displacement
// D = −(2/3) w0³ / (A² (1 − r³)) (mechanics.hpp, reset step 2), felt by the free mass through
// the coupling; A is the held stop's contact acceleration, which the engine takes with the
// nonlinear forces in it, and so must the reset's derivative. The skipped tail's effect is
// O(w0³) and its derivative O(w0²) ~ chatter_height·L: with the default 1e-9 a wrong A would
// hide under the differences' error, so the scene's 1e-3 makes it O(1e-3). The map over one
// period from a state in flight (a release, bounces, the capture, sticking) and its derivative in
// β (which moves A) against Richardson-extrapolated central differences of runs keeping
// the map's events (checked): h = 1e-4 of the scales, truncation ~h⁴|P⁽⁵⁾| ~ 1e-16, the runs'
// rounding ε_run/h ~ 1e-10, so 1e-8 of the sizes again (the capture's reset is as smooth as an
// impact's: D is a rational function of w0 and A; it has no further rounding of its own).
TEST_CASE("Taylor engine: the map through a chatter capture against central differences",
          "[taylor][analysis][chatter]") {
  for (const std::string rule : {"second_order", "third_order"}) {
    INFO("chatter rule " << rule);
    const std::string text = pressed_duffing(rule);
    const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
    const vibro::ImpactSystem sys = scene.impact_system();
    REQUIRE(scene.engine == vibro::io::EngineKind::taylor);
    const double T = scene.period(), t0 = 20.5 * T;  // in flight: released at ~20.4 T, bounces at ~20.7 T
    vibro::TaylorSimulator sim(sys, scene.forces, scene.solver);
    const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t0);
    REQUIRE(warm.status == vibro::RunStatus::completed);
    REQUIRE(warm.stuck.empty());
    const vibro::TangentMap m = vibro::linearise(sys, scene.forces, scene.solver, t0, warm.x, warm.v, t0 + T);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    bool caught = false;
    for (const vibro::SaltationRecord& s : m.saltations) caught = caught || !s.caught.empty();
    REQUIRE(caught);
    // (Not Ω: at t0 ≈ 129 a step h in Ω moves the drive's phase by t0·h, so the differences' error
    // (t0 h)⁴ ~ 3e-8 at h = 1e-4 exceeds the bound; β moves A, which is what is tested here.)
    const MapGap g = map_against_differences(text, t0, warm.x, warm.v, m, {{"parameters.beta", 2.0}});
    WARN("chatter capture (" << rule << ", chatter_height 1e-3): |J − J_fd| / max(1, |J|) = " << g.jacobian
                             << "; d/dβ: relative difference " << g.parameter);
  }
}
