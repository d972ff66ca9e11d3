// The Taylor engine (vibro/taylor_simulator.hpp) inside the shared event loop, against the exact
// dense engine on a linear scene with impacts, chatter and sticking.
#include "vibro/io/scene.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "vibro/taylor_simulator.hpp"
#include "support/reference_compliant_duffing.hpp"
#include "support/reference_duffing_impact.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <memory>
#include <cmath>
#include <string>
#include <vector>

namespace {

vibro::io::Scene wagg_scene() {
  return vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml").build();
}

}  // namespace

// The seed paper's sticking orbit (Wagg 2004, fig. 2): two masses, two stops, impacts that chatter
// to sticking and release, 20 forcing periods (~1200 events). The dense engine's flow is exact to
// ~1e-15 of the scales; the Taylor engine's series is truncated at the unit roundoff of the state's
// scale per step and evaluated by compensated Horner, so both carry only rounding, and they must
// resolve every event alike (same stops, kinds and order). How far their event times may differ is
// set by conditioning: an event time is a root of a guard, and a state difference δ moves it by
// δ/|g'|. The two roundings random-walk apart over the ~1500 steps and ~1200 events (each impact
// passes a velocity error on through the restitution law): measured 6e-14 L in x and 5e-13 V in v
// at the end. In a chatter sequence the approach speeds fall to ~1e-5 V, so the times themselves
// differ by up to ~1e-11 T, while the time error measured on the gap, |Δt|·|g'|/L, is of the
// states' size (measured 1.7e-13). Both that and the states are held to 1e-12 (a few times the
// rounding measured), events at rest (stick, release: both speeds 0; measured 5e-15 T) to 1e-13 T;
// a missed or differently resolved event differs by O(1).
TEST_CASE("a linear scene through the Taylor engine agrees with the exact dense engine", "[taylor][engine]") {
  const vibro::io::Scene scene = wagg_scene();
  const vibro::ImpactSystem system = scene.impact_system();
  const double T = scene.period(), t_end = 20.0 * T;
  vibro::Simulator dense(system, scene.solver);
  vibro::TaylorSimulator taylor(system, {}, scene.solver);
  vibro::EventLog dense_events, taylor_events;
  const vibro::RunSummary a = dense.run(0.0, scene.x0, scene.v0, t_end, {&dense_events});
  const vibro::RunSummary b = taylor.run(0.0, scene.x0, scene.v0, t_end, {&taylor_events});
  REQUIRE(a.status == vibro::RunStatus::completed);
  INFO(b.message);
  REQUIRE(b.status == vibro::RunStatus::completed);
  REQUIRE(a.sticks > 0);
  REQUIRE(a.chatters > 0);
  CHECK(b.impacts == a.impacts);
  CHECK(b.sticks == a.sticks);
  CHECK(b.releases == a.releases);
  CHECK(b.chatters == a.chatters);
  REQUIRE(dense_events.events.size() == taylor_events.events.size());
  const double L = a.length_scale, V = a.velocity_scale;
  double dt_raw = 0.0, dt_gap = 0.0, dt_rest = 0.0;
  for (std::size_t i = 0; i < dense_events.events.size(); ++i) {
    const vibro::Event& e = dense_events.events[i];
    const vibro::Event& f = taylor_events.events[i];
    REQUIRE(e.stop == f.stop);
    REQUIRE(e.kind == f.kind);
    const double dt = std::abs(e.t - f.t), speed = std::max(std::abs(e.v_before), std::abs(e.v_after));
    dt_raw = std::max(dt_raw, dt / T);
    if (speed > 0.0) dt_gap = std::max(dt_gap, dt * speed / L);
    else dt_rest = std::max(dt_rest, dt / T);
  }
  const double dx = (a.x - b.x).cwiseAbs().maxCoeff() / L;
  const double dv = (a.v - b.v).cwiseAbs().maxCoeff() / V;
  INFO(dense_events.events.size() << " events (" << a.impacts << " impacts, " << a.chatters << " chatters, " << a.sticks
                                  << " sticks): max |dt|/T = " << dt_raw << ", |dt||g'|/L = " << dt_gap
                                  << ", at rest |dt|/T = " << dt_rest << "; end |dx|/L = " << dx << ", |dv|/V = " << dv
                                  << "; " << taylor.steps() << " Taylor steps");
  CHECK(dt_gap < 1e-12);
  CHECK(dt_rest < 1e-13);
  CHECK(dt_raw < 1e-10);
  CHECK(dx < 1e-12);
  CHECK(dv < 1e-12);
  WARN("Taylor vs dense: " << dense_events.events.size() << " events, max |dt|/T = " << dt_raw << ", |dt||g'|/L = "
                           << dt_gap << ", at rest |dt|/T = " << dt_rest << "; end |dx|/L = " << dx << ", |dv|/V = " << dv);
}

