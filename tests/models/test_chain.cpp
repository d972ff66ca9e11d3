// Tests of vibro::models::build_chain: the system of Wagg (2004), section 2, eqs. (1)–(5), against
// its closed forms, and general chains (walls, free-free, forcing, validation messages).
#include "vibro/flow.hpp"
#include "vibro/models/chain.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <complex>
#include <limits>
#include <vector>

namespace {

using vibro::models::build_chain;
using vibro::models::Chain;
using vibro::models::wagg2004_chain;
using vibro::models::Wagg2004;

constexpr double eps = std::numeric_limits<double>::epsilon();

/// E = [[2,-1],[-1,1]] of eq. (3).
Eigen::Matrix2d coupling_matrix() {
  Eigen::Matrix2d e;
  e << 2.0, -1.0, -1.0, 1.0;
  return e;
}

/// Eigenvalues of E, roots of λ² - 3λ + 1 = 0, ascending. The small root is written as
/// 2/(3+√5) (= (3-√5)/2) to avoid the cancellation in 3 - √5: both are then correct to ~1 ulp.
Eigen::Vector2d coupling_eigenvalues() {
  const double r5 = std::sqrt(5.0);
  return {2.0 / (3.0 + r5), (3.0 + r5) / 2.0};
}

/// ξ_j ∝ (1, 2 - λ_j): E (1, 2-λ) = (λ, 1-λ) and λ(2-λ) = 1-λ because λ² = 3λ - 1.
Eigen::Matrix2d closed_form_modal_matrix() {
  const Eigen::Vector2d lambda = coupling_eigenvalues();
  Eigen::Matrix2d psi;
  for (int j = 0; j < 2; ++j) psi.col(j) = Eigen::Vector2d(1.0, 2.0 - lambda(j)).normalized();
  return psi;
}

/// Largest |a_ij| over i ≠ j.
double off_diagonal(const Eigen::MatrixXd& a) {
  Eigen::MatrixXd b = a;
  b.diagonal().setZero();
  return b.cwiseAbs().maxCoeff();
}

}  // namespace

TEST_CASE("Wagg (2004) chain: M = m I, K = k E, C = c E exactly", "[chain][wagg2004]") {
  // The defaults m = k = 1, c = 0.1 and a set with m ≠ 1 so that m, k and c cannot be confused.
  const Wagg2004 p = GENERATE(Wagg2004{}, Wagg2004{.m = 2.5, .k = 3.0, .c = 0.4});
  CAPTURE(p.m, p.k, p.c);
  const vibro::LinearSystem sys = build_chain(wagg2004_chain(p));
  REQUIRE(sys.dof() == 2);
  const Eigen::Matrix2d E = coupling_matrix();
  // Each entry is a single sum of two equal doubles or a negation: exact, so compare exactly.
  CHECK(sys.mass() == Eigen::MatrixXd(p.m * Eigen::Matrix2d::Identity()));
  CHECK(sys.stiffness() == Eigen::MatrixXd(p.k * E));
  CHECK(sys.damping() == Eigen::MatrixXd(p.c * E));
  // f(t) = A cos Ωt with A = (A1, A2) (eq. 3): no constant or sine part.
  CHECK(sys.forcing().cosine == Eigen::VectorXd(Eigen::Vector2d(p.A1, p.A2)));
  CHECK(sys.forcing().sine.isZero(0.0));
  CHECK(sys.forcing().constant.isZero(0.0));
  CHECK(sys.forcing().frequency == p.frequency);
}

TEST_CASE("Wagg (2004) chain: section 3 parameters are the defaults", "[chain][wagg2004]") {
  const Wagg2004 p;
  CHECK(p.m == 1.0);
  CHECK(p.k == 1.0);
  CHECK(p.c == 0.1);
  CHECK(p.A1 == 0.5);
  CHECK(p.A2 == 0.0);
  CHECK(p.frequency == 0.255);
  CHECK(p.s1 == -0.3);
  CHECK(p.s2 == 0.1);
  CHECK(p.r == 0.7);
}

