// The analysis layer on friction scenes (friction_tangent.hpp): the tangent map of a stick-slip
// period against central differences of the map, a Den Hartog orbit's Floquet multipliers
// against those of the finite-difference Jacobian, its Lyapunov spectrum against its multipliers,
// and continuation in Ω locating the onset of sticking against Den Hartog's closed form.
// Parameter derivatives in N, μ_k, μ_s and continuation in N: at the end of the file.
#include "support/den_hartog.hpp"
#include "support/symmetric_orbit.hpp"
#include "vibro/continuation.hpp"
#include "vibro/friction_tangent.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <iomanip>
#include <limits>
#include <tuple>
#include <numbers>

using namespace vibro;

namespace {

LinearSystem one_mass(double m, double c, double k, double fc, double omega) {
  HarmonicForcing f{.constant = Eigen::VectorXd::Zero(1), .cosine = Eigen::VectorXd::Constant(1, fc),
                    .sine = Eigen::VectorXd::Zero(1), .frequency = omega};
  return LinearSystem(Eigen::MatrixXd::Constant(1, 1, m), Eigen::MatrixXd::Constant(1, 1, c),
                      Eigen::MatrixXd::Constant(1, 1, k), f);
}

Eigen::VectorXd stacked(const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  Eigen::VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// The map z ↦ (x, v)(t1) of a friction run from (t0, z).
Eigen::VectorXd map_of(const LinearSystem& sys, const std::vector<FrictionContact>& contacts, double t0,
                       const Eigen::VectorXd& z, double t1) {
  FrictionSimulator sim(sys, contacts);
  const Eigen::Index n = sys.dof();
  const FrictionSummary s = sim.run(t0, z.head(n), z.tail(n), t1);
  REQUIRE(s.status == RunStatus::completed);
  return stacked(s.x, s.v);
}

/// Central differences of the map with step h (relative to the scales L, V).
Eigen::MatrixXd central_differences(const LinearSystem& sys, const std::vector<FrictionContact>& contacts, double t0,
                                    const Eigen::VectorXd& z, double t1, double h, double L, double V) {
  const Eigen::Index n2 = z.size();
  Eigen::MatrixXd J(n2, n2);
  for (Eigen::Index i = 0; i < n2; ++i) {
    const double step = h * (i < n2 / 2 ? L : V);
    Eigen::VectorXd zp = z, zm = z;
    zp(i) += step;
    zm(i) -= step;
    J.col(i) = (map_of(sys, contacts, t0, zp, t1) - map_of(sys, contacts, t0, zm, t1)) / (2.0 * step);
  }
  return J;
}

/// The number of events of one kind in a tangent map's run.
int count(const TangentMap& m, EventKind kind) {
  int n = 0;
  for (const Event& e : m.events) n += e.kind == kind;
  return n;
}

/// The middle of the longest stretch of [t0, t1] free of switches and stuck phases.
double free_time(const TangentMap& m) {
  std::vector<double> busy;
  for (const Event& e : m.events) busy.push_back(e.t);
  for (const HeldPhase& h : m.phases) {
    busy.push_back(h.t_start);
    busy.push_back(h.t_end);
  }
  std::sort(busy.begin(), busy.end());
  double best = -1.0, mid = m.t0;
  for (std::size_t i = 0; i + 1 < busy.size(); ++i) {
    bool stuck = false;
    for (const HeldPhase& h : m.phases) stuck = stuck || (h.t_start <= busy[i] && busy[i + 1] <= h.t_end);
    if (!stuck && busy[i + 1] - busy[i] > best) best = busy[i + 1] - busy[i], mid = 0.5 * (busy[i] + busy[i + 1]);
  }
  return mid;
}

}  // namespace

TEST_CASE("the tangent map of a stick-slip period against central differences of the map", "[friction][analysis]") {
  // experiments/examples/stick_slip.yaml: a mass on a moving belt, μ_s > μ_k, sticking for part
  // of each period.
  const LinearSystem sys = one_mass(1.0, 0.05, 1.0, 1.0, 0.6);
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, 0.5, 0.3, 0.5, 0.3)};
  const double T = 2.0 * std::numbers::pi / 0.6;
  FrictionSimulator sim(sys, contacts);
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1), 20 * T);
  REQUIRE(settle.status == RunStatus::completed);
  LinearisationOptions probe;
  probe.jacobian = false;
  const TangentMap look = linearise(sys, contacts, {}, settle.t, settle.x, settle.v, settle.t + T, probe);
  const double ta = free_time(look);  // slipping, away from every switch
  const Eigen::VectorXd za = map_of(sys, contacts, settle.t, stacked(settle.x, settle.v), ta);

  const TangentMap m = linearise(sys, contacts, {}, ta, za.head(1), za.tail(1), ta + T);
  REQUIRE(m.summary.status == RunStatus::completed);
  REQUIRE(count(m, EventKind::friction_stick) >= 1);
  REQUIRE(count(m, EventKind::friction_slip) >= 1);
  // The stuck direction collapses: the reduced map is 1 × 1 and J has an exact zero eigenvalue.
  CHECK(m.free_dimension == 1);
  CHECK(m.reduced.rows() == 1);
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  // Step and tolerance: the central difference's truncation error is h²|P'''|/6 per unit, and
  // its rounding error δ/h, δ the rounding of the map itself (the state after ~10 flows and
  // located switches, ~1e-14 of the scales). With h = 1e-6 the first is ~1e-12 and the second
  // ~1e-8: the difference to the exact J may be a few 1e-8 (scaled by L, V), and 1e-6 is the
  // bound asked of it — a wrong saltation (a missing term, a wrong sign) changes J by O(1).
  const Eigen::MatrixXd fd = central_differences(sys, contacts, ta, za, ta + T, 1e-6, L, V);
  Eigen::Vector2d D(L, V);
  const Eigen::MatrixXd scaled = D.cwiseInverse().asDiagonal() * (m.jacobian - fd) * D.asDiagonal();
  const double err = scaled.cwiseAbs().maxCoeff();
  WARN("stick-slip period: max |J − J_fd| (scaled) = " << err << ", |J| = " << m.jacobian.cwiseAbs().maxCoeff());
  CHECK(err < 1e-6);
  CHECK(std::abs(m.jacobian.determinant()) < 1e-12 * m.jacobian.squaredNorm());
  // The other multiplier is the trace (the zero one adds nothing).
  CHECK(std::abs(m.reduced(0, 0) - m.jacobian.trace()) < 1e-12 * (1.0 + std::abs(m.jacobian.trace())));
}

