// Stops moving with several harmonics of Ω (stops.hpp): a ball bouncing on a table shaken with
// two harmonics against the closed-form free flight, a root solve and Newton's law written here;
// the same ball carried by the table (held) and released where the table's acceleration first
// reaches −g; the validation of the harmonics and the forcing slots ImpactSystem adds.
#include "vibro/friction.hpp"
#include "vibro/friction_stops.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "vibro/stops.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::ImpactSystem;
using vibro::LinearSystem;
using vibro::Stop;
using Catch::Matchers::Contains;

/// The table p(t) = p0 + a cos(Ωt + φ) + c2 cos 2Ωt + s2 sin 2Ωt + s3 sin 3Ωt, its derivatives
/// written out here (independent of stops.cpp).
struct Table {
  double p0, a, phi, c2, s2, s3, Omega;
  double p(double t) const {
    return p0 + a * std::cos(Omega * t + phi) + c2 * std::cos(2 * Omega * t) + s2 * std::sin(2 * Omega * t) +
           s3 * std::sin(3 * Omega * t);
  }
  double dp(double t) const {
    return -a * Omega * std::sin(Omega * t + phi) - 2 * Omega * c2 * std::sin(2 * Omega * t) +
           2 * Omega * s2 * std::cos(2 * Omega * t) + 3 * Omega * s3 * std::cos(3 * Omega * t);
  }
  double ddp(double t) const {
    return -a * Omega * Omega * std::cos(Omega * t + phi) - 4 * Omega * Omega * c2 * std::cos(2 * Omega * t) -
           4 * Omega * Omega * s2 * std::sin(2 * Omega * t) - 9 * Omega * Omega * s3 * std::sin(3 * Omega * t);
  }
  Stop stop(double restitution) const {
    return Stop::lower(0, p0, restitution).moving(a, phi).with_harmonics({{2, c2, s2}, {3, 0.0, s3}});
  }
};

/// A unit mass under gravity g (no spring, no dashpot): M = 1, K = C = 0, f = −g.
LinearSystem falling(double g, double Omega) {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, Omega);
  f.constant(0) = -g;
  return LinearSystem(MatrixXd::Ones(1, 1), MatrixXd::Zero(1, 1), MatrixXd::Zero(1, 1), f);
}

/// The first t > t0 where a free flight from (t0, x0, v0) under g meets the table from above:
/// h(t) = x0 + v0 τ − g τ²/2 − p(t) scanned in steps of T/2000, then bisected to adjacent doubles.
double next_impact(const Table& tab, double g, double t0, double x0, double v0) {
  auto h = [&](double t) {
    const double tau = t - t0;
    return x0 + v0 * tau - 0.5 * g * tau * tau - tab.p(t);
  };
  const double step = 2.0 * std::numbers::pi / tab.Omega / 2000.0;
  double a = t0 + 1e-9, b = a;
  while (h(b) > 0.0) {
    a = b;
    b += step;
    REQUIRE(b < t0 + 1e3);
  }
  while (std::nextafter(a, b) < b) {
    const double m = 0.5 * (a + b);
    if (m <= a || m >= b) break;
    (h(m) > 0.0 ? a : b) = m;
  }
  return a;
}

}  // namespace

/// The ball's run: alone on the dense engine, or on the friction engine beside a second,
/// uncoupled mass on a spring that slides and sticks on a rough surface (its contact must not
/// change the ball's motion). Only the stop's events are kept.
struct BallRun {
  vibro::RunSummary summary;
  std::vector<vibro::Event> events;
  vibro::Samples samples;
};

BallRun run_ball(bool friction, double g, const Table& tab, double r, double x0, double v0, double t_end,
                 std::vector<double> times) {
  vibro::EventLog log;
  BallRun out{{}, {}, vibro::Samples(std::move(times))};
  if (!friction) {
    const ImpactSystem scene(falling(g, tab.Omega), {tab.stop(r)});
    vibro::Simulator sim(scene, vibro::SimulatorOptions{});
    out.summary = sim.run(0.0, VectorXd::Constant(1, x0), VectorXd::Constant(1, v0), t_end, {&log, &out.samples});
  } else {
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(2, tab.Omega);
    f.constant(0) = -g;
    const MatrixXd K = (Eigen::Vector2d() << 0.0, 1.0).finished().asDiagonal();
    const ImpactSystem scene(LinearSystem(MatrixXd::Identity(2, 2), MatrixXd::Zero(2, 2), K, f), {tab.stop(r)});
    vibro::FrictionStopSimulator sim(scene, {vibro::FrictionContact::on_surface(1, 1.0, 0.05, 0.04)});
    out.summary = sim.run(0.0, Eigen::Vector2d(x0, 0.2), Eigen::Vector2d(v0, 0.5), t_end, {&log, &out.samples});
  }
  for (const vibro::Event& e : log.events)
    if (e.stop == 0 && (e.kind == vibro::EventKind::impact || e.kind == vibro::EventKind::stick ||
                        e.kind == vibro::EventKind::release || e.kind == vibro::EventKind::chatter_limit))
      out.events.push_back(e);
  return out;
}

