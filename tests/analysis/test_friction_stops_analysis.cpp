// The analysis layer on scenes with friction and stops (friction_tangent.hpp, the ImpactSystem
// overloads): the period map's Jacobian of orbits with impacts and stick-slip against Richardson
// central differences of the map, the Floquet multipliers with the structural zeros of a stuck
// contact and of a held stop, the parameter column (Ω, the forcing, a stop's position and
// restitution, a contact's N, μ_s, μ_k) against central differences, the Lyapunov spectrum's
// structural exponents, and a continuation in Ω whose orbits are shot again.
#include "vibro/continuation.hpp"
#include "vibro/friction_tangent.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <string>

using namespace vibro;

namespace {

/// Scene A (1 DOF): experiments/examples/stick_slip.yaml's mass on a moving belt (m = k = 1,
/// c = 0.05, f = fc cos Ωt; N = 1, μ_s = 0.5, μ_k = 0.3, belt 0.5 cos(Ωt + 0.3)) with a rigid
/// upper stop at 1 (r = 0.7). Its period-1 orbit at Ω = 0.6 sticks twice to the belt, slips
/// twice, and strikes the stop once, the impact reversing its slip (one event, two changes).
ImpactSystem belt_with_stop(double omega = 0.6, double fc = 1.0, double position = 1.0, double r = 0.7) {
  HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, fc),
                    .sine = Eigen::VectorXd::Zero(1), .frequency = omega};
  const LinearSystem sys(Eigen::MatrixXd::Identity(1, 1), Eigen::MatrixXd::Constant(1, 1, 0.05),
                         Eigen::MatrixXd::Identity(1, 1), f);
  return ImpactSystem(sys, {Stop::upper(0, position, r)});
}
std::vector<FrictionContact> belt(double N = 1.0, double mu_s = 0.5, double mu_k = 0.3) {
  return {FrictionContact::on_surface(0, N, mu_s, mu_k, 0.5, 0.3)};
}

/// Scene B (2 DOF): mass 0 on the same belt, tied to the wall (k = 1, c = 0.05) and by a spring
/// and dashpot (1, 0.05) to mass 1, which is forced (cos 0.6 t) and meets a plastic stop at 1.2
/// (r = 0): each period it sticks on the stop until its force lets go, and mass 0 sticks to the
/// belt once.
ImpactSystem plastic_pair() {
  Eigen::Matrix2d K, C;
  K << 2.0, -1.0, -1.0, 1.0;
  C << 0.1, -0.05, -0.05, 0.05;
  HarmonicForcing f{.constant = Eigen::Vector2d::Zero(), .cosine = Eigen::Vector2d(0.0, 1.0),
                    .sine = Eigen::Vector2d::Zero(), .frequency = 0.6};
  return ImpactSystem(LinearSystem(Eigen::Matrix2d::Identity(), C, K, f), {Stop::upper(1, 1.2, 0.0)});
}

