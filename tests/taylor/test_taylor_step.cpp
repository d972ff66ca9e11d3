// The Taylor step (taylor_step.hpp) against closed forms: every recurrence's high-order
// coefficients against the function itself, the undamped Duffing oscillator against Jacobi's cn,
// the pendulum's period against 4K(sin(θ₀/2)), a forced damped linear oscillator against its
// exact solution, energy conservation, and the variational matrix against central differences.
//
// References in long double (tests/support/elliptic.hpp), so that their own rounding (~1e-19
// relative, ~1e-16 after 100 periods of phase) stays far below the tolerances checked.
#include "support/elliptic.hpp"
#include "vibro/taylor/guard_roots.hpp"
#include "vibro/taylor/taylor_step.hpp"

#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

using namespace vibro::taylor;
using vibro::test::elliptic_k;
using vibro::test::jacobi;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

TaylorSystem one_mass(const std::string& force, double stiffness = 0.0, double damping = 0.0,
                      std::vector<std::pair<std::string, double>> parameters = {}, double frequency = 0.0,
                      std::vector<std::string> guards = {}) {
  TaylorSystemSpec spec;
  spec.mass = Eigen::MatrixXd::Identity(1, 1);
  spec.stiffness = stiffness * Eigen::MatrixXd::Identity(1, 1);
  spec.damping = damping * Eigen::MatrixXd::Identity(1, 1);
  spec.parameters = std::move(parameters);
  spec.frequency = frequency;
  spec.forces = {force};
  spec.guards = std::move(guards);
  return TaylorSystem(spec);
}

struct DuffingRun {
  double max_error = 0.0, max_energy_drift = 0.0;
  long steps = 0;
  double seconds = 0.0;
  double period = 0.0;
};

/// x'' + x + βx³ = 0, x(0) = A, v(0) = 0: x = A cn(ωt, m), ω² = 1 + βA², m = βA²/(2ω²).
/// Checked at 20 points per period over `periods` periods; energy v²/2 + x²/2 + βx⁴/4 there too.
DuffingRun run_duffing(double beta, double amplitude, int periods) {
  TaylorSystem system = one_mass("-beta*x0^3", 1.0, 0.0, {{"beta", beta}});
  TaylorStep step(system);
  const long double omega = std::sqrt(1.0L + (long double)beta * amplitude * amplitude);
  const long double m = (long double)beta * amplitude * amplitude / (2.0L * omega * omega);
  const long double period = 4.0L * elliptic_k(m) / omega;
  const double energy0 = 0.5 * amplitude * amplitude + 0.25 * beta * std::pow(amplitude, 4);
  DuffingRun run;
  run.period = static_cast<double>(period);
  Eigen::VectorXd z(2), next(2);
  z << amplitude, 0.0;
  double t = 0.0;
  const auto start = std::chrono::steady_clock::now();
  for (int j = 1; j <= 20 * periods; ++j) {
    const double t1 = static_cast<double>(period * j / 20.0L);
    long steps = 0;
    REQUIRE(advance(step, t, z, t1, next, nullptr, &steps) == StepStatus::ok);
    run.steps += steps;
    z = next;
    t = t1;
    const long double u = omega * (long double)t1;
    const auto f = jacobi(u, m);
    const double x = static_cast<double>(amplitude * f.cn);
    const double v = static_cast<double>(-amplitude * omega * f.sn * f.dn);
    run.max_error = std::max({run.max_error, std::abs(z[0] - x), std::abs(z[1] - v)});
    const double energy = 0.5 * z[1] * z[1] + 0.5 * z[0] * z[0] + 0.25 * beta * std::pow(z[0], 4);
    run.max_energy_drift = std::max(run.max_energy_drift, std::abs(energy - energy0) / energy0);
  }
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return run;
}