// A ball (unit mass, gravity g = 1) on a table moving with three harmonics, restitution 0.7. From
// each impact the simulator logs, the test restarts an exact free flight (x = p(t_i), v =
// p'(t_i) − g'⁺ with the logged g'⁺) and solves for the next impact itself: its time, approach
// speed g'⁻ = p'(t) − v⁻ and rebound g'⁺ = −r g'⁻ must be the simulator's. Restarting at each
// impact keeps the comparison local (the bouncing ball is chaotic: two exact computations part
// exponentially over many impacts). 1e-12: both sides are exact to rounding; the impact time's
// rounding is ε|h|/|h'| with |h'| the approach speed ≥ 0.2 here, so 1e-12 leaves three decades.
// Both on the dense engine and on the friction engine (beside an uncoupled frictional mass).
TEST_CASE("a ball on a table shaken with three harmonics bounces as the closed form says", "[base][stop harmonics]") {
  const bool friction = GENERATE(false, true);
  INFO((friction ? "friction engine" : "dense engine"));
  const double g = 1.0, r = 0.7;
  const Table tab{0.0, 0.6, 0.4, 0.25, -0.1, 0.05, 1.3};
  REQUIRE(ImpactSystem(falling(g, 1.3), {tab.stop(r)}).system().forcing().harmonics.size() == 2);  // orders 2, 3
  const BallRun run = run_ball(friction, g, tab, r, 1.5, 0.0, 80.0, {});
  REQUIRE(run.summary.status == vibro::RunStatus::completed);
  REQUIRE(run.events.size() >= 10);
  double t0 = 0.0, x0 = 1.5, v0 = 0.0, worst_t = 0.0, worst_v = 0.0, slowest = 1e300;
  for (std::size_t i = 0; i < 10; ++i) {
    const vibro::Event& e = run.events[i];
    REQUIRE(e.kind == vibro::EventKind::impact);
    const double t = next_impact(tab, g, t0, x0, v0);
    const double v_minus = v0 - g * (t - t0), approach = tab.dp(t) - v_minus;  // g'⁻ of g = p − x
    worst_t = std::max(worst_t, std::abs(e.t - t));
    worst_v = std::max({worst_v, std::abs(e.v_before - approach), std::abs(e.v_after + r * approach)});
    slowest = std::min(slowest, approach);
    t0 = e.t;
    x0 = tab.p(e.t);
    v0 = tab.dp(e.t) - e.v_after;
  }
  WARN((friction ? "friction" : "dense") << " engine: max |Δt| = " << worst_t << ", max |Δg'| = " << worst_v << ", slowest approach " << slowest);
  CHECK(slowest > 0.2);
  CHECK(worst_t <= 1e-12);
  CHECK(worst_v <= 1e-12);
}

// A table shaken so that its downward acceleration stays below g until t ≈ 3.19: the
// ball placed on it at rest relative to it is held (the acceleration LCP with the stop's exact
// s''), rides with it, x = p(t) and v = p'(t) to rounding, and leaves it where p''(t) first
// reaches −g (the contact force m (g + p'') vanishes there), located by bisection here.
// 1e-12: the held motion is the reduced flow of an exact generator (rounding ~1e-15 of |p|);
// the release time's rounding is ε/|d(g + p'')/dt| ≈ 1e-15 here.
TEST_CASE("a ball held by a table shaken with harmonics rides with it and leaves where p'' = −g", "[base][stop harmonics]") {
  const bool friction = GENERATE(false, true);
  INFO((friction ? "friction engine" : "dense engine"));
  const double g = 1.0;
  const Table tab{0.1, 0.5, 2.5, 0.08, 0.1, 0.02, 1.1};  // g + p'' > 0 until t ≈ 3.19
  double t_release = 0.0;
  {
    double a = 0.0;
    while (g + tab.ddp(a + 1e-3) > 0.0) a += 1e-3;
    double b = a + 1e-3;
    while (std::nextafter(a, b) < b) {
      const double m = 0.5 * (a + b);
      if (m <= a || m >= b) break;
      (g + tab.ddp(m) > 0.0 ? a : b) = m;
    }
    t_release = a;
  }
  REQUIRE(t_release > 3.0);
  std::vector<double> times;
  for (int i = 1; i <= 40; ++i) times.push_back(t_release * i / 41.0);
  const BallRun run = run_ball(friction, g, tab, 0.5, tab.p(0.0), tab.dp(0.0), t_release + 0.05, times);
  REQUIRE(run.summary.status == vibro::RunStatus::completed);
  const vibro::Samples& samples = run.samples;
  double dx = 0.0, dv = 0.0;
  for (std::size_t i = 0; i < times.size(); ++i) {
    dx = std::max(dx, std::abs(samples.x(0, static_cast<Eigen::Index>(i)) - tab.p(times[i])));
    dv = std::max(dv, std::abs(samples.v(0, static_cast<Eigen::Index>(i)) - tab.dp(times[i])));
  }
  WARN((friction ? "friction" : "dense") << " engine, held: max |x − p| = " << dx << ", max |v − p'| = " << dv);
  CHECK(dx <= 1e-12);
  CHECK(dv <= 1e-12);
  const vibro::Event* release = nullptr;
  for (const vibro::Event& e : run.events)
    if (e.kind == vibro::EventKind::release && !release) release = &e;
  REQUIRE(release != nullptr);
  WARN("release at " << release->t << ", closed form " << t_release);
  CHECK(std::abs(release->t - t_release) <= 1e-12);
}

