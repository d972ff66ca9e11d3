/// Tests of the tangent maps of framework/analysis (linearisation.hpp): the exact derivative of
/// the state at t1 with respect to the state at t0, a parameter and both times, through impacts,
/// chatter, sticking, releases and simultaneous impacts.
///
/// Against what:
///  1. closed form: a 1-DOF impact oscillator whose period-1 orbit with one impact per period is
///     designed in the test (its stop position and forcing amplitude solved from the wanted impact
///     time and speed), so its monodromy matrix Φ(T/2) S Φ(T/2) and Floquet multipliers are known
///     from the 2 × 2 exponential and the saltation matrix derived by hand below;
///  2. central finite differences of the engine's own map (double), on orbits with impacts,
///     chatter into sticking and releases (the paper's system), plastic impacts, a moving stop, a
///     stop between masses; the tolerance is the finite differences' own accuracy, estimated in
///     each test from two step sizes;
///  3. central finite differences in long double of the same map computed by the independent
///     fixed-step RK8 hybrid integrator (tests/support/reference_hybrid.hpp);
///  4. parameter derivatives (frequency, forcing amplitude, stop position, restitution, damping)
///     against central differences in the parameter; time derivatives likewise;
///  5. structure: the structural zeros sticking produces, and simultaneous impacts (smooth when
///     the order does not matter, flagged non-smooth when it does).
#include "support/analysis_helpers.hpp"
#include "support/designed_orbit.hpp"
#include "support/reference_hybrid.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/models/chain.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::ImpactSystem;
using vibro::LinearisationOptions;
using vibro::LinearSystem;
using vibro::SimulatorOptions;
using vibro::Stop;
using vibro::SystemDerivative;
using vibro::TangentMap;
using vibro::test::DesignedOrbit;

constexpr double kPi = std::numbers::pi;

using vibro::test::engine_map;
using vibro::test::stack;
using vibro::test::state_scale;

/// Central differences of `f` at z0 with steps h·scale_i; the estimate of their own error is the
/// difference between steps h and 2h (the O(h²) truncation of the larger step dominates it).
struct Differences {
  MatrixXd value, error;
};
Differences central(const std::function<VectorXd(const VectorXd&)>& f, const VectorXd& z0,
                    const VectorXd& scale, double h) {
  const VectorXd f0 = f(z0);
  Differences d{MatrixXd(f0.size(), z0.size()), MatrixXd(f0.size(), z0.size())};
  for (Eigen::Index i = 0; i < z0.size(); ++i) {
    auto diff = [&](double step) {
      VectorXd a = z0, b = z0;
      a(i) += step * scale(i);
      b(i) -= step * scale(i);
      return VectorXd((f(a) - f(b)) / (2.0 * step * scale(i)));
    };
    const VectorXd d1 = diff(h), d2 = diff(2.0 * h);
    d.value.col(i) = d1;
    d.error.col(i) = (d2 - d1).cwiseAbs();
  }
  return d;
}

/// |J − D| ≤ bound, entry by entry, where J and D are compared in the state's scales (column i
/// multiplied by scale_i, row r divided by scale_r) and bound = max(floor, 10 × the differences'
/// own error estimate).
void check_against(const MatrixXd& J, const Differences& d, const VectorXd& scale, double floor) {
  double worst = 0.0, worst_bound = 0.0;
  for (Eigen::Index r = 0; r < J.rows(); ++r)
    for (Eigen::Index c = 0; c < J.cols(); ++c) {
      const double k = scale(c) / scale(r);
      const double diff = std::abs(J(r, c) - d.value(r, c)) * k;
      const double bound = std::max(floor, 10.0 * d.error(r, c) * k);
      if (diff - bound > worst - worst_bound) {
        worst = diff;
        worst_bound = bound;
      }
      CHECK(diff <= bound);
    }
  INFO("worst entry difference " << worst << " against its bound " << worst_bound);
  CHECK(worst <= worst_bound);
}