TEST_CASE("a Den Hartog orbit's multipliers against the finite-difference Jacobian, and its Lyapunov exponents",
          "[friction][analysis]") {
  const double m = 1.0, c = 0.1, k = 1.0, F0 = 1.0, Ff = 0.2, W = 0.8;
  const LinearSystem sys = one_mass(m, c, k, F0, W);
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, Ff, Ff)};
  const double T = 2.0 * std::numbers::pi / W;
  ShootingOptions o;
  const ShootingResult r = shoot(sys, contacts, o, 10 * T, Eigen::VectorXd::Constant(1, 0.3), Eigen::VectorXd::Zero(1));
  REQUIRE(r.converged());
  // The orbit is Den Hartog's: continuous motion, a reversal twice per period.
  const test::DenHartog dh(m, c, k, F0, Ff, W);
  const auto [x_ref, v_ref] = dh.at(r.t0);
  CHECK(std::abs(r.x(0) - static_cast<double>(x_ref)) < 1e-10 * static_cast<double>(dh.X));
  CHECK(std::abs(r.v(0) - static_cast<double>(v_ref)) < 1e-10 * static_cast<double>(dh.X * dh.W));
  int reversals = 0;
  for (const Event& e : r.map.events) reversals += e.kind == EventKind::friction_reversal;
  CHECK(reversals == 2);
  CHECK(r.map.events.size() == 2);
  CHECK(r.multipliers.structural_zeros == 0);
  // Floquet multipliers of J against those of central differences (step and tolerance as above).
  const double L = r.map.summary.length_scale, V = r.map.summary.velocity_scale;
  const Eigen::MatrixXd fd = central_differences(sys, contacts, r.t0, stacked(r.x, r.v), r.t0 + T, 1e-6, L, V);
  Eigen::VectorXcd mu_fd = fd.eigenvalues();
  std::sort(mu_fd.data(), mu_fd.data() + mu_fd.size(),
            [](auto a, auto b) { return std::abs(a) != std::abs(b) ? std::abs(a) > std::abs(b) : a.imag() > b.imag(); });
  const Eigen::VectorXcd& mu = r.multipliers.values;
  REQUIRE(mu.size() == 2);
  for (Eigen::Index i = 0; i < 2; ++i) {
    WARN("Den Hartog multiplier " << i << ": " << mu(i) << " (finite differences " << mu_fd(i) << ")");
    CHECK(std::abs(mu(i) - mu_fd(i)) < 1e-6);
  }
  // Between the reversals the motion is the viscous oscillator's, det Φ = e^{−(c/m) T} over a
  // period (Liouville); a reversal's saltation I + (f⁺ − f⁻) ℓᵀ/(ℓᵀf⁻) has det = ℓᵀf⁺/ℓᵀf⁻ =
  // u'⁺/u'⁻, at the lowest point (a − F_f)/(a + F_f) with a = F0 cos Ωt1 − k x(t1), and the same at
  // the highest (the orbit is symmetric): μ₁μ₂ = e^{−cT/m} ((a − F_f)/(a + F_f))², all from the
  // closed form.
  const long double a = dh.F0 * std::cos(dh.W * dh.t1) - dh.k * dh.at(dh.t1).first;
  const double ratio = static_cast<double>((a - dh.Ff) / (a + dh.Ff));
  const double det = std::real(mu(0) * mu(1));
  WARN("Den Hartog: μ₁μ₂ = " << det << ", closed form " << std::exp(-c / m * T) * ratio * ratio);
  CHECK(std::abs(det - std::exp(-c / m * T) * ratio * ratio) < 1e-10);
  // The Lyapunov exponents are log|μ_i|/T. Averaged over N periods from a frame that is not yet
  // the orbit's, each is off by at most log κ/(N T), κ the condition of J's eigenvector basis
  // (the frame's growth over any number of periods is within κ of |μ|^N); their sum is exact.
  LyapunovOptions lo;
  lo.transient = 0;
  lo.align = 5;
  lo.periods = 200;
  const LyapunovResult ly = lyapunov_spectrum(sys, contacts, {}, r.t0, r.x, r.v, lo);
  REQUIRE(ly.status == RunStatus::completed);
  CHECK(ly.structural == 0);
  const Eigen::EigenSolver<Eigen::MatrixXd> eig(r.map.jacobian);
  const Eigen::MatrixXcd basis = eig.eigenvectors();
  const double kappa = basis.norm() * basis.inverse().norm();
  const double bound = std::log(kappa) / (lo.periods * T) + 1e-12;
  for (Eigen::Index i = 0; i < 2; ++i) {
    WARN("Den Hartog exponent " << i << ": " << ly.exponents(i) << " (log|μ|/T " << std::log(std::abs(mu(i))) / T
                                << ", bound " << bound << ")");
    CHECK(std::abs(ly.exponents(i) - std::log(std::abs(mu(i))) / T) <= bound);
  }
  CHECK(std::abs(ly.exponents.sum() - std::log(std::abs(det)) / T) < 1e-12);
}

