// Tests of Poincaré sections on a hyperplane (framework/include/vibro/section.hpp): crossing
// times against the closed form of a linear oscillator's steady state, the count on the paper's
// system (Wagg 2004) against the sign of the motion sampled densely and between the crossings,
// the dense engine against the modal one, and the run unchanged by the section, bit for bit.
#include "support/chains.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/modal.hpp"
#include "vibro/section.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace {

using Eigen::VectorXd;
using vibro::Hyperplane;
using vibro::Section;

constexpr double kPi = std::numbers::pi;

vibro::ImpactSystem oscillator(double m, double c, double k, double force, double omega) {
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, omega);
  f.cosine(0) = force;
  return vibro::ImpactSystem(vibro::LinearSystem(Eigen::MatrixXd::Constant(1, 1, m), Eigen::MatrixXd::Constant(1, 1, c),
                                                 Eigen::MatrixXd::Constant(1, 1, k), f),
                             {});
}

/// h = nᵀx − c at the given times, from the same run's exact flow (Samples).
std::vector<double> plane_values(vibro::Simulator& sim, const Hyperplane& plane, const VectorXd& x0,
                                 const VectorXd& v0, double t_end, std::vector<double> times) {
  vibro::Samples samples(std::move(times));
  sim.run(0.0, x0, v0, t_end, {&samples});
  std::vector<double> h;
  for (Eigen::Index k = 0; k < samples.x.cols(); ++k) h.push_back(plane.at(samples.x.col(k)));
  return h;
}

}  // namespace

TEST_CASE("section: crossing times of a linear oscillator's steady state equal the closed form", "[section]") {
  // m x'' + c x' + k x = F cos Ωt started on its steady state x = X cos(Ωt − φ),
  // X = F/√((k − mΩ²)² + (cΩ)²), φ = atan2(cΩ, k − mΩ²). x = a crosses upwards at
  // Ωt = φ − acos(a/X) + 2πj and downwards at Ωt = φ + acos(a/X) + 2πj. The run's state errs by
  // rounding (~1e-16 X, the transient excited by x0's rounding decays), the crossing time by
  // that over |x'| = XΩ sin(acos(a/X)) ≈ 0.95 XΩ: ~1e-16 T; the roots are placed to a few ulps of
  // t ≤ 20T. 1e-13 T leaves a margin of ~100.
  const double m = 1.3, c = 0.07, k = 2.1, F = 0.8, omega = 1.7;
  const double X = F / std::hypot(k - m * omega * omega, c * omega), phi = std::atan2(c * omega, k - m * omega * omega);
  const double a = 0.3 * X, T = 2.0 * kPi / omega;
  const vibro::ImpactSystem sys = oscillator(m, c, k, F, omega);
  vibro::Simulator sim(sys);
  const VectorXd x0 = VectorXd::Constant(1, X * std::cos(-phi)), v0 = VectorXd::Constant(1, -X * omega * std::sin(-phi));
  const int periods = 20;
  for (const auto direction : {Section::Direction::up, Section::Direction::down, Section::Direction::both}) {
    Section section(Hyperplane{VectorXd::Ones(1), a}, direction);
    sim.run(0.0, x0, v0, periods * T, {&section});
    std::vector<double> expected;
    std::vector<int> sense;
    for (int j = -1; j <= periods + 1; ++j) {
      for (int s : {1, -1}) {
        if ((direction == Section::Direction::up && s < 0) || (direction == Section::Direction::down && s > 0)) continue;
        const double t = (phi - s * std::acos(a / X) + 2.0 * kPi * j) / omega;
        if (t > 0.0 && t <= periods * T) {
          expected.push_back(t);
          sense.push_back(s);
        }
      }
    }
    std::vector<std::size_t> order(expected.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t p, std::size_t q) { return expected[p] < expected[q]; });
    REQUIRE(section.t.size() == expected.size());
    REQUIRE(expected.size() >= static_cast<std::size_t>(periods));
    double worst = 0.0;
    for (std::size_t i = 0; i < order.size(); ++i) {
      worst = std::max(worst, std::abs(section.t[i] - expected[order[i]]) / T);
      CHECK(section.crossing[i] == sense[order[i]]);
      CHECK(std::abs(section.x[i](0) - a) <= 1e-13 * X);
      CHECK(section.v[i](0) * sense[order[i]] > 0.0);
      const double theta = std::fmod(omega * section.t[i], 2.0 * kPi);
      CHECK(std::abs(section.phase[i] - theta) <= 1e-12);
    }
    CHECK(worst <= 1e-13);
  }
}