/// Exact normalised Taylor coefficients are not at hand for every function, but its polynomial
/// over a step must equal the function: G(τ) = f(t₀ + τ) to rounding where τ is well inside the
/// radius of convergence (here (0.1/ρ)^{21} ≤ 1e-16 for every case).
void check_time_function(const std::string& text, double (*f)(double)) {
  TaylorSystem system = one_mass("", 0.0, 0.0, {}, 0.0, {text});
  TaylorStep step(system);
  const double t0 = 0.3;
  REQUIRE(step.expand(t0, Eigen::Vector2d(0.0, 1.0)) == StepStatus::ok);
  const double* g = step.guard_coefficients(0);
  for (double tau : {0.0, 0.025, 0.05, 0.075, 0.1}) {
    double value = g[step.order()];
    for (int k = step.order() - 1; k >= 0; --k) value = value * tau + g[k];
    const double exact = f(t0 + tau);
    INFO(text << " at t = " << t0 + tau);
    CHECK(std::abs(value - exact) <= 8 * kEps * std::max(1.0, std::abs(exact)));
  }
}

}  // namespace

TEST_CASE("every recurrence's polynomial equals its function over the step") {
  check_time_function("exp(0.5*t)", [](double t) { return std::exp(0.5 * t); });
  check_time_function("log(2 + t)", [](double t) { return std::log(2 + t); });
  check_time_function("sqrt(1 + t^2)", [](double t) { return std::sqrt(1 + t * t); });
  check_time_function("tanh(t - 0.3)", [](double t) { return std::tanh(t - 0.3); });
  check_time_function("tan(0.4*t)", [](double t) { return std::tan(0.4 * t); });
  check_time_function("atan(2*t)", [](double t) { return std::atan(2 * t); });
  check_time_function("1/(1.5 + cos(t))", [](double t) { return 1 / (1.5 + std::cos(t)); });
  check_time_function("(1 + t)^2.5", [](double t) { return std::pow(1 + t, 2.5); });
  check_time_function("(1 + t)^-3", [](double t) { return std::pow(1 + t, -3.0); });
  check_time_function("sin(t)*cos(2*t) - t^5", [](double t) { return std::sin(t) * std::cos(2 * t) - std::pow(t, 5); });
  check_time_function("2^t", [](double t) { return std::pow(2.0, t); });
}

TEST_CASE("the order and step follow the order rule and Jorba and Zou's step") {
  TaylorSystem system = one_mass("", 1.0);  // x'' = -x: z_[k] ~ 1/k!
  TaylorStep step(system);
  CHECK(step.order() == 20);  // min(20, ⌈−0.7 ln 2⁻⁵² + 1⌉ = ⌈26.23⌉)
  REQUIRE(step.expand(0.0, Eigen::Vector2d(1.0, 0.0)) == StepStatus::ok);
  // ‖z_[19]‖ = 1/19!, ‖z_[20]‖ = 1/20!: h = min_k (ε/‖z_[k]‖)^{1/k} · e^{−0.7/19}.
  const double expected = std::min(std::pow(kEps * std::tgamma(20.0), 1.0 / 19), std::pow(kEps * std::tgamma(21.0), 1.0 / 20)) *
                          std::exp(-0.7 / 19);
  CHECK(step.step_size() == Approx(expected).epsilon(1e-12));
  TaylorStep coarse(system, {.tolerance = 1e-8});
  CHECK(coarse.order() == 14);  // ⌈−0.7 ln 1e-8 + 1⌉ = ⌈13.89⌉
  CHECK(TaylorStep(system, {.tolerance = 1e-10}).order() == 18);  // ⌈17.12⌉
  CHECK_THROWS_WITH(TaylorStep(system, {.tolerance = 0.5}),
                    "TaylorSettings.tolerance = 0.500000: must lie in (0, 0.01) (it sets the order p = min(20, ceil(-0.7 ln(tolerance) + 1)))");
}

