/// The analysis layer on compliant (Kelvin–Voigt) stops (linearisation.hpp, stops.hpp), on the
/// 1-DOF soft-impact oscillator m x'' + c x' + k x = F cos Ωt with a spring-dashpot stop of
/// stiffness k_s, damping c_s and preload F_p engaged while x > p:
///  1. the tangent map across one engagement against the product of the two modes' own
///     transition matrices (2 × 2 exponentials written here) and the saltation matrix
///     S = I + (f⁺ − f⁻) ∇gᵀ / ġ written out for this system, S = [[1, 0], [∓(c_s ġ + F_p)/(m ġ), 1]]:
///     S = I exactly for c_s = 0 and F_p = 0, and far from I with a dashpot or a preload;
///  2. shooting's periodic orbit and its Jacobian over one period against central finite
///     differences of the engine's period map, with c_s > 0, with a preload, and with neither;
///  3. the Lyapunov exponents along that orbit against its Floquet multipliers;
///  4. continuation in Ω locating the grazing of the compliant stop against the closed form: the
///     non-contacting orbit is the linear response of amplitude A(Ω) = F/√((k − mΩ²)² + (cΩ)²),
///     which touches the stop where A(Ω) = p, a quadratic in Ω².
#include "support/analysis_helpers.hpp"
#include "vibro/continuation.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/lyapunov.hpp"
#include "vibro/shooting.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <complex>
#include <numbers>

namespace {

using Eigen::Matrix2d;
using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::test::stack;

struct Oscillator {
  double m = 1.0, c = 0.1, k = 1.0, F = 0.25, omega = 0.9;
  double p = 1.0, ks = 10.0, cs = 0.0, fp = 0.0;

  vibro::ImpactSystem scene() const { return scene_at(omega); }
  vibro::ImpactSystem scene_at(double w) const {
    vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(1, w);
    f.cosine(0) = F;
    return vibro::ImpactSystem(vibro::LinearSystem(MatrixXd::Constant(1, 1, m), MatrixXd::Constant(1, 1, c),
                                                   MatrixXd::Constant(1, 1, k), f),
                               {vibro::Stop::upper(0, p, 1.0).compliant(ks, cs, fp)});
  }
  /// The state block of one mode's flow over τ: exp([[0, 1], [−K/m, −C/m]] τ).
  Matrix2d flow(bool engaged, double tau) const {
    Matrix2d A;
    A << 0.0, 1.0, -(k + (engaged ? ks : 0.0)) / m, -(c + (engaged ? cs : 0.0)) / m;
    return (A * tau).exp();
  }
  double period() const { return 2.0 * std::numbers::pi / omega; }
};

/// A state on the attracting orbit (after 150 periods from rest) and the orbit by shooting.
vibro::ShootingResult orbit_of(const Oscillator& o) {
  const vibro::ImpactSystem sys = o.scene();
  vibro::Simulator warm(sys);
  const vibro::RunSummary w = warm.run(0.0, VectorXd::Zero(1), VectorXd::Zero(1), 150.0 * o.period());
  REQUIRE(w.status == vibro::RunStatus::completed);
  const vibro::ShootingResult r = vibro::shoot(sys, {}, w.t, w.x, w.v);
  INFO(r.message);
  REQUIRE(r.converged());
  return r;
}

/// ‖J − central differences of the period map‖ / ‖J‖, the step h = 1e-5 of the state's scale.
/// Truncation is h² |P'''| ~ 1e-10 and the runs' rounding ~ ε/h ~ 1e-11 (the events are located
/// to a few ulps and the flows are exact to rounding), so a correct J agrees to ~1e-9; a saltation
/// left out would miss by |S − I| ~ c_s/m or F_p/(m ġ), i.e. O(0.1 – 1).
double finite_difference_mismatch(const Oscillator& o, const vibro::ShootingResult& r) {
  const vibro::ImpactSystem sys = o.scene();
  const VectorXd z = stack(r.x, r.v);
  const double T = o.period();
  const double h = 1e-5;
  MatrixXd fd(2, 2);
  for (int i = 0; i < 2; ++i) {
    VectorXd e = VectorXd::Zero(2);
    e(i) = h;
    fd.col(i) = (vibro::test::engine_map(sys, {}, r.t0, z + e, r.t0 + T) -
                 vibro::test::engine_map(sys, {}, r.t0, z - e, r.t0 + T)) /
                (2.0 * h);
  }
  INFO("J = " << r.map.jacobian << "\nfinite differences = " << fd);
  return (r.map.jacobian - fd).norm() / r.map.jacobian.norm();
}

int count(const vibro::TangentMap& m, vibro::EventKind kind) {
  int n = 0;
  for (const vibro::Event& e : m.events) n += e.kind == kind;
  return n;
}

}  // namespace