// A guard that starts inside its own remainder band: two masses, two stops, started 0.01 above the
// lower stop s1 and moving up. Each impact leaves its gap at rounding distance of the trigger
// level, and at a high order the whole step's band of that gap is wider than the trigger, so the
// search must decide the start from the band's share there and still find the crossing later in
// the same step (the return to the stop after each impact); walking over it fails the run's check
// that no state lies past a stop. The scene is linear, so the exact dense engine is the reference,
// with the tolerances (and their reasons) of the test above; at the order the tolerance sets and at
// 20 and 27 (the orders of the rules ⌈−½ ln ε + 1⌉ and ⌈−0.7 ln ε + 1⌉ at ε = 2⁻⁵²).
TEST_CASE("a crossing in the step after an impact is found at every order", "[taylor][engine]") {
  const std::string text =
      "model:\n  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1}}\n"
      "forcing: {frequency: 1.2, cosine: [0.5, 0]}\n"
      "stops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}\n"
      "  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2}\n"
      "initial: {x: [-0.29, 0], v: [0.6, 0]}\n";
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
  const vibro::ImpactSystem system = scene.impact_system();
  const double T = scene.period(), t_end = 5.0 * T;
  vibro::Simulator dense(system, scene.solver);
  vibro::EventLog de;
  const vibro::RunSummary a = dense.run(0.0, scene.x0, scene.v0, t_end, {&de});
  REQUIRE(a.status == vibro::RunStatus::completed);
  REQUIRE(a.impacts >= 4);
  const double L = a.length_scale, V = a.velocity_scale;
  for (int order : {0, 20, 27}) {
    vibro::NonlinearForces forces;
    forces.order = order;
    vibro::TaylorSimulator taylor(system, forces, scene.solver);
    vibro::EventLog te;
    const vibro::RunSummary b = taylor.run(0.0, scene.x0, scene.v0, t_end, {&te});
    INFO("order " << order << ": " << b.message);
    REQUIRE(b.status == vibro::RunStatus::completed);
    REQUIRE(de.events.size() == te.events.size());
    double dt_gap = 0.0, dt_rest = 0.0;
    for (std::size_t i = 0; i < de.events.size(); ++i) {
      REQUIRE(de.events[i].stop == te.events[i].stop);
      REQUIRE(de.events[i].kind == te.events[i].kind);
      const double dt = std::abs(de.events[i].t - te.events[i].t);
      const double speed = std::max(std::abs(de.events[i].v_before), std::abs(de.events[i].v_after));
      if (speed > 0.0) dt_gap = std::max(dt_gap, dt * speed / L);
      else dt_rest = std::max(dt_rest, dt / T);
    }
    const double dx = (a.x - b.x).cwiseAbs().maxCoeff() / L, dv = (a.v - b.v).cwiseAbs().maxCoeff() / V;
    INFO(de.events.size() << " events: |dt||g'|/L = " << dt_gap << ", at rest |dt|/T = " << dt_rest
                          << ", end |dx|/L = " << dx << ", |dv|/V = " << dv << "; " << taylor.steps() << " steps");
    CHECK(dt_gap < 1e-12);
    CHECK(dt_rest < 1e-13);
    CHECK(dx < 1e-12);
    CHECK(dv < 1e-12);
  }
}

namespace {

/// x'' + c x' + k x + β x³ = A cos Ωt with one stop x ≤ s on the mass (m = 1).
vibro::ImpactSystem duffing_system(double c, double k, double amplitude, double omega, double stop, double r) {
  vibro::HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, amplitude),
                           .sine = Eigen::VectorXd::Zero(1), .frequency = omega};
  vibro::LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, c),
                          Eigen::MatrixXd::Constant(1, 1, k), f);
  return vibro::ImpactSystem(sys, {vibro::Stop::upper(0, stop, r)});
}

constexpr double kDuffingStop = 0.6;

/// x'' + c x' + x + β x³ = A cos Ωt (m = 1) with `stop` on the mass, through the Taylor engine
/// from rest to t_end (its events into `log`); `steps` gets the Taylor steps taken.
vibro::RunSummary taylor_duffing(double c, double beta, double A, double omega, const vibro::Stop& stop, double t_end,
                                 vibro::EventLog& log, long* steps) {
  vibro::HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, A),
                           .sine = Eigen::VectorXd::Zero(1), .frequency = omega};
  vibro::LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, c),
                          Eigen::MatrixXd::Identity(1, 1), f);
  const vibro::ImpactSystem system(sys, {stop});
  vibro::NonlinearForces forces;
  forces.parameters = {{"beta", beta}};
  forces.forces = {"-beta*x0^3"};
  vibro::TaylorSimulator taylor(system, forces);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(1);
  const vibro::RunSummary run = taylor.run(0.0, zero, zero, t_end, {&log});
  *steps = taylor.steps();
  return run;
}

/// How far the Taylor engine's run lies from the long-double reference's.
struct ReferenceGap {
  std::size_t impacts = 0;
  long steps = 0;
  double dt = 0.0, du = 0.0, dx = 0.0, dv = 0.0;  ///< max |Δt|/T, max |Δv⁻| over the impacts; end |Δx|/s, |Δv|
};