TEST_CASE("a stick-slip orbit's stuck direction: a structural zero multiplier and an exponent −∞", "[friction][analysis]") {
  const LinearSystem sys = one_mass(1.0, 0.05, 1.0, 1.0, 0.6);
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, 0.5, 0.3, 0.5, 0.3)};
  const double T = 2.0 * std::numbers::pi / 0.6;
  const ShootingResult r = shoot(sys, contacts, {}, 20 * T, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1));
  REQUIRE(r.converged());
  CHECK(r.multipliers.structural_zeros == 1);
  CHECK(r.multipliers.values(1) == std::complex<double>(0.0, 0.0));
  LyapunovOptions lo;
  lo.transient = 0;
  lo.align = 2;
  lo.periods = 10;
  const LyapunovResult ly = lyapunov_spectrum(sys, contacts, {}, r.t0, r.x, r.v, lo);
  REQUIRE(ly.status == RunStatus::completed);
  CHECK(ly.structural == 1);
  CHECK(std::isinf(ly.exponents(1)));
  CHECK(ly.exponents(1) < 0.0);
  CHECK(std::abs(ly.exponents(0) - std::log(std::abs(r.multipliers.values(0))) / T) < 1e-9);
}

TEST_CASE("continuation of Den Hartog's oscillator in Ω locates the onset of sticking to 1e-8", "[friction][analysis]") {
  // m = k = F0 = 1, c = 0.05, F_f = 0.5: without stops above Ω* ≈ 0.6007, sticking at the
  // turning points below (his boundary of motion without stops, here born at the turning point:
  // a crossing-sliding bifurcation).
  const double m = 1.0, c = 0.05, k = 1.0, F0 = 1.0, Ff = 0.5;
  // Ω*: the zero of the turning point's acceleration of the closed form (long double bisection).
  long double lo = 0.59L, hi = 0.62L;
  REQUIRE(test::DenHartog(m, c, k, F0, Ff, lo).turning_acceleration() < 0);
  REQUIRE(test::DenHartog(m, c, k, F0, Ff, hi).turning_acceleration() > 0);
  for (int i = 0; i < 80; ++i) {
    const long double mid = 0.5L * (lo + hi);
    (test::DenHartog(m, c, k, F0, Ff, mid).turning_acceleration() > 0 ? hi : lo) = mid;
  }
  const double omega_star = static_cast<double>(0.5L * (lo + hi));
  // Above it the closed form is without stops over the whole half period (not only at t1).
  {
    const test::DenHartog dh(m, c, k, F0, Ff, omega_star + 1e-6);
    for (int i = 1; i < 2000; ++i) REQUIRE(dh.at(dh.t1 + dh.T / 2 * i / 2000.0L).second > 0.0L);
  }
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, Ff, Ff)};
  const ContinuationFamily family = [&](double omega) {
    return friction_family_engine(one_mass(m, c, k, F0, omega), contacts, SystemDerivative::frequency_only(), {});
  };
  ContinuationOptions o;
  o.p_min = 0.58;
  o.p_max = 0.7;
  o.direction = -1;
  o.max_points = 200;
  // The guess: Den Hartog's steady motion at Ω = 0.7 (the transient decays like e^{−0.025 t}).
  const LinearSystem start = one_mass(m, c, k, F0, 0.7);
  FrictionSimulator sim(start, contacts);
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 600.0);
  REQUIRE(settle.status == RunStatus::completed);
  const ContinuationResult r = continue_orbits(family, 0.7, settle.t, settle.x, settle.v, o);
  REQUIRE(!r.branches.empty());
  const Bifurcation* onset = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.kind == BifurcationKind::rising && b.stop == 0) onset = &b;
  REQUIRE(onset != nullptr);
  WARN("onset of sticking: Ω = " << onset->p << " (closed form " << omega_star << ", difference " << onset->p - omega_star
                                  << "), value " << onset->value << ", smooth " << onset->smooth);
  CHECK(onset->smooth);
  CHECK(std::abs(onset->p - omega_star) < 1e-8);
  // Below it the orbit sticks at both turning points: four switches per period.
  const Branch& b = r.branches.front();
  REQUIRE(b.points.size() > 2);
  const BranchPoint& last = b.points.back();
  CHECK(last.p < omega_star);
  CHECK(last.signature.phases.at(0) == 4);
  CHECK(last.sticking(0) > 0.0);
  CHECK(last.multipliers.structural_zeros == 1);
}