/// A start on the (attracting) periodic orbit of `sys` at forcing phase `phase` (fraction of T),
/// after `transient` periods from rest. The system is T-periodic in t, so the tests start from
/// it at t0 = phase·T: small times keep the rounding of event times (ulp(t)) small, and with it
/// the noise of the finite differences.
VectorXd on_orbit(const ImpactSystem& sys, double transient, double phase) {
  const double T = 2.0 * kPi / sys.system().forcing().frequency;
  return engine_map(sys, {}, 0.0, VectorXd::Zero(2 * sys.dof()), (transient + phase) * T);
}

}  // namespace

TEST_CASE("linearisation: the designed 1-DOF impacting orbits' monodromy matrices and Floquet "
          "multipliers equal the closed form to 1e-10 (a stable and an unstable orbit)",
          "[linearisation][closed-form]") {
  // support/designed_orbit.hpp derives J = Φ(T/2) S Φ(T/2) from half a period after the impact.
  for (const DesignedOrbit& orbit : {DesignedOrbit(0.125), DesignedOrbit(5.0 / 16.0)}) {
    INFO("impact at t* = " << orbit.t_star / orbit.T << " T");
    const ImpactSystem sys = orbit.system();
    const double t0 = orbit.t_star + 0.5 * orbit.T;
    const VectorXd z0 = orbit.state_after_impact(0.5 * orbit.T);
    const TangentMap m = vibro::linearise(sys, {}, t0, z0.head(1), z0.tail(1), t0 + orbit.T);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    REQUIRE(m.saltations.size() == 1);  // the orbit exists as designed: one impact, at t* + T
    CHECK(std::abs(m.saltations[0].t - (orbit.t_star + orbit.T)) < 1e-12 * orbit.T);
    CHECK(std::abs(m.saltations[0].guard_rate - orbit.u) < 1e-12);
    CHECK((stack(m.x1, m.v1) - z0).cwiseAbs().maxCoeff() < 1e-13);  // periodic

    const MatrixXd J = orbit.monodromy();
    CHECK((m.jacobian - J).cwiseAbs().maxCoeff() <= 1e-10 * J.cwiseAbs().maxCoeff());
    // Multipliers: the roots of μ² − tr J μ + det J, det J = r² e^{−cT}.
    const double tr = J.trace(), det = orbit.r * orbit.r * std::exp(-orbit.c * orbit.T);
    CHECK(std::abs(J.determinant() - det) < 1e-12);
    const std::complex<double> disc = std::sqrt(std::complex<double>(tr * tr - 4.0 * det));
    const std::complex<double> mu1 = 0.5 * (tr + disc), mu2 = 0.5 * (tr - disc);
    const Eigen::VectorXcd mu = m.jacobian.eigenvalues();
    const double e1 = std::min(std::abs(mu(0) - mu1) + std::abs(mu(1) - mu2), std::abs(mu(0) - mu2) + std::abs(mu(1) - mu1));
    INFO("closed form " << mu1 << ", " << mu2 << "; computed " << mu(0) << ", " << mu(1));
    CHECK(e1 <= 1e-10);
    CHECK(m.free_dimension == 2);  // nothing held: no structural zero
  }
}

