/// Neimark–Sacker bifurcations located by continuation, against an independent closed form.
///
/// The engineered case: two unit masses in a chain (wall spring 1, coupling spring 1, both
/// dashpots 0.02), mass 1 forced by cos Ωt and stopped from above at x1 = d = 0.2 (r = 0.8).
/// Its period-1 orbit with one impact per period is computed here without the engine:
///   ż = A z + b cos Ωt,  particular solution z_p(t) = Re(Z e^{iΩt}), (iΩ − A) Z = b;
///   from just after the impact at τ to just before the next at τ + T:
///     z⁻ = Φ (z⁺ − z_p(τ)) + z_p(τ),  Φ = exp(A T) (Eigen's MatrixFunctions, not the engine's
///     flow), and z⁺ = R z⁻, R = diag(1, 1, −r, 1);
///   so z⁺ = (I − RΦ)⁻¹ R (I − Φ) z_p(τ), and τ solves the scalar equation x1⁺(τ) = d (with v1⁻ > 0
///   and the orbit below the stop in between, checked by sampling the closed-form solution).
/// The monodromy matrix is S Φ with the impact's saltation matrix (Müller 1995; di Bernardo et al.
/// 2008, ch. 2) S = R + (f⁺ − R f⁻) e₁ᵀ / (e₁ · f⁻), f∓ the vector field just before / after.
/// Along Ω ∈ [1.38, 1.55] its dominant pair of complex multipliers leaves the unit circle at
/// Ω ≈ 1.41768 and comes back at Ω ≈ 1.50431 (found by exploring this closed form): two
/// Neimark–Sacker points, bracketed here by bisection on |μ| − 1 of the closed form to rounding.
#include "support/analysis_helpers.hpp"
#include "vibro/continuation.hpp"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>
#include <catch2/catch.hpp>

#include <cmath>
#include <complex>
#include <iomanip>
#include <numbers>
#include <optional>

namespace {

using Eigen::Matrix4d;
using Eigen::Vector4d;
using Eigen::VectorXd;

constexpr double kDamping = 0.02, kStop = 0.2, kRestitution = 0.8;

struct ClosedForm {
  Matrix4d A;
  Vector4d b;
  ClosedForm() {
    Eigen::Matrix2d K, C;
    K << 2.0, -1.0, -1.0, 1.0;
    C = kDamping * K;
    A.setZero();
    A.topRightCorner<2, 2>().setIdentity();
    A.bottomLeftCorner<2, 2>() = -K;
    A.bottomRightCorner<2, 2>() = -C;
    b << 0.0, 0.0, 1.0, 0.0;
  }

  struct Orbit {
    double tau = 0.0;  ///< impact time in [0, T)
    Vector4d after;    ///< state just after the impact
    Eigen::Vector4cd multipliers;
  };

  /// The admissible period-1 orbit with one impact per period at frequency w (throws if none or
  /// several).
  Orbit orbit(double w) const {
    const double T = 2.0 * std::numbers::pi / w;
    const Eigen::Vector4cd Z = (std::complex<double>(0.0, w) * Eigen::Matrix4cd::Identity() - A.cast<std::complex<double>>())
                                   .partialPivLu()
                                   .solve(b.cast<std::complex<double>>());
    auto zp = [&](double t) -> Vector4d { return (Z * std::exp(std::complex<double>(0.0, w * t))).real(); };
    const Matrix4d Phi = (A * T).exp();
    Matrix4d R = Matrix4d::Identity();
    R(2, 2) = -kRestitution;
    const Matrix4d map = (Matrix4d::Identity() - R * Phi).inverse() * R * (Matrix4d::Identity() - Phi);
    auto g = [&](double tau) { return (map * zp(tau))(0) - kStop; };
    std::optional<Orbit> found;
    const int n = 400;
    for (int i = 0; i < n; ++i) {
      double lo = T * i / n, hi = T * (i + 1) / n, glo = g(lo);
      if ((glo > 0.0) == (g(hi) > 0.0)) continue;
      for (int it = 0; it < 200 && hi - lo > 4e-16 * T; ++it) {  // bisection to rounding
        const double mid = 0.5 * (lo + hi), gm = g(mid);
        ((gm > 0.0) == (glo > 0.0) ? lo : hi) = mid;
      }
      const double tau = 0.5 * (lo + hi);
      const Vector4d after = map * zp(tau);
      const Vector4d before = Phi * (after - zp(tau)) + zp(tau);
      if (before(2) <= 0.0) continue;  // mass 1 must move towards the stop
      // Below the stop over the whole period (sampled on 4000 steps of the closed form).
      const Matrix4d step = (A * (T / 4000.0)).exp();
      Vector4d h = after - zp(tau);
      bool admissible = true;
      for (int k = 1; k < 4000 && admissible; ++k) {
        h = step * h;
        admissible = h(0) + zp(tau + k * T / 4000.0)(0) <= kStop + 1e-12;
      }
      if (!admissible) continue;
      const double force = std::cos(w * tau);
      const Vector4d f_before = A * before + b * force, f_after = A * after + b * force;
      const Matrix4d S = R + (f_after - R * f_before) * Vector4d::Unit(0).transpose() / f_before(0);
      REQUIRE_FALSE(found.has_value());  // one admissible orbit only
      found = Orbit{tau, after, (S * Phi).eigenvalues()};
    }
    REQUIRE(found.has_value());
    return *found;
  }

