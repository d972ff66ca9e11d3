// Base (support) excitation (base_motion.hpp): the drive it adds against the closed-form
// transmissibility of a mass on a shaken wall, in both frames; the two frames against each
// other on an impacting chain with a stop on the base and a stop in the laboratory, for a base
// of one harmonic and of two (the moving stops then move with two harmonics of their own).
#include "vibro/base_motion.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "vibro/stops.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::BaseExcitation;
using vibro::BaseFrame;
using vibro::ImpactSystem;
using vibro::LinearSystem;
using vibro::RunStatus;
using vibro::Simulator;
using vibro::SimulatorOptions;
using vibro::Stop;
using Catch::Matchers::Contains;

/// The base of a system: ι, K ι, C ι, M ι.
BaseExcitation base_of(const MatrixXd& M, const MatrixXd& C, const MatrixXd& K, const VectorXd& iota,
                       std::vector<vibro::BaseHarmonic> xb, BaseFrame frame) {
  return {std::move(xb), iota, K * iota, C * iota, M * iota, frame};
}

struct Traced {
  vibro::RunSummary summary;
  vibro::EventLog log;
  vibro::Samples samples;
};

Traced run(const ImpactSystem& s, const VectorXd& x0, const VectorXd& v0, double t_end, std::vector<double> times,
           double length_scale) {
  SimulatorOptions o;
  o.length_scale = length_scale;  // the same tolerances in both frames
  Simulator sim(s, o);
  Traced r{{}, {}, vibro::Samples(std::move(times))};
  r.summary = sim.run(0.0, x0, v0, t_end, {&r.log, &r.samples});
  return r;
}

}  // namespace

// One mass m on a wall spring k and dashpot c, the wall moving as x_b = Re(X_b e^{iωt}) for
// each harmonic: the steady state is X = (k + iωc) X_b / (k − mω² + iωc) in absolute
// coordinates and Y = mω² X_b / (k − mω² + iωc) = X − X_b in relative ones (the textbook
// transmissibility of a base-excited oscillator), with X_b = a − i b for a cos ωt + b sin ωt.
// After 60 decay times (e^{−60} ≈ 1e-26 of the start remains) the run must be this steady state
// to rounding: 1e-13 of the amplitude.
TEST_CASE("a mass on a shaken wall moves as the closed-form transmissibility, in both frames", "[base]") {
  const double m = 1.3, k = 2.0, c = 0.25, Omega = 0.9;
  const MatrixXd M = MatrixXd::Constant(1, 1, m), C = MatrixXd::Constant(1, 1, c), K = MatrixXd::Constant(1, 1, k);
  const std::vector<vibro::BaseHarmonic> xb{{1, 0.2, -0.05}, {2, 0.03, 0.04}, {3, 0.0, 0.01}};
  const double decay = c / (2.0 * m);
  const double t_end = 60.0 / decay;
  std::vector<double> times;
  for (int i = 0; i <= 40; ++i) times.push_back(t_end - 10.0 + 10.0 * i / 40.0);
  for (BaseFrame frame : {BaseFrame::absolute, BaseFrame::relative}) {
    const BaseExcitation b = base_of(M, C, K, VectorXd::Ones(1), xb, frame);
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, Omega);
    vibro::add_base_forcing(f, b);
    REQUIRE(f.harmonics.size() == 2);
    const ImpactSystem s(LinearSystem(M, C, K, f), {});
    const Traced r = run(s, VectorXd::Zero(1), VectorXd::Zero(1), t_end, times, 1.0);
    REQUIRE(r.summary.status == RunStatus::completed);
    double worst = 0.0, size = 0.0;
    for (std::size_t i = 0; i < times.size(); ++i) {
      const double t = times[i];
      std::complex<double> x = 0.0;
      for (const vibro::BaseHarmonic& h : xb) {
        const double w = h.order * Omega;
        const std::complex<double> Xb(h.cosine, -h.sine), D(k - m * w * w, w * c);
        const std::complex<double> X = frame == BaseFrame::absolute ? (k + std::complex<double>(0.0, w * c)) * Xb / D
                                                                    : m * w * w * Xb / D;
        x += X * std::exp(std::complex<double>(0.0, w * t));
      }
      worst = std::max(worst, std::abs(r.samples.x(0, static_cast<Eigen::Index>(i)) - x.real()));
      size = std::max(size, std::abs(x.real()));
    }
    INFO((frame == BaseFrame::absolute ? "absolute" : "relative") << ": max |x − closed form| = " << worst
                                                                    << ", amplitude " << size);
    CHECK(worst <= 1e-13 * size);
  }
}