/// x'' + 0.05 x' + x + 0.5 x³ = 0.8 cos 1.3t (m = 1) with `stop` (an upper stop on the mass at
/// kDuffingStop, r = 0.8, moving as `motion` says to the reference) from rest over 10 forcing
/// periods, through the Taylor engine and through the reference; every event must be an impact,
/// the two must find as many, and the differences stay below the bounds of the test below.
ReferenceGap duffing_against_reference(const vibro::Stop& stop,
                                       const std::vector<vibro::test::ReferenceDuffingImpact::Harmonic>& motion) {
  const double c = 0.05, k = 1.0, beta = 0.5, A = 0.8, omega = 1.3;
  const double T = 2.0 * std::acos(-1.0) / omega, t_end = 10.0 * T;
  vibro::EventLog log;
  long steps = 0;
  const vibro::RunSummary run = taylor_duffing(c, beta, A, omega, stop, t_end, log, &steps);
  INFO(run.message);
  REQUIRE(run.status == vibro::RunStatus::completed);

  vibro::test::ReferenceDuffingImpact ref;
  ref.c = c;
  ref.k = k;
  ref.beta = beta;
  ref.amplitude = A;
  ref.omega = omega;
  ref.stop = stop.position;
  ref.restitution = stop.restitution;
  ref.stop_harmonics = motion;
  ref.run(0.0L, 0.0L, 0.0L, t_end);
  REQUIRE(ref.impacts.size() >= 5);
  REQUIRE(log.events.size() == ref.impacts.size());
  ReferenceGap g;
  g.impacts = log.events.size();
  g.steps = steps;
  for (std::size_t i = 0; i < log.events.size(); ++i) {
    REQUIRE(log.events[i].kind == vibro::EventKind::impact);
    g.dt = std::max(g.dt, std::abs(log.events[i].t - static_cast<double>(ref.impacts[i].t)) / T);
    g.du = std::max(g.du, std::abs(log.events[i].v_before - static_cast<double>(ref.impacts[i].v_before)));
  }
  g.dx = std::abs(run.x(0) - static_cast<double>(ref.x)) / stop.position;
  g.dv = std::abs(run.v(0) - static_cast<double>(ref.v));
  INFO(g.impacts << " impacts: max |dt|/T = " << g.dt << ", |du| = " << g.du << "; end |dx|/s = " << g.dx
                 << ", |dv| = " << g.dv << "; " << g.steps << " Taylor steps");
  CHECK(g.dt < 1e-12);
  CHECK(g.du < 1e-12);
  CHECK(g.dx < 1e-12);
  CHECK(g.dv < 1e-12);
  return g;
}

}  // namespace

// A forced, damped Duffing impact oscillator (hardening β = 0.5, stop at 0.6, r = 0.8) over 10
// forcing periods, against the independent long-double RK8 reference with its own bisection on the
// gap (tests/support/reference_duffing_impact.hpp, accurate to ~1e-16 of the state). Both start at
// rest; the orbit impacts about once a period at speeds of order 0.5 (no chatter). The Taylor
// engine carries rounding only (~1e-16 per step, a few hundred steps), and an impact passes the
// state's error on (times r), so the impact times and the end state are held to 1e-12 of the
// scales (T, and the stop's position and the speed scale 1): a wrong root, a missed impact or a
// truncated series would differ by far more (a step at tolerance 1e-10 gives ~1e-9).
TEST_CASE("a Duffing impact oscillator agrees with an independent long-double reference", "[taylor][engine]") {
  const ReferenceGap g = duffing_against_reference(vibro::Stop::upper(0, kDuffingStop, 0.8), {});
  WARN("Duffing vs reference: " << g.impacts << " impacts, max |dt|/T = " << g.dt << ", |du| = " << g.du
                                << ", end |dx|/s = " << g.dx << ", |dv| = " << g.dv << ", " << g.steps << " steps");
}

// A conservative Duffing oscillator (no damping, no drive, β = 1) bouncing elastically (r = 1) on a
// stop at 0.5 from x0 = 0, v0 = 1.2: the energy E = v²/2 + x²/2 + x⁴/4 is a constant of the motion,
// and at each impact x = 0.5 exactly, so E there is read from the impact speed alone. Over t = 1500
// (460 impacts, ~6900 steps) rounding moves E by at most ~ε per step and per impact: ≤ 7400 ε ≈
// 1.6e-12 if every rounding had one sign, ~√7400 ε ≈ 2e-14 as a random walk (measured 9.4e-14).
// 1e-12 is the first bound; an error of the method shows far above it (a series truncated at
// tolerance 1e-10 instead of ε, or a root misplaced by 1e-10 in time, changes E by ~1e-10).
TEST_CASE("a conservative Duffing oscillator with elastic impacts keeps its energy to rounding", "[taylor][engine]") {
  const double s = 0.5;
  const vibro::ImpactSystem system = duffing_system(0.0, 1.0, 0.0, 0.0, s, 1.0);
  vibro::NonlinearForces forces;
  forces.forces = {"-x0^3"};
  vibro::SimulatorOptions options;
  options.max_events = 1000000;
  vibro::TaylorSimulator taylor(system, forces, options);
  vibro::EventLog log;
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(1), v0 = Eigen::VectorXd::Constant(1, 1.2);
  auto energy = [](double x, double v) { return 0.5 * v * v + 0.5 * x * x + 0.25 * x * x * x * x; };
  const double e0 = energy(0.0, 1.2);
  const vibro::RunSummary run = taylor.run(0.0, x0, v0, 1500.0, {&log});
  INFO(run.message);
  REQUIRE(run.status == vibro::RunStatus::completed);
  REQUIRE(log.events.size() >= 300);
  double drift = 0.0;
  for (const vibro::Event& e : log.events) {
    REQUIRE(e.kind == vibro::EventKind::impact);
    drift = std::max({drift, std::abs(energy(s, e.v_before) - e0) / e0, std::abs(energy(s, e.v_after) - e0) / e0});
  }
  drift = std::max(drift, std::abs(energy(run.x(0), run.v(0)) - e0) / e0);
  INFO(log.events.size() << " impacts, max |E - E0|/E0 = " << drift << ", " << taylor.steps() << " steps");
  CHECK(drift < 1e-12);
  WARN("energy: " << log.events.size() << " elastic impacts over t = 1500, max |E - E0|/E0 = " << drift << ", "
                  << taylor.steps() << " steps");
}