TEST_CASE("linearisation: Jacobians equal central differences of the engine's map through impacts, "
          "chatter, sticking and releases",
          "[linearisation][differences]") {
  SECTION("the paper's system at Ω = 0.27: chatter into sticking on both stops, releases") {
    vibro::models::Wagg2004 p;
    p.frequency = 0.27;
    const ImpactSystem sys = vibro::models::wagg2004(p);
    const double T = 2.0 * kPi / p.frequency;
    const VectorXd z0 = on_orbit(sys, 200.0, 0.0);
    const TangentMap m = vibro::linearise(sys, {}, 0.0, z0.head(2), z0.tail(2), T);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    REQUIRE_FALSE(m.starts_held);
    CHECK(m.summary.chatters >= 2);
    CHECK(m.summary.releases >= 2);
    const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
    const Differences d = central([&](const VectorXd& z) { return engine_map(sys, {}, 0.0, z, T); },
                                  z0, scale, 1e-5);
    check_against(m.jacobian, d, scale, 1e-8);
  }
  SECTION("the chatter rules' own derivatives: a coarse chatter_height (1e-5) makes the caught "
          "bounces' part of the map (the second-order rule's kick) large enough to see") {
    vibro::models::Wagg2004 p;
    p.frequency = 0.27;
    const ImpactSystem sys = vibro::models::wagg2004(p);
    const double T = 2.0 * kPi / p.frequency;
    for (vibro::ChatterRule rule : {vibro::ChatterRule::second_order, vibro::ChatterRule::first_order}) {
      SimulatorOptions o;
      o.chatter_height = 1e-5;
      o.chatter_rule = rule;
      vibro::Simulator sim(sys, o);
      const vibro::RunSummary warm = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 200.0 * T);
      const VectorXd z0 = stack(warm.x, warm.v);
      const TangentMap m = vibro::linearise(sys, o, 0.0, z0.head(2), z0.tail(2), T);
      REQUIRE(m.summary.chatters >= 2);
      const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
      check_against(m.jacobian, central([&](const VectorXd& z) { return engine_map(sys, o, 0.0, z, T); }, z0, scale, 1e-5),
                    scale, 1e-8);
    }
  }
  SECTION("plastic impacts (r = 0) and a moving stop") {
    vibro::models::Wagg2004 p;
    p.frequency = 0.3;
    p.r = 0.0;
    ImpactSystem base = vibro::models::wagg2004(p);
    std::vector<Stop> stops = base.stops();
    stops[1] = stops[1].moving(0.02, 0.4);
    const ImpactSystem sys(base.system(), stops);
    const double T = 2.0 * kPi / p.frequency;
    const VectorXd z0 = on_orbit(sys, 100.0, 0.3);
    const TangentMap m = vibro::linearise(sys, {}, 0.3 * T, z0.head(2), z0.tail(2), 1.3 * T);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    REQUIRE_FALSE(m.starts_held);
    CHECK(m.summary.sticks >= 1);
    const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
    const Differences d = central([&](const VectorXd& z) { return engine_map(sys, {}, 0.3 * T, z, 1.3 * T); },
                                  z0, scale, 1e-5);
    check_against(m.jacobian, d, scale, 1e-8);
  }
  SECTION("a stop between masses (three-mass chain, clearance between masses 1 and 2)") {
    vibro::models::Chain c;
    c.masses = {1.0, 1.0, 1.0};
    c.springs = {1.0, 1.0};
    c.dampers = {0.05, 0.05};
    c.left_spring = 1.0;
    c.left_damper = 0.05;
    c.force_cosine = {0.4, 0.0, 0.0};
    c.frequency = 0.7;
    const ImpactSystem sys(vibro::models::build_chain(c),
                           {Stop::between(1, 2, 0.05, 0.6), Stop::upper(2, 0.2, 0.8)});
    const double T = 2.0 * kPi / c.frequency;
    const VectorXd z0 = on_orbit(sys, 50.0, 0.1);
    const TangentMap m = vibro::linearise(sys, {}, 0.1 * T, z0.head(3), z0.tail(3), 2.1 * T);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    REQUIRE(m.summary.impacts >= 2);
    bool between = false;
    for (const vibro::Event& e : m.events) between |= e.kind == vibro::EventKind::impact && e.stop == 0;
    CHECK(between);
    const VectorXd scale = state_scale(3, 0.2, 0.2 * c.frequency);
    const Differences d = central([&](const VectorXd& z) { return engine_map(sys, {}, 0.1 * T, z, 2.1 * T); },
                                  z0, scale, 1e-5);
    check_against(m.jacobian, d, scale, 1e-8);
  }
}