TEST_CASE("Wagg (2004) chain: natural frequencies ω_nj = sqrt(λ_j k / m)", "[chain][wagg2004]") {
  const Wagg2004 p = GENERATE(Wagg2004{}, Wagg2004{.m = 2.5, .k = 3.0, .c = 0.4});
  CAPTURE(p.m, p.k);
  const vibro::LinearSystem sys = build_chain(wagg2004_chain(p));
  // K φ = ω² M φ, solved from the assembled matrices.
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ges(sys.stiffness(), sys.mass());
  REQUIRE(ges.info() == Eigen::Success);
  const Eigen::Vector2d lambda = coupling_eigenvalues();
  for (int j = 0; j < 2; ++j) {
    const double expected = std::sqrt(lambda(j) * p.k / p.m);
    const double computed = std::sqrt(ges.eigenvalues()(j));
    CAPTURE(j, expected, computed);
    // A symmetric 2x2 eigenvalue is backward stable: |δ(ω²)| ≲ few ε ‖M⁻¹K‖ and
    // ‖M⁻¹K‖/ω₁² = λ₂/λ₁ ≈ 6.9, so δω/ω ≲ ½·6.9·few ε ≈ 1e-15; 1e-14 leaves a margin of ~10.
    CHECK(std::abs(computed - expected) <= 1e-14 * expected);
  }
  // The paper's numbers for k = m = 1: sqrt((3 ∓ √5)/2) = 0.618..., 1.618... (the golden ratio).
  if (p.k == 1.0 && p.m == 1.0) {
    const double golden = (1.0 + std::sqrt(5.0)) / 2.0;
    CHECK(std::abs(std::sqrt(ges.eigenvalues()(0)) - (golden - 1.0)) <= 1e-14);
    CHECK(std::abs(std::sqrt(ges.eigenvalues()(1)) - golden) <= 1e-14);
  }
}

TEST_CASE("Wagg (2004) chain: the flow's generator has the modal eigenvalues", "[chain][wagg2004]") {
  const Wagg2004 p = GENERATE(Wagg2004{}, Wagg2004{.m = 2.5, .k = 3.0, .c = 0.4});
  CAPTURE(p.m, p.k, p.c);
  const vibro::LinearSystem sys = build_chain(wagg2004_chain(p));
  const vibro::LinearFlow flow(sys);
  // Light damping, distinct eigenvalues: the spectral method must be accepted.
  REQUIRE(flow.method() == vibro::FlowMethod::spectral);
  const Eigen::VectorXcd& computed = flow.eigenvalues();
  REQUIRE(computed.size() == 7);

  // Expected: -ζ_j ω_j ± i ω_j sqrt(1 - ζ_j²) with ζ_j = (c/2) sqrt(λ_j/(k m)) (eq. 5),
  // then ±iΩ (the cos/sin forcing block) and 0 (the constant-forcing component).
  const Eigen::Vector2d lambda = coupling_eigenvalues();
  std::vector<std::complex<double>> expected;
  for (int j = 0; j < 2; ++j) {
    const double omega = std::sqrt(lambda(j) * p.k / p.m);
    const double zeta = 0.5 * p.c * std::sqrt(lambda(j) / (p.k * p.m));
    REQUIRE(zeta < 1.0);
    const double re = -zeta * omega, im = omega * std::sqrt(1.0 - zeta * zeta);
    expected.emplace_back(re, im);
    expected.emplace_back(re, -im);
  }
  expected.emplace_back(0.0, p.frequency);
  expected.emplace_back(0.0, -p.frequency);
  expected.emplace_back(0.0, 0.0);

  // The nonsymmetric QR algorithm is backward stable: |δλ| ≲ κ(λ) · c ε ‖Â‖ with the eigenvalue
  // condition κ(λ) ≤ cond(V). ‖Â‖_F ≈ 3 here and cond(V) is O(10) (checked below), so
  // 100 ε cond(V) ‖Â‖_F ≈ 1e-12 is a bound with room; the computed errors are ~1e-16.
  const double cond = flow.eigenvector_condition();
  REQUIRE(cond < 1e3);
  const double tol = 100.0 * eps * cond * flow.generator().norm();
  CAPTURE(cond, tol);
  // Both directions of the nearest match: every expected value is found and every computed value
  // is expected; with 7 distinct values ≥ 0.25 apart this is a one-to-one match.
  for (const auto& e : expected) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index k = 0; k < computed.size(); ++k) best = std::min(best, std::abs(computed(k) - e));
    CAPTURE(e, best);
    CHECK(best <= tol);
  }
  for (Eigen::Index k = 0; k < computed.size(); ++k) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& e : expected) best = std::min(best, std::abs(computed(k) - e));
    CAPTURE(computed(k), best);
    CHECK(best <= tol);
  }
}