// The two frames on an impacting two-mass chain between two walls: a stop on mass 1 fixed to the
// base (it rides with x_b) and a stop on mass 0 fixed in the laboratory. Absolute: the first
// moves as x_b, the second stands; relative: the first stands, the second moves as −x_b. The
// relative run mapped back, x = y + x_b 1, v = v_y + x_b' 1, must be the absolute run: same events,
// and states equal to the level of event location accumulated over the run (the metamorphic
// tests' 1e-12 L: a non-chaotic orbit keeps rounding at the 1e-13 L of the event location). The
// orbit is a stable one with impacts on both stops every period, reached from rest: a chaotic
// orbit (this chain at Ω = 0.8, say) amplifies the frames' different rounding exponentially, and
// its two runs part by 2e-11 L within 60 periods, which says nothing about the formulation.
// With a second harmonic in x_b the attached stop moves with two harmonics in the absolute
// frame and the laboratory stop with two in the relative one (minus the base's motion).
TEST_CASE("base excitation in relative coordinates, mapped back, is the absolute computation", "[base]") {
  const int harmonics = GENERATE(1, 2);
  std::vector<vibro::BaseHarmonic> xb{{1, 0.1, 0.05}};
  if (harmonics == 2) xb.push_back({2, 0.02, -0.015});
  const double Omega = 1.5;
  MatrixXd M = MatrixXd::Zero(2, 2);
  M.diagonal() << 1.0, 0.7;
  MatrixXd K(2, 2), C(2, 2);
  K << 2.0, -1.0, -1.0, 1.5;  // k_L = 1, k_01 = 1, k_R = 0.5
  C << 0.08, -0.03, -0.03, 0.05;
  const VectorXd iota = VectorXd::Ones(2);
  const std::vector<Stop> stops{Stop::lower(0, -0.25, 0.6), Stop::upper(1, 0.2, 0.8)};
  const std::vector<bool> attached{false, true};
  vibro::HarmonicForcing f0 = vibro::HarmonicForcing::zero(2, Omega);
  f0.cosine << 0.3, 0.0;

  auto build = [&](BaseFrame frame) {
    const BaseExcitation b = base_of(M, C, K, iota, xb, frame);
    vibro::HarmonicForcing f = f0;
    vibro::add_base_forcing(f, b);
    std::vector<Stop> s = stops;
    vibro::move_stops_with_base(s, attached, b);
    return std::pair{ImpactSystem(LinearSystem(M, C, K, f), s), b};
  };
  const auto [abs_sys, b] = build(BaseFrame::absolute);
  const auto [rel_sys, b_rel] = build(BaseFrame::relative);
  CHECK(abs_sys.stops()[0].amplitude == 0.0);
  CHECK(abs_sys.stops()[1].amplitude > 0.0);
  CHECK(rel_sys.stops()[0].amplitude > 0.0);
  CHECK(rel_sys.stops()[1].amplitude == 0.0);
  CHECK(abs_sys.stops()[1].harmonics.size() == xb.size() - 1);
  CHECK(rel_sys.stops()[0].harmonics.size() == xb.size() - 1);
  CHECK(abs_sys.stops()[0].harmonics.empty());
  CHECK(rel_sys.stops()[1].harmonics.empty());

  const double T = 2.0 * std::numbers::pi / Omega, periods = 60.0;
  std::vector<double> times;
  for (int i = 1; i <= 60 * 40; ++i) times.push_back(T * i / 40.0);
  const double L = 0.25;
  // Start on the attractor (200 periods from rest in the absolute frame): a transient from an
  // arbitrary state passes low-velocity impacts whose sensitivity amplifies any rounding.
  const Traced warm = run(abs_sys, VectorXd::Zero(2), VectorXd::Zero(2), 200.0 * T, {}, L);
  REQUIRE(warm.summary.status == RunStatus::completed);
  const VectorXd x0 = warm.summary.x, v0 = warm.summary.v;
  const Traced a = run(abs_sys, x0, v0, periods * T, times, L);
  const Traced r = run(rel_sys, x0 - iota * b.position(Omega, 0.0), v0 - iota * b.velocity(Omega, 0.0), periods * T,
                       times, L);
  REQUIRE(a.summary.status == RunStatus::completed);
  REQUIRE(r.summary.status == RunStatus::completed);
  int impacts[2] = {0, 0};
  for (const vibro::Event& e : a.log.events)
    if (e.kind == vibro::EventKind::impact) ++impacts[e.stop];
  CHECK(impacts[0] > 5);  // both stops are hit
  CHECK(impacts[1] > 5);
  REQUIRE(a.log.events.size() == r.log.events.size());
  double dt = 0.0, dx = 0.0, dv = 0.0;
  for (std::size_t e = 0; e < a.log.events.size(); ++e) {
    CHECK(a.log.events[e].kind == r.log.events[e].kind);
    CHECK(a.log.events[e].stop == r.log.events[e].stop);
    dt = std::max(dt, std::abs(a.log.events[e].t - r.log.events[e].t));
  }
  for (std::size_t i = 0; i < times.size(); ++i) {
    const Eigen::Index c = static_cast<Eigen::Index>(i);
    const double t = r.samples.t[i];
    dx = std::max(dx, (r.samples.x.col(c) + iota * b.position(Omega, t) - a.samples.x.col(c)).cwiseAbs().maxCoeff());
    dv = std::max(dv, (r.samples.v.col(c) + iota * b.velocity(Omega, t) - a.samples.v.col(c)).cwiseAbs().maxCoeff());
  }
  WARN("base frames, " << xb.size() << " harmonic(s): " << a.log.events.size() << " events (" << impacts[0] << " + " << impacts[1]
                       << " impacts), max |Δt| = " << dt << ", max |Δx|/L = " << dx / L
                       << ", max |Δv|/(LΩ) = " << dv / (L * Omega));
  CHECK(dx <= 1e-12 * L);
  CHECK(dv <= 1e-12 * L * Omega);
  CHECK(dt <= 1e-12 * T);
}