TEST_CASE("a scene with forces runs on the Taylor engine, a linear one stays where it was", "[taylor][scene]") {
  const vibro::io::Scene duffing =
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/duffing_impact.yaml").build();
  CHECK(duffing.engine == vibro::io::EngineKind::taylor);
  CHECK_THAT(duffing.engine_reason, Catch::Contains("forces"));
  REQUIRE(duffing.forces.forces.size() == 1);
  CHECK(duffing.forces.forces[0] == "(-(beta)*x0^3)");
  REQUIRE(duffing.forces.parameters.size() == 1);
  CHECK(duffing.forces.parameters[0].second == 0.5);
  const std::unique_ptr<vibro::Engine> engine = vibro::io::make_engine(duffing);
  CHECK(dynamic_cast<vibro::TaylorEngine*>(engine.get()) != nullptr);

  const std::string fig2 = std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml";
  const vibro::io::Scene linear = vibro::io::SceneDocument::load(fig2).build();
  CHECK(linear.engine == vibro::io::EngineKind::dense);
  CHECK(linear.forces.forces.empty());
  const vibro::io::Scene forced =
      vibro::io::SceneDocument::parse(vibro::io::SceneDocument::load(fig2).text() + "solver: {engine: taylor}\n").build();
  CHECK(forced.engine == vibro::io::EngineKind::taylor);
  CHECK(forced.engine_reason == "solver.engine: taylor");
}

// The between shorthand: −c (x_i − x_k)³ on i and its reaction on k.
TEST_CASE("the cubic spring between two masses expands to a force and its reaction", "[taylor][scene]") {
  const std::string text = R"yaml(model:
  chain:
    masses: [1, 1]
    springs: [1]
    left_wall: {spring: 1}
stops:
  - {mass: 1, side: upper, position: 0.5, restitution: 0.7}
parameters: {c3: 0.25}
forces:
  - {cubic_spring: {between: [0, 1], coefficient: c3}}
  - {coordinate: 1, expression: "-0.1*sin(x1)"}
initial: {x: [0.1, 0]}
)yaml";
  const vibro::io::Scene s = vibro::io::SceneDocument::parse(text).build();
  REQUIRE(s.forces.forces.size() == 2);
  CHECK(s.forces.forces[0] == "(-(c3)*(x0 - x1)^3)");
  CHECK(s.forces.forces[1] == "((c3)*(x0 - x1)^3) + (-0.1*sin(x1))");
  CHECK(s.engine == vibro::io::EngineKind::taylor);
}

// Cost per forcing period (a quick timing, not a benchmark): ./vibro_tests_taylor_engine "[.report]".
TEST_CASE("cost per period of the Taylor engine against the dense engine", "[.report]") {
  auto per_period = [](vibro::Engine& e, const vibro::io::Scene& s, double periods) {
    const auto start = std::chrono::steady_clock::now();
    const vibro::RunSummary run = e.run(s.t0, s.x0, s.v0, s.t0 + periods * s.period());
    const std::chrono::duration<double> took = std::chrono::steady_clock::now() - start;
    REQUIRE(run.status == vibro::RunStatus::completed);
    return took.count() / periods * 1e6;
  };
  const std::string fig2 = std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml";
  const vibro::io::Scene linear = vibro::io::SceneDocument::load(fig2).build();
  const vibro::io::Scene linear_taylor =
      vibro::io::SceneDocument::parse(vibro::io::SceneDocument::load(fig2).text() + "solver: {engine: taylor}\n").build();
  const vibro::io::Scene duffing =
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/duffing_impact.yaml").build();
  auto dense = vibro::io::make_engine(linear);
  auto taylor = vibro::io::make_engine(linear_taylor);
  auto nonlinear = vibro::io::make_engine(duffing);
  const double a = per_period(*dense, linear, 400), b = per_period(*taylor, linear_taylor, 400),
               c = per_period(*nonlinear, duffing, 400);
  WARN("µs per forcing period: Wagg fig. 2 dense " << a << ", the same on the Taylor engine " << b
                                                    << "; duffing_impact.yaml (Taylor) " << c);
}