namespace {

/// The least interior local minimum of x' over the half period (t1, t1 + T/2) of Den Hartog's
/// closed form (4000 samples, then golden-section search on x'), or +∞ if x' has none there.
long double interior_velocity_minimum(const test::DenHartog& dh) {
  const int samples = 4000;
  const long double h = dh.T / 2 / samples;
  auto v = [&](long double s) { return dh.at(dh.t1 + s).second; };
  long double best = INFINITY;
  for (int i = 5; i < samples - 5; ++i) {
    if (!(v((i - 1) * h) > v(i * h) && v(i * h) <= v((i + 1) * h))) continue;
    long double a = (i - 1) * h, b = (i + 1) * h;
    const long double g = (std::sqrt(5.0L) - 1) / 2;
    for (int it = 0; it < 120; ++it) {
      const long double c = b - g * (b - a), d = a + g * (b - a);
      (v(c) < v(d) ? b : a) = v(c) < v(d) ? d : c;
    }
    best = std::min(best, v(0.5L * (a + b)));
  }
  return best;
}

}  // namespace

TEST_CASE("continuation locates a stick phase born inside a slip (grazing-sliding) against Den Hartog's closed form",
          "[friction][analysis]") {
  // F_f = 0.1: below Ω ≈ 0.387 the velocity of the half period without stops has an interior
  // local minimum, which falls to 0 at Ω_g ≈ 0.3839 while the turning points still reverse
  // (x''(t1) > 0): the mass stops inside the slip there (his boundary of motion without stops
  // at these low frequencies).
  const double m = 1.0, c = 0.05, k = 1.0, F0 = 1.0, Ff = 0.1;
  long double lo = 0.383L, hi = 0.3855L;
  REQUIRE(interior_velocity_minimum(test::DenHartog(m, c, k, F0, Ff, lo)) < 0);
  REQUIRE(interior_velocity_minimum(test::DenHartog(m, c, k, F0, Ff, hi)) > 0);
  for (int i = 0; i < 60; ++i) {
    const long double mid = 0.5L * (lo + hi);
    (interior_velocity_minimum(test::DenHartog(m, c, k, F0, Ff, mid)) > 0 ? hi : lo) = mid;
  }
  const double omega_g = static_cast<double>(0.5L * (lo + hi));
  REQUIRE(test::DenHartog(m, c, k, F0, Ff, omega_g).turning_acceleration() > 0.01L);
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, Ff, Ff)};
  const ContinuationFamily family = [&](double omega) {
    return friction_family_engine(one_mass(m, c, k, F0, omega), contacts, SystemDerivative::frequency_only(), {});
  };
  ContinuationOptions o;
  o.p_min = 0.378;
  o.p_max = 0.45;
  o.direction = -1;
  o.max_points = 200;
  const LinearSystem start = one_mass(m, c, k, F0, 0.45);
  FrictionSimulator sim(start, contacts);
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 900.0);
  REQUIRE(settle.status == RunStatus::completed);
  const ContinuationResult r = continue_orbits(family, 0.45, settle.t, settle.x, settle.v, o);
  const Bifurcation* onset = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.kind == BifurcationKind::rising && b.stop == 0 && (!onset || b.p > onset->p)) onset = &b;
  REQUIRE(onset != nullptr);
  WARN("grazing-sliding: Ω = " << onset->p << " (closed form " << omega_g << ", difference " << onset->p - omega_g
                               << "), smooth " << onset->smooth);
  CHECK(onset->smooth);
  CHECK(std::abs(onset->p - omega_g) < 1e-8);
}

namespace {

/// Counts a friction run's switches (the start's decision, at t0, not counted).
struct SwitchCounter final : FrictionObserver {
  double t0 = 0.0;
  int switches = 0;
  void friction_event(const FrictionEvent& e, const Eigen::VectorXd&, const Eigen::VectorXd&) override {
    switches += e.t > t0;
  }
};

/// The switches per forcing period of Den Hartog's oscillator (m = k = F0 = 1, c = 0.05,
/// μ_s = μ_k = 1, normal load N) in its steady state at Ω: 120 periods from rest (where it is
/// used its multipliers are ≤ 0.63 in modulus: 0.63¹²⁰ ≈ 1e-24, the transient far below rounding),
/// then one period counted from a crest of the forcing (Ωt ≡ 0).
int switches_per_period(double omega, double load = 0.5) {
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, load, load)};
  const LinearSystem sys = one_mass(1.0, 0.05, 1.0, 1.0, omega);
  const double T = 2.0 * std::numbers::pi / omega;
  FrictionSimulator sim(sys, contacts);
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 120 * T);
  INFO(settle.message);
  REQUIRE(settle.status == RunStatus::completed);
  SwitchCounter counter;
  counter.t0 = settle.t;
  FrictionSimulator again(sys, contacts);
  REQUIRE(again.run(settle.t, settle.x, settle.v, settle.t + T, {}, {&counter}).status == RunStatus::completed);
  return counter.switches;
}

ContinuationResult den_hartog_in_omega(double from, double to, double Ff = 0.5) {
  const double m = 1.0, c = 0.05, k = 1.0, F0 = 1.0;
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, Ff, Ff)};
  const ContinuationFamily family = [&](double omega) {
    return friction_family_engine(one_mass(m, c, k, F0, omega), contacts, SystemDerivative::frequency_only(), {});
  };
  ContinuationOptions o;
  o.p_min = std::min(from, to);
  o.p_max = std::max(from, to);
  o.direction = to < from ? -1 : 1;
  o.max_points = 300;
  const LinearSystem start = one_mass(m, c, k, F0, from);
  FrictionSimulator sim(start, contacts);
  const double T = 2.0 * std::numbers::pi / from;
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 120 * T);
  REQUIRE(settle.status == RunStatus::completed);
  return continue_orbits(family, from, settle.t, settle.x, settle.v, o);
}

}  // namespace