TEST_CASE("compliant stops: the tangent map across an engagement is the two flows and the saltation "
          "matrix S = I + (f+ - f-) grad g^T / g'",
          "[compliant][linearisation]") {
  struct Case {
    double cs, fp;
  };
  for (const Case cse : {Case{0.0, 0.0}, Case{0.3, 0.0}, Case{0.0, 0.2}, Case{0.3, 0.2}}) {
    Oscillator o;
    o.cs = cse.cs;
    o.fp = cse.fp;
    INFO("c_s = " << o.cs << ", F_p = " << o.fp);
    const vibro::ImpactSystem sys = o.scene();
    // From below the stop, rising fast enough to engage and not yet to leave again.
    const double t0 = 0.3;
    VectorXd x0(1), v0(1);
    x0 << 0.9;
    v0 << 0.8;
    // Find the engagement time first, then linearise over [t0, t1] with t1 inside the contact.
    vibro::LinearisationOptions lo;
    const vibro::TangentMap probe = vibro::linearise(sys, {}, t0, x0, v0, t0 + 0.3, lo);
    REQUIRE(probe.summary.status == vibro::RunStatus::completed);
    REQUIRE(probe.events.size() == 1);
    REQUIRE(probe.events[0].kind == vibro::EventKind::engage);
    const double te = probe.events[0].t;
    const double rate = probe.events[0].v_before;  // ġ = v at the switch (w = 1, fixed stop)
    REQUIRE(rate > 0.0);
    Matrix2d S = Matrix2d::Identity();
    S(1, 0) = -(o.cs * rate + o.fp) / (o.m * rate);  // engaging: f⁺ − f⁻ = (0, −(c_s ġ + F_p)/m)
    const Matrix2d expected = o.flow(true, t0 + 0.3 - te) * S * o.flow(false, te - t0);
    const MatrixXd J = probe.jacobian;
    INFO("J = " << J << "\nexpected = " << expected);
    // Both are products of exact exponentials (to rounding, ~1e-15 relative each) and of S; the
    // event time enters the expected value through the engine's te (located to a few ulps).
    CHECK((J - expected).norm() <= 1e-12 * expected.norm());
    if (o.cs == 0.0 && o.fp == 0.0) {
      // S = I: the vector field is continuous across g = 0.
      CHECK((S - Matrix2d::Identity()).norm() == 0.0);
    } else {
      // With a dashpot or a preload S is far from I, so the check above tests it.
      CHECK((S - Matrix2d::Identity()).norm() > 0.1);
    }
    // Disengaging: from inside the stop moving out.
    VectorXd x1(1), v1(1);
    x1 << 1.05;
    v1 << -0.8;
    const vibro::TangentMap out = vibro::linearise(sys, {}, t0, x1, v1, t0 + 0.15, lo);
    REQUIRE(out.summary.status == vibro::RunStatus::completed);
    REQUIRE(out.events.size() == 1);
    REQUIRE(out.events[0].kind == vibro::EventKind::disengage);
    const double td = out.events[0].t, rd = out.events[0].v_before;
    REQUIRE(rd < 0.0);
    Matrix2d Sd = Matrix2d::Identity();
    Sd(1, 0) = (o.cs * rd + o.fp) / (o.m * rd);  // f⁺ − f⁻ = (0, +N/m), N = c_s ġ + F_p at g = 0
    const Matrix2d expected_out = o.flow(false, t0 + 0.15 - td) * Sd * o.flow(true, td - t0);
    CHECK((out.jacobian - expected_out).norm() <= 1e-12 * expected_out.norm());
  }
}

TEST_CASE("compliant stops: shooting's Jacobian over a period matches central differences of the "
          "period map, with a dashpot, with a preload and with neither",
          "[compliant][shooting]") {
  struct Case {
    double cs, fp;
  };
  for (const Case cse : {Case{0.3, 0.0}, Case{0.0, 0.2}, Case{0.0, 0.0}}) {
    Oscillator o;
    o.cs = cse.cs;
    o.fp = cse.fp;
    INFO("c_s = " << o.cs << ", F_p = " << o.fp);
    const vibro::ShootingResult r = orbit_of(o);
    // The orbit engages the stop once per period.
    CHECK(count(r.map, vibro::EventKind::engage) == 1);
    CHECK(count(r.map, vibro::EventKind::disengage) == 1);
    CHECK(finite_difference_mismatch(o, r) <= 1e-8);
    // The multipliers are J's eigenvalues: both inside the unit circle for this damped orbit.
    CHECK(r.multipliers.stable);
    const Eigen::VectorXcd mu = r.map.jacobian.eigenvalues();
    CHECK(std::abs(std::abs(mu(0) * mu(1)) - std::abs(r.multipliers.values(0) * r.multipliers.values(1))) <= 1e-12);
  }
}