TEST_CASE("the guard's remainder bound covers the truncated tail") {
  // x'' = -x from (1, 0): the guard x0 is cos τ exactly; G(τ) − cos τ is the tail beyond τ^p
  // (plus rounding) and must lie within guard_remainder at every τ of the step; at the coarse
  // tolerances the tail is far above rounding, so the truncation part of the bound is tested.
  TaylorSystem system = one_mass("", 1.0, 0.0, {}, 0.0, {"x0", "3*x0 - 2*v0"});
  for (double tolerance : {1e-16, 1e-12, 1e-8}) {
    TaylorStep step(system, {.tolerance = tolerance});
    REQUIRE(step.expand(0.0, Eigen::Vector2d(1.0, 0.0)) == StepStatus::ok);
    const int p = step.order();
    for (int g = 0; g < 2; ++g) {
      const double* c = step.guard_coefficients(g);
      const double bound = step.guard_remainder(g);
      double worst = 0.0;
      for (int i = 0; i <= 50; ++i) {
        const double tau = step.step_size() * i / 50;
        double value = c[p];
        for (int k = p - 1; k >= 0; --k) value = value * tau + c[k];
        const long double exact = g == 0 ? std::cos((long double)tau) : 3 * std::cos((long double)tau) + 2 * std::sin((long double)tau);
        worst = std::max(worst, static_cast<double>(std::fabs(value - exact)));
      }
      INFO("tolerance " << tolerance << ", guard " << g << ": |G − g| ≤ " << worst << ", bound " << bound);
      CHECK(worst <= bound);
      // Not vacuous: within 100 tolerances of the guard's amplitude (1 and √13), and at the
      // default below 1e-13 of it, the trigger level the event search uses (events.hpp).
      const double amplitude = g == 0 ? 1.0 : std::sqrt(13.0);
      CHECK(bound <= std::max(100 * tolerance, 1e-13) * amplitude);
    }
  }
}

TEST_CASE("undamped Duffing oscillator against Jacobi's cn over 100 periods") {
  // Round-off makes the energy (hence the frequency of a nonlinear oscillator) random-walk, so
  // the phase error of any double-precision integration grows like t^{3/2} (Brouwer's law,
  // Brouwer 1937; Hairer, McLachlan & Razakarivony 2008): 1e-13 is checked over 20 periods and
  // its t^{3/2} extrapolation, 1e-13 · 5^{3/2} ≈ 1.1e-12, over 100. A systematic error (∝ t or t²:
  // a biased step, a wrong time) would exceed it.
  const DuffingRun first = run_duffing(1.0, 1.0, 20);
  INFO("20 periods: max |state error| " << first.max_error);
  CHECK(first.max_error <= 1e-13);
  const DuffingRun run = run_duffing(1.0, 1.0, 100);
  INFO("100 periods: max |state error| " << run.max_error << ", energy drift " << run.max_energy_drift << ", "
                                         << run.steps << " steps");
  CHECK(run.max_error <= 1e-13 * std::pow(5.0, 1.5));
  // Energy: each step's error is ≲ ε of the state's scale (the step rule), so over N steps the
  // drift is at most N ε (rounding and truncation adding up in the worst case).
  CHECK(run.max_energy_drift <= run.steps * kEps);
  // A weaker nonlinearity (frequency less sensitive to energy): 1e-13 over all 100 periods.
  const DuffingRun soft = run_duffing(0.1, 1.0, 100);
  INFO("beta = 0.1: max |state error| " << soft.max_error);
  CHECK(soft.max_error <= 1e-13);
  CHECK(soft.max_energy_drift <= soft.steps * kEps);
}