namespace {

/// The paper's system with one value changed, and the derivative of its data along that value.
struct PaperParameter {
  const char* name;
  std::function<void(vibro::models::Wagg2004&, double)> shift;
  SystemDerivative derivative;
};

std::vector<PaperParameter> paper_parameters() {
  std::vector<PaperParameter> out;
  out.push_back({"frequency", [](auto& p, double h) { p.frequency += h; }, SystemDerivative::frequency_only()});
  SystemDerivative a1;
  a1.cosine = Eigen::Vector2d(1.0, 0.0);
  out.push_back({"A1", [](auto& p, double h) { p.A1 += h; }, a1});
  SystemDerivative s1, s2;  // stop 0 is lower (s0 = −s1), stop 1 upper (s0 = s2)
  s1.stops = {{-1.0, 0.0, 0.0, 0.0}, {}};
  s2.stops = {{}, {1.0, 0.0, 0.0, 0.0}};
  out.push_back({"s1", [](auto& p, double h) { p.s1 += h; }, s1});
  out.push_back({"s2", [](auto& p, double h) { p.s2 += h; }, s2});
  SystemDerivative r;
  r.stops = {{0.0, 0.0, 0.0, 1.0}, {0.0, 0.0, 0.0, 1.0}};
  out.push_back({"r", [](auto& p, double h) { p.r += h; }, r});
  SystemDerivative c;  // C = c E, E = [[2, −1], [−1, 1]]
  c.damping = (MatrixXd(2, 2) << 2.0, -1.0, -1.0, 1.0).finished();
  out.push_back({"c", [](auto& p, double h) { p.c += h; }, c});
  return out;
}

}  // namespace

TEST_CASE("linearisation: parameter derivatives equal central differences in the parameter "
          "(frequency, forcing amplitude, stop positions, restitution, damping)",
          "[linearisation][parameter]") {
  for (double omega : {0.27, 0.3}) {
    vibro::models::Wagg2004 p0;
    p0.frequency = omega;
    const ImpactSystem sys = vibro::models::wagg2004(p0);
    const double T = 2.0 * kPi / omega;
    const VectorXd z0 = on_orbit(sys, 200.0, 0.1);
    const VectorXd scale = state_scale(2, 0.3, 0.3 * omega);
    for (const PaperParameter& q : paper_parameters()) {
      INFO("Omega = " << omega << ", parameter " << q.name);
      LinearisationOptions o;
      o.parameter = q.derivative;
      const TangentMap m = vibro::linearise(sys, {}, 0.1 * T, z0.head(2), z0.tail(2), 1.1 * T, o);
      REQUIRE(m.summary.status == vibro::RunStatus::completed);
      REQUIRE(m.parameter.size() == 4);
      auto at = [&](const VectorXd& h) {
        vibro::models::Wagg2004 p = p0;
        q.shift(p, h(0));
        return engine_map(vibro::models::wagg2004(p), {}, 0.1 * T, z0, 1.1 * T);
      };
      const Differences d = central(at, VectorXd::Zero(1), VectorXd::Ones(1), 1e-6);
      // In the state's scales, relative to the parameter's own size (p or 1).
      for (Eigen::Index r = 0; r < 4; ++r) {
        const double diff = std::abs(m.parameter(r) - d.value(r, 0)) / scale(r);
        const double bound = std::max(1e-8, 10.0 * d.error(r, 0) / scale(r));
        INFO("row " << r << ": exact " << m.parameter(r) << ", differences " << d.value(r, 0));
        CHECK(diff <= bound);
      }
    }
  }
}

