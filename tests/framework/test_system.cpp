/// Tests of vibro::LinearSystem and vibro::HarmonicForcing (framework/src/system.cpp): the
/// validation messages name the quantity, the index and the value (STYLE.md, point 7), what is
/// valid is accepted, and acceleration/energy are the formulas of system.hpp.
#include "vibro/system.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

namespace {

using Catch::Contains;
using vibro::HarmonicForcing;
using vibro::InvalidInput;
using vibro::LinearSystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A valid 2-DOF system: M = diag(2, 4), K a spring chain, C diagonal, all forcing terms set.
struct Parts {
  Eigen::MatrixXd mass = Eigen::Vector2d(2.0, 4.0).asDiagonal();
  Eigen::MatrixXd damping = Eigen::Vector2d(0.5, 0.25).asDiagonal();
  Eigen::MatrixXd stiffness = (Eigen::MatrixXd(2, 2) << 3.0, -1.0, -1.0, 2.0).finished();
  HarmonicForcing forcing{.constant = Eigen::Vector2d(1.0, 0.0),
                          .cosine = Eigen::Vector2d(0.0, 2.0),
                          .sine = Eigen::Vector2d(0.5, 0.0),
                          .frequency = 2.0};

  LinearSystem build() const { return LinearSystem(mass, damping, stiffness, forcing); }
};

/// The message of the InvalidInput that building `parts` throws ("<no exception>" if none; any
/// other exception type escapes and fails the test).
std::string rejection(const Parts& parts) {
  try {
    (void)parts.build();
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "<no exception>";
}

/// The number printed after `label` in `message` (NaN if absent).
double number_after(const std::string& message, const std::string& label) {
  const auto at = message.find(label);
  if (at == std::string::npos) return kNaN;
  return std::stod(message.substr(at + label.size()));
}

}  // namespace

TEST_CASE("system: a valid system is stored unchanged", "[system]") {
  const Parts parts;
  const LinearSystem sys = parts.build();
  CHECK(sys.dof() == 2);
  CHECK(sys.mass() == parts.mass);
  CHECK(sys.damping() == parts.damping);
  CHECK(sys.stiffness() == parts.stiffness);
  CHECK(sys.forcing().cosine == parts.forcing.cosine);
  CHECK(sys.forcing().frequency == 2.0);
  // InvalidInput is a std::invalid_argument, so generic handlers catch it.
  Parts bad;
  bad.mass(0, 0) = -1.0;
  CHECK_THROWS_AS(bad.build(), std::invalid_argument);
}

TEST_CASE("system: valid edge cases are accepted (C = 0, singular K, Ω = 0, rounding)",
          "[system]") {
  Parts parts;
  parts.damping.setZero();
  parts.stiffness << 1.0, -1.0, -1.0, 1.0;  // free-free: semi-definite, singular
  parts.forcing.frequency = 0.0;
  CHECK_NOTHROW(parts.build());

  // Asymmetry below the documented relative 1e-12 is rounding and accepted ...
  Parts almost;
  almost.stiffness(0, 1) = -1.0 + 1e-13 * 3.0;
  CHECK_NOTHROW(almost.build());
  // ... and so is a smallest eigenvalue of -1e-14 ‖K‖ (semi-definite up to rounding).
  Parts rounding;
  rounding.stiffness << 1.0, -1.0, -1.0, 1.0 - 2e-14;
  CHECK_NOTHROW(rounding.build());
}

TEST_CASE("system: mismatched sizes are rejected with both sizes", "[system]") {
  Parts nonsquare;
  nonsquare.mass = Eigen::MatrixXd::Identity(2, 3);
  CHECK_THAT(rejection(nonsquare), Contains("mass matrix") && Contains("2x3") &&
                                       Contains("square"));

  Parts empty;
  empty.mass.resize(0, 0);
  CHECK_THAT(rejection(empty), Contains("mass matrix") && Contains("0x0"));

  Parts damping;
  damping.damping = Eigen::MatrixXd::Zero(3, 3);
  CHECK_THAT(rejection(damping),
             Contains("damping matrix") && Contains("3x3") && Contains("expected 2x2"));

  Parts stiffness;
  stiffness.stiffness = Eigen::MatrixXd::Zero(2, 1);
  CHECK_THAT(rejection(stiffness),
             Contains("stiffness matrix") && Contains("2x1") && Contains("expected 2x2"));
}

TEST_CASE("system: non-finite entries are rejected with the entry and the value", "[system]") {
  Parts nan_stiffness;
  nan_stiffness.stiffness(1, 0) = kNaN;
  const std::string nan_message = rejection(nan_stiffness);
  CHECK_THAT(nan_message, Contains("stiffness matrix") && Contains("entry (1,0)") &&
                              Contains("nan", Catch::CaseSensitive::No) && Contains("finite"));

  Parts inf_damping;
  inf_damping.damping(0, 1) = kInf;
  CHECK_THAT(rejection(inf_damping), Contains("damping matrix") && Contains("entry (0,1)") &&
                                         Contains("inf", Catch::CaseSensitive::No));

  Parts nan_mass;
  nan_mass.mass(1, 1) = kNaN;
  CHECK_THAT(rejection(nan_mass), Contains("mass matrix") && Contains("entry (1,1)"));
}

TEST_CASE("system: a non-positive mass is reported as such, with its index and value",
          "[system]") {
  Parts negative;
  negative.mass(0, 0) = -1.5;
  CHECK_THAT(rejection(negative), Contains("mass matrix") && Contains("diagonal entry 0") &&
                                      Contains("-1.5") && Contains("positive"));

  Parts zero;
  zero.mass(1, 1) = 0.0;
  CHECK_THAT(rejection(zero), Contains("diagonal entry 1") && Contains("is 0"));

  // Positive masses but not positive definite: the Cholesky factorisation is what fails.
  Parts indefinite;
  indefinite.mass << 1.0, 2.0, 2.0, 1.0;
  CHECK_THAT(rejection(indefinite), Contains("mass matrix") && Contains("positive definite"));
}

TEST_CASE("system: a non-symmetric matrix is rejected naming both entries and values",
          "[system]") {
  Parts damping;
  damping.damping << 0.5, 0.5, 0.25, 0.25;
  CHECK_THAT(rejection(damping), Contains("damping matrix") && Contains("(0,1) = 0.5") &&
                                     Contains("(1,0) = 0.25") && Contains("symmetric"));

  Parts mass;
  mass.mass << 2.0, 0.75, 0.5, 4.0;
  CHECK_THAT(rejection(mass), Contains("mass matrix") && Contains("(0,1) = 0.75") &&
                                  Contains("(1,0) = 0.5"));

  // Just above the relative 1e-12 tolerance is rejected (the check is relative to max |K|).
  Parts stiffness;
  stiffness.stiffness(0, 1) = -1.0 + 3e-11 * 3.0;
  CHECK_THAT(rejection(stiffness), Contains("stiffness matrix") && Contains("symmetric"));
}

TEST_CASE("system: indefinite stiffness or damping is rejected with the smallest eigenvalue",
          "[system]") {
  // [[1, 2], [2, 1]] has eigenvalues -1 and 3.
  Parts stiffness;
  stiffness.stiffness << 1.0, 2.0, 2.0, 1.0;
  const std::string k_message = rejection(stiffness);
  CHECK_THAT(k_message, Contains("stiffness matrix") && Contains("smallest eigenvalue") &&
                            Contains("semi-definite"));
  CHECK(number_after(k_message, "smallest eigenvalue is ") == Approx(-1.0).epsilon(1e-12));

  // diag(0.5, -0.25): smallest eigenvalue -0.25.
  Parts damping;
  damping.damping = Eigen::Vector2d(0.5, -0.25).asDiagonal();
  const std::string c_message = rejection(damping);
  CHECK_THAT(c_message, Contains("damping matrix") && Contains("semi-definite"));
  CHECK(number_after(c_message, "smallest eigenvalue is ") == Approx(-0.25).epsilon(1e-12));

  // Beyond rounding (-1e-10 ‖K‖) is a real negative eigenvalue.
  Parts slightly;
  slightly.stiffness << 1.0, -1.0, -1.0, 1.0 - 2e-10;
  CHECK_THAT(rejection(slightly), Contains("stiffness matrix") && Contains("semi-definite"));
}

TEST_CASE("system: forcing of the wrong length or non-finite is rejected", "[system]") {
  Parts cosine;
  cosine.forcing.cosine = Eigen::Vector3d(1.0, 2.0, 3.0);
  CHECK_THAT(rejection(cosine),
             Contains("forcing.cosine") && Contains("length is 3") && Contains("expected 2"));

  Parts constant;
  constant.forcing.constant = Eigen::VectorXd::Zero(1);
  CHECK_THAT(rejection(constant), Contains("forcing.constant") && Contains("length is 1"));

  Parts sine;
  sine.forcing.sine = Eigen::VectorXd();
  CHECK_THAT(rejection(sine), Contains("forcing.sine") && Contains("length is 0"));

  Parts nan;
  nan.forcing.sine(1) = kNaN;
  CHECK_THAT(rejection(nan), Contains("forcing.sine") && Contains("entry 1") &&
                                 Contains("nan", Catch::CaseSensitive::No));
}

TEST_CASE("system: a negative or infinite forcing frequency is rejected with its value",
          "[system]") {
  Parts negative;
  negative.forcing.frequency = -1.5;
  CHECK_THAT(rejection(negative),
             Contains("forcing.frequency") && Contains("-1.5") && Contains("≥ 0"));

  Parts infinite;
  infinite.forcing.frequency = kInf;
  CHECK_THAT(rejection(infinite), Contains("forcing.frequency") &&
                                      Contains("inf", Catch::CaseSensitive::No) &&
                                      Contains("finite"));

  Parts nan;
  nan.forcing.frequency = kNaN;
  CHECK_THAT(rejection(nan), Contains("forcing.frequency"));
}

TEST_CASE("system: forcing evaluates F0 + Fc cos Ωt + Fs sin Ωt, and zero() is zero", "[system]") {
  const Parts parts;
  // t = 0: cos = 1, sin = 0 exactly.
  CHECK(parts.forcing.at(0.0) == Eigen::Vector2d(1.0, 2.0));
  // Ωt = π/2 up to rounding: f ≈ F0 + Fs.
  const Eigen::VectorXd quarter = parts.forcing.at(std::acos(-1.0) / 4.0);
  CHECK(quarter(0) == Approx(1.5).epsilon(1e-15));
  CHECK(std::fabs(quarter(1)) <= 1e-15);

  const HarmonicForcing zero = HarmonicForcing::zero(3, 1.25);
  CHECK(zero.frequency == 1.25);
  CHECK(zero.at(0.7) == Eigen::VectorXd::Zero(3));
  CHECK(zero.constant.size() == 3);
  CHECK(zero.cosine.size() == 3);
  CHECK(zero.sine.size() == 3);
}

TEST_CASE("system: acceleration is M^-1 (f - Cv - Kx) and energy is ½vᵀMv + ½xᵀKx", "[system]") {
  const LinearSystem sys = Parts{}.build();
  const Eigen::Vector2d x(1.0, -1.0), v(2.0, 4.0);
  // At t = 0: f = (1, 2), Kx = (4, -3), Cv = (1, 1), so f - Cv - Kx = (-4, 4) and
  // a = diag(1/2, 1/4) (-4, 4) = (-2, 1). (The Cholesky solve divides twice by √2, so allow
  // rounding: 1e-15 is a few ε.)
  const Eigen::VectorXd a0 = sys.acceleration(0.0, x, v);
  CHECK(a0(0) == Approx(-2.0).epsilon(1e-15));
  CHECK(a0(1) == Approx(1.0).epsilon(1e-15));
  // vᵀMv = 2·4 + 4·16 = 72, xᵀKx = 3 + 2 + 2 = 7: E = 36 + 3.5.
  CHECK(sys.energy(x, v) == 39.5);

  // A non-diagonal mass matrix: the residual M a - (f - Cv - Kx) vanishes to rounding.
  Parts coupled;
  coupled.mass << 2.0, 1.0, 1.0, 2.0;
  const LinearSystem csys = coupled.build();
  const double t = 0.3;
  const Eigen::VectorXd a = csys.acceleration(t, x, v);
  const Eigen::VectorXd rhs =
      coupled.forcing.at(t) - coupled.damping * v - coupled.stiffness * x;
  CHECK((coupled.mass * a - rhs).lpNorm<Eigen::Infinity>() <= 1e-14 * rhs.lpNorm<Eigen::Infinity>());
}