// Moving stops, a stop along a general normal and a drive with harmonics (what the dense engine
// takes besides fixed stops): the two-tone example with its stops replaced, forced through the
// Taylor engine, against the dense engine over 30 periods. Same tolerances and reasons as the
// seed paper's scene above (the stops' motion and the harmonics enter both as closed forms).
TEST_CASE("moving stops, a general normal and harmonics agree with the dense engine", "[taylor][engine]") {
  vibro::io::SceneDocument doc =
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/two_tone_impact.yaml");
  doc.replace("stops", "[{mass: 0, side: lower, position: -0.3, amplitude: 0.05, phase: 0.4, restitution: 0.7},"
                       " {normal: [0.6, 0.8], position: 0.15, amplitude: 0.02, restitution: 0.75}]");
  doc.replace("run", "{kind: simulate}");
  const vibro::io::Scene scene = doc.build();
  const vibro::ImpactSystem system = scene.impact_system();
  REQUIRE(!scene.forcing().harmonics.empty());
  const double T = scene.period(), t_end = 30.0 * T;
  vibro::Simulator dense(system, scene.solver);
  vibro::TaylorSimulator taylor(system, {}, scene.solver);
  vibro::EventLog de, te;
  const vibro::RunSummary a = dense.run(0.0, scene.x0, scene.v0, t_end, {&de});
  const vibro::RunSummary b = taylor.run(0.0, scene.x0, scene.v0, t_end, {&te});
  REQUIRE(a.status == vibro::RunStatus::completed);
  INFO(b.message);
  REQUIRE(b.status == vibro::RunStatus::completed);
  REQUIRE(a.impacts > 10);
  REQUIRE(de.events.size() == te.events.size());
  const double L = a.length_scale, V = a.velocity_scale;
  double dt_gap = 0.0, dt_rest = 0.0;
  for (std::size_t i = 0; i < de.events.size(); ++i) {
    REQUIRE(de.events[i].stop == te.events[i].stop);
    REQUIRE(de.events[i].kind == te.events[i].kind);
    const double dt = std::abs(de.events[i].t - te.events[i].t);
    const double speed = std::max(std::abs(de.events[i].v_before), std::abs(de.events[i].v_after));
    if (speed > 0.0) dt_gap = std::max(dt_gap, dt * speed / L);
    else dt_rest = std::max(dt_rest, dt / T);
  }
  const double dx = (a.x - b.x).cwiseAbs().maxCoeff() / L, dv = (a.v - b.v).cwiseAbs().maxCoeff() / V;
  INFO(de.events.size() << " events (" << a.impacts << " impacts, " << a.sticks << " sticks): |dt||g'|/L = " << dt_gap
                        << ", at rest |dt|/T = " << dt_rest << ", end |dx|/L = " << dx << ", |dv|/V = " << dv);
  CHECK(dt_gap < 1e-12);
  CHECK(dt_rest < 1e-13);
  CHECK(dx < 1e-12);
  CHECK(dv < 1e-12);
  WARN("moving and general stops, harmonics: " << de.events.size() << " events, |dt||g'|/L = " << dt_gap
                                               << ", end |dx|/L = " << dx << ", |dv|/V = " << dv);
}

namespace {

/// The dense and the Taylor engine on one scene over `periods` forcing periods: the largest event
/// time difference weighted by the speed (|dt||g'|/L), at rest (|dt|/T), and the end state's.
struct EngineGap {
  vibro::RunSummary dense, taylor;
  std::size_t events = 0, engagements = 0;
  double dt_gap = 0.0, dt_rest = 0.0, dx = 0.0, dv = 0.0;
  double dforce = 0.0;  ///< max |ΔN|/(k_s L + c_s V) over the compliant stops' engagements (their recorded force)
};

EngineGap dense_against_taylor(const vibro::io::Scene& scene, double periods) {
  const vibro::ImpactSystem system = scene.impact_system();
  const double T = scene.period(), t_end = periods * T;
  vibro::Simulator dense(system, scene.solver);
  vibro::TaylorSimulator taylor(system, {}, scene.solver);
  vibro::EventLog de, te;
  EngineGap g;
  g.dense = dense.run(0.0, scene.x0, scene.v0, t_end, {&de});
  g.taylor = taylor.run(0.0, scene.x0, scene.v0, t_end, {&te});
  REQUIRE(g.dense.status == vibro::RunStatus::completed);
  INFO(g.taylor.message);
  REQUIRE(g.taylor.status == vibro::RunStatus::completed);
  REQUIRE(de.events.size() == te.events.size());
  g.events = de.events.size();
  const double L = g.dense.length_scale, V = g.dense.velocity_scale;
  for (std::size_t i = 0; i < de.events.size(); ++i) {
    REQUIRE(de.events[i].stop == te.events[i].stop);
    REQUIRE(de.events[i].kind == te.events[i].kind);
    const double dt = std::abs(de.events[i].t - te.events[i].t);
    const double speed = std::max(std::abs(de.events[i].v_before), std::abs(de.events[i].v_after));
    if (speed > 0.0) g.dt_gap = std::max(g.dt_gap, dt * speed / L);
    else g.dt_rest = std::max(g.dt_rest, dt / T);
    if (de.events[i].kind == vibro::EventKind::engage) {
      ++g.engagements;
      const vibro::Stop& st = system.stops()[static_cast<std::size_t>(de.events[i].stop)];
      const double scale = st.stiffness * L + st.damping * V + st.preload;
      g.dforce = std::max(g.dforce, std::abs(de.events[i].force - te.events[i].force) / scale);
    }
  }
  g.dx = (g.dense.x - g.taylor.x).cwiseAbs().maxCoeff() / L;
  g.dv = (g.dense.v - g.taylor.v).cwiseAbs().maxCoeff() / V;
  return g;
}

}  // namespace