TEST_CASE("linearisation: time derivatives: dz1/dt1 is the vector field at the end, dz1/dt0 is "
          "-J times the vector field at the start",
          "[linearisation][time]") {
  vibro::models::Wagg2004 p;
  p.frequency = 0.27;
  const ImpactSystem sys = vibro::models::wagg2004(p);
  const double T = 2.0 * kPi / p.frequency;
  const VectorXd z0 = on_orbit(sys, 200.0, 0.1);
  const double t0 = 0.1 * T, t1 = 1.1 * T;
  const TangentMap m = vibro::linearise(sys, {}, t0, z0.head(2), z0.tail(2), t1);
  const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
  const Differences end = central([&](const VectorXd& h) { return engine_map(sys, {}, t0, z0, t1 + h(0)); },
                                  VectorXd::Zero(1), VectorXd::Ones(1), 1e-6);
  // The start moves along the trajectory: from (t0 + h) with the state the orbit has there.
  const Differences start = central(
      [&](const VectorXd& h) { return engine_map(sys, {}, t0 + h(0), z0, t1); }, VectorXd::Zero(1),
      VectorXd::Ones(1), 1e-6);
  const VectorXd dstart = -m.jacobian * m.rate_start;
  for (Eigen::Index r = 0; r < 4; ++r) {
    CHECK(std::abs(m.rate_end(r) - end.value(r, 0)) / scale(r) <= std::max(1e-8, 10.0 * end.error(r, 0) / scale(r)));
    CHECK(std::abs(dstart(r) - start.value(r, 0)) / scale(r) <= std::max(1e-8, 10.0 * start.error(r, 0) / scale(r)));
  }
}

TEST_CASE("linearisation: Jacobians equal long-double central differences of the independent "
          "RK8 hybrid integrator's map (impacts, plastic impacts into sticking and releases)",
          "[linearisation][reference]") {
  using vibro::test::ReferenceHybrid;
  using VectorL = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
  auto reference_map = [](const ImpactSystem& sys, double t0, double t1) {
    return [&sys, t0, t1](const VectorXd& z) {
      const auto n = sys.dof();
      ReferenceHybrid ref(sys);
      const VectorL z0 = z.cast<long double>();
      ref.run(t0, z0.head(n), z0.tail(n), t1);
      VectorXd out(2 * n);
      for (Eigen::Index i = 0; i < n; ++i) {
        out(i) = static_cast<double>(ref.x(i));
        out(n + i) = static_cast<double>(ref.v(i));
      }
      return out;
    };
  };
  // Long double differences of the reference: the map is evaluated in long double and only its
  // result rounded, so the difference quotient at h = 1e-5 carries ~1e-16/1e-5 of rounding and
  // h² of truncation; the reference's own integration error (≲ 1e-13, smooth in z0) adds less.
  SECTION("designed 1-DOF orbit (impacts only)") {
    const DesignedOrbit orbit;
    const ImpactSystem sys = orbit.system();
    const double t0 = orbit.t_star + 0.5 * orbit.T;
    const VectorXd z0 = orbit.state_after_impact(0.5 * orbit.T);
    const double t1 = t0 + 3.0 * orbit.T;
    const TangentMap m = vibro::linearise(sys, {}, t0, z0.head(1), z0.tail(1), t1);
    const VectorXd scale = state_scale(1, orbit.s, orbit.s * orbit.omega);
    check_against(m.jacobian, central(reference_map(sys, t0, t1), z0, scale, 1e-5), scale, 1e-8);
  }
  SECTION("the paper's system with r = 0: each mass sticks at impact and is released") {
    vibro::models::Wagg2004 p;
    p.frequency = 0.3;
    p.r = 0.0;
    const ImpactSystem sys = vibro::models::wagg2004(p);
    const double T = 2.0 * kPi / p.frequency;
    const VectorXd z0 = on_orbit(sys, 100.0, 0.3);
    const TangentMap m = vibro::linearise(sys, {}, 0.3 * T, z0.head(2), z0.tail(2), 1.3 * T);
    REQUIRE(m.summary.sticks >= 1);
    REQUIRE(m.summary.releases >= 1);
    const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
    check_against(m.jacobian, central(reference_map(sys, 0.3 * T, 1.3 * T), z0, scale, 1e-5), scale, 1e-8);
  }
}