TEST_CASE("pendulum: period 4K(sin(θ₀/2)) and the closed form over 100 periods") {
  // θ₀ = 2 rad (115°): a strongly nonlinear swing.
  const double theta0 = 2.0;
  TaylorSystem system = one_mass("-sin(x0)", 0.0, 0.0, {}, 0.0, {"-x0"});
  TaylorStep step(system);
  GuardRootFinder finder(step.order());
  const long double k = std::sin(0.5L * theta0), m = k * k;
  const long double period = 4.0L * elliptic_k(m);
  // Step along, locating every rise of −θ above 0 (θ crossing 0 downwards, at T/4 + j T) with the
  // certified root search, and comparing the state with sin(θ/2) = k cd(t) at each step's end.
  Eigen::VectorXd z(2);
  z << theta0, 0.0;
  double t = 0.0, carry = 0.0;  // elapsed time t − carry, compensated (Kahan), as advance() does
  double max_error = 0.0, max_error_20 = 0.0, max_energy_drift = 0.0;
  const double energy0 = -std::cos(theta0);
  std::vector<double> crossings;
  long steps = 0;
  while (crossings.size() < 101) {
    REQUIRE(step.expand(t, z) == StepStatus::ok);
    const double h = step.step_size();
    const auto c = finder.first_crossing(step.guard_coefficients(0), step.order(), h, 0.0, step.guard_remainder(0));
    REQUIRE(c.kind != CrossingKind::grazing);
    if (c.kind == CrossingKind::crossing) crossings.push_back((t - carry) + c.tau);
    step.state(h, z);
    const double y = h - carry, sum = t + y;
    carry = (sum - t) - y;
    t = sum;
    ++steps;
    const auto f = jacobi((long double)t - carry, m);
    const double theta = static_cast<double>(2.0L * std::asin(k * f.cn / f.dn));
    max_error = std::max(max_error, std::abs(z[0] - theta));
    if (crossings.size() <= 20) max_error_20 = max_error;
    max_energy_drift = std::max(max_energy_drift, std::abs(0.5 * z[1] * z[1] - std::cos(z[0]) - energy0));
  }
  const double measured = (crossings[100] - crossings[0]) / 100.0;
  INFO("period " << measured << " vs 4K = " << static_cast<double>(period) << " (difference "
                 << measured - static_cast<double>(period) << "), state error " << max_error_20 << " over 20 periods, "
                 << max_error << " over 100, energy drift " << max_energy_drift << ", " << steps << " steps");
  CHECK(std::abs(measured - static_cast<double>(period)) <= 1e-13 * static_cast<double>(period));
  CHECK(std::abs(crossings[0] - static_cast<double>(period / 4)) <= 1e-13);
  // The state: 1e-13 over 20 periods, its t^{3/2} extrapolation over 100 (Brouwer's law, see the
  // Duffing test).
  CHECK(max_error_20 <= 1e-13);
  CHECK(max_error <= 1e-13 * std::pow(5.0, 1.5));
  CHECK(max_energy_drift <= steps * kEps * std::abs(energy0));
}

TEST_CASE("forced damped linear oscillator against its exact solution") {
  // x'' + 2ζ x' + x = F cos(Ω t), x(0) = 0.5, v(0) = 0, over t ∈ [0, 100] (the forcing through
  // an expression in t and Ω, the linear part through the matrices).
  const double zeta = 0.05, force = 0.3, frequency = 1.3;
  TaylorSystem system = one_mass("F*cos(Omega*t)", 1.0, 2.0 * zeta, {{"F", force}}, frequency);
  TaylorStep step(system);
  const long double W = frequency, z = zeta, wd = std::sqrt(1.0L - z * z);
  // Particular solution X cos Ωt + Y sin Ωt.
  const long double a = 1.0L - W * W, b = 2.0L * z * W, det = a * a + b * b;
  const long double X = force * a / det, Y = force * b / det;
  const long double c1 = 0.5L - X, c2 = (0.0L + z * c1 - W * Y) / wd;
  Eigen::VectorXd state(2), next(2);
  state << 0.5, 0.0;
  double t = 0.0, max_error = 0.0;
  for (int j = 1; j <= 100; ++j) {
    const double t1 = j;
    REQUIRE(advance(step, t, state, t1, next) == StepStatus::ok);
    state = next;
    t = t1;
    const long double T = t1, e = std::exp(-z * T);
    const long double x = e * (c1 * std::cos(wd * T) + c2 * std::sin(wd * T)) + X * std::cos(W * T) + Y * std::sin(W * T);
    const long double v = e * (-z * (c1 * std::cos(wd * T) + c2 * std::sin(wd * T)) +
                               wd * (-c1 * std::sin(wd * T) + c2 * std::cos(wd * T))) -
                          W * X * std::sin(W * T) + W * Y * std::cos(W * T);
    max_error = std::max({max_error, std::abs(state[0] - static_cast<double>(x)), std::abs(state[1] - static_cast<double>(v))});
  }
  INFO("max |state error| " << max_error);
  CHECK(max_error <= 1e-13);
}