Eigen::VectorXd stacked(const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  Eigen::VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// The map z ↦ (x, v)(t1) of a run from (t0, z).
Eigen::VectorXd map_of(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts, double t0,
                       const Eigen::VectorXd& z, double t1) {
  FrictionStopSimulator sim(scene, contacts);
  const Eigen::Index n = scene.dof();
  const RunSummary s = sim.run(t0, z.head(n), z.tail(n), t1);
  REQUIRE(s.status == RunStatus::completed);
  return stacked(s.x, s.v);
}

/// Richardson's extrapolation of central differences of g at 0 with steps h and h/2: the error
/// is O(h⁴) (truncation) plus ~3 δ/h (δ the rounding of g).
Eigen::VectorXd richardson(const std::function<Eigen::VectorXd(double)>& g, double h) {
  const Eigen::VectorXd d1 = (g(h) - g(-h)) / (2.0 * h);
  const Eigen::VectorXd d2 = (g(h / 2) - g(-h / 2)) / h;
  return (4.0 * d2 - d1) / 3.0;
}

Eigen::MatrixXd richardson_jacobian(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts, double t0,
                                    const Eigen::VectorXd& z, double t1, double h, double L, double V) {
  const Eigen::Index n2 = z.size();
  Eigen::MatrixXd J(n2, n2);
  for (Eigen::Index i = 0; i < n2; ++i) {
    const double scale = i < n2 / 2 ? L : V;
    J.col(i) = richardson(
        [&](double s) {
          Eigen::VectorXd zs = z;
          zs(i) += s * scale;
          return map_of(scene, contacts, t0, zs, t1);
        },
        h) / scale;
  }
  return J;
}

int count(const TangentMap& m, EventKind kind) {
  int n = 0;
  for (const Event& e : m.events) n += e.kind == kind;
  return n;
}

/// The middle of the longest stretch of [t0, t1] free of events and of held or stuck phases.
double free_time(const TangentMap& m) {
  std::vector<double> busy{m.t0, m.t1};
  for (const Event& e : m.events) busy.push_back(e.t);
  for (const HeldPhase& h : m.phases) {
    busy.push_back(h.t_start);
    busy.push_back(h.t_end);
  }
  std::sort(busy.begin(), busy.end());
  double best = -1.0, mid = m.t0;
  for (std::size_t i = 0; i + 1 < busy.size(); ++i) {
    bool held = false;
    for (const HeldPhase& h : m.phases) held = held || (h.t_start <= busy[i] && busy[i + 1] <= h.t_end);
    if (!held && busy[i + 1] - busy[i] > best) best = busy[i + 1] - busy[i], mid = 0.5 * (busy[i] + busy[i + 1]);
  }
  return mid;
}

/// A state on scene A's orbit at a time in free slip, one period's map from there, and the
/// Richardson Jacobian of the same map.
struct PeriodMap {
  double t0 = 0.0, T = 0.0;
  Eigen::VectorXd z0;
  TangentMap map;
};
PeriodMap period_map(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& v, long transient, const LinearisationOptions& options = {}) {
  PeriodMap out;
  out.T = 2.0 * std::numbers::pi / scene.system().forcing().frequency;
  FrictionStopSimulator sim(scene, contacts);
  const RunSummary settle = sim.run(0.0, x, v, static_cast<double>(transient) * out.T);
  REQUIRE(settle.status == RunStatus::completed);
  LinearisationOptions probe;
  probe.jacobian = false;
  const TangentMap look = linearise(scene, contacts, {}, settle.t, settle.x, settle.v, settle.t + out.T, probe);
  out.t0 = free_time(look);
  out.z0 = map_of(scene, contacts, settle.t, stacked(settle.x, settle.v), out.t0);
  const Eigen::Index n = scene.dof();
  out.map = linearise(scene, contacts, {}, out.t0, out.z0.head(n), out.z0.tail(n), out.t0 + out.T, options);
  REQUIRE(out.map.summary.status == RunStatus::completed);
  return out;
}

}  // namespace

