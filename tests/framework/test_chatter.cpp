/// \file test_chatter.cpp
/// Order of the chatter rules (vibro::ChatterRule, simulator.hpp) against their threshold.
///
///  1. A ball on a floor under a gravity that varies in time, g(t) = g0 - f cos Ωt (so the
///     approach acceleration drifts, A' ≠ 0): its bounce series is computed here exactly
///     (closed-form flights, roots by Newton in long double) and summed to its accumulation
///     point t*. The engine's chatter-limit time at threshold h errs by O(T0²) ∝ h with the
///     first-order (Budd–Dux) rule, by O(T0³) ∝ h^1.5 with the second-order rule and by
///     O(T0⁴) ∝ h² with the third-order rule (T0: the skipped tail, ∝ √h). The measured slopes
///     of log error against log h must show it.
///  2. The paper's system (damped: α ≠ 0; A' ≠ 0) against the independent RK8 hybrid reference
///     (tests/support/reference_hybrid.hpp), whose chatter ends at rebounds below 1e-7 with its
///     own accumulation estimate (error ≲ 1e-10): the chatter-limit times, and the state on a
///     fixed grid against the engine's own tightest run (the second-order rule's kick for the
///     bounces' mean displacement).
#include "support/reference_hybrid.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::ChatterRule;
using vibro::Event;
using vibro::EventKind;
using vibro::ImpactSystem;
using vibro::Simulator;
using vibro::SimulatorOptions;
using vibro::Stop;

// --- 1. Ball under a time-varying gravity --------------------------------------------------------

constexpr double kG0 = 1.0, kF = 0.5, kOmega = 1.0, kR = 0.5, kDrop = 0.1;

/// x'' = -g0 + f cos Ωt, floor x ≥ 0, restitution r, dropped from rest at x = kDrop at t = 0.
ImpactSystem modulated_ball() {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, kOmega);
  f.constant(0) = -kG0;
  f.cosine(0) = kF;
  vibro::LinearSystem sys(MatrixXd::Identity(1, 1), MatrixXd::Zero(1, 1), MatrixXd::Zero(1, 1), f);
  return ImpactSystem(std::move(sys), {Stop::lower(0, 0.0, kR)});
}

/// The exact flight: x(t) from (t0, x0, v0) in long double,
/// x = x0 + v0 τ - g0 τ²/2 - (f/Ω²)(cos Ωt - cos Ωt0) - (f/Ω) sin(Ωt0) τ, the forcing's part
/// written as (f/Ω²)(sin Ωt0 (sin u − u) + 2 cos Ωt0 sin²(u/2)), u = Ωτ: without cancellation.
/// (As written first, its O(τ) terms cancelled to the O(τ²) flight: at rebounds below ~1e-7 the
/// landings were off by ~1e-19/w, and the series carried an error of 3e-11, the floor that the
/// rules' errors met at h ≤ 1e-6 until issue 13's stop 21.)
struct Flight {
  long double t0, x0, v0;
  long double x(long double t) const {
    const long double tau = t - t0, w = kOmega, u = w * tau, half = std::sin(0.5L * u);
    return x0 + v0 * tau - 0.5L * kG0 * tau * tau +
           (kF / (w * w)) * (std::sin(w * t0) * (std::sin(u) - u) + 2.0L * std::cos(w * t0) * half * half);
  }
  long double v(long double t) const {
    const long double tau = t - t0, w = kOmega;
    return v0 - kG0 * tau + (kF / w) * (std::sin(w * t) - std::sin(w * t0));
  }
};

/// The accumulation point t* of the ball's bounces, summed bounce by bounce (each landing
/// located by Newton in long double from the constant-acceleration estimate) until the rebound
/// is below 1e-12, plus that last tail by Budd–Dux (≲ 1e-23 off).
long double exact_accumulation() {
  // First landing from rest at kDrop.
  Flight fl{0.0L, kDrop, 0.0L};
  long double t = std::sqrt(2.0L * kDrop / (kG0 - kF));
  for (int it = 0; it < 100; ++it) t -= fl.x(t) / fl.v(t);
  long double w = -kR * fl.v(t);
  while (w > 1e-12L) {
    fl = Flight{t, 0.0L, w};
    const long double a = kG0 - kF * std::cos(kOmega * t);
    long double s = t + 2.0L * w / a;
    for (int it = 0; it < 100; ++it) {
      const long double step = fl.x(s) / fl.v(s);
      s -= step;
      if (std::fabs(step) < 1e-30L) break;
    }
    w = -kR * fl.v(s);
    t = s;
  }
  const long double a = kG0 - kF * std::cos(kOmega * t);
  return t + 2.0L * w / (a * (1.0L - kR));
}