namespace {

/// Two coupled masses whose forces use every operation of the Dag (and guards with the rest: a
/// quotient by a varying series, time itself, a negation, sqrt, exp and a difference).
TaylorSystemSpec every_operation_spec() {
  TaylorSystemSpec spec;
  spec.mass = (Eigen::Matrix2d() << 2.0, 0.3, 0.3, 1.0).finished();
  spec.stiffness = (Eigen::Matrix2d() << 2.0, -1.0, -1.0, 1.5).finished();
  spec.damping = (Eigen::Matrix2d() << 0.05, 0.0, 0.0, 0.02).finished();
  spec.frequency = 1.1;
  spec.parameters = {{"beta", 0.8}};
  spec.forces = {"-beta*x0^3 + 0.3*cos(Omega*t) + 0.1*sin(x1) - 0.05*v0^2*tanh(x1)",
                 "-0.2*x1^3/(1 + x0^2) + 0.05*exp(-x1^2)*sqrt(1.5 + cos(x0)) + 0.02*log(2 + sin(v1))"
                 " + 0.01*atan(v0)*tan(0.3*x1) + 0.01*(2 + x0)^1.5 - 0.01*(2 + v1)^beta"};
  spec.guards = {"x0/(2 + sin(t)) - t", "-sqrt(3 + x1*v0) + exp(0.2*t)*x0"};
  return spec;
}

}  // namespace

TEST_CASE("the variational matrix equals central differences of the flow") {
  // Over t ∈ [0, 5] (many steps).
  TaylorSystem system(every_operation_spec());
  TaylorStep step(system, {.variational = true});
  Eigen::Vector4d z0(0.4, -0.3, 0.2, 0.5);
  Eigen::VectorXd end(4), plus(4), minus(4);
  Eigen::MatrixXd phi;
  long steps = 0;
  REQUIRE(advance(step, 0.0, z0, 5.0, end, &phi, &steps) == StepStatus::ok);
  CHECK(steps > 5);
  // Central differences: truncation δ²|z'''|/6 ~ 1e-10 and rounding ε/δ ~ 2e-11 for δ = 1e-5, so
  // 1e-8 separates them from a wrong Jacobian (any error in a recurrence shows at ≥ 1e-4).
  TaylorStep plain(system);
  const double delta = 1e-5;
  double worst = 0.0;
  for (int d = 0; d < 4; ++d) {
    Eigen::Vector4d zp = z0, zm = z0;
    zp[d] += delta;
    zm[d] -= delta;
    REQUIRE(advance(plain, 0.0, zp, 5.0, plus) == StepStatus::ok);
    REQUIRE(advance(plain, 0.0, zm, 5.0, minus) == StepStatus::ok);
    const Eigen::VectorXd column = (plus - minus) / (2.0 * delta);
    worst = std::max(worst, (column - phi.col(d)).cwiseAbs().maxCoeff());
  }
  INFO("max |Φ − central difference| " << worst << ", |Φ| " << phi.cwiseAbs().maxCoeff());
  CHECK(worst <= 1e-8 * std::max(1.0, phi.cwiseAbs().maxCoeff()));
  // The state computed with the variational equations on is the plain one (same polynomials for
  // z, only the step sizes may differ through Φ's norms): equal to the integration's accuracy.
  REQUIRE(advance(plain, 0.0, z0, 5.0, plus) == StepStatus::ok);
  CHECK((plus - end).cwiseAbs().maxCoeff() <= 1e-13);
}