TEST_CASE("continuation locates a slip born inside a stick (adding-sliding) against bracketing simulations",
          "[friction][analysis]") {
  // Den Hartog's oscillator at F_f = 0.5 sticks at both turning points below Ω ≈ 0.6007 (four
  // switches per period). Lower, one stick phase spans a crest of the forcing: the holding force
  // F0 cos Ωt − k x_s has an interior maximum F0 − k x_s there, which reaches the limit
  // μ_s N at Ω_a ≈ 0.18496 (where x_s = (F0 − μ_s N)/k): below it a slip is born inside the stick,
  // and each half period gains a slip and a stick (eight switches per period). The reference
  // brackets Ω_a by the engine's own switch counts of the steady motion (no analysis layer).
  double lo = 0.18, hi = 0.19;
  REQUIRE(switches_per_period(lo) == 8);
  REQUIRE(switches_per_period(hi) == 4);
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (switches_per_period(mid) == 4 ? hi : lo) = mid;
  }
  const ContinuationResult r = den_hartog_in_omega(0.3, 0.17);
  REQUIRE(!r.branches.empty());
  const Bifurcation* adding = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.p > 0.17 && b.p < 0.2) adding = &b;
  REQUIRE(adding != nullptr);
  WARN(std::setprecision(15) << "adding-sliding: Ω = " << adding->p << " (simulations' bracket [" << lo << ", " << hi
                              << "], difference " << adding->p - 0.5 * (lo + hi) << "), smooth " << adding->smooth);
  CHECK(adding->kind == BifurcationKind::rising);
  CHECK(adding->stop == 0);
  CHECK(adding->smooth);
  // The bracket is 1e-14 wide after 40 halvings; the engine decides a slip where the margin
  // crosses its trigger (1e-13 of the force scale), and the margin moves by O(1) per unit of Ω,
  // so the simulations place Ω_a to ~1e-13. 1e-11 leaves a factor 100 for the location itself.
  CHECK(std::abs(adding->p - 0.5 * (lo + hi)) < 1e-11);
  // Each side of it: four and eight switches per period on the branch.
  const Branch& b = r.branches.front();
  CHECK(b.points.back().signature.phases.at(0) == 8);
}

TEST_CASE("continuation locates a reversal turning into a stick (crossing-sliding from the sticking side)",
          "[friction][analysis]") {
  // F_f = 0.1, below the grazing-sliding of the test above: each half period slips, stops inside
  // the slip, slips on, and reverses at the turning point, where a short slip back ends in a
  // stick (six switches per period). Lower, at Ω_c ≈ 0.36003, the turning point's arrival reaches
  // the boundary |F_hold| = μ_s N and the reversal with its short slip becomes a stick (four
  // switches): the side with fewer switches is the one that sticks, so the arrival's margin
  // (≤ 0 at its stick, > 0 at the reversal) locates it. Reference: the engine's switch counts.
  double lo = 0.355, hi = 0.365;
  REQUIRE(switches_per_period(lo, 0.1) == 4);
  REQUIRE(switches_per_period(hi, 0.1) == 6);
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (switches_per_period(mid, 0.1) == 6 ? hi : lo) = mid;
  }
  const ContinuationResult r = den_hartog_in_omega(0.375, 0.35, 0.1);
  REQUIRE(!r.branches.empty());
  const Bifurcation* located = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.p > 0.355 && b.p < 0.365) located = &b;
  REQUIRE(located != nullptr);
  WARN(std::setprecision(15) << "reversal to stick: Ω = " << located->p << " (simulations' bracket [" << lo << ", "
                             << hi << "], difference " << located->p - 0.5 * (lo + hi) << "), smooth "
                             << located->smooth);
  CHECK(located->kind == BifurcationKind::rising);
  CHECK(located->smooth);
  // As for the adding-sliding above: the simulations place Ω_c to ~1e-13.
  CHECK(std::abs(located->p - 0.5 * (lo + hi)) < 1e-11);
  CHECK(r.branches.front().points.back().signature.phases.at(0) == 4);
}

TEST_CASE("continuation reports no bifurcation where a stick phase's start crosses the Poincaré section",
          "[friction][analysis]") {
  // Between Ω = 0.5 and 0.4 the orbit keeps its four switches per period, while the start of one
  // stick phase passes the section t ≡ 0 (mod T) at Ω ≈ 0.43844: an orbit that starts inside a
  // stick phase is the same orbit, and its signature (the switches inside the period) does not
  // change there.
  const ContinuationResult r = den_hartog_in_omega(0.5, 0.4);
  REQUIRE(!r.branches.empty());
  CHECK(r.bifurcations.empty());
  for (const BranchPoint& p : r.branches.front().points) CHECK(p.signature.phases.at(0) == 4);
  CHECK(r.branches.front().points.back().p < 0.41);
}

namespace {

/// Den Hartog's oscillator with stiction: m = k = F0 = 1, c = 0.05, N = 0.3, μ_s = 1.5, μ_k = 1.
LinearSystem stiction_system(double omega) { return one_mass(1.0, 0.05, 1.0, 1.0, omega); }
std::vector<FrictionContact> stiction_contacts() { return {FrictionContact::on_surface(0, 0.3, 1.5, 1.0)}; }

/// The system is unchanged by x → −x, t → t + T/2, so H(z) = −z(T/2) of the run from (0, z)
/// maps the section t ≡ 0 (mod T) onto itself: a symmetric orbit is a fixed point of H, its
/// period map is H∘H, and its multipliers are the squares of H's. Where the symmetric orbit
/// loses its symmetry to a pair of asymmetric ones, a multiplier of H passes −1 (one of the
/// period map passes +1 without a fold).
Eigen::VectorXd half_map(double omega, const Eigen::VectorXd& z) {
  return -map_of(stiction_system(omega), stiction_contacts(), 0.0, z, std::numbers::pi / omega);
}

/// The symmetric orbit at Ω and H's multiplier nearest −1 (symmetric_orbit.hpp). The step 1e-7
/// (the scales are O(1)) puts the differences' truncation error near 1e-14 and their rounding
/// near 1e-9 (the runs' rounding ~1e-16 over 2e-7).
std::pair<Eigen::VectorXd, double> symmetric_orbit(double omega, const Eigen::VectorXd& z) {
  return test::symmetric_fixed_point([omega](const Eigen::VectorXd& y) { return half_map(omega, y); }, z, 1e-7);
}

}  // namespace