TEST_CASE("Wagg (2004) chain: orthogonal modal matrix diagonalises E (eq. 4)",
          "[chain][wagg2004]") {
  const vibro::LinearSystem sys = build_chain(wagg2004_chain());
  const Eigen::Matrix2d E = sys.stiffness();  // k = 1: K = E
  const Eigen::Matrix2d psi = closed_form_modal_matrix();
  const Eigen::Vector2d lambda = coupling_eigenvalues();

  // Closed form: Ψ orthogonal and Ψᵀ E Ψ = Λ. Entries are O(1) and every product is a short sum
  // of O(1) terms, so rounding is a few ε ≈ 1e-15; 1e-14 is a margin of ~10.
  CHECK((psi.transpose() * psi - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff() <= 1e-14);
  const Eigen::Matrix2d Lambda = psi.transpose() * E * psi;
  CHECK(off_diagonal(Lambda) <= 1e-14);
  CHECK(std::abs(Lambda(0, 0) - lambda(0)) <= 1e-14);
  CHECK(std::abs(Lambda(1, 1) - lambda(1)) <= 1e-14);

  // The numerically computed normalized eigenvectors agree with the closed form up to sign.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(E);
  REQUIRE(es.info() == Eigen::Success);
  for (int j = 0; j < 2; ++j) {
    const Eigen::Vector2d numeric = es.eigenvectors().col(j);
    const double sign = numeric.dot(psi.col(j)) < 0.0 ? -1.0 : 1.0;
    CAPTURE(j, numeric.transpose(), psi.col(j).transpose());
    // An eigenvector's error is ≲ ε ‖E‖ / gap = ε·2.6/√5 ≈ 3e-16; 1e-14 has ample room.
    CHECK((sign * numeric - psi.col(j)).cwiseAbs().maxCoeff() <= 1e-14);
  }
}

TEST_CASE("Wagg (2004) chain: modal damping ratios ζ_j = (c/2) sqrt(λ_j/(k m)) (eq. 5)",
          "[chain][wagg2004]") {
  // m = 1 as in the paper (eq. 5 with unit modal mass); c and k varied.
  const Wagg2004 p = GENERATE(Wagg2004{}, Wagg2004{.k = 3.0, .c = 0.4});
  CAPTURE(p.k, p.c);
  const vibro::LinearSystem sys = build_chain(wagg2004_chain(p));
  const Eigen::Matrix2d psi = closed_form_modal_matrix();
  const Eigen::Vector2d lambda = coupling_eigenvalues();

  const Eigen::Matrix2d modal_damping = psi.transpose() * sys.damping() * psi;
  const Eigen::Matrix2d modal_stiffness = psi.transpose() * sys.stiffness() * psi;
  const Eigen::Matrix2d modal_mass = psi.transpose() * sys.mass() * psi;
  // Same rounding argument as for Ψᵀ E Ψ, scaled by c, k ≤ 3: 1e-14 absolute.
  CHECK(off_diagonal(modal_damping) <= 1e-14);
  CHECK(off_diagonal(modal_stiffness) <= 1e-14);
  CHECK((modal_mass - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff() <= 1e-14);
  for (int j = 0; j < 2; ++j) {
    const double omega = std::sqrt(lambda(j) * p.k / p.m);
    const double zeta = 0.5 * p.c * std::sqrt(lambda(j) / (p.k * p.m));
    CAPTURE(j, omega, zeta);
    CHECK(std::abs(modal_damping(j, j) - 2.0 * zeta * omega) <= 1e-14);
    CHECK(std::abs(modal_stiffness(j, j) - omega * omega) <= 1e-14);
  }
}

TEST_CASE("chain: a single mass between two walls", "[chain]") {
  Chain c;
  c.masses = {2.0};
  c.left_spring = 3.0;
  c.right_spring = 5.0;
  c.left_damper = 0.25;
  c.right_damper = 0.5;
  const vibro::LinearSystem sys = build_chain(c);
  REQUIRE(sys.dof() == 1);
  CHECK(sys.mass()(0, 0) == 2.0);
  CHECK(sys.stiffness()(0, 0) == 8.0);  // k_L + k_R
  CHECK(sys.damping()(0, 0) == 0.75);   // c_L + c_R
  CHECK(sys.forcing().cosine.size() == 1);
  CHECK(sys.forcing().cosine.isZero(0.0));
}

TEST_CASE("chain: five masses free-free have a rigid-body mode", "[chain]") {
  Chain c;
  c.masses = {1.0, 2.0, 3.0, 4.0, 5.0};
  c.springs = {1.0, 2.0, 3.0, 4.0};
  c.dampers = {0.1, 0.2, 0.3, 0.4};
  const vibro::LinearSystem sys = build_chain(c);
  REQUIRE(sys.dof() == 5);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(5);
  // Rows of K sum to zero: k_{i-1} + k_i - k_{i-1} - k_i with small integers is exact.
  CHECK((sys.stiffness() * ones).cwiseAbs().maxCoeff() == 0.0);
  // For C the decimals are inexact, but each row sum cancels to within a few ε·0.7.
  CHECK((sys.damping() * ones).cwiseAbs().maxCoeff() <= 1e-15);
  // Exactly one zero eigenvalue: the others are well away from zero.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sys.stiffness(), Eigen::EigenvaluesOnly);
  CHECK(std::abs(es.eigenvalues()(0)) <= 1e-14);  // backward error ~ ε ‖K‖ = 7ε ≈ 1.6e-15
  CHECK(es.eigenvalues()(1) > 0.1);
}

TEST_CASE("chain: a right wall adds to the last diagonal entry only", "[chain]") {
  Chain c;
  c.masses = {1.0, 1.0, 1.0};
  c.springs = {2.0, 3.0};
  c.dampers = {0.5, 0.25};
  c.right_spring = 7.0;
  c.right_damper = 0.125;
  const vibro::LinearSystem sys = build_chain(c);
  Eigen::Matrix3d K, C;
  K << 2.0, -2.0, 0.0,  //
      -2.0, 5.0, -3.0,  //
      0.0, -3.0, 10.0;
  C << 0.5, -0.5, 0.0,    //
      -0.5, 0.75, -0.25,  //
      0.0, -0.25, 0.375;
  // Binary fractions and small integers: exact.
  CHECK(sys.stiffness() == Eigen::MatrixXd(K));
  CHECK(sys.damping() == Eigen::MatrixXd(C));
  // No left wall: the first row sums to zero.
  CHECK(sys.stiffness().row(0).sum() == 0.0);
}

TEST_CASE("chain: tridiagonal structure K_ii = k_{i-1} + k_i, K_{i,i+1} = -k_i", "[chain]") {
  Chain c;
  c.masses = {1.0, 1.5, 2.0, 0.5, 3.0, 1.25};
  c.springs = {1.0, 0.5, 2.0, 4.0, 0.25};
  c.dampers = {0.125, 0.0, 0.5, 0.25, 1.0};
  c.left_spring = 8.0;
  c.left_damper = 0.0625;
  c.right_spring = 16.0;
  c.right_damper = 2.0;
  const vibro::LinearSystem sys = build_chain(c);
  const int n = 6;
  REQUIRE(sys.dof() == n);

  // Link i-1 on the left of mass i (k_{-1} = k_L) and link i on its right (k_{n-1} = k_R).
  const auto link = [&](const std::vector<double>& inner, double left, double right, int i) {
    if (i < 0) return left;
    if (i >= n - 1) return right;
    return inner[static_cast<std::size_t>(i)];
  };
  for (int i = 0; i < n; ++i) {
    CAPTURE(i);
    CHECK(sys.mass()(i, i) == c.masses[static_cast<std::size_t>(i)]);
    CHECK(sys.stiffness()(i, i) ==
          link(c.springs, c.left_spring, c.right_spring, i - 1) +
              link(c.springs, c.left_spring, c.right_spring, i));
    CHECK(sys.damping()(i, i) == link(c.dampers, c.left_damper, c.right_damper, i - 1) +
                                     link(c.dampers, c.left_damper, c.right_damper, i));
    for (int j = 0; j < n; ++j) {
      if (j == i) continue;
      CAPTURE(j);
      CHECK(sys.mass()(i, j) == 0.0);
      const bool neighbours = std::abs(i - j) == 1;
      const int between = std::min(i, j);
      CHECK(sys.stiffness()(i, j) == (neighbours ? -c.springs[static_cast<std::size_t>(between)] : 0.0));
      CHECK(sys.damping()(i, j) == (neighbours ? -c.dampers[static_cast<std::size_t>(between)] : 0.0));
    }
  }
}

TEST_CASE("chain: empty dampers mean no damping", "[chain]") {
  Chain c;
  c.masses = {1.0, 1.0};
  c.springs = {1.0};
  c.left_spring = 1.0;
  const vibro::LinearSystem sys = build_chain(c);
  CHECK(sys.damping().isZero(0.0));
}

TEST_CASE("chain: per-mass forcing vectors", "[chain]") {
  Chain c;
  c.masses = {1.0, 1.0, 1.0};
  c.springs = {1.0, 1.0};
  c.left_spring = 1.0;
  c.force_constant = {0.5, 0.0, -1.0};
  c.force_cosine = {0.0, 2.0, 0.0};
  c.force_sine = {3.0, 0.0, 0.25};
  c.frequency = 1.75;
  const vibro::LinearSystem sys = build_chain(c);
  CHECK(sys.forcing().constant == Eigen::VectorXd(Eigen::Vector3d(0.5, 0.0, -1.0)));
  CHECK(sys.forcing().cosine == Eigen::VectorXd(Eigen::Vector3d(0.0, 2.0, 0.0)));
  CHECK(sys.forcing().sine == Eigen::VectorXd(Eigen::Vector3d(3.0, 0.0, 0.25)));
  CHECK(sys.forcing().frequency == 1.75);
  // f(t) = F0 + Fc cos Ωt + Fs sin Ωt, one mass at a time (ordinary libm rounding: 1e-15).
  const double t = 0.6;
  const Eigen::VectorXd f = sys.forcing().at(t);
  CHECK(std::abs(f(0) - (0.5 + 3.0 * std::sin(1.75 * t))) <= 1e-15);
  CHECK(std::abs(f(1) - 2.0 * std::cos(1.75 * t)) <= 1e-15);
  CHECK(std::abs(f(2) - (-1.0 + 0.25 * std::sin(1.75 * t))) <= 1e-15);

  // Omitted vectors are zero vectors of the right length.
  c.force_constant.clear();
  c.force_sine.clear();
  const vibro::LinearSystem partial = build_chain(c);
  CHECK(partial.forcing().constant.size() == 3);
  CHECK(partial.forcing().constant.isZero(0.0));
  CHECK(partial.forcing().sine.size() == 3);
  CHECK(partial.forcing().sine.isZero(0.0));
}

TEST_CASE("chain: validation messages name the field, the index and the value", "[chain]") {
  using Catch::Contains;
  const Chain good = wagg2004_chain();
  REQUIRE_NOTHROW(build_chain(good));

  SECTION("negative mass") {
    Chain c = good;
    c.masses[1] = -2.5;
    REQUIRE_THROWS_AS(build_chain(c), vibro::InvalidInput);
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.masses[1]") && Contains("-2.5") &&
                                            Contains("> 0"));
  }
  SECTION("zero mass") {
    Chain c = good;
    c.masses[0] = 0.0;
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.masses[0] = 0"));
  }
  SECTION("wrong number of springs") {
    Chain c = good;
    c.springs = {1.0, 1.0};
    REQUIRE_THROWS_AS(build_chain(c), vibro::InvalidInput);
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.springs") && Contains("has 2 entries") &&
                                            Contains("expected 1"));
  }
  SECTION("missing springs for two masses") {
    Chain c = good;
    c.springs.clear();
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.springs") && Contains("has 0 entries"));
  }
  SECTION("negative damper") {
    Chain c = good;
    c.dampers[0] = -0.5;
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.dampers[0]") && Contains("-0.5") &&
                                            Contains("≥ 0"));
  }
  SECTION("NaN spring") {
    Chain c = good;
    c.springs[0] = std::numeric_limits<double>::quiet_NaN();
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.springs[0]") && Contains("nan") &&
                                            Contains("finite"));
  }
  SECTION("infinite mass") {
    Chain c = good;
    c.masses[1] = std::numeric_limits<double>::infinity();
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.masses[1]") && Contains("inf"));
  }
  SECTION("negative wall spring") {
    Chain c = good;
    c.left_spring = -1.0;
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.left_spring") && Contains("-1"));
  }
  SECTION("negative right wall damper") {
    Chain c = good;
    c.right_damper = -0.125;
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.right_damper") && Contains("-0.125"));
  }
  SECTION("forcing vector of the wrong length") {
    Chain c = good;
    c.force_cosine = {0.5, 0.0, 0.0};
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.force_cosine") &&
                                            Contains("has 3 entries") && Contains("expected 2"));
  }
  SECTION("empty masses") {
    Chain c;
    REQUIRE_THROWS_AS(build_chain(c), vibro::InvalidInput);
    REQUIRE_THROWS_WITH(build_chain(c), Contains("chain.masses") && Contains("empty"));
  }
}