TEST_CASE("stop harmonics: validation, forcing slots, bounds of the motion", "[base][stop harmonics]") {
  const LinearSystem sys = falling(1.0, 0.8);
  auto refused = [&](const Stop& s) {
    try {
      ImpactSystem scene(sys, {s});
    } catch (const vibro::InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const Stop base = Stop::lower(0, 0.0, 0.5);
  CHECK_THAT(refused(base.with_harmonics({{1, 0.1, 0.0}})), Contains("stops[0]") && Contains("order 1"));
  CHECK_THAT(refused(base.with_harmonics({{0, 0.1, 0.0}})), Contains("order 0"));
  CHECK_THAT(refused(base.with_harmonics({{2, 0.1, 0.0}, {2, 0.0, 0.1}})), Contains("given twice"));
  CHECK_THAT(refused(base.with_harmonics({{2, std::nan(""), 0.0}})), Contains("must be finite"));
  CHECK_THAT(refused(base.with_harmonics({{3, 0.0, std::numeric_limits<double>::infinity()}})), Contains("must be finite"));
  const LinearSystem still = falling(1.0, 0.0);
  CHECK_THROWS_WITH(ImpactSystem(still, {base.with_harmonics({{2, 0.1, 0.0}})}), Contains("forcing frequency > 0"));

  // A drive that has order 3 keeps it, order 2 is appended as zero; the motion's bound.
  vibro::HarmonicForcing f = sys.forcing();
  f.harmonics.push_back({3, VectorXd::Constant(1, 0.2), VectorXd::Zero(1)});
  const ImpactSystem scene(LinearSystem(sys.mass(), sys.damping(), sys.stiffness(), f),
                           {base.moving(0.1, 0.0).with_harmonics({{2, 0.03, 0.04}, {3, 0.0, 0.01}})});
  const vibro::HarmonicForcing& g = scene.system().forcing();
  REQUIRE(g.harmonics.size() == 2);
  CHECK(g.harmonics[0].order == 3);
  CHECK(g.harmonics[0].cosine(0) == 0.2);
  CHECK(g.harmonics[1].order == 2);
  CHECK(g.harmonics[1].cosine.isZero(0.0));
  CHECK(scene.stops()[0].motion_extent() == 0.1 + 0.05 + 0.01);
  // Opposite stops whose summed harmonics peak beyond the clearance are refused; moving
  // together (the same harmonics) they keep it.
  // Here 0.2 + 0.25 cos 2Ωt above −0.2 − 0.25 cos 2Ωt: clearance 0.4 + 0.5 cos 2Ωt, least −0.1.
  const Stop up = Stop::upper(0, 0.2, 0.5).with_harmonics({{2, 0.25, 0.0}});
  const Stop down = Stop::lower(0, -0.2, 0.5).with_harmonics({{2, -0.25, 0.0}});
  CHECK_THROWS_WITH(ImpactSystem(sys, {up, down}), Contains("leave no room"));
  CHECK_NOTHROW(ImpactSystem(sys, {up, Stop::lower(0, -0.2, 0.5).with_harmonics({{2, 0.25, 0.0}})}));
  // stop_motion and its derivatives against the closed form (Table).
  const Table tab{0.0, 0.6, 0.4, 0.25, -0.1, 0.05, 1.3};
  const Stop st = tab.stop(0.5);
  for (double t : {0.0, 0.37, 2.9}) {
    // s = −p for a lower stop.
    CHECK(std::abs(vibro::stop_motion(st, 1.3, t, 0) + tab.p(t)) <= 1e-15);
    CHECK(std::abs(vibro::stop_motion(st, 1.3, t, 1) + tab.dp(t)) <= 1e-14);
    CHECK(std::abs(vibro::stop_motion(st, 1.3, t, 2) + tab.ddp(t)) <= 1e-14);
  }
}

TEST_CASE("stop harmonics: opposite stops are refused exactly when their clearance reaches zero",
          "[base][stop harmonics]") {
  // An upper stop at 0.1 moving with 0.12 cos Ωt + 0.12 cos 2Ωt above a fixed lower stop at −d:
  // the clearance 0.1 + d + 0.12 (cos θ + cos 2θ) = 0.1 + d + 0.12 (2c² + c − 1), c = cos θ, is
  // least at c = −1/4, where it is 0.1 + d − 0.135 (written out here). Summing the harmonics'
  // amplitudes would bound it by 0.1 + d − 0.24 and refuse every d ≤ 0.14.
  const LinearSystem sys = falling(1.0, 0.8);
  const Stop up = Stop::upper(0, 0.1, 0.5).moving(0.12, 0.0).with_harmonics({{2, 0.12, 0.0}});
  auto outcome = [&](const Stop& a, const Stop& b) {
    try {
      ImpactSystem scene(sys, {a, b});
    } catch (const vibro::InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  CHECK(outcome(up, Stop::lower(0, -0.1, 0.5)) == "accepted");  // least 0.065, the summed bound −0.04
  CHECK_THAT(outcome(up, Stop::lower(0, 0.0, 0.5)),
             Contains("leave no room") && Contains("least clearance while they move -0.034999"));
  // Within 1e-9 of touching, on either side (the search's certificate is M₂h²/8 + rounding).
  CHECK(outcome(up, Stop::lower(0, -(0.035 + 1e-9), 0.5)) == "accepted");
  CHECK_THAT(outcome(up, Stop::lower(0, -(0.035 - 1e-9), 0.5)), Contains("leave no room"));
  // The same through a general normal n = 2 (compared on unit normals: the stop's values halve).
  const Stop general = Stop::general(VectorXd::Constant(1, 2.0), 0.2, 0.5).moving(0.24, 0.0).with_harmonics({{2, 0.24, 0.0}});
  CHECK(outcome(general, Stop::lower(0, -0.1, 0.5)) == "accepted");
  CHECK_THAT(outcome(general, Stop::lower(0, 0.0, 0.5)), Contains("leave no room"));
  // With sines and a third order: the upper stop at 0.3 − 0.1 sin Ωt + 0.15 sin 2Ωt + 0.12 cos 3Ωt
  // (its summed amplitudes reach −0.07) above a fixed lower stop at q: room exactly while q is
  // below the upper stop's least position, found by a fine scan here (10⁶ points; the slope is
  // ≤ 0.76, so the scan is within 2.4e-6 of it).
  const Stop wavy = Stop::upper(0, 0.3, 0.5).moving(0.1, std::numbers::pi / 2).with_harmonics({{2, 0.0, 0.15}, {3, 0.12, 0.0}});
  double least = 1.0;
  for (int i = 0; i < 1000000; ++i) {
    const double th = 2.0 * std::numbers::pi * i / 1e6;
    least = std::min(least, 0.3 + 0.1 * std::cos(th + std::numbers::pi / 2) + 0.15 * std::sin(2 * th) + 0.12 * std::cos(3 * th));
  }
  REQUIRE(least > 0.0);
  CHECK(outcome(wavy, Stop::lower(0, least - 1e-5, 0.5)) == "accepted");
  CHECK_THAT(outcome(wavy, Stop::lower(0, least + 1e-5, 0.5)), Contains("leave no room"));
}

TEST_CASE("stop harmonics: the run's velocity scale includes a stop's harmonics' speeds", "[base][stop harmonics]") {
  // V = L Ω without higher harmonics; a stop moving with 0.02 cos 5Ωt reaches the speed 5 Ω 0.02
  // (+ Ω · its first harmonic's amplitude 0.01), above L Ω for L = 0.03 (its extent).
  const double W = 0.8;
  const LinearSystem sys = falling(0.0, W);
  const VectorXd x0 = VectorXd::Constant(1, 0.01), v0 = VectorXd::Zero(1);
  const Stop plain = Stop::lower(0, 0.0, 0.5).moving(0.01, 0.0);
  const ImpactSystem slow(sys, {plain});
  vibro::Simulator a(slow);
  const auto sa = a.run(0.0, x0, v0, 1.0);
  CHECK(sa.velocity_scale == sa.length_scale * W);
  const ImpactSystem fast(sys, {plain.with_harmonics({{5, 0.02, 0.0}})});
  vibro::Simulator b(fast);
  const auto sb = b.run(0.0, x0 + VectorXd::Constant(1, 0.03), v0, 1.0);
  CHECK(sb.length_scale == 0.04);  // |x0|
  CHECK(std::abs(sb.velocity_scale - W * (0.01 + 5 * 0.02)) <= 1e-15);
}