TEST_CASE("continuation passes the branch point where a stick-slip orbit loses its symmetry, and locates it",
          "[friction][analysis]") {
  // With stiction the symmetric orbit of Den Hartog's oscillator (a stick at each turning point,
  // four switches per period) loses its stability at Ω_b ≈ 0.52247 to an asymmetric pair that
  // exists below it (a subcritical pitchfork): a multiplier passes +1 while the branch goes
  // straight on in Ω. Reference: the half-period map's multiplier passing −1 (symmetric_orbit),
  // Ω_b bracketed by bisection on its sign; the differences' error (~1e-9) and the multiplier's
  // slope (~5 per unit of Ω) place it to a few 1e-10; continuation locates it to its tolerance
  // (1e-10), so 1e-9 bounds the sum with a margin.
  Eigen::VectorXd z(2);
  {
    const double W = 0.5, T = 2.0 * std::numbers::pi / W;
    const LinearSystem sys = stiction_system(W);
    FrictionSimulator sim(sys, stiction_contacts());
    const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 200 * T);
    REQUIRE(settle.status == RunStatus::completed);
    z << settle.x(0), settle.v(0);
  }
  double mu = 0.0;
  for (double W = 0.5; W < 0.5221; W += 0.0055) std::tie(z, mu) = symmetric_orbit(W, z);
  REQUIRE(mu > -1.0);  // stable at 0.5220
  double lo = 0.522, hi = 0.523;
  Eigen::VectorXd z_lo = symmetric_orbit(lo, z).first;
  REQUIRE(symmetric_orbit(hi, z_lo).second < -1.0);
  for (int i = 0; i < 22; ++i) {
    const double mid = 0.5 * (lo + hi);
    const auto [z_mid, mu_mid] = symmetric_orbit(mid, z_lo);
    if (mu_mid > -1.0) lo = mid, z_lo = z_mid;
    else hi = mid;
  }
  const double reference = 0.5 * (lo + hi);

  const ContinuationFamily family = [](double omega) {
    return friction_family_engine(stiction_system(omega), stiction_contacts(), SystemDerivative::frequency_only(), {});
  };
  ContinuationOptions o;
  o.p_min = 0.45;
  o.p_max = 0.56;
  o.direction = +1;
  o.max_points = 300;
  const double W = 0.5, T = 2.0 * std::numbers::pi / W;
  const LinearSystem sys = stiction_system(W);
  FrictionSimulator sim(sys, stiction_contacts());
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 200 * T);
  REQUIRE(settle.status == RunStatus::completed);
  const ContinuationResult r = continue_orbits(family, W, settle.t, settle.x, settle.v, o);
  REQUIRE(!r.branches.empty());
  const Bifurcation* bp = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.kind == BifurcationKind::branch_point) bp = &b;
  REQUIRE(bp != nullptr);
  WARN(std::setprecision(15) << "branch point: Ω = " << bp->p << " (half-period map's bracket [" << lo << ", " << hi
                             << "], difference " << bp->p - reference << "), smooth " << bp->smooth << ", value "
                             << bp->value);
  CHECK(bp->smooth);
  CHECK(std::abs(bp->p - reference) < 1e-9);
  // The branch goes on past it, unstable, with the same events (it no longer ends there).
  const Branch& b = r.branches.front();
  CHECK(b.points.back().p == Approx(0.56).margin(1e-12));
  for (const BranchPoint& p : b.points) {
    if (p.located) continue;
    CHECK(p.signature.phases.at(0) == 4);
    if (std::abs(p.p - reference) > 1e-6) CHECK(p.multipliers.stable == (p.p < reference));
  }
  // The crossing branch is switched onto, both ways: asymmetric orbits below Ω_b, each checked
  // by plain runs — periodic (one period returns to its state), and not symmetric (H moves it).
  int switched = 0;
  for (std::size_t i = 1; i < r.branches.size(); ++i) {
    const Branch& s = r.branches[i];
    INFO("branch " << i << ": " << s.start << " … " << s.end);
    CHECK(s.parent == 0);
    REQUIRE(s.bifurcation >= 0);
    CHECK(r.bifurcations[static_cast<std::size_t>(s.bifurcation)].kind == BifurcationKind::branch_point);
    REQUIRE(s.points.size() > 4);
    ++switched;
    const BranchPoint& q = s.points[3];
    CHECK(q.p < reference);
    const double Tq = 2.0 * std::numbers::pi / q.p;
    const LinearSystem sq = stiction_system(q.p);
    FrictionSimulator run(sq, stiction_contacts());
    const FrictionSummary one = run.run(q.t0, q.x, q.v, q.t0 + Tq);
    REQUIRE(one.status == RunStatus::completed);
    // The corrector's tolerance is 1e-11 of the scales (O(1) here); 1e-9 leaves the runs' rounding.
    CHECK(std::max(std::abs(one.x(0) - q.x(0)), std::abs(one.v(0) - q.v(0))) < 1e-9);
    // The section of branch points is at phase q.phase; H is taken from t0 = q.t0 likewise.
    const LinearSystem sh = stiction_system(q.p);
    const Eigen::VectorXd zq = stacked(q.x, q.v);
    const Eigen::VectorXd hz = -map_of(sh, stiction_contacts(), q.t0, zq, q.t0 + Tq / 2);
    CHECK((hz - zq).norm() > 1e-4);
  }
  CHECK(switched == 2);
}