TEST_CASE("section: on the paper's system no crossing is missed or invented (dense sampling and between crossings)",
          "[section][wagg2004]") {
  // Wagg (2004)'s two-mass system, Ω = 0.255 (impacts on both stops and sticking), 30 periods
  // from rest: the section x₂ − 0.5 x₁ = 0.02 (a general normal), both directions. Checked
  // against the motion itself, from Samples of the same exact flow:
  //  * between two consecutive crossings (and before the first, after the last) h has the sign
  //    the crossings say, at their midpoint;
  //  * at 400 samples per period h has that sign wherever |h| exceeds 1e-9 (away from a root);
  //  * at each crossing h = 0 to 1e-12 (the root, evaluated by another rounding path).
  vibro::models::Wagg2004 p;
  p.frequency = 0.255;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  vibro::Simulator sim(sys);
  const double T = 2.0 * kPi / p.frequency, t_end = 30.0 * T;
  const VectorXd zero = VectorXd::Zero(2);
  VectorXd n(2);
  n << -0.5, 1.0;
  const Hyperplane plane{n, 0.02};
  Section section(plane);
  vibro::EventLog log;
  const vibro::RunSummary s = sim.run(0.0, zero, zero, t_end, {&section, &log});
  REQUIRE(s.status == vibro::RunStatus::completed);
  CHECK(s.impacts > 20);
  CHECK(s.sticks > 0);
  const std::size_t count = section.t.size();
  REQUIRE(count > 20);
  const int start_side = plane.at(zero) > 0.0 ? 1 : -1;  // h(0) = −0.02: below
  REQUIRE(start_side == -1);
  // Side after k crossings: they alternate, starting upwards from below.
  for (std::size_t k = 0; k < count; ++k) {
    CHECK(section.crossing[k] == (k % 2 == 0 ? 1 : -1));
    if (k > 0) CHECK(section.t[k] > section.t[k - 1]);
  }
  std::vector<double> mid;
  mid.push_back(0.5 * section.t[0]);
  for (std::size_t k = 0; k + 1 < count; ++k) mid.push_back(0.5 * (section.t[k] + section.t[k + 1]));
  mid.push_back(0.5 * (section.t.back() + t_end));
  const std::vector<double> h_mid = plane_values(sim, plane, zero, zero, t_end, mid);
  REQUIRE(h_mid.size() == mid.size());
  for (std::size_t k = 0; k < h_mid.size(); ++k) {
    const int side = k == 0 ? start_side : section.crossing[k - 1];
    CHECK(h_mid[k] * side > 0.0);
  }
  std::vector<double> grid;
  const int per_period = 400;
  for (int i = 0; i <= 30 * per_period; ++i) grid.push_back(t_end * i / (30.0 * per_period));
  const std::vector<double> h_grid = plane_values(sim, plane, zero, zero, t_end, grid);
  std::size_t next = 0;
  int sign_changes = 0, last_sign = start_side, checked = 0;
  for (std::size_t i = 0; i < grid.size(); ++i) {
    while (next < count && section.t[next] <= grid[i]) ++next;
    const int side = next == 0 ? start_side : section.crossing[next - 1];
    if (std::abs(h_grid[i]) > 1e-9) {
      CHECK(h_grid[i] * side > 0.0);
      ++checked;
      const int sign = h_grid[i] > 0.0 ? 1 : -1;
      if (sign != last_sign) ++sign_changes;
      last_sign = sign;
    }
  }
  CHECK(checked > 29 * per_period);
  // Every sign change of the samples is a crossing; crossings beyond them come in pairs inside
  // one sampling interval (checked at their midpoints above).
  CHECK(sign_changes <= static_cast<int>(count));
  CHECK((static_cast<int>(count) - sign_changes) % 2 == 0);
  const std::vector<double> h_at = plane_values(sim, plane, zero, zero, t_end, section.t);
  for (double h : h_at) CHECK(std::abs(h) <= 1e-12);
}