TEST_CASE("a stop on the base follows every harmonic of the base", "[base]") {
  const MatrixXd M = MatrixXd::Identity(2, 2), C = 0.1 * MatrixXd::Identity(2, 2);
  MatrixXd K(2, 2);
  K << 2.0, -1.0, -1.0, 1.0;
  const VectorXd iota = VectorXd::Ones(2);
  SECTION("the position moves by c_j x_b: lower, upper, between and normal stops") {
    std::vector<Stop> s{Stop::lower(0, -0.3, 0.5), Stop::upper(1, 0.3, 0.5), Stop::between(0, 1, 0.4, 0.5),
                        Stop::general(VectorXd::Constant(2, 0.5), 0.5, 0.5)};
    const BaseExcitation b = base_of(M, C, K, iota, {{1, 0.1, -0.2}}, BaseFrame::absolute);
    vibro::move_stops_with_base(s, {true, true, true, true}, b);
    // s(t) − s0 must be c_j x_b(t) (c = 1, 1, 0, 1) with the lower stop's sign −1 (s = −p).
    for (double t : {0.0, 0.7, 2.1}) {
      const double x_b = b.position(0.9, t);
      const double sign[4] = {-1.0, 1.0, 0.0, 1.0};
      for (std::size_t j = 0; j < 4; ++j) {
        const double moved = s[j].s_cos() * std::cos(0.9 * t) + s[j].s_sin() * std::sin(0.9 * t);
        CHECK(std::abs(moved - sign[j] * x_b) <= 1e-15);
      }
    }
  }
  SECTION("orders ≥ 2 become the stop's harmonics: attached in the absolute frame, fixed in the relative one") {
    const std::vector<vibro::BaseHarmonic> xb{{1, 0.1, 0.0}, {2, 0.02, -0.01}, {3, 0.0, 0.005}};
    for (BaseFrame frame : {BaseFrame::absolute, BaseFrame::relative}) {
      std::vector<Stop> s{Stop::lower(0, -0.3, 0.5), Stop::upper(1, 0.3, 0.5)};
      const BaseExcitation b = base_of(M, C, K, iota, xb, frame);
      vibro::move_stops_with_base(s, {false, true}, b);
      // The stop that moves: s[1] (attached) in the absolute frame by +x_b, s[0] (laboratory) in
      // the relative one by −x_b, a lower stop (s = −p): its canonical offset moves by +x_b.
      const std::size_t moving = frame == BaseFrame::absolute ? 1 : 0, still = 1 - moving;
      CHECK(s[still].harmonics.empty());
      CHECK(s[still].amplitude == 0.0);
      REQUIRE(s[moving].harmonics.size() == 2);
      for (double t : {0.0, 0.7, 2.1}) {
        const double moved = vibro::stop_motion(s[moving], 0.9, t, 0) - s[moving].s0();
        CHECK(std::abs(moved - b.position(0.9, t)) <= 1e-15);
        CHECK(std::abs(vibro::stop_motion(s[moving], 0.9, t, 1) - b.velocity(0.9, t)) <= 1e-15);
        CHECK(std::abs(vibro::stop_motion(s[moving], 0.9, t, 2) - b.acceleration(0.9, t)) <= 1e-15);
      }
    }
  }
  SECTION("a stop on the base with its own motion is refused") {
    std::vector<Stop> s{Stop::upper(1, 0.3, 0.5).moving(0.05, 0.0)};
    const BaseExcitation b = base_of(M, C, K, iota, {{1, 0.1, 0.0}}, BaseFrame::absolute);
    CHECK_THROWS_WITH(vibro::move_stops_with_base(s, {true}, b), Contains("stops[0]") && Contains("own amplitude"));
  }
  SECTION("validation: orders, repeats, lengths, finite values") {
    BaseExcitation b = base_of(M, C, K, iota, {{0, 0.1, 0.0}}, BaseFrame::absolute);
    CHECK_THROWS_WITH(b.validate(2), Contains("order 0"));
    b.displacement = {{2, 0.1, 0.0}, {2, 0.0, 0.1}};
    CHECK_THROWS_WITH(b.validate(2), Contains("given twice"));
    b.displacement = {{1, std::nan(""), 0.0}};
    CHECK_THROWS_WITH(b.validate(2), Contains("not finite"));
    b.displacement = {{1, 0.1, 0.0}};
    CHECK_THROWS_WITH(b.validate(3), Contains("influence vector has 2 entries, expected 3"));
  }
}
