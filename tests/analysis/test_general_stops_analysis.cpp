/// The analysis layer on stops along general normals (Stop::general, dense engine): shooting and
/// Floquet multipliers of a chain in rotated coordinates y = Q x against the chain itself. The
/// rotation is a similarity of the Poincaré map (J' = diag(Q, Q) J diag(Qᵀ, Qᵀ)), so the orbit
/// maps back and the multipliers agree; only the rotated scene's stops are general, so its
/// tangent map goes through the dense-normal rows of the linearisation (mechanics.hpp).
#include "vibro/shooting.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

/// Two masses, a wall on each side, forcing on mass 0 at Ω = 1.3; a stop above mass 1 and a
/// clearance x0 − x1 ≤ 0.15.
vibro::LinearSystem two_masses() {
  MatrixXd M(2, 2), K(2, 2), C(2, 2);
  M << 1.0, 0.0, 0.0, 1.4;
  K << 2.0, -1.0, -1.0, 1.8;
  C << 0.05, -0.01, -0.01, 0.04;
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(2, 1.3);
  f.cosine << 0.6, 0.0;
  return vibro::LinearSystem(M, C, K, f);
}

std::vector<std::complex<double>> sorted(const Eigen::VectorXcd& v) {
  std::vector<std::complex<double>> out(v.data(), v.data() + v.size());
  std::sort(out.begin(), out.end(), [](auto a, auto b) {
    return std::abs(a) != std::abs(b) ? std::abs(a) > std::abs(b) : a.imag() > b.imag();
  });
  return out;
}

}  // namespace

TEST_CASE("shooting in rotated coordinates with general stops finds the same orbit and multipliers", "[general-stops]") {
  const vibro::LinearSystem sys = two_masses();
  const std::vector<vibro::Stop> stops{vibro::Stop::upper(1, 0.25, 0.7), vibro::Stop::between(0, 1, 0.15, 0.6)};
  const vibro::ImpactSystem plain(sys, stops);
  const double a = 0.7;
  MatrixXd Q(2, 2);
  Q << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  vibro::HarmonicForcing f = sys.forcing();
  f.cosine = Q * f.cosine;
  auto turn = [&](const MatrixXd& A) {
    const MatrixXd B = Q * A * Q.transpose();
    return MatrixXd(0.5 * (B + B.transpose()));
  };
  std::vector<vibro::Stop> general;
  for (const vibro::Stop& s : stops) general.push_back(vibro::Stop::general(Q * s.normal(2), s.s0(), s.restitution));
  const vibro::ImpactSystem rotated(vibro::LinearSystem(turn(sys.mass()), turn(sys.damping()), turn(sys.stiffness()), f),
                                    general);

  const double T = 2.0 * std::numbers::pi / 1.3;
  vibro::Simulator warm(plain);
  const vibro::RunSummary w = warm.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), 60.0 * T);
  REQUIRE(w.status == vibro::RunStatus::completed);
  vibro::ShootingOptions o;
  o.solver.length_scale = 0.25;  // the same scales in both frames
  const vibro::ShootingResult r = vibro::shoot(plain, o, w.t, w.x, w.v);
  REQUIRE(r.converged());
  const vibro::ShootingResult s = vibro::shoot(rotated, o, w.t, Q * w.x, Q * w.v);
  REQUIRE(s.converged());
  // The orbit impacts (else the general rows would not be exercised).
  CHECK(r.map.events.size() > 0);
  CHECK(r.t0 == s.t0);
  // Both are converged to 1e-11 of L and V; the orbits agree to that.
  CHECK((Q.transpose() * s.x - r.x).cwiseAbs().maxCoeff() <= 1e-10 * 0.25);
  CHECK((Q.transpose() * s.v - r.v).cwiseAbs().maxCoeff() <= 1e-10 * 0.25 * 1.3);
  REQUIRE(r.multipliers.values.size() == s.multipliers.values.size());
  CHECK(r.multipliers.structural_zeros == s.multipliers.structural_zeros);
  const auto mr = sorted(r.multipliers.values), ms = sorted(s.multipliers.values);
  double d = 0.0;
  for (std::size_t i = 0; i < mr.size(); ++i) d = std::max(d, std::abs(mr[i] - ms[i]));
  WARN("general-stop shooting: " << r.map.events.size() << " events per period, spectral radius "
                                 << r.multipliers.spectral_radius << ", max |Δμ| = " << d);
  // The Jacobians are exact maps evaluated on orbits 1e-11 apart; their multipliers move by as
  // much times the Jacobian's sensitivity, far below 1e-8.
  CHECK(d <= 1e-8);
  CHECK(std::abs(r.multipliers.spectral_radius - s.multipliers.spectral_radius) <= 1e-8);
}