TEST_CASE("section: a stop lying in the hyperplane is touched, not crossed", "[section][wagg2004]") {
  // x₂ = s₂ is the upper stop of mass 2: the motion reaches it at every impact and sticks on it,
  // but never passes it by more than the trigger, so the section has no crossing (section.hpp).
  vibro::models::Wagg2004 p;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  vibro::Simulator sim(sys);
  const double t_end = 20.0 * 2.0 * kPi / p.frequency;
  VectorXd n(2);
  n << 0.0, 1.0;
  Section section(Hyperplane{n, p.s2});
  const vibro::RunSummary s = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, {&section});
  CHECK(s.impacts > 10);
  CHECK(section.t.empty());
}

TEST_CASE("section: the run is the same with and without a section, bit for bit (dense and modal)",
          "[section][observers]") {
  vibro::models::Wagg2004 p;
  const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
  const double t_end = 20.0 * 2.0 * kPi / p.frequency;
  const VectorXd zero = VectorXd::Zero(2);
  std::vector<double> times;
  for (int i = 0; i <= 2000; ++i) times.push_back(t_end * i / 2000.0);
  vibro::Simulator bare(sys), watched(sys);
  vibro::Samples sa(times), sb(times);
  vibro::EventLog la, lb;
  Section section(Hyperplane{VectorXd::Unit(2, 0), 0.0});
  const vibro::RunSummary a = bare.run(0.0, zero, zero, t_end, {&sa, &la});
  const vibro::RunSummary b = watched.run(0.0, zero, zero, t_end, {&sb, &lb, &section});
  CHECK(section.t.size() > 10);
  CHECK(a.segments == b.segments);
  CHECK(a.guard_evaluations == b.guard_evaluations);
  CHECK(a.x == b.x);
  CHECK(a.v == b.v);
  CHECK(sa.x == sb.x);
  CHECK(sa.v == sb.v);
  REQUIRE(la.events.size() == lb.events.size());
  for (std::size_t i = 0; i < la.events.size(); ++i) CHECK(la.events[i].t == lb.events[i].t);

  // The modal engine: an 8-mass chain with sticking, a stop between masses and chatter.
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(8, 0.5);
  f.cosine(0) = 0.8;
  f.sine(7) = -0.5;
  const vibro::BandedChain chain = vibro::BandedChain::from_links(
      std::vector<double>(8, 1.0), std::vector<double>(7, 1.0), std::vector<double>(7, 0.03), 1.0, 0.03, 2.0, 0.06, f);
  const std::vector<vibro::Stop> stops{vibro::Stop::upper(0, 0.3, 0.0), vibro::Stop::lower(7, -0.2, 0.4),
                                       vibro::Stop::between(6, 7, 0.05, 0.3)};
  const vibro::ChainModes modes(chain);
  const double tm = 20.0 * 2.0 * kPi / 0.5;
  const VectorXd z8 = VectorXd::Zero(8);
  vibro::ModalChainSimulator mbare(modes, stops), mwatched(modes, stops);
  VectorXd n8 = VectorXd::Zero(8);
  n8(6) = 1.0;
  n8(7) = -1.0;
  Section modal_section(Hyperplane{n8, 0.02});
  const auto ma = mbare.run(0.0, z8, z8, tm);
  const auto mb = mwatched.run(0.0, z8, z8, tm, {&modal_section});
  CHECK(ma.sticks > 0);
  CHECK(modal_section.t.size() > 5);
  CHECK(ma.segments == mb.segments);
  CHECK(ma.impacts == mb.impacts);
  CHECK(ma.x == mb.x);
  CHECK(ma.v == mb.v);
}

