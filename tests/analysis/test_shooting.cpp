/// Tests of Newton shooting and Floquet multipliers (framework/analysis, shooting.hpp).
///
///  * closed form: the designed 1-DOF orbits of support/designed_orbit.hpp, stable and unstable,
///    found from perturbed guesses; multipliers to 1e-10 of the closed form; quadratic
///    convergence while the event sequence is fixed;
///  * the running method as cross-check: on the paper's system (sticking orbits, chatter) the
///    orbit shooting finds is the one running to convergence finds, and the contraction rate
///    the multipliers predict is the one the running method shows;
///  * the unstable orbit, which running cannot find, is left by a run at the rate its largest
///    multiplier says;
///  * failures are reported (residual, iterations, why), never a false orbit.
#include "support/analysis_helpers.hpp"
#include "support/designed_orbit.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/running_orbit.hpp"
#include "vibro/shooting.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <complex>
#include <numbers>

namespace {

using Eigen::VectorXd;
using vibro::ShootingOptions;
using vibro::ShootingResult;
using vibro::test::DesignedOrbit;

constexpr double kPi = std::numbers::pi;

using vibro::test::stack;

/// The closed-form multipliers of a designed orbit, sorted by decreasing modulus.
std::pair<std::complex<double>, std::complex<double>> closed_form(const DesignedOrbit& orbit) {
  const Eigen::MatrixXd J = orbit.monodromy();
  const double tr = J.trace(), det = J.determinant();
  const std::complex<double> disc = std::sqrt(std::complex<double>(tr * tr - 4.0 * det));
  std::complex<double> a = 0.5 * (tr + disc), b = 0.5 * (tr - disc);
  if (std::abs(b) > std::abs(a)) std::swap(a, b);
  return {a, b};
}

}  // namespace

TEST_CASE("shooting: the designed 1-DOF orbits (stable and unstable) from perturbed guesses, "
          "quadratic convergence, multipliers to 1e-10 of the closed form",
          "[shooting][closed-form]") {
  for (const DesignedOrbit& orbit : {DesignedOrbit(0.125), DesignedOrbit(5.0 / 16.0)}) {
    INFO("impact at t* = " << orbit.t_star / orbit.T << " T");
    const vibro::ImpactSystem sys = orbit.system();
    // Guess: the orbit's state half a period after the impact, off by 3 % of the stop distance
    // and of the impact speed.
    const double t_guess = orbit.t_star + 0.5 * orbit.T;
    VectorXd guess = orbit.state_after_impact(0.5 * orbit.T);
    guess(0) += 0.03 * orbit.s;
    guess(1) -= 0.03 * orbit.u;
    ShootingOptions o;
    o.phase = orbit.omega * t_guess;  // the section where the guess is
    o.free_section = false;
    const ShootingResult r = vibro::shoot(sys, o, t_guess, guess.head(1), guess.tail(1));
    INFO(r.message);
    REQUIRE(r.converged());
    CHECK(r.residual <= 1e-11);
    CHECK(r.minimal_k == 1);
    const VectorXd exact = orbit.state_after_impact(0.5 * orbit.T);
    // The state's error is the residual's times ‖(J − I)⁻¹‖ (about 2 for the unstable orbit).
    const double inverse = (orbit.monodromy() - Eigen::MatrixXd::Identity(2, 2)).inverse().cwiseAbs().maxCoeff();
    INFO("state error " << (stack(r.x, r.v) - exact).cwiseAbs().maxCoeff() << ", ‖(J − I)⁻¹‖ " << inverse);
    CHECK((stack(r.x, r.v) - exact).cwiseAbs().maxCoeff() <= 4.0 * inverse * 1e-11 * std::max(orbit.s, orbit.u));
    // Quadratic convergence: once the residual is small, each step squares it up to a constant,
    // |P''| |(J − I)⁻¹| / 2 in the scaled variables: measured 2–3 for the stable orbit and 20–30
    // for the unstable one (μ = 1.5 makes (J − I)⁻¹ ≈ 2, and S varies like a/u² with the impact
    // speed); 100 leaves room, while linear convergence would fail it within two steps.
    int quadratic_steps = 0;
    for (std::size_t i = 1; i < r.residuals.size(); ++i) {
      const double prev = r.residuals[i - 1], now = r.residuals[i];
      if (prev < 1e-2 && now > 1e-14) {
        CHECK(now <= 100.0 * prev * prev);
        ++quadratic_steps;
      }
    }
    CHECK(quadratic_steps >= 1);
    CHECK(r.iterations <= 8);
    const auto [mu1, mu2] = closed_form(orbit);
    REQUIRE(r.multipliers.values.size() == 2);
    CHECK(r.multipliers.structural_zeros == 0);
    CHECK(std::abs(r.multipliers.values(0) - mu1) <= 1e-10);
    CHECK(std::abs(r.multipliers.values(1) - mu2) <= 1e-10);
    CHECK(r.multipliers.stable == (std::abs(mu1) < 1.0));
  }
}