TEST_CASE("two masses with a surface contact and a rubbing pair: the tangent map against central differences",
          "[friction][analysis]") {
  // Several contacts sticking and slipping, coupled through the masses: the settling projection
  // over every contact stuck before or after a switch is part of each saltation.
  Eigen::MatrixXd K(2, 2);
  K << 2.0, -1.0, -1.0, 1.0;
  HarmonicForcing f{.constant = Eigen::VectorXd::Zero(2), .cosine = Eigen::Vector2d(0.0, 0.8),
                    .sine = Eigen::VectorXd::Zero(2), .frequency = 0.9};
  const LinearSystem sys(Eigen::MatrixXd::Identity(2, 2), 0.05 * Eigen::MatrixXd::Identity(2, 2), K, f);
  const std::vector<FrictionContact> contacts{FrictionContact::on_surface(0, 1.0, 0.5, 0.35),
                                              FrictionContact::between(0, 1, 1.0, 0.3, 0.2)};
  const double T = 2.0 * std::numbers::pi / 0.9;
  FrictionSimulator sim(sys, contacts);
  const FrictionSummary settle = sim.run(0.0, Eigen::Vector2d(0.3, -0.2), Eigen::Vector2d(0.0, 0.1), 30 * T);
  REQUIRE(settle.status == RunStatus::completed);
  LinearisationOptions probe;
  probe.jacobian = false;
  const TangentMap look = linearise(sys, contacts, {}, settle.t, settle.x, settle.v, settle.t + T, probe);
  const double ta = free_time(look);
  const Eigen::VectorXd za = map_of(sys, contacts, settle.t, stacked(settle.x, settle.v), ta);
  const TangentMap m = linearise(sys, contacts, {}, ta, za.head(2), za.tail(2), ta + T);
  REQUIRE(m.summary.status == RunStatus::completed);
  REQUIRE_FALSE(m.non_smooth);
  int sticks = 0;
  for (const Event& e : m.events) sticks += e.kind == EventKind::friction_stick;
  WARN("two masses: " << m.events.size() << " switches, " << sticks << " sticks, least tangent dimension "
                      << m.free_dimension);
  REQUIRE(sticks >= 1);
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  // Step and tolerance as for the one-mass stick-slip period above.
  const Eigen::MatrixXd fd = central_differences(sys, contacts, ta, za, ta + T, 1e-6, L, V);
  Eigen::Vector4d D(L, L, V, V);
  const double err = (D.cwiseInverse().asDiagonal() * (m.jacobian - fd) * D.asDiagonal()).cwiseAbs().maxCoeff();
  WARN("two masses: max |J − J_fd| (scaled) = " << err);
  CHECK(err < 1e-6);
}

// Parameter derivatives in a frictional contact's data (parameter.hpp, FrictionDerivative): the
// period map's parameter column in N, μ_k and μ_s against central differences of the map on a
// stick-slip orbit (μ_k N moves the slips' force, μ_s N the slip starts), and continuation of Den
// Hartog's oscillator in N locating the onset of sticking against his closed form.

namespace {

enum class Datum { normal_load, kinetic, static_ };

double& datum(FrictionContact& c, Datum d) {
  return d == Datum::normal_load ? c.normal_load : (d == Datum::kinetic ? c.kinetic_coefficient : c.static_coefficient);
}
double& datum(FrictionDerivative& c, Datum d) {
  return d == Datum::normal_load ? c.normal_load : (d == Datum::kinetic ? c.kinetic_coefficient : c.static_coefficient);
}
const char* name_of(Datum d) { return d == Datum::normal_load ? "N" : (d == Datum::kinetic ? "mu_k" : "mu_s"); }

}  // namespace