TEST_CASE("friction with stops: the period map's Jacobian with impacts and stick-slip against Richardson differences",
          "[friction][stops][analysis]") {
  const ImpactSystem scene = belt_with_stop();
  const std::vector<FrictionContact> contacts = belt();
  const PeriodMap p = period_map(scene, contacts, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1), 200);
  const TangentMap& m = p.map;
  REQUIRE(count(m, EventKind::impact) == 1);
  REQUIRE(count(m, EventKind::friction_stick) == 2);
  REQUIRE(count(m, EventKind::friction_slip) == 2);
  REQUIRE(count(m, EventKind::friction_reversal) == 1);  // at the impact: the impact reverses the slip
  for (const Event& e : m.events)
    if (e.kind == EventKind::friction_stick) CHECK(e.stop == 1);  // contact 0 after the stop
  CHECK_FALSE(m.non_smooth);
  // The stuck direction collapses: J (2 × 2) has an exact zero eigenvalue, the reduced map is 1 × 1.
  CHECK(m.free_dimension == 1);
  REQUIRE(m.reduced.rows() == 1);
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  // Steps and tolerance: Richardson's truncation error is O(h⁴) ~ 1e-16 with h = 1e-4 (scaled),
  // its rounding error ~3 δ/h, δ the rounding of the map (flows exact, about ten events located
  // to a few ulps of t < 2T: ~1e-14 of the scales), so ~3e-10; 1e-7 is asked. A wrong saltation
  // term (the settling of the belt's velocity, the impact's time shift, the friction jump) moves
  // J by O(1).
  const Eigen::MatrixXd fd = richardson_jacobian(scene, contacts, p.t0, p.z0, p.t0 + p.T, 1e-4, L, V);
  const Eigen::Vector2d D(L, V);
  const Eigen::MatrixXd scaled = D.cwiseInverse().asDiagonal() * (m.jacobian - fd) * D.asDiagonal();
  const double err = scaled.cwiseAbs().maxCoeff();
  WARN("belt with a stop: max |J − J_Richardson| (scaled) = " << err << ", |J| = " << m.jacobian.cwiseAbs().maxCoeff());
  CHECK(err < 1e-7);
  CHECK(std::abs(m.jacobian.determinant()) < 1e-12 * m.jacobian.squaredNorm());
  CHECK(std::abs(m.reduced(0, 0) - m.jacobian.trace()) < 1e-12 * (1.0 + std::abs(m.jacobian.trace())));
}

TEST_CASE("friction with stops: an orbit's multipliers have the structural zeros of a stuck contact and a held stop",
          "[friction][stops][analysis]") {
  SECTION("scene A: one stuck contact, one zero") {
    const ImpactSystem scene = belt_with_stop();
    const std::vector<FrictionContact> contacts = belt();
    const double T = 2.0 * std::numbers::pi / 0.6;
    const ShootingResult r =
        shoot(scene, contacts, {}, 200 * T, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1));
    REQUIRE(r.converged());
    CHECK(r.multipliers.structural_zeros == 1);
    CHECK(r.multipliers.values(1) == std::complex<double>(0.0, 0.0));
    // The other multiplier is the trace of the Richardson Jacobian at the orbit (the zero one
    // adds nothing): to the bound of the test above.
    const Eigen::VectorXd z = stacked(r.x, r.v);
    const Eigen::MatrixXd fd = richardson_jacobian(scene, contacts, r.t0, z, r.t0 + T, 1e-4, r.length_scale, r.velocity_scale);
    WARN("scene A: multiplier " << r.multipliers.values(0) << ", trace of the Richardson Jacobian " << fd.trace());
    CHECK(std::abs(r.multipliers.values(0) - fd.trace()) < 1e-7);
    CHECK(std::abs(r.multipliers.values(0)) < 1.0);
  }
  SECTION("scene B: a held stop (position and velocity) and a stuck contact") {
    const ImpactSystem scene = plastic_pair();
    const std::vector<FrictionContact> contacts = belt();
    const double T = 2.0 * std::numbers::pi / 0.6;
    const ShootingResult r = shoot(scene, contacts, {}, 100 * T, Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero());
    REQUIRE(r.converged());
    // The held stop fixes mass 1's position and velocity (2 zeros); the stuck phase's zero falls
    // in the same kernel's complement generically, so J has rank 2.
    CHECK(r.multipliers.structural_zeros == 2);
    const Eigen::VectorXd z = stacked(r.x, r.v);
    LinearisationOptions lo;
    const TangentMap m = linearise(scene, contacts, {}, r.t0, r.x, r.v, r.t0 + T, lo);
    REQUIRE(m.summary.status == RunStatus::completed);
    REQUIRE(count(m, EventKind::impact) >= 1);
    REQUIRE(count(m, EventKind::stick) >= 1);
    REQUIRE(count(m, EventKind::release) >= 1);
    REQUIRE(count(m, EventKind::friction_stick) >= 1);
    CHECK(m.free_dimension == 2);
    // J against Richardson differences of the map (bound as in the first test).
    const Eigen::MatrixXd fd = richardson_jacobian(scene, contacts, r.t0, z, r.t0 + T, 1e-4, r.length_scale, r.velocity_scale);
    Eigen::Vector4d D;
    D << r.length_scale, r.length_scale, r.velocity_scale, r.velocity_scale;
    const double err = (D.cwiseInverse().asDiagonal() * (m.jacobian - fd) * D.asDiagonal()).cwiseAbs().maxCoeff();
    WARN("scene B: max |J − J_Richardson| (scaled) = " << err << ", multipliers " << r.multipliers.values.transpose());
    CHECK(err < 1e-7);
    // The Lyapunov spectrum: the two collapsed directions are exponents −∞, the others those of
    // the multipliers.
    LyapunovOptions lyo;
    lyo.transient = 0;
    lyo.align = 2;
    lyo.periods = 6;
    const LyapunovResult ly = lyapunov_spectrum(scene, contacts, {}, r.t0, r.x, r.v, lyo);
    REQUIRE(ly.status == RunStatus::completed);
    CHECK(ly.structural == 2);
    CHECK(std::isinf(ly.exponents(3)));
    CHECK(std::isfinite(ly.exponents(1)));
  }
}