TEST_CASE("compliant stops: continuation in the frequency locates the grazing of the compliant stop "
          "where the linear response's amplitude reaches the stop",
          "[compliant][continuation]") {
  Oscillator o;
  o.cs = 0.3;
  // The non-contacting orbit at Ω = 0.8: x = Re(X e^{iΩt}), X = F/(k − mΩ² + icΩ).
  const double w0 = 0.8;
  const std::complex<double> X = o.F / std::complex<double>(o.k - o.m * w0 * w0, o.c * w0);
  VectorXd x0(1), v0(1);
  x0 << X.real();
  v0 << -w0 * X.imag();
  const vibro::ParameterFamily family = [o](double w) {
    return vibro::FamilyPoint{o.scene_at(w), vibro::SystemDerivative::frequency_only()};
  };
  vibro::ContinuationOptions opt;
  opt.p_min = 0.8;
  opt.p_max = 0.95;
  opt.step = 0.02;
  const vibro::ContinuationResult r = vibro::continue_orbits(family, w0, 0.0, x0, v0, opt);
  REQUIRE_FALSE(r.branches.empty());
  // Grazing: (k − mΩ²)² + (cΩ)² = (F/p)², a quadratic in W = Ω²; the lower root (long double).
  using ld = long double;
  const ld m = o.m, k = o.k, c = o.c, q = static_cast<ld>(o.F) / o.p;
  const ld b = c * c - 2 * k * m, disc = std::sqrt(b * b - 4 * m * m * (k * k - q * q));
  const double graze = static_cast<double>(std::sqrt((-b - disc) / (2 * m * m)));
  const vibro::Bifurcation* found = nullptr;
  for (const vibro::Bifurcation& f : r.bifurcations)
    if (f.kind == vibro::BifurcationKind::grazing && f.branch == 0) found = &f;
  INFO("branch: " << r.branches[0].end << "; expected grazing at " << graze);
  REQUIRE(found != nullptr);
  INFO("located at " << found->p << " (bracket " << found->p_low << " … " << found->p_high << ", value " << found->value << ")");
  CHECK(found->stop == 0);
  CHECK(found->smooth);
  // Located to the continuation's tolerance (1e-10) by the one-sided secant on the largest gap
  // maximum, which is A(Ω) − p, smooth in Ω on the side without contact.
  CHECK(std::abs(found->p - graze) <= 1e-9);
  // Beyond it the orbit engages once per period: the signature counts the engagement.
  const vibro::BranchPoint& last = r.branches[0].points.back();
  CHECK(last.signature.impacts[0] == 1);
  CHECK(r.branches[0].points.front().signature.impacts[0] == 0);
}

TEST_CASE("compliant stops: Lyapunov exponents along a periodic orbit with a dashpot are its "
          "multipliers' log|mu| / T",
          "[compliant][lyapunov]") {
  Oscillator o;
  o.cs = 0.3;
  o.fp = 0.1;
  const vibro::ShootingResult r = orbit_of(o);
  vibro::LyapunovOptions lo;
  lo.transient = 0;
  lo.align = 50;
  lo.periods = 1000;
  const vibro::LyapunovResult l = vibro::lyapunov_spectrum(o.scene(), {}, r.t0, r.x, r.v, lo);
  REQUIRE(l.status == vibro::RunStatus::completed);
  REQUIRE(l.exponents.size() == 2);
  const double T = o.period();
  const double top = std::log(std::abs(r.multipliers.values(0))) / T;
  const double bottom = std::log(std::abs(r.multipliers.values(1))) / T;
  INFO("exponents " << l.exponents.transpose() << ", from the multipliers " << top << ", " << bottom);
  // The sum is log|det J| / T on every period (the frame's QR keeps volumes exactly; det S = 1
  // here, S being unit lower triangular), to rounding over 1000 periods.
  CHECK(std::abs(l.exponents.sum() - (top + bottom)) <= 1e-10 * std::abs(top + bottom));
  // Each converges like log(cond of J's eigenvectors)/(N T), N = 1000 periods of T ≈ 7.
  CHECK(std::abs(l.exponents(0) - top) <= 1e-3);
  CHECK(std::abs(l.exponents(1) - bottom) <= 1e-3);
}