// Stops moving with several harmonics (orders 2, 3 and 5 besides the first): the seed paper's
// sticking orbit with both stops shaken, forced through the Taylor engine, against the dense
// engine over 20 periods, with impacts, chatter and sticking on the moving stops (the held
// stops' p̈ enters the constrained series, the impact law the stop's velocity). Same tolerances
// and reasons as the first test above: the stops' motion enters both engines in closed form.
TEST_CASE("stops moving with several harmonics agree with the dense engine", "[taylor][engine]") {
  vibro::io::SceneDocument doc =
      vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/wagg2004/fig2_sticking_orbit.yaml");
  doc.replace("stops", "[{mass: 0, side: lower, position: -0.3, restitution: 0.7, amplitude: 0.01, phase: 0.3,"
                       "   harmonics: [{order: 2, cosine: 0.01, sine: 0.005}, {order: 3, sine: -0.004}]},"
                       " {mass: 1, side: upper, position: 0.1, restitution: 0.7, harmonics: [{order: 5, cosine: 0.003}]}]");
  doc.replace("run", "{kind: simulate}");
  const vibro::io::Scene scene = doc.build();
  REQUIRE(scene.stops[0].harmonics.size() == 2);
  const EngineGap g = dense_against_taylor(scene, 20.0);
  REQUIRE(g.dense.impacts > 10);
  REQUIRE(g.dense.sticks > 0);
  REQUIRE(g.dense.chatters > 0);
  INFO(g.events << " events (" << g.dense.impacts << " impacts, " << g.dense.chatters << " chatters, " << g.dense.sticks
                << " sticks): |dt||g'|/L = " << g.dt_gap << ", at rest |dt|/T = " << g.dt_rest << ", end |dx|/L = " << g.dx
                << ", |dv|/V = " << g.dv);
  CHECK(g.dt_gap < 1e-12);
  CHECK(g.dt_rest < 1e-13);
  CHECK(g.dx < 1e-12);
  CHECK(g.dv < 1e-12);
}

// A base moving with three harmonics (orders 1, 2, 3) in the absolute frame, one stop attached to
// it (so it moves with all three) and one fixed: the scene as written, forced through the Taylor
// engine, against the dense engine over 20 periods, with the tolerances above.
TEST_CASE("a stop riding a base of several harmonics agrees with the dense engine", "[taylor][engine]") {
  const std::string text =
      "model:\n  chain: {masses: [1, 1], springs: [1], dampers: [0.1], left_wall: {spring: 1, damper: 0.1},"
      " right_wall: {spring: 0.5, damper: 0.05}}\n"
      "forcing: {frequency: 0.3, cosine: [0.3, 0]}\n"
      "base:\n  displacement: {cosine: 0.05, harmonics: [{order: 2, cosine: 0.02}, {order: 3, sine: 0.01}]}\n"
      "  frame: absolute\n"
      "stops:\n  - {mass: 0, side: lower, position: -0.3, restitution: 0.7, name: s1}\n"
      "  - {mass: 1, side: upper, position: 0.1, restitution: 0.7, name: s2, attached: base}\n"
      "initial: {x: [0, 0], v: [0, 0]}\n"
      "solver: {engine: taylor}\n";
  const vibro::io::Scene scene = vibro::io::SceneDocument::parse(text).build();
  CHECK(scene.engine == vibro::io::EngineKind::taylor);
  REQUIRE(scene.stops[1].harmonics.size() == 2);
  const EngineGap g = dense_against_taylor(scene, 20.0);
  REQUIRE(g.dense.impacts > 10);
  INFO(g.events << " events (" << g.dense.impacts << " impacts, " << g.dense.sticks << " sticks): |dt||g'|/L = "
                << g.dt_gap << ", at rest |dt|/T = " << g.dt_rest << ", end |dx|/L = " << g.dx << ", |dv|/V = " << g.dv);
  CHECK(g.dt_gap < 1e-12);
  CHECK(g.dt_rest < 1e-13);
  CHECK(g.dx < 1e-12);
  CHECK(g.dv < 1e-12);
}

// The forced Duffing impact oscillator of the reference test above with its stop moving at
// orders 1, 2 and 4: every impact against the long-double reference, which bisects the gap
// x − p(t) with p(t) summed from its own cosines and sines and applies Newton's law to the
// velocity relative to the stop (tests/support/reference_duffing_impact.hpp). Impact times,
// relative approach speeds and the end state to 1e-12, as there and for the same reasons.
TEST_CASE("a Duffing impact oscillator on a stop moving with several harmonics agrees with the reference",
          "[taylor][engine]") {
  const double a1 = 0.03, b1 = -0.02, a2 = 0.02, b4 = 0.005;  // p(t) = s + a1 cos Ωt + b1 sin Ωt + a2 cos 2Ωt + b4 sin 4Ωt
  // a cos(Ωt + φ) = a1 cos Ωt + b1 sin Ωt with a = hypot(a1, b1), φ = atan2(−b1, a1).
  const vibro::Stop stop = vibro::Stop::upper(0, kDuffingStop, 0.8)
                               .moving(std::hypot(a1, b1), std::atan2(-b1, a1))
                               .with_harmonics({{.order = 2, .cosine = a2}, {.order = 4, .sine = b4}});
  const ReferenceGap g = duffing_against_reference(stop, {{1, a1, b1}, {2, a2, 0.0L}, {4, 0.0L, b4}});
  WARN("Duffing on a stop of three harmonics vs reference: " << g.impacts << " impacts, max |dt|/T = " << g.dt
                                                             << ", |du| = " << g.du << ", end |dx|/s = " << g.dx
                                                             << ", |dv| = " << g.dv << ", " << g.steps << " steps");
}