double ball_chatter_error(double height, ChatterRule rule, long double exact) {
  const ImpactSystem scene = modulated_ball();
  SimulatorOptions o;
  o.chatter_height = height;
  o.chatter_rule = rule;
  Simulator sim(scene, o);
  vibro::EventLog log;
  const auto s = sim.run(0.0, VectorXd::Constant(1, kDrop), VectorXd::Zero(1), 5.0, {&log});
  REQUIRE(s.status == vibro::RunStatus::completed);
  REQUIRE(s.chatters == 1);
  for (const Event& e : log.events)
    if (e.kind == EventKind::chatter_limit) return std::fabs(static_cast<double>(e.t - exact));
  FAIL("no chatter limit");
  return 0.0;
}

/// Least-squares slope of log(error) against log(height).
double slope(const std::vector<double>& h, const std::vector<double>& err) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(h.size());
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double x = std::log(h[i]), y = std::log(err[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

TEST_CASE(
    "chatter: on a ball under a drifting gravity the first-order rule errs like h, the "
    "second-order rule like h^1.5, the third-order rule like h^2 (exact bounce series)",
    "[simulator][chatter][closed-form]") {
  const long double exact = exact_accumulation();
  // Where the drift matters: the accumulation happens where g(t) changes (Ω t* not near kπ).
  REQUIRE(std::fabs(std::sin(kOmega * static_cast<double>(exact))) > 0.3);
  const std::vector<double> heights{1e-4, 1e-5, 1e-6, 1e-7};
  std::vector<double> first, second, third;
  for (double h : heights) {
    first.push_back(ball_chatter_error(h, ChatterRule::first_order, exact));
    second.push_back(ball_chatter_error(h, ChatterRule::second_order, exact));
    third.push_back(ball_chatter_error(h, ChatterRule::third_order, exact));
    std::printf("ball chatter limit, h = %.0e: error %.3e (first order), %.3e (second order), %.3e (third order)\n",
                h, first.back(), second.back(), third.back());
  }
  const double p1 = slope(heights, first), p2 = slope(heights, second), p3 = slope(heights, third);
  std::printf("ball chatter limit: slope %.3f (first order), %.3f (second order), %.3f (third order)\n", p1, p2, p3);
  // Theory: 1, 1.5 and 2 (the third-order model leaves out g''' s³/6 of the drift: O(T0⁴) ∝ h²).
  // The thresholds are decades apart, so a rule of the wrong order would be off by a factor √10
  // per decade; ±0.2 leaves room for the discrete bounce count (the tail starts at the first
  // bounce below h, within a factor r² = 0.25 of it).
  CHECK(p1 == Approx(1.0).margin(0.2));
  CHECK(p2 >= 1.3);
  CHECK(p3 >= 1.8);
  // A larger threshold, the same accuracy: second order at 1e-5 beats first order at 1e-7, third
  // order at 1e-6 second order at 1e-7.
  CHECK(second[1] <= first[3]);
  CHECK(third[2] <= second[3]);
}

// --- 2. The paper's system against the RK8 hybrid reference ------------------------------------

struct PaperRun {
  std::vector<Event> events;
  Eigen::MatrixXd x, v;  // a column per sample
  double L = 0.0, V = 0.0;
  long impacts = 0;
};

PaperRun paper_run(double height, ChatterRule rule, double t_end, int samples) {
  const ImpactSystem scene = vibro::models::wagg2004();
  SimulatorOptions o;
  o.chatter_height = height;
  o.chatter_rule = rule;
  Simulator sim(scene, o);
  vibro::EventLog log;
  std::vector<double> times;
  for (int i = 1; i <= samples; ++i) times.push_back(t_end * i / samples);
  vibro::Samples grid(times);
  const auto s = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, {&log, &grid});
  REQUIRE(s.status == vibro::RunStatus::completed);
  return {log.events, grid.x, grid.v, s.length_scale, s.velocity_scale, s.impacts};
}

/// Worst |Δt| between the engine's chatter limits and the reference's accumulation estimates
/// (nearest stick of the same stop).
double chatter_limit_error(const PaperRun& run, const std::vector<vibro::test::ReferenceEvent>& ref) {
  double worst = 0.0;
  long count = 0;
  for (const Event& e : run.events) {
    if (e.kind != EventKind::chatter_limit) continue;
    double best = std::numeric_limits<double>::infinity();
    for (const auto& r : ref)
      if (r.stop == e.stop && r.kind == vibro::test::ReferenceEventKind::stick)
        best = std::min(best, std::fabs(static_cast<double>(r.t_limit) - e.t));
    worst = std::max(worst, best);
    ++count;
  }
  REQUIRE(count > 5);
  return worst;
}

/// Chatter tails [impact that ends the chatter, chatter limit] of a run.
std::vector<std::pair<double, double>> tails(const PaperRun& run) {
  std::vector<std::pair<double, double>> out;
  for (std::size_t i = 1; i < run.events.size(); ++i)
    if (run.events[i].kind == EventKind::chatter_limit) out.emplace_back(run.events[i - 1].t, run.events[i].t);
  return out;
}

/// Max of |Δx|/L and |Δv|/V on the sample grid, leaving out samples inside either run's chatter
/// tails: there the true motion still bounces (rebound speeds up to r u, heights up to
/// chatter_height·L) while a run that ended the chatter holds the stop, whatever the rule.
double state_error(const PaperRun& run, const PaperRun& tight, double t_end) {
  REQUIRE(run.x.cols() == tight.x.cols());
  std::vector<std::pair<double, double>> skip = tails(run);
  for (const auto& tail : tails(tight)) skip.push_back(tail);
  double err = 0.0;
  const Eigen::Index count = run.x.cols();
  long used = 0;
  for (Eigen::Index i = 0; i < count; ++i) {
    const double t = t_end * static_cast<double>(i + 1) / static_cast<double>(count);
    if (std::any_of(skip.begin(), skip.end(), [&](const auto& tail) { return t >= tail.first && t <= tail.second; }))
      continue;
    ++used;
    err = std::max(err, (run.x.col(i) - tight.x.col(i)).cwiseAbs().maxCoeff() / tight.L);
    err = std::max(err, (run.v.col(i) - tight.v.col(i)).cwiseAbs().maxCoeff() / tight.V);
  }
  REQUIRE(used > static_cast<long>(count) / 2);
  return err;
}

TEST_CASE(
    "chatter: on the paper's system the second-order rule's chatter limits and states at a "
    "threshold 100x larger match the RK8 reference as well as the first-order rule's, and the "
    "third-order rule's limits are ten times closer still",
    "[simulator][chatter][reference][wagg2004]") {
  const vibro::models::Wagg2004 p;
  const double t_end = 10.0 * 2.0 * std::numbers::pi / p.frequency;
  vibro::test::ReferenceHybridOptions ro;
  ro.stick_velocity = 1e-7L;
  vibro::test::ReferenceHybrid ref(vibro::models::wagg2004(), ro);
  ref.run(0.0L, vibro::test::VectorL::Zero(2), vibro::test::VectorL::Zero(2), static_cast<long double>(t_end));

  const int samples = 2000;
  const PaperRun tight = paper_run(1e-13, ChatterRule::second_order, t_end, samples);
  double time_error[3][3], state[3][3];
  const double heights[3] = {1e-7, 1e-8, 1e-9};
  const ChatterRule rules[3] = {ChatterRule::first_order, ChatterRule::second_order, ChatterRule::third_order};
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < 3; ++i) {
      const PaperRun run = paper_run(heights[i], rules[k], t_end, samples);
      time_error[k][i] = chatter_limit_error(run, ref.events);
      state[k][i] = state_error(run, tight, t_end);
      std::printf("paper, %s, h = %.0e: chatter-limit error %.3e, state error %.3e, %ld impacts\n",
                  vibro::to_string(rules[k]), heights[i], time_error[k][i], state[k][i], run.impacts);
    }
  }
  // The reference's own accumulation estimate is good to ≲ 1e-10 (reference_hybrid.hpp), far
  // below the first-order rule's O(T0²) errors (~1e-7 at h = 1e-9 here, README). The second-order
  // rule at h = 1e-7 (T0 ten times longer) must do at least as well as the first-order rule at
  // 1e-9, and at every threshold it must be better by a factor of ten.
  CHECK(time_error[1][0] <= time_error[0][2]);
  for (int i = 0; i < 3; ++i) CHECK(time_error[1][i] <= 0.1 * time_error[0][i]);
  // The third-order rule at h = 1e-7 is at the reference's own floor (measured 7.9e-11, the
  // second-order rule 1.5e-8): required, ten times better than the second order there. Its time
  // is only reported: the states must be the second-order rule's, bit for bit.
  CHECK(time_error[2][0] <= 0.1 * time_error[1][0]);
  for (int i = 0; i < 3; ++i) CHECK(state[2][i] == state[1][i]);
  // States on the grid (outside chatter tails) against the engine's own tightest run: the
  // correction for the bounces' mean displacement (simulator.hpp, ChatterRule: Δx through C,
  // Δv through C and K) removes the whole O(w0³) error; measured at h = 1e-7: first order
  // 1.18e-9, second order 1.9e-12. With Δv's K term alone (as until issue 13's stop 21) it was
  // 1.8e-10, a factor 0.15; without any correction, or a wrong-signed one, the ratio is ≥ 1.
  // Required: a factor 50 (floor 1e-12: rounding over ~500 events).
  CHECK(state[1][0] <= std::max(0.02 * state[0][0], 1e-12));
}

}  // namespace