TEST_CASE("linearisation: sticking gives exact structural zeros, the reduced map carries the "
          "other multipliers and their eigenvectors",
          "[linearisation][structure]") {
  // Ω = 0.255 (Wagg 2004, fig. 2): each mass sticks once per period, one at a time, so the
  // least tangent dimension is 2(n − 1) = 2 and J = ∂z(T)/∂z(0) has 2 zero eigenvalues.
  vibro::models::Wagg2004 p;
  const ImpactSystem sys = vibro::models::wagg2004(p);
  const double T = 2.0 * kPi / p.frequency;
  const VectorXd z0 = on_orbit(sys, 200.0, 0.0);
  const TangentMap m = vibro::linearise(sys, {}, 0.0, z0.head(2), z0.tail(2), T);
  REQUIRE_FALSE(m.starts_held);
  CHECK(m.free_dimension == 2);
  REQUIRE(m.reduced.rows() == 2);
  const Eigen::VectorXcd mu = m.reduced.eigenvalues();
  const Eigen::VectorXcd all = m.jacobian.eigenvalues();
  // Two of J's eigenvalues vanish (to rounding of ‖J‖), the other two are the reduced map's.
  std::vector<double> moduli;
  for (Eigen::Index i = 0; i < 4; ++i) moduli.push_back(std::abs(all(i)));
  std::sort(moduli.begin(), moduli.end());
  const double norm = m.jacobian.norm();
  CHECK(moduli[0] <= 1e-13 * norm);
  CHECK(moduli[1] <= 1e-13 * norm);
  for (Eigen::Index k = 0; k < 2; ++k) {
    double closest = 1e300;
    for (Eigen::Index i = 0; i < 4; ++i) closest = std::min(closest, std::abs(all(i) - mu(k)));
    CHECK(closest <= 1e-10 * std::max(1.0, std::abs(mu(k))));
    // The lifted eigenvector is J's.
    Eigen::ComplexEigenSolver<Eigen::MatrixXcd> es(m.reduced.cast<std::complex<double>>());
    const Eigen::VectorXcd e = m.lift.cast<std::complex<double>>() * es.eigenvectors().col(k);
    const Eigen::VectorXcd residual = m.jacobian.cast<std::complex<double>>() * e - es.eigenvalues()(k) * e;
    CHECK(residual.norm() <= 1e-12 * std::max(1.0, norm) * e.norm());
  }
}

namespace {

/// Two masses, each on a wall spring and damper, joined by a spring kc (and a damper cc), both
/// driven by the same A cos Ωt, each with an upper stop at the same place: the symmetric motion
/// hits both stops at the same instants.
ImpactSystem symmetric_pair(double coupling_damper) {
  vibro::models::Chain c;
  c.masses = {1.0, 1.0};
  c.springs = {0.5};
  c.dampers = {coupling_damper};
  c.left_spring = c.right_spring = 1.0;
  c.left_damper = c.right_damper = 0.05;
  c.force_cosine = {0.3, 0.3};
  c.frequency = 0.9;
  // The right wall pulls mass 1 the other way: x1 is measured from its own rest, so with the
  // same force and stops both masses move alike (the coupling spring never stretches).
  return ImpactSystem(vibro::models::build_chain(c), {Stop::upper(0, 0.15, 0.8), Stop::upper(1, 0.15, 0.8)});
}

}  // namespace