// ---- compliant stops (stops.hpp, Law::compliant) ------------------------------------------

// Compliant stops forced through the Taylor engine against the exact dense engine: the
// soft-impact example (one mass, a spring-dashpot stop, c_s > 0: the vector field jumps by
// c_s g' at each switch), and two masses with a two-stage stop (a preloaded spring-dashpot with a
// rigid stop behind it, which takes impacts and holds the mass while the spring is engaged), a
// compliant stop between the masses and one along a general normal. Both engines place a switch
// at the gap's zero as they place an impact, and their flows carry rounding only, so the
// tolerances and their reasons are the first test's: event times through the gap they imply
// (|dt||g'|/L) and the states to 1e-12, events at rest to 1e-13 T. The force recorded at an
// engagement, N = k_s g + c_s g' + F_p, differs by k_s Δg + c_s Δg' with Δg/L and Δg'/V of the
// states' size: 1e-12 of k_s L + c_s V + F_p (|dN| below).
TEST_CASE("compliant stops through the Taylor engine agree with the dense engine", "[taylor][engine][compliant]") {
  SECTION("the soft-impact oscillator (c_s > 0)") {
    vibro::io::SceneDocument doc =
        vibro::io::SceneDocument::load(std::string(VIBRO_EXPERIMENTS) + "/examples/soft_impact.yaml");
    doc.replace("run", "{kind: simulate}");
    const EngineGap g = dense_against_taylor(doc.build(), 30.0);
    INFO(g.events << " events (" << g.engagements << " engagements): |dt||g'|/L = " << g.dt_gap << ", end |dx|/L = "
                  << g.dx << ", |dv|/V = " << g.dv << ", |dN| = " << g.dforce);
    REQUIRE(g.engagements >= 10);
    CHECK(g.dt_gap < 1e-12);
    CHECK(g.dx < 1e-12);
    CHECK(g.dv < 1e-12);
    CHECK(g.dforce < 1e-12);
    WARN("soft impact, Taylor vs dense: " << g.events << " events, |dt||g'|/L = " << g.dt_gap << ", end |dx|/L = "
                                          << g.dx << ", |dv|/V = " << g.dv << ", |dN| = " << g.dforce);
  }
  SECTION("a two-stage stop, a stop between masses and one along a general normal") {
    const std::string text = R"yaml(model:
  chain:
    masses: [1, 1.5]
    springs: [2]
    dampers: [0.02]
    left_wall: {spring: 1, damper: 0.02}
forcing: {frequency: 0.8, cosine: [0.6, 0]}
stops:
  - {mass: 0, side: upper, position: 0.5, law: compliant, stiffness: 15, damping: 0.2, preload: 0.1}
  - {mass: 0, side: upper, position: 0.6, restitution: 0.5}
  - {between: [1, 0], gap: 0.4, law: compliant, stiffness: 10, damping: 0.05}
  - {normal: [0.5, 1], position: 0.7, law: compliant, stiffness: 8}
initial: {x: [0, 0], v: [0, 0]}
)yaml";
    const EngineGap g = dense_against_taylor(vibro::io::SceneDocument::parse(text).build(), 30.0);
    INFO(g.events << " events (" << g.engagements << " engagements, " << g.dense.impacts << " impacts, "
                  << g.dense.sticks << " sticks): |dt||g'|/L = " << g.dt_gap << ", at rest |dt|/T = " << g.dt_rest
                  << ", end |dx|/L = " << g.dx << ", |dv|/V = " << g.dv << ", |dN| = " << g.dforce);
    REQUIRE(g.engagements >= 10);
    REQUIRE(g.dense.impacts >= 5);
    CHECK(g.dt_gap < 1e-12);
    CHECK(g.dt_rest < 1e-13);
    CHECK(g.dx < 1e-12);
    CHECK(g.dv < 1e-12);
    CHECK(g.dforce < 1e-12);
    WARN("two-stage, between, normal compliant stops, Taylor vs dense: "
         << g.events << " events (" << g.engagements << " engagements, " << g.dense.impacts << " impacts, "
         << g.dense.sticks << " sticks), |dt||g'|/L = " << g.dt_gap << ", end |dx|/L = " << g.dx << ", |dv|/V = "
         << g.dv);
  }
}