TEST_CASE("section: the dense and the modal engine find the same crossings", "[section][modal]") {
  // A 6-mass chain (C = βK) with a stop above mass 0 and one between masses 3 and 4, 15 periods
  // from a generic state; sections on x₂ = 0.05 (up) and x₁ − x₄ = 0 (both). The engines' events agree to
  // ~1e-12 T (test_modal.cpp); a crossing inherits that: 1e-10 T and 1e-9 in the states.
  const vibro::BandedChain chain = vibro::test::uniform_chain(6, 0.02, 0.6, 0.9);
  const std::vector<vibro::Stop> stops{vibro::Stop::upper(0, 0.25, 0.8), vibro::Stop::between(3, 4, 0.1, 0.7)};
  const vibro::ChainModes modes(chain);
  const vibro::ImpactSystem dense_system(chain.dense(), stops);
  const double T = 2.0 * kPi / 0.9, t_end = 15.0 * T;
  // A generic start (from rest at 0, x₁ − x₄ would leave 0 like a high power of t, a root no
  // two roundings place alike).
  const VectorXd x0 = VectorXd::LinSpaced(6, 0.02, -0.03), v0 = VectorXd::LinSpaced(6, -0.01, 0.01);
  VectorXd diff = VectorXd::Zero(6);
  diff(1) = 1.0;
  diff(4) = -1.0;
  for (const Hyperplane& plane : {Hyperplane{VectorXd::Unit(6, 2), 0.05}, Hyperplane{diff, 0.0}}) {
    const auto direction = plane.value != 0.0 ? Section::Direction::up : Section::Direction::both;
    Section in_dense(plane, direction), in_modal(plane, direction);
    vibro::Simulator dense(dense_system);
    vibro::ModalChainSimulator modal(modes, stops);
    const auto a = dense.run(0.0, x0, v0, t_end, {&in_dense});
    const auto b = modal.run(0.0, x0, v0, t_end, {&in_modal});
    CHECK(a.impacts > 5);
    CHECK(a.impacts == b.impacts);
    REQUIRE(in_dense.t.size() == in_modal.t.size());
    CHECK(in_dense.t.size() > 5);
    for (std::size_t k = 0; k < in_dense.t.size(); ++k) {
      INFO("crossing " << k << " at t = " << in_dense.t[k] << ", h' = " << plane.normal.dot(in_dense.v[k])
                       << ", impacts " << a.impacts);
      CHECK(std::abs(in_dense.t[k] - in_modal.t[k]) <= 1e-10 * T);
      CHECK(in_dense.crossing[k] == in_modal.crossing[k]);
      CHECK((in_dense.x[k] - in_modal.x[k]).cwiseAbs().maxCoeff() <= 1e-9);
      CHECK((in_dense.v[k] - in_modal.v[k]).cwiseAbs().maxCoeff() <= 1e-9);
    }
  }
}

TEST_CASE("section: bad hyperplanes are refused with a message", "[section]") {
  CHECK_THROWS_WITH(Section(Hyperplane{VectorXd::Zero(2), 0.0}), Catch::Contains("the normal is zero"));
  CHECK_THROWS_WITH(Section(Hyperplane{VectorXd::Constant(2, std::nan("")), 0.0}), Catch::Contains("not finite"));
  CHECK_THROWS_WITH(Section(Hyperplane{VectorXd::Ones(2), std::nan("")}), Catch::Contains("value is not finite"));
  const vibro::ImpactSystem sys = oscillator(1.0, 0.1, 1.0, 0.5, 1.0);
  vibro::Simulator sim(sys);
  Section wrong(Hyperplane{VectorXd::Ones(3), 0.0});
  CHECK_THROWS_WITH(sim.run(0.0, VectorXd::Zero(1), VectorXd::Zero(1), 1.0, {&wrong}),
                    Catch::Contains("the normal has 3 entries, the system 1 coordinates"));
}