TEST_CASE("friction with stops: the period map's parameter column against Richardson differences",
          "[friction][stops][analysis][parameter]") {
  const std::vector<FrictionContact> contacts = belt();
  const PeriodMap p = period_map(belt_with_stop(), contacts, Eigen::VectorXd::Constant(1, 0.2),
                                 Eigen::VectorXd::Constant(1, -0.1), 200);
  struct Case {
    const char* name;
    SystemDerivative d;
    std::function<std::pair<ImpactSystem, std::vector<FrictionContact>>(double)> at;
  };
  auto derivative = [](auto set) {
    SystemDerivative d;
    set(d);
    return d;
  };
  const std::vector<Case> cases{
      {"Omega", SystemDerivative::frequency_only(), [&](double h) { return std::make_pair(belt_with_stop(0.6 + h), contacts); }},
      {"forcing", derivative([](SystemDerivative& d) { d.cosine = Eigen::VectorXd::Ones(1); }),
       [&](double h) { return std::make_pair(belt_with_stop(0.6, 1.0 + h), contacts); }},
      {"stop position", derivative([](SystemDerivative& d) { d.stops = {StopDerivative{.offset = 1.0}}; }),
       [&](double h) { return std::make_pair(belt_with_stop(0.6, 1.0, 1.0 + h), contacts); }},
      {"restitution", derivative([](SystemDerivative& d) { d.stops = {StopDerivative{.restitution = 1.0}}; }),
       [&](double h) { return std::make_pair(belt_with_stop(0.6, 1.0, 1.0, 0.7 + h), contacts); }},
      {"N", derivative([](SystemDerivative& d) { d.friction = {FrictionDerivative{1.0, 0.0, 0.0}}; }),
       [&](double h) { return std::make_pair(belt_with_stop(), belt(1.0 + h)); }},
      {"mu_s", derivative([](SystemDerivative& d) { d.friction = {FrictionDerivative{0.0, 1.0, 0.0}}; }),
       [&](double h) { return std::make_pair(belt_with_stop(), belt(1.0, 0.5 + h)); }},
      {"mu_k", derivative([](SystemDerivative& d) { d.friction = {FrictionDerivative{0.0, 0.0, 1.0}}; }),
       [&](double h) { return std::make_pair(belt_with_stop(), belt(1.0, 0.5, 0.3 + h)); }},
  };
  for (const Case& c : cases) {
    INFO("d/d" << c.name);
    LinearisationOptions lo;
    lo.jacobian = false;
    lo.parameter = c.d;
    const auto [scene, cs] = c.at(0.0);
    const TangentMap m = linearise(scene, cs, {}, p.t0, p.z0.head(1), p.z0.tail(1), p.t0 + p.T, lo);
    REQUIRE(m.summary.status == RunStatus::completed);
    // Richardson with h = 1e-4 of the datum's size (~1): error ~3 δ/h ~ 3e-10 as for J; 1e-7
    // relative is asked. A missing term (a mode's dÂ/dp, the guard's h_p, the reset's R_p)
    // changes the column by O(1). Ω moves the forcing's phase Ωt by t dΩ at t ~ 2000 here: its
    // step is 1e-4 of a radian over the run (h = 1e-4 / t1), the same relative size.
    const double step = std::string(c.name) == "Omega" ? 1e-4 / (p.t0 + p.T) : 1e-4;
    const Eigen::VectorXd fd = richardson(
        [&](double h) {
          const auto [sh, ch] = c.at(h);
          return map_of(sh, ch, p.t0, p.z0, p.t0 + p.T);
        },
        step);
    const double err = (m.parameter - fd).norm() / m.parameter.norm();
    WARN("d/d" << c.name << ": |dP/dp − Richardson| / |dP/dp| = " << err << ", |dP/dp| = " << m.parameter.norm());
    CHECK(m.parameter.norm() > 1e-2);
    CHECK(err < 1e-7);
  }
}