TEST_CASE("shooting: an unstable orbit is left by a run at the rate of its largest multiplier",
          "[shooting][unstable]") {
  // The designed orbit with the impact at 5T/16 has multipliers 0.253 and 1.501: running from a
  // point 1e-9 off it, the deviation grows by 1.501 per period once the other direction decays.
  const DesignedOrbit orbit(5.0 / 16.0);
  const vibro::ImpactSystem sys = orbit.system();
  const double t0 = orbit.t_star + 0.5 * orbit.T;
  const VectorXd guess = orbit.state_after_impact(0.5 * orbit.T);
  ShootingOptions o;
  o.phase = orbit.omega * t0;
  o.free_section = false;
  const ShootingResult r = vibro::shoot(sys, o, t0, guess.head(1), guess.tail(1));
  REQUIRE(r.converged());
  REQUIRE_FALSE(r.multipliers.stable);
  const double mu = std::abs(r.multipliers.values(0));
  vibro::Simulator sim(sys);
  VectorXd z = stack(r.x, r.v);
  z(0) -= 1e-9;
  const VectorXd orbit_z = stack(r.x, r.v);
  std::vector<double> deviation;
  double t = r.t0;
  for (int k = 0; k < 14; ++k) {
    const vibro::RunSummary s = sim.run(t, z.head(1), z.tail(1), t + orbit.T);
    REQUIRE(s.status == vibro::RunStatus::completed);
    z = stack(s.x, s.v);
    t += orbit.T;
    deviation.push_back((z - orbit_z).norm());
  }
  const double growth = std::pow(deviation[13] / deviation[9], 0.25);
  INFO("growth per period " << growth << ", largest multiplier " << mu);
  CHECK(std::abs(growth - mu) <= 1e-3 * mu);  // 0.253⁴ ≈ 4e-3 of the decaying direction is left
}