// Orders ≥ 1 of a step without tangents run on the flat tape of the Dag (TaylorStep::tape_order);
// with tangents every order runs on the Dag itself (node_order). Both apply the same recurrences
// in the same order, so the state's and the guards' coefficients must be the same to the bit.
TEST_CASE("the tape's coefficients equal the Dag's to the bit") {
  TaylorSystem system(every_operation_spec());
  for (double tolerance : {kEps, 1e-10}) {
    TaylorStep tape(system, {.tolerance = tolerance});
    TaylorStep dag(system, {.tolerance = tolerance, .variational = true});
    const Eigen::Vector4d z0(0.4, -0.3, 0.2, 0.5);
    REQUIRE(tape.expand(0.7, z0) == StepStatus::ok);
    REQUIRE(dag.expand(0.7, z0) == StepStatus::ok);
    const int p = tape.order();
    long differing = 0;
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k <= p; ++k) differing += tape.state_coefficients(i)[k] != dag.state_coefficients(i)[k];
    for (int g = 0; g < 2; ++g)
      for (int k = 0; k <= p; ++k) differing += tape.guard_coefficients(g)[k] != dag.guard_coefficients(g)[k];
    INFO("tolerance " << tolerance << ", order " << p);
    CHECK(differing == 0);
    CHECK(tape.guard_coefficients(1)[p] != 0.0);  // the series reach the last order
  }
}

TEST_CASE("Duffing steps per period and time per step", "[.report]") {
  const DuffingRun run = run_duffing(1.0, 1.0, 100);
  std::printf("Duffing x'' + x + x^3 = 0, A = 1, order 20, tolerance 2^-52:\n"
              "  %.2f steps per period, %.3f us per step (%ld steps in %.4f s), max |error| %.3g, "
              "energy drift %.3g\n",
              run.steps / 100.0, 1e6 * run.seconds / run.steps, run.steps, run.seconds, run.max_error,
              run.max_energy_drift);
  const DuffingRun hard = run_duffing(9.0, 1.5, 100);
  std::printf("Duffing x'' + x + 9x^3 = 0, A = 1.5: max |error| %.3g over 100 periods (velocity scale 6.9)\n",
              hard.max_error);
  // Steps per period without the samples' shortened steps: one advance over 100 periods.
  TaylorSystem system = one_mass("-beta*x0^3", 1.0, 0.0, {{"beta", 1.0}});
  TaylorStep step(system);
  Eigen::VectorXd end(2);
  long steps = 0;
  const auto start = std::chrono::steady_clock::now();
  REQUIRE(advance(step, 0.0, Eigen::Vector2d(1.0, 0.0), 100 * run.period, end, nullptr, &steps) == StepStatus::ok);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("  unsampled: %.2f steps per period, %.3f us per step\n", steps / 100.0, 1e6 * seconds / steps);
  TaylorStep variational(system, {.variational = true});
  Eigen::MatrixXd phi;
  const auto start2 = std::chrono::steady_clock::now();
  REQUIRE(advance(variational, 0.0, Eigen::Vector2d(1.0, 0.0), 100 * run.period, end, &phi, &steps) == StepStatus::ok);
  const double seconds2 = std::chrono::duration<double>(std::chrono::steady_clock::now() - start2).count();
  std::printf("  with variational equations: %.2f steps per period, %.3f us per step\n", steps / 100.0,
              1e6 * seconds2 / steps);
}