TEST_CASE("friction with stops: continuation in Omega, its orbits shot again", "[friction][stops][analysis]") {
  const std::vector<FrictionContact> contacts = belt();
  const ContinuationFamily family = [&](double omega) {
    return friction_stop_family_engine(belt_with_stop(omega), contacts, SystemDerivative::frequency_only(), {});
  };
  ContinuationOptions o;
  o.p_min = 0.57;
  o.p_max = 0.63;
  o.direction = +1;
  o.max_points = 40;
  const double T = 2.0 * std::numbers::pi / 0.6;
  const ImpactSystem start = belt_with_stop();
  FrictionStopSimulator sim(start, contacts);
  const RunSummary settle = sim.run(0.0, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1), 200 * T);
  REQUIRE(settle.status == RunStatus::completed);
  const ContinuationResult r = continue_orbits(family, 0.6, settle.t, settle.x, settle.v, o);
  REQUIRE(!r.branches.empty());
  const Branch& b = r.branches.front();
  REQUIRE(b.points.size() >= 3);
  // The event signature counts the stop (index 0) and the contact (index 1).
  CHECK(b.points.front().signature.impacts.size() == 2);
  CHECK(b.points.front().signature.impacts.at(0) == 1);
  CHECK(b.points.front().signature.phases.at(1) >= 2);
  double worst = 0.0;
  int shot = 0;
  for (const BranchPoint& q : b.points) {
    if (q.located) continue;  // a bifurcation point (a grazing's orbit is not a smooth zero)
    ++shot;
    // Shot again from the point's own state: Newton finds the same orbit at once (the corrector's
    // residual ~1e-10 of the scales; 1e-8 of L is asked).
    const ShootingResult s = shoot(belt_with_stop(q.p), contacts, {}, q.t0, q.x, q.v);
    REQUIRE(s.converged());
    REQUIRE(std::abs(s.t0 - q.t0) < 1e-12 * T);
    const double d = std::max((s.x - q.x).cwiseAbs().maxCoeff() / s.length_scale,
                              (s.v - q.v).cwiseAbs().maxCoeff() / s.velocity_scale);
    worst = std::max(worst, d);
    CHECK(d < 1e-8);
    CHECK(s.multipliers.structural_zeros == q.multipliers.structural_zeros);
  }
  CHECK(shot >= 3);
  WARN("continuation in Ω: " << b.points.size() << " points over [" << b.points.front().p << ", " << b.points.back().p
                             << "], largest difference to the re-shot orbits " << worst);
}