TEST_CASE("shooting: the paper's sticking orbits equal the running method's, their multipliers "
          "have the structural zeros of sticking and predict the running method's contraction",
          "[shooting][wagg2004]") {
  for (double omega : {0.255, 0.27}) {
    INFO("Omega = " << omega);
    vibro::models::Wagg2004 p;
    p.frequency = omega;
    const vibro::ImpactSystem sys = vibro::models::wagg2004(p);
    const double T = 2.0 * kPi / omega;
    // A short run as the guess (20 periods: far from converged), then Newton.
    vibro::Simulator sim(sys);
    const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 20.0 * T);
    const ShootingResult r = vibro::shoot(sys, {}, 20.0 * T, warm.x, warm.v);
    INFO(r.message);
    REQUIRE(r.converged());
    CHECK(r.multipliers.structural_zeros == 2);  // one mass held at a time: d = 2(n − 1)
    CHECK(r.multipliers.stable);
    // The running method (running_orbit.hpp) from rest finds the same orbit.
    vibro::RunningOrbitOptions oo;
    oo.min_periods = 200;
    const vibro::RunningOrbit run = vibro::run_to_periodic_orbit(sys, oo, 0.0, VectorXd::Zero(2), VectorXd::Zero(2));
    REQUIRE(run.periodic);
    REQUIRE(run.k == 1);
    // Compare at the shooting section: run the orbit there.
    const vibro::RunSummary at = sim.run(0.0, run.x, run.v, r.t0);  // run.t_start is at phase 0
    CHECK((stack(at.x, at.v) - stack(r.x, r.v)).cwiseAbs().maxCoeff() <= 1e-9);
    // Contraction. A deviation d from the orbit, after one period, lies in the range of J, which
    // is spanned by `lift` (linearisation.hpp): d = lift·y with y mapped by the reduced map, and in
    // the reduced map's eigenvectors E each coordinate of c = E⁻¹ y is multiplied by its
    // multiplier per period. So running the engine from a point 1e-5 off the orbit, each
    // coordinate must be multiplied by μ_i per period, up to the map's nonlinear part at that
    // distance (relative ~1e-5; measured ≤ 9e-6 over the first two periods). Later periods shrink
    // the deviation to ~1e-9 of the state, where the runs' rounding (~1e-12) is 1e-3 of it.
    const Eigen::MatrixXd& lift = r.map.lift;
    const Eigen::MatrixXd pinv = (lift.transpose() * lift).ldlt().solve(lift.transpose());
    Eigen::ComplexEigenSolver<Eigen::MatrixXcd> es(r.map.reduced.cast<std::complex<double>>());
    const Eigen::MatrixXcd Einv = es.eigenvectors().inverse();
    VectorXd z = stack(r.x, r.v);
    z(2) += 1e-5 * 0.3 * omega;
    std::vector<Eigen::VectorXcd> coords;
    double t = r.t0;
    for (int k = 0; k < 4; ++k) {
      const vibro::RunSummary s = sim.run(t, z.head(2), z.tail(2), t + T);
      z = stack(s.x, s.v);
      t += T;
      coords.push_back(Einv * (pinv * (z - stack(r.x, r.v))).cast<std::complex<double>>());
    }
    for (int k = 0; k < 2; ++k)
      for (Eigen::Index i = 0; i < 2; ++i) {
        const std::complex<double> predicted = es.eigenvalues()(i) * coords[static_cast<std::size_t>(k)](i);
        INFO("period " << k << ", multiplier " << es.eigenvalues()(i));
        INFO("error " << std::abs(coords[static_cast<std::size_t>(k) + 1](i) - predicted) / std::abs(predicted));
        CHECK(std::abs(coords[static_cast<std::size_t>(k) + 1](i) - predicted) <= 1e-4 * std::abs(predicted));
      }
  }
}

TEST_CASE("shooting: failures are reported with the residual, the iterations and why",
          "[shooting][failure]") {
  const DesignedOrbit orbit(0.125);
  const vibro::ImpactSystem sys = orbit.system();
  const double t0 = orbit.t_star + 0.5 * orbit.T;
  VectorXd guess = orbit.state_after_impact(0.5 * orbit.T);
  guess(1) += 0.2;
  ShootingOptions o;
  o.phase = orbit.omega * t0;
  o.free_section = false;
  o.max_iterations = 1;
  const ShootingResult r = vibro::shoot(sys, o, t0, guess.head(1), guess.tail(1));
  CHECK_FALSE(r.converged());
  CHECK(r.status == vibro::ShootingStatus::not_converged);
  CHECK(r.message.find("residual") != std::string::npos);
  CHECK(r.residual > o.tolerance);
  CHECK(r.iterations == 1);
  // Bad options are refused, naming the field.
  o.period = 0;
  CHECK_THROWS_WITH(vibro::shoot(sys, o, t0, guess.head(1), guess.tail(1)), Catch::Contains("shooting.period"));
}