TEST_CASE("linearisation: simultaneous impacts: smooth when their order does not matter (equal "
          "to finite differences), flagged non-smooth when a coupling damper makes it matter",
          "[linearisation][simultaneous]") {
  const ImpactSystem sys = symmetric_pair(0.0);
  const double T = 2.0 * kPi / 0.9;
  const VectorXd z0 = on_orbit(sys, 60.0, 0.05);
  REQUIRE(std::abs(z0(0) - z0(1)) < 1e-12);
  const TangentMap m = vibro::linearise(sys, {}, 0.05 * T, z0.head(2), z0.tail(2), 1.05 * T);
  REQUIRE(m.summary.status == vibro::RunStatus::completed);
  int simultaneous = 0;
  for (const vibro::SaltationRecord& r : m.saltations) {
    if (!r.simultaneous) continue;
    ++simultaneous;
    CHECK(r.impacting.size() == 2);
    CHECK(r.order_spread < 1e-12);
  }
  REQUIRE(simultaneous >= 1);
  CHECK_FALSE(m.non_smooth);
  const VectorXd scale = state_scale(2, 0.15, 0.15 * 0.9);
  check_against(m.jacobian,
                central([&](const VectorXd& z) { return engine_map(sys, {}, 0.05 * T, z, 1.05 * T); }, z0, scale, 1e-5),
                scale, 1e-8);

  const ImpactSystem damped = symmetric_pair(0.05);
  const VectorXd w0 = on_orbit(damped, 60.0, 0.05);
  const TangentMap d = vibro::linearise(damped, {}, 0.05 * T, w0.head(2), w0.tail(2), 1.05 * T);
  bool found = false;
  for (const vibro::SaltationRecord& r : d.saltations) found |= r.simultaneous && r.order_spread > 1e-8;
  CHECK(found);
  CHECK(d.non_smooth);
  CHECK(d.non_smooth_reason.find("simultaneous impacts") != std::string::npos);
}

TEST_CASE("linearisation: on a 32-mass chain (eigen-decomposition path of the flows and of the "
          "parameter sensitivity) Jacobian and parameter derivatives equal central differences",
          "[linearisation][large]") {
  // 2n + 3 = 67 > 64: the tangent maps of free flight take the eigen-decomposition of the flow
  // (its cond(V) ≤ 1e4 makes that path's rounding ~1e-12) and the parameter sensitivity the
  // divided differences of its eigenvalues instead of a 134 × 134 block exponential.
  const int n = 32;
  auto chain_at = [](double omega, double amplitude) {
    vibro::models::Chain c;
    c.masses.assign(n, 1.0);
    c.springs.assign(n - 1, 1.0);
    c.dampers.assign(n - 1, 0.2);
    c.left_spring = 1.0;
    c.left_damper = 0.2;
    c.force_cosine.assign(n, 0.0);
    c.force_cosine[0] = amplitude;
    c.frequency = omega;
    return ImpactSystem(vibro::models::build_chain(c), {Stop::upper(0, 0.3, 0.8)});
  };
  const double omega = 0.6, amplitude = 0.5;
  const ImpactSystem sys = chain_at(omega, amplitude);
  const double T = 2.0 * kPi / omega;
  const VectorXd z0 = engine_map(sys, {}, 0.0, VectorXd::Zero(2 * n), 30.0 * T);
  for (int which = 0; which < 2; ++which) {
    LinearisationOptions o;
    SystemDerivative d;
    if (which == 0) {
      d = SystemDerivative::frequency_only();
    } else {
      d.cosine = VectorXd::Zero(n);
      d.cosine(0) = 1.0;
    }
    o.parameter = d;
    const TangentMap m = vibro::linearise(sys, {}, 0.1 * T, z0.head(n), z0.tail(n), 1.1 * T, o);
    REQUIRE(m.summary.status == vibro::RunStatus::completed);
    REQUIRE(m.summary.impacts >= 1);
    auto at = [&](const VectorXd& h) {
      return engine_map(which == 0 ? chain_at(omega + h(0), amplitude) : chain_at(omega, amplitude + h(0)), {}, 0.1 * T,
                        z0, 1.1 * T);
    };
    const Differences fd = central(at, VectorXd::Zero(1), VectorXd::Ones(1), 1e-6);
    const VectorXd scale = state_scale(n, 0.3, 0.3 * omega);
    double worst = 0.0;
    for (Eigen::Index r = 0; r < 2 * n; ++r) {
      const double diff = std::abs(m.parameter(r) - fd.value(r, 0)) / scale(r);
      const double bound = std::max(1e-8, 10.0 * fd.error(r, 0) / scale(r));
      worst = std::max(worst, diff / bound);
      CHECK(diff <= bound);
    }
    INFO("worst difference / bound " << worst);
    if (which == 0) {
      // The Jacobian too, a few columns.
      for (Eigen::Index col : {Eigen::Index(0), Eigen::Index(n), Eigen::Index(2 * n - 1)}) {
        auto f = [&](const VectorXd& h) {
          VectorXd z = z0;
          z(col) += h(0);
          return engine_map(sys, {}, 0.1 * T, z, 1.1 * T);
        };
        const Differences dc = central(f, VectorXd::Zero(1), VectorXd::Ones(1), 1e-6);
        for (Eigen::Index r = 0; r < 2 * n; ++r)
          CHECK(std::abs(m.jacobian(r, col) - dc.value(r, 0)) <= std::max(1e-8, 10.0 * dc.error(r, 0)) * std::max(1.0, std::abs(dc.value(r, 0))));
      }
    }
  }
}