  /// |μ| − 1 of the complex pair of largest modulus.
  double pair_modulus_minus_one(double w) const {
    const Eigen::Vector4cd mu = orbit(w).multipliers;
    double best = 0.0;
    for (int i = 0; i < 4; ++i)
      if (std::abs(mu(i).imag()) > 1e-9) best = std::max(best, std::abs(mu(i)));
    REQUIRE(best > 0.0);
    return best - 1.0;
  }

  /// Bisection on |μ| − 1 in [lo, hi] to rounding.
  double neimark_sacker(double lo, double hi) const {
    double flo = pair_modulus_minus_one(lo);
    REQUIRE((flo > 0.0) != (pair_modulus_minus_one(hi) > 0.0));
    while (hi - lo > 4e-16 * hi) {
      const double mid = 0.5 * (lo + hi), fm = pair_modulus_minus_one(mid);
      if ((fm > 0.0) == (flo > 0.0)) {
        lo = mid;
        flo = fm;
      } else {
        hi = mid;
      }
    }
    return 0.5 * (lo + hi);
  }
};

vibro::FamilyPoint two_masses(double omega) {
  Eigen::MatrixXd K(2, 2);
  K << 2.0, -1.0, -1.0, 1.0;
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(2, omega);
  f.cosine(0) = 1.0;
  vibro::ImpactSystem sys(vibro::LinearSystem(Eigen::MatrixXd::Identity(2, 2), kDamping * K, K, f),
                          {vibro::Stop::upper(0, kStop, kRestitution)});
  return vibro::FamilyPoint{std::move(sys), vibro::SystemDerivative::frequency_only()};
}

}  // namespace

TEST_CASE("continuation: a two-mass impact oscillator's branch loses and regains stability at two "
          "Neimark-Sacker points located to 1e-10 of the closed form",
          "[continuation][closed-form]") {
  const ClosedForm cf;
  const double ns_low = cf.neimark_sacker(1.41, 1.42), ns_high = cf.neimark_sacker(1.50, 1.51);

  // The branch from the closed-form orbit at Ω = 1.38, half a period after its impact.
  const double w0 = 1.38, T0 = 2.0 * std::numbers::pi / w0;
  const ClosedForm::Orbit start = cf.orbit(w0);
  const Eigen::Vector4cd Z0 = (std::complex<double>(0.0, w0) * Eigen::Matrix4cd::Identity() - cf.A.cast<std::complex<double>>())
                                  .partialPivLu()
                                  .solve(cf.b.cast<std::complex<double>>());
  auto zp0 = [&](double t) -> Vector4d { return (Z0 * std::exp(std::complex<double>(0.0, w0 * t))).real(); };
  const double t0 = start.tau + 0.5 * T0;
  const Vector4d z0 = (cf.A * (0.5 * T0)).exp() * (start.after - zp0(start.tau)) + zp0(t0);

  vibro::ContinuationOptions o;
  o.p_min = 1.38;
  o.p_max = 1.55;
  o.step = 0.02;
  const vibro::ContinuationResult r = vibro::continue_orbits(two_masses, w0, t0, z0.head(2), z0.tail(2), o);
  REQUIRE_FALSE(r.branches.empty());
  INFO("branch: " << r.branches[0].end);
  CHECK(r.branches[0].end.find("reached p_max") != std::string::npos);

  std::vector<const vibro::Bifurcation*> ns;
  for (const vibro::Bifurcation& b : r.bifurcations)
    if (b.kind == vibro::BifurcationKind::neimark_sacker) ns.push_back(&b);
  REQUIRE(ns.size() == 2);
  if (ns[0]->p > ns[1]->p) std::swap(ns[0], ns[1]);
  for (auto [found, expected] : {std::pair{ns[0], ns_low}, std::pair{ns[1], ns_high}}) {
    INFO(std::setprecision(15) << "expected at " << expected << ", located at " << found->p << " (difference "
                                << found->p - expected << ", bracket " << found->p_low << " … "
                        << found->p_high << ", value " << found->value << ")");
    CHECK(found->smooth);
    CHECK(std::abs(found->p - expected) <= 1e-10);
    // The located orbit's own multipliers: the pair on the unit circle.
    double pair = 0.0;
    for (const std::complex<double>& m : found->point.multipliers.values)
      if (std::abs(m.imag()) > 1e-9) pair = std::max(pair, std::abs(m));
    CHECK(std::abs(pair - 1.0) <= 1e-9);
  }
  // Stable below the first, unstable between, stable above the second; no other bifurcation
  // (the orbit keeps its one impact per period).
  for (const vibro::BranchPoint& q : r.branches[0].points) {
    if (q.located) continue;
    INFO("Ω = " << q.p);
    const bool outside = q.p < ns_low - 1e-6 || q.p > ns_high + 1e-6, inside = q.p > ns_low + 1e-6 && q.p < ns_high - 1e-6;
    if (outside) CHECK(q.multipliers.stable);
    if (inside) CHECK_FALSE(q.multipliers.stable);
    CHECK(q.signature.impacts[0] == 1);
  }
  CHECK(r.bifurcations.size() == 2);
}