TEST_CASE("friction: the period map's parameter column in N, mu_k and mu_s equals central differences",
          "[friction][analysis][parameter]") {
  // experiments/examples/stick_slip.yaml: a mass on a moving belt (N = 1, μ_s = 0.5, μ_k = 0.3,
  // belt 0.5 cos(0.6 t + 0.3)), sticking for part of each period.
  const LinearSystem sys = one_mass(1.0, 0.05, 1.0, 1.0, 0.6);
  const FrictionContact base = FrictionContact::on_surface(0, 1.0, 0.5, 0.3, 0.5, 0.3);
  const double T = 2.0 * std::numbers::pi / 0.6;
  FrictionSimulator sim(sys, {base});
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Constant(1, 0.2), Eigen::VectorXd::Constant(1, -0.1), 20 * T);
  REQUIRE(settle.status == RunStatus::completed);
  const double t0 = settle.t;
  const Eigen::VectorXd z0 = stacked(settle.x, settle.v);
  for (Datum d : {Datum::normal_load, Datum::kinetic, Datum::static_}) {
    INFO("d/d" << name_of(d));
    LinearisationOptions lo;
    lo.jacobian = false;
    SystemDerivative sd;
    sd.friction.resize(1);
    datum(sd.friction[0], d) = 1.0;
    lo.parameter = sd;
    const TangentMap m = linearise(sys, {base}, {}, t0, z0.head(1), z0.tail(1), t0 + T, lo);
    REQUIRE(m.summary.status == RunStatus::completed);
    REQUIRE(count(m, EventKind::friction_stick) >= 1);
    REQUIRE(count(m, EventKind::friction_slip) >= 1);
    // Central differences with h = 1e-5 of the value: truncation h²|P'''|/6 ~ 1e-11 of the
    // scale, rounding δ/h with δ ~ 1e-14 of the map (flows exact, switches located to a few
    // ulps) ~ 1e-9. 1e-6 relative is asked (as of the Jacobian in the first test above);
    // a missing term (the slips' force, the slip start's shift) is O(1) of the column.
    FrictionContact plus = base, minus = base;
    const double h = 1e-5 * datum(plus, d);
    datum(plus, d) += h;
    datum(minus, d) -= h;
    const Eigen::VectorXd fd = (map_of(sys, {plus}, t0, z0, t0 + T) - map_of(sys, {minus}, t0, z0, t0 + T)) / (2.0 * h);
    INFO("dP/dp = " << m.parameter.transpose() << ", central differences " << fd.transpose());
    WARN("stick-slip period, d/d" << name_of(d) << ": |dP/dp - central differences| / |dP/dp| = "
                                  << (m.parameter - fd).norm() / m.parameter.norm() << ", |dP/dp| = " << m.parameter.norm());
    CHECK(m.parameter.norm() > 1e-2);
    CHECK((m.parameter - fd).norm() <= 1e-6 * m.parameter.norm());
  }
}

TEST_CASE("friction: a derivative of more or fewer contacts than the scene has is refused", "[friction][analysis][parameter]") {
  const LinearSystem sys = one_mass(1.0, 0.05, 1.0, 1.0, 0.6);
  LinearisationOptions lo;
  SystemDerivative sd;
  sd.friction.resize(2);
  lo.parameter = sd;
  CHECK_THROWS_WITH(linearise(sys, {FrictionContact::on_surface(0, 1.0, 0.5, 0.3)}, {}, 0.0, Eigen::VectorXd::Zero(1),
                              Eigen::VectorXd::Constant(1, 0.3), 1.0, lo),
                    Catch::Contains("2 contact derivatives for 1 frictional contacts"));
}

TEST_CASE("friction: continuation of Den Hartog's oscillator in the normal load locates the onset of sticking",
          "[friction][analysis][parameter]") {
  // m = k = F0 = 1, c = 0.05, Ω = 0.65, μ_s = μ_k = 0.5, so F_f = N/2: without stops for small
  // N, sticking at the turning points beyond N* = 2 F_f*, F_f* the friction force where the
  // turning point's acceleration of his closed form falls to 0 (long double bisection in F_f).
  const double m = 1.0, c = 0.05, k = 1.0, F0 = 1.0, W = 0.65, mu = 0.5;
  long double lo = 0.3L, hi = 0.95L;
  REQUIRE(test::DenHartog(m, c, k, F0, lo, W).turning_acceleration() > 0);
  REQUIRE(test::DenHartog(m, c, k, F0, hi, W).turning_acceleration() < 0);
  for (int i = 0; i < 80; ++i) {
    const long double mid = 0.5L * (lo + hi);
    (test::DenHartog(m, c, k, F0, mid, W).turning_acceleration() > 0 ? lo : hi) = mid;
  }
  const double n_star = static_cast<double>(lo + hi) / mu * 0.5;
  const LinearSystem sys = one_mass(m, c, k, F0, W);
  SystemDerivative along_n;
  along_n.friction = {FrictionDerivative{1.0, 0.0, 0.0}};
  const ContinuationFamily family = [&](double n) {
    return friction_family_engine(sys, {FrictionContact::on_surface(0, n, mu, mu)}, along_n, {});
  };
  ContinuationOptions o;
  o.p_min = 0.4;
  o.p_max = n_star + 0.3;
  o.direction = +1;
  o.max_points = 200;
  const double n0 = 0.5;
  FrictionSimulator sim(sys, {FrictionContact::on_surface(0, n0, mu, mu)});
  const FrictionSummary settle = sim.run(0.0, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Zero(1), 600.0);
  REQUIRE(settle.status == RunStatus::completed);
  const ContinuationResult r = continue_orbits(family, n0, settle.t, settle.x, settle.v, o);
  REQUIRE(!r.branches.empty());
  const Bifurcation* onset = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.kind == BifurcationKind::rising && b.stop == 0) onset = &b;
  REQUIRE(onset != nullptr);
  WARN("onset of sticking: N = " << onset->p << " (closed form " << n_star << ", difference " << onset->p - n_star
                                  << "), smooth " << onset->smooth);
  CHECK(onset->smooth);
  // Located to the continuation's locate_tolerance (1e-10) on a smooth test function; the closed
  // form's bisection is exact to long double: 1e-8 leaves room for the corrector's tolerance.
  CHECK(std::abs(onset->p - n_star) < 1e-8);
  // Beyond it the orbit sticks at both turning points: four switches per period, a structural zero.
  const BranchPoint& last = r.branches.front().points.back();
  CHECK(last.p > n_star);
  CHECK(last.signature.phases.at(0) == 4);
  CHECK(last.multipliers.structural_zeros == 1);
}