// A forced, damped Duffing oscillator (β = 0.5) against a preloaded spring-dashpot stop at 0.6
// (k_s = 20, c_s = 0.3, F_p = 0.2) over 10 forcing periods, against the independent long-double
// RK8 reference that writes the piecewise-linear contact force out and bisects its switches
// (tests/support/reference_compliant_duffing.hpp, ~1e-16 of the state). Both start at rest. The
// Taylor engine carries rounding only, so the switch times and velocities and the end state are
// held to 1e-12 of the scales (T, the speed scale 1, the stop's position), as the rigid stop's
// test above; a missed switch, a switch at the wrong root or a wrong contact force (a spring
// without its dashpot or preload) differ by far more.
TEST_CASE("a Duffing oscillator with a compliant stop agrees with an independent long-double reference",
          "[taylor][engine][compliant]") {
  const double c = 0.05, beta = 0.5, A = 0.8, omega = 1.3, s = 0.6, ks = 20.0, cs = 0.3, fp = 0.2;
  const double T = 2.0 * std::acos(-1.0) / omega, t_end = 10.0 * T;
  vibro::EventLog log;
  long steps = 0;
  const vibro::RunSummary run =
      taylor_duffing(c, beta, A, omega, vibro::Stop::upper(0, s, 1.0).compliant(ks, cs, fp), t_end, log, &steps);
  INFO(run.message);
  REQUIRE(run.status == vibro::RunStatus::completed);

  vibro::test::ReferenceCompliantDuffing ref;
  ref.c = c;
  ref.beta = beta;
  ref.amplitude = A;
  ref.omega = omega;
  ref.stop = s;
  ref.k_s = ks;
  ref.c_s = cs;
  ref.preload = fp;
  ref.run(0.0L, 0.0L, 0.0L, t_end);
  REQUIRE(ref.switches.size() >= 10);
  REQUIRE(log.events.size() == ref.switches.size());
  double dt = 0.0, du = 0.0;
  for (std::size_t i = 0; i < log.events.size(); ++i) {
    const vibro::Event& e = log.events[i];
    REQUIRE(e.kind == (ref.switches[i].engage ? vibro::EventKind::engage : vibro::EventKind::disengage));
    dt = std::max(dt, std::abs(e.t - static_cast<double>(ref.switches[i].t)) / T);
    du = std::max(du, std::abs(e.v_before - static_cast<double>(ref.switches[i].v)));
    // The force recorded at an engagement is the law's at the switch, c_s g' + F_p (g = 0).
    if (e.kind == vibro::EventKind::engage) CHECK(std::abs(e.force - (cs * e.v_before + fp)) < 1e-12);
  }
  const double dx = std::abs(run.x(0) - static_cast<double>(ref.x)) / s, dv = std::abs(run.v(0) - static_cast<double>(ref.v));
  INFO(log.events.size() << " switches: max |dt|/T = " << dt << ", |du| = " << du << "; end |dx|/s = " << dx
                         << ", |dv| = " << dv << "; " << steps << " Taylor steps");
  CHECK(dt < 1e-12);
  CHECK(du < 1e-12);
  CHECK(dx < 1e-12);
  CHECK(dv < 1e-12);
  WARN("compliant Duffing vs reference: " << log.events.size() << " switches, max |dt|/T = " << dt << ", |du| = " << du
                                          << ", end |dx|/s = " << dx << ", |dv| = " << dv);
}

// A conservative Duffing oscillator (no damping, no drive, β = 1) against an undamped compliant
// stop at 0.5 (k_s = 20, c_s = 0), without and with a preload F_p = 0.3, from x0 = 0, v0 = 1.2:
// the stop's potential k_s g²/2 + F_p g (g > 0) is continuous at g = 0, so the energy
// E = v²/2 + x²/2 + x⁴/4 (+ the stop's potential while engaged) is a constant of the motion
// across every switch, and at a switch g = 0, so E there is read from the speed alone. Over
// t = 1000 (~600 switches, a few thousand steps) rounding moves E by ~ε per step and switch: the
// first bound on a sum of ~10⁴ roundings of one sign is 2e-12, 1e-12 is met by their random walk
// (~2e-14) with room; a switch placed 1e-10 off in time (the series truncated at 1e-10), or a
// missing preload, changes E by far more.
TEST_CASE("a conservative Duffing oscillator against an undamped compliant stop keeps its energy to rounding",
          "[taylor][engine][compliant]") {
  const double s = 0.5, ks = 20.0;
  for (const double fp : {0.0, 0.3}) {
    const vibro::LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Zero(1, 1),
                                  Eigen::MatrixXd::Identity(1, 1), vibro::HarmonicForcing::zero(1));
    const vibro::ImpactSystem system(sys, {vibro::Stop::upper(0, s, 1.0).compliant(ks, 0.0, fp)});
    vibro::NonlinearForces forces;
    forces.forces = {"-x0^3"};
    vibro::SimulatorOptions options;
    options.max_events = 1000000;
    vibro::TaylorSimulator taylor(system, forces, options);
    vibro::EventLog log;
    const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(1), v0 = Eigen::VectorXd::Constant(1, 1.2);
    auto energy = [&](double x, double v) {
      const double g = x - s;
      return 0.5 * v * v + 0.5 * x * x + 0.25 * x * x * x * x + (g > 0.0 ? 0.5 * ks * g * g + fp * g : 0.0);
    };
    const double e0 = energy(0.0, 1.2);
    const vibro::RunSummary run = taylor.run(0.0, x0, v0, 1000.0, {&log});
    INFO("F_p = " << fp << ": " << run.message);
    REQUIRE(run.status == vibro::RunStatus::completed);
    REQUIRE(log.events.size() >= 300);
    double drift = 0.0;
    for (const vibro::Event& e : log.events) {
      REQUIRE((e.kind == vibro::EventKind::engage || e.kind == vibro::EventKind::disengage));
      drift = std::max(drift, std::abs(energy(s, e.v_before) - e0) / e0);
    }
    drift = std::max(drift, std::abs(energy(run.x(0), run.v(0)) - e0) / e0);
    INFO(log.events.size() << " switches, max |E - E0|/E0 = " << drift << ", " << taylor.steps() << " steps");
    CHECK(drift < 1e-12);
    WARN("energy against a compliant stop, F_p = " << fp << ": " << log.events.size()
                                                    << " switches over t = 1000, max |E - E0|/E0 = " << drift << ", "
                                                    << taylor.steps() << " steps");
  }
}