// A stop moving with three harmonics of Ω (stops.hpp): the tangent map through its impacts and
// sticking, and the derivative in its second harmonic's cosine (SystemDerivative's
// stop_harmonic_cosine), against central differences of the engine's map, with the bounds of
// the tests above.
TEST_CASE("linearisation: a stop moving with three harmonics: Jacobian and the derivative in its "
          "second harmonic equal central differences",
          "[linearisation][differences][parameter]") {
  vibro::models::Wagg2004 p;
  p.frequency = 0.3;
  p.r = 0.0;
  const ImpactSystem plain = vibro::models::wagg2004(p);
  auto with_stop = [&](double c2) {
    std::vector<Stop> stops = plain.stops();
    stops[1] = stops[1].moving(0.02, 0.4).with_harmonics({{2, c2, -0.005}, {3, 0.0, 0.004}});
    return ImpactSystem(plain.system(), stops);
  };
  const ImpactSystem sys = with_stop(0.01);
  REQUIRE(sys.system().forcing().harmonics.size() == 2);
  const double T = 2.0 * kPi / p.frequency;
  const VectorXd z0 = on_orbit(sys, 100.0, 0.3);
  LinearisationOptions o;
  o.parameter = SystemDerivative{};
  o.parameter->stop_harmonic_cosine = {{}, {1.0, 0.0}};  // stop 1 is upper: s = p
  const TangentMap m = vibro::linearise(sys, {}, 0.3 * T, z0.head(2), z0.tail(2), 1.3 * T, o);
  REQUIRE(m.summary.status == vibro::RunStatus::completed);
  REQUIRE_FALSE(m.starts_held);
  CHECK(m.summary.impacts + m.summary.sticks >= 1);
  const VectorXd scale = state_scale(2, 0.3, 0.3 * p.frequency);
  check_against(m.jacobian,
                central([&](const VectorXd& z) { return engine_map(sys, {}, 0.3 * T, z, 1.3 * T); }, z0, scale, 1e-5),
                scale, 1e-8);
  REQUIRE(m.parameter.size() == 4);
  const Differences d = central(
      [&](const VectorXd& h) { return engine_map(with_stop(0.01 + h(0)), {}, 0.3 * T, z0, 1.3 * T); },
      VectorXd::Zero(1), VectorXd::Ones(1), 1e-6);
  for (Eigen::Index r = 0; r < 4; ++r) {
    const double diff = std::abs(m.parameter(r) - d.value(r, 0)) / scale(r);
    const double bound = std::max(1e-8, 10.0 * d.error(r, 0) / scale(r));
    INFO("row " << r << ": exact " << m.parameter(r) << ", differences " << d.value(r, 0));
    CHECK(diff <= bound);
  }
  CHECK(m.parameter.cwiseAbs().maxCoeff() > 1e-3);  // the harmonic moves the map
}
