/// Tests of vibro::ContactMode, vibro::ContactModes and vibro::solve_lcp
/// (framework/src/contact.cpp), largely on the system of Wagg (2004) (vibro::models::wagg2004:
/// stop 0 below mass 1 at s1 < 0, stop 1 above mass 2 at s2 > 0, M = m I, K = k E, C = c E).
///
/// What is checked, and against what (every expected value is derived here, by hand or by a
/// small independent computation; none is copied from the library):
///  1. restitution: R_S of the paper equals R1, R2, R3 of eq. (8); Ψ⁻¹ R_S Ψ (eq. 10) equals the
///     modal matrices expanded by hand with the closed-form Ψ of E = [[2,-1],[-1,1]]; for a full
///     mass matrix and stops between masses, R_S obeys the generalised Newton law
///     Wᵀ R_S v = -diag(r) Wᵀ v, moves v only along M⁻¹W (impulses along the normals), keeps
///     tangential velocities (Wᵀu = 0 ⇒ R_S u = u), is an M-orthogonal reflection for r = 1 and
///     a projection for r = 0;
///  2. sticking subsystems: the reduced M, C, K and forcing of eqs. (11) and (14), default and
///     other parameters; the reduced flow against the exact solutions (13) and (16) (with the
///     static term +s2/2, not the -s2/2 printed in eq. 16), and the static equilibria;
///  3. contact forces: λ of force_rows and the watch rows against the force balance of the
///     stuck mass written from eqs. (1)-(2): λ = -F2 (eq. 12) with mass 1 stuck below s1 < 0,
///     λ = +F1 (eq. 15) with mass 2 stuck above s2 > 0, i.e. λ > 0 ⇔ F_i s_i > 0 (section 4);
///     (contact.hpp's comment says "-F1"; that contradicts both the balance and its own
///     F_i s_i > 0 remark, and the code computes +F1, which is what is tested);
///     both masses stuck: λ from the static balance;
///  4. the reduced flow is the constrained flow: for a stop between masses of a 3-DOF chain, for
///     a harmonically moving stop, and for two moving stops (one between masses) held at once
///     with a full mass matrix, the full state T z_r stays on the constraints, and the
///     acceleration M⁻¹(f - Cv - Kx - Wλ) with λ from force_rows equals both the derivative of
///     T z_r given by the reduced generator and a 5-point finite difference of the exact flow;
///  5. solve_lcp: complementarity on random SPD problems of size 1..8, against brute-force
///     enumeration of all 2^m active sets, closed-form special cases, and scale invariance;
///  6. ContactModes builds only the sets asked for, reduced subsystems only when asked;
///  7. a mode's state rows [x; v] evaluated by Segment::evaluate (its per-segment table, what the
///     observers' states use) against the segment's augmented state expanded by T, on every
///     evaluation path (spectral, closed form on Schur clusters, Padé).
/// The worst errors are printed by the hidden test "[.report]":
///     ./vibro_tests_framework "[.report]"
#include "vibro/contact.hpp"
#include "vibro/flow.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace {

using vibro::ContactMode;
using vibro::ContactModes;
using vibro::ContactSet;
using vibro::HarmonicForcing;
using vibro::ImpactSystem;
using vibro::LinearSystem;
using vibro::Stop;
using vibro::models::Wagg2004;

double max_abs(const Eigen::MatrixXd& a) { return a.size() == 0 ? 0.0 : a.cwiseAbs().maxCoeff(); }

/// Full augmented state [x; v; cos Ωt; sin Ωt; 1] written out here (not LinearFlow::augment).
Eigen::VectorXd augmented(double omega, double t, const Eigen::VectorXd& x,
                          const Eigen::VectorXd& v) {
  const Eigen::Index n = x.size();
  Eigen::VectorXd z(2 * n + 3);
  z << x, v, std::cos(omega * t), std::sin(omega * t), 1.0;
  return z;
}

/// Physical position s(t) of a stop in the gap form g = wᵀx - s(t), from the stop's definition:
/// upper and between: p + a cos(Ωt + φ); lower: -(p + a cos(Ωt + φ)). And its derivatives.
double stop_s(const Stop& st, double omega, double t, int derivative = 0) {
  const double th = omega * t + st.phase;
  double value = 0.0;
  switch (derivative) {
    case 0: value = st.position + st.amplitude * std::cos(th); break;
    case 1: value = -st.amplitude * omega * std::sin(th); break;
    default: value = -st.amplitude * omega * omega * std::cos(th); break;
  }
  return st.kind == Stop::Kind::lower ? -value : value;
}

/// Normal w of a stop, from its definition.
Eigen::VectorXd stop_w(const Stop& st, Eigen::Index n) {
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  if (st.kind == Stop::Kind::lower)
    w(st.mass) = -1.0;
  else
    w(st.mass) = 1.0;
  if (st.kind == Stop::Kind::between) w(st.other) = -1.0;
  return w;
}

/// f(t) = F0 + Fc cos Ωt + Fs sin Ωt written out.
Eigen::VectorXd force_at(const HarmonicForcing& f, double t) {
  return f.constant + f.cosine * std::cos(f.frequency * t) + f.sine * std::sin(f.frequency * t);
}

// =============================================================================================
// 1. Restitution
// =============================================================================================

/// The orthogonal modal matrix Ψ of E = [[2,-1],[-1,1]] in closed form: λ₁,₂ = (3 ∓ √5)/2, and
/// (E - λI)ξ = 0 gives (2 - λ)ξ₁ = ξ₂, so ξ ∝ (1, 2 - λ), normalised.
Eigen::Matrix2d paper_modal_matrix() {
  const double root5 = std::sqrt(5.0);
  const double lambda[2] = {(3.0 - root5) / 2.0, (3.0 + root5) / 2.0};
  Eigen::Matrix2d psi;
  for (int j = 0; j < 2; ++j) psi.col(j) = Eigen::Vector2d(1.0, 2.0 - lambda[j]).normalized();
  return psi;
}

/// Ψ⁻¹ R Ψ expanded by hand. With φ = (1+√5)/2, ξ₁ = (1, φ)/√(1+φ²) = (a, b) and
/// ξ₂ = (1, -1/φ)/√(1+φ⁻²) = (b, -a), where a² = 2/(5+√5) = (5-√5)/10, b² = (5+√5)/10 and
/// ab = φ/(φ+2) = 1/√5. So Ψ = [[a, b], [b, -a]] = Ψᵀ = Ψ⁻¹ and for R = diag(d1, d2)
///     Ψ⁻¹ R Ψ = [[a² d1 + b² d2, ab (d1 - d2)], [ab (d1 - d2), b² d1 + a² d2]]:
///   R1 = diag(-r, 1):  [[((5+√5) - r(5-√5))/10, -(1+r)/√5], [-(1+r)/√5, ((5-√5) - r(5+√5))/10]]
///   R2 = diag(1, -r):  [[((5-√5) - r(5+√5))/10,  (1+r)/√5], [ (1+r)/√5, ((5+√5) - r(5-√5))/10]]
///   R3 = -r I:         -r I.
Eigen::Matrix2d modal_r1(double r) {
  const double s5 = std::sqrt(5.0);
  Eigen::Matrix2d m;
  m << ((5 + s5) - r * (5 - s5)) / 10, -(1 + r) / s5,  //
      -(1 + r) / s5, ((5 - s5) - r * (5 + s5)) / 10;
  return m;
}
Eigen::Matrix2d modal_r2(double r) {
  const double s5 = std::sqrt(5.0);
  Eigen::Matrix2d m;
  m << ((5 - s5) - r * (5 + s5)) / 10, (1 + r) / s5,  //
      (1 + r) / s5, ((5 + s5) - r * (5 - s5)) / 10;
  return m;
}
Eigen::Matrix2d modal_r3(double r) { return -r * Eigen::Matrix2d::Identity(); }

struct PaperRestitutionErrors {
  double physical = 0.0;  // R_S vs eq. (8)
  double modal = 0.0;     // Ψ⁻¹ R_S Ψ vs the hand expansion
};

PaperRestitutionErrors paper_restitution_errors(double r) {
  const ImpactSystem scene = vibro::models::wagg2004(Wagg2004{.r = r});
  ContactModes modes(scene);
  const Eigen::Matrix2d R1 = Eigen::Vector2d(-r, 1.0).asDiagonal();
  const Eigen::Matrix2d R2 = Eigen::Vector2d(1.0, -r).asDiagonal();
  const Eigen::Matrix2d R3 = Eigen::Vector2d(-r, -r).asDiagonal();
  const Eigen::Matrix2d psi = paper_modal_matrix();
  const Eigen::Matrix2d psi_inv = psi.inverse();
  const Eigen::MatrixXd& S1 = modes.get({0}).restitution_matrix();
  const Eigen::MatrixXd& S2 = modes.get({1}).restitution_matrix();
  const Eigen::MatrixXd& S3 = modes.get({0, 1}).restitution_matrix();
  PaperRestitutionErrors e;
  e.physical = std::max({max_abs(S1 - R1), max_abs(S2 - R2), max_abs(S3 - R3)});
  e.modal = std::max({max_abs(psi_inv * S1 * psi - modal_r1(r)),
                      max_abs(psi_inv * S2 * psi - modal_r2(r)),
                      max_abs(psi_inv * S3 * psi - modal_r3(r))});
  return e;
}

/// A 4-DOF system with a full random SPD mass matrix and four stops: two between masses, one
/// upper, one lower (normals e0-e1, e2, -e3, e3-e1: linearly independent, so every subset is a
/// valid contact set). `restitution` < 0 keeps the mixed coefficients below.
ImpactSystem coupled_scene(double restitution = -1.0) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd A(4, 4);
  for (Eigen::Index i = 0; i < 4; ++i)
    for (Eigen::Index j = 0; j < 4; ++j) A(i, j) = u(rng);
  Eigen::MatrixXd M = A * A.transpose() + 0.5 * Eigen::MatrixXd::Identity(4, 4);
  M = 0.5 * (M + M.transpose());
  Eigen::MatrixXd K(4, 4);
  K << 2, -1, 0, 0,  //
      -1, 2, -1, 0,  //
      0, -1, 2, -1,  //
      0, 0, -1, 1;
  Eigen::MatrixXd C = 0.1 * K;
  std::vector<Stop> stops{Stop::between(0, 1, 0.1, 0.3), Stop::upper(2, 0.2, 0.8),
                          Stop::lower(3, -0.2, 0.0), Stop::between(3, 1, 0.3, 1.0)};
  if (restitution >= 0.0)
    for (Stop& s : stops) s.restitution = restitution;
  return ImpactSystem(LinearSystem(M, C, K, HarmonicForcing::zero(4, 1.0)), std::move(stops));
}

/// All non-empty subsets of {0, …, m-1}, sorted.
std::vector<ContactSet> all_sets(int m) {
  std::vector<ContactSet> sets;
  for (int mask = 1; mask < (1 << m); ++mask) {
    ContactSet s;
    for (int j = 0; j < m; ++j)
      if (mask & (1 << j)) s.push_back(j);
    sets.push_back(s);
  }
  return sets;
}

struct NewtonLawErrors {
  double newton = 0.0;      // |Wᵀ R v + diag(r) Wᵀ v| / |v|
  double direction = 0.0;   // part of M (R - I) v outside range(W), / |v|
  double tangential = 0.0;  // |R u - u| / |u| for Wᵀu = 0
  double reflection = 0.0;  // r = 1: |R² - I|, |RᵀMR - M|/|M|
  double projection = 0.0;  // r = 0: |R² - R|, |Wᵀ R|
};

Eigen::MatrixXd normals_of(const ImpactSystem& scene, const ContactSet& set) {
  Eigen::MatrixXd W(scene.dof(), static_cast<Eigen::Index>(set.size()));
  for (std::size_t a = 0; a < set.size(); ++a)
    W.col(static_cast<Eigen::Index>(a)) =
        stop_w(scene.stops()[static_cast<std::size_t>(set[a])], scene.dof());
  return W;
}

NewtonLawErrors newton_law_errors() {
  NewtonLawErrors e;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const ImpactSystem scene = coupled_scene();
  const Eigen::MatrixXd& M = scene.system().mass();
  ContactModes modes(scene);
  for (const ContactSet& set : all_sets(4)) {
    const Eigen::MatrixXd W = normals_of(scene, set);
    Eigen::VectorXd r(W.cols());
    for (Eigen::Index a = 0; a < W.cols(); ++a)
      r(a) = scene.stops()[static_cast<std::size_t>(set[static_cast<std::size_t>(a)])].restitution;
    const Eigen::MatrixXd& R = modes.get(set).restitution_matrix();
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> range_w(W);
    for (int trial = 0; trial < 5; ++trial) {
      Eigen::VectorXd v(4);
      for (Eigen::Index i = 0; i < 4; ++i) v(i) = u(rng);
      const double vn = v.norm();
      e.newton = std::max(
          e.newton, (W.transpose() * R * v + r.asDiagonal() * (W.transpose() * v)).norm() / vn);
      const Eigen::VectorXd impulse = M * (R * v - v);  // = -W Λ if the impulse is along -W
      const Eigen::VectorXd outside = impulse - W * range_w.solve(impulse);
      e.direction = std::max(e.direction, outside.norm() / vn);
    }
    // Tangential velocities: a basis of the kernel of Wᵀ (4 - m vectors).
    const Eigen::MatrixXd kernel = Eigen::FullPivLU<Eigen::MatrixXd>(W.transpose()).kernel();
    if (static_cast<Eigen::Index>(set.size()) < 4) {
      for (Eigen::Index c = 0; c < kernel.cols(); ++c) {
        const Eigen::VectorXd t = kernel.col(c);
        e.tangential = std::max(e.tangential, (R * t - t).norm() / t.norm());
      }
    }
  }
  const ImpactSystem elastic = coupled_scene(1.0);
  const ImpactSystem plastic = coupled_scene(0.0);
  ContactModes elastic_modes(elastic), plastic_modes(plastic);
  for (const ContactSet& set : all_sets(4)) {
    const Eigen::MatrixXd& Re = elastic_modes.get(set).restitution_matrix();
    e.reflection = std::max({e.reflection, max_abs(Re * Re - Eigen::MatrixXd::Identity(4, 4)),
                             max_abs(Re.transpose() * M * Re - M) / max_abs(M)});
    const Eigen::MatrixXd& Rp = plastic_modes.get(set).restitution_matrix();
    e.projection = std::max(
        {e.projection, max_abs(Rp * Rp - Rp), max_abs(normals_of(plastic, set).transpose() * Rp)});
  }
  return e;
}

// =============================================================================================
// 2. Sticking subsystems and their exact solutions
// =============================================================================================

/// Non-default parameters for the paper's model (A2 ≠ 0, m ≠ 1, s2 ≠ -s1/3).
const Wagg2004 kOther{.m = 2.0,
                      .k = 3.0,
                      .c = 0.05,
                      .A1 = 0.7,
                      .A2 = 0.2,
                      .frequency = 0.9,
                      .s1 = -0.4,
                      .s2 = 0.25,
                      .r = 0.6};

struct Motion {
  double x, v;
};

/// Mass 1 stuck at s1: eq. (11) with the A2 cos Ωt term, m x2'' + c x2' + k (x2 - s1) = A2 cos Ωt.
/// For A2 = 0 this is eq. (13): x2 = e^{-ζω τ}(C1 cos ωd τ + C2 sin ωd τ) + s1, ω = √(k/m),
/// ζ = c/(2mω), ωd = ω√(1-ζ²), C1 = x2(ts) - s1, C2 = (x2'(ts) + ζω C1)/ωd. With A2 ≠ 0 the
/// particular solution D cos(Ωt - θ) is added, D = (A2/m)/√((ω² - Ω²)² + (2ζωΩ)²),
/// θ = atan2(2ζωΩ, ω² - Ω²), and C1, C2 take it off the initial conditions.
Motion eq13_motion(const Wagg2004& p, double ts, Motion start, double t) {
  const double wn = std::sqrt(p.k / p.m);
  const double zeta = p.c / (2 * p.m * wn);
  const double wd = wn * std::sqrt(1 - zeta * zeta);
  const double W = p.frequency;
  const double D = (p.A2 / p.m) / std::hypot(wn * wn - W * W, 2 * zeta * wn * W);
  const double theta = std::atan2(2 * zeta * wn * W, wn * wn - W * W);
  const double C1 = start.x - p.s1 - D * std::cos(W * ts - theta);
  const double C2 = (start.v + D * W * std::sin(W * ts - theta) + zeta * wn * C1) / wd;
  const double tau = t - ts;
  const double e = std::exp(-zeta * wn * tau);
  const double c = std::cos(wd * tau), s = std::sin(wd * tau);
  return {e * (C1 * c + C2 * s) + p.s1 + D * std::cos(W * t - theta),
          e * ((-zeta * wn * C1 + wd * C2) * c + (-zeta * wn * C2 - wd * C1) * s) -
              D * W * std::sin(W * t - theta)};
}

/// Mass 2 stuck at s2: eq. (16) with the static term corrected to +s2/2 (eq. 14 at rest:
/// 2k x1 = k s2):
///     x1 = e^{-2ζω τ}(C1 cos 2ω* τ + C2 sin 2ω* τ) + C3 cos(Ωt - φ*) + s2/2,
/// ω = √(k/m), ζ = c/(2mω), ω* = ω√(0.5 - ζ²), φ* of eq. (17) (atan2 for the quadrant), and
/// C3 = (A1/m)/√((2ω² - Ω²)² + (4ζωΩ)²) from x1'' + 4ζω x1' + 2ω² x1 = (A1/m) cos Ωt + ....
Motion eq16_motion(const Wagg2004& p, double ts, Motion start, double t) {
  const double wn = std::sqrt(p.k / p.m);
  const double zeta = p.c / (2 * p.m * wn);
  const double wstar = wn * std::sqrt(0.5 - zeta * zeta);
  const double W = p.frequency;
  const double phi = std::atan2(4 * zeta * (W / wn), 2 - W * W / (wn * wn));  // eq. (17)
  const double C3 = (p.A1 / p.m) / std::hypot(2 * wn * wn - W * W, 4 * zeta * wn * W);
  const double sigma = 2 * zeta * wn, wd = 2 * wstar;
  const double C1 = start.x - p.s2 / 2 - C3 * std::cos(W * ts - phi);
  const double C2 = (start.v + C3 * W * std::sin(W * ts - phi) + sigma * C1) / wd;
  const double tau = t - ts;
  const double e = std::exp(-sigma * tau);
  const double c = std::cos(wd * tau), s = std::sin(wd * tau);
  return {e * (C1 * c + C2 * s) + C3 * std::cos(W * t - phi) + p.s2 / 2,
          e * ((-sigma * C1 + wd * C2) * c + (-sigma * C2 - wd * C1) * s) -
              C3 * W * std::sin(W * t - phi)};
}

/// Worst |x - x_exact|, |v - v_exact| over 40 time units of the reduced flow of `set` against
/// the closed form, from the state (s_stuck, x_free) at ts.
double sticking_closed_form_error(const Wagg2004& p, int set) {
  const ImpactSystem scene = vibro::models::wagg2004(p);
  ContactModes modes(scene);
  const ContactMode& mode = modes.get({set});
  const auto& red = mode.reduced();
  const double ts = 1.7;
  const Motion start{set == 0 ? 0.05 : -0.35, set == 0 ? 0.4 : -0.6};
  const Eigen::Vector2d x0 =
      set == 0 ? Eigen::Vector2d(p.s1, start.x) : Eigen::Vector2d(start.x, p.s2);
  const Eigen::Vector2d v0 =
      set == 0 ? Eigen::Vector2d(0.0, start.v) : Eigen::Vector2d(start.v, 0.0);
  const Eigen::VectorXd z0 = mode.reduce(ts, x0, v0);
  Eigen::VectorXd z(z0.size());
  double worst = 0.0;
  for (int j = 0; j <= 200; ++j) {
    const double tau = 0.2 * j;
    red.flow->propagate(z0, tau, z);
    const Motion exact =
        set == 0 ? eq13_motion(p, ts, start, ts + tau) : eq16_motion(p, ts, start, ts + tau);
    worst = std::max({worst, std::abs(z(0) - exact.x), std::abs(z(1) - exact.v)});
  }
  return worst;
}

/// |x - s2/2| and |v| after 1500 time units of mass 2 stuck with A1 = 0 (and |x - s1| with mass
/// 1 stuck, A2 = 0), from far away.
double static_equilibrium_error(const Wagg2004& p, int set) {
  Wagg2004 unforced = p;
  unforced.A1 = 0.0;
  unforced.A2 = 0.0;
  const ImpactSystem scene = vibro::models::wagg2004(unforced);
  ContactModes modes(scene);
  const ContactMode& mode = modes.get({set});
  const Eigen::Vector2d x0 = set == 0 ? Eigen::Vector2d(p.s1, 0.8) : Eigen::Vector2d(-0.9, p.s2);
  const Eigen::Vector2d v0 = set == 0 ? Eigen::Vector2d(0.0, -0.5) : Eigen::Vector2d(0.7, 0.0);
  const Eigen::VectorXd z0 = mode.reduce(0.3, x0, v0);
  Eigen::VectorXd z(z0.size());
  mode.reduced().flow->propagate(z0, 1500.0, z);
  const double target = set == 0 ? p.s1 : p.s2 / 2;
  return std::max(std::abs(z(0) - target), std::abs(z(1)));
}

// =============================================================================================
// 3. Contact forces of the paper's sticking modes
// =============================================================================================

struct ForceErrors {
  double force_rows = 0.0;  // |λ(force_rows) - λ(hand)| / scale
  double watch = 0.0;       // |watch rows - (gap, -λ)(hand)| / scale
  int positive = 0, negative = 0, sign_mismatch = 0;
};

/// λ at random states of mass 1 stuck (set {0}) and of mass 2 stuck (set {1}), against the force
/// balance of the stuck mass (eqs. 1-2 with the contact force; λ ≥ 0 acts along -w):
///  * set {0}, x1 = s1, x1' = x1'' = 0, contact pushes mass 1 up (+λ):
///        c(0 - x2') + k(2 s1 - x2) = A1 cos Ωt + λ
///      ⇒ λ = -(c x2' + k(x2 - 2 s1) + A1 cos Ωt) = -F2;
///  * set {1}, x2 = s2, x2' = x2'' = 0, contact pushes mass 2 down (-λ):
///        c(0 - x1') + k(s2 - x1) = A2 cos Ωt - λ
///      ⇒ λ = c x1' + k(x1 - s2) + A2 cos Ωt = F1 + A2 cos Ωt.
/// The scale of each comparison is the sum of the magnitudes of the terms (rounding is relative
/// to it, cancellation is not).
ForceErrors contact_force_errors(const Wagg2004& p) {
  const ImpactSystem scene = vibro::models::wagg2004(p);
  ContactModes modes(scene);
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> pos(-1.0, 1.0), vel(-2.0, 2.0), time(0.0, 100.0);
  const double W = p.frequency;
  ForceErrors e;
  for (int set = 0; set < 2; ++set) {
    const ContactMode& mode = modes.get({set});
    const auto& red = mode.reduced();
    REQUIRE(red.force_rows.rows() == 1);
    REQUIRE(red.force_rows.cols() == 7);
    REQUIRE(red.gap_rows == 1);
    REQUIRE(red.watched == std::vector<int>{1 - set, set});
    for (int trial = 0; trial < 200; ++trial) {
      const double t = time(rng), y = pos(rng), yd = vel(rng);
      const double cw = std::cos(W * t);
      Eigen::Vector2d x, v;
      double F = 0.0, lambda = 0.0, scale = 0.0, s = 0.0, other_gap = 0.0;
      if (set == 0) {
        x << p.s1, y;
        v << 0.0, yd;
        F = p.c * yd + p.k * (y - 2 * p.s1) + p.A1 * cw;  // eq. (12)
        lambda = -F;
        scale =
            std::abs(p.c * yd) + std::abs(p.k * y) + std::abs(2 * p.k * p.s1) + std::abs(p.A1 * cw);
        s = p.s1;
        other_gap = y - p.s2;  // stop 1: x2 - s2
      } else {
        x << y, p.s2;
        v << yd, 0.0;
        F = p.c * yd + p.k * (y - p.s2);  // eq. (15)
        lambda = F + p.A2 * cw;
        scale = std::abs(p.c * yd) + std::abs(p.k * y) + std::abs(p.k * p.s2) + std::abs(p.A2 * cw);
        s = p.s2;
        other_gap = p.s1 - y;  // stop 0: -x1 + s1
      }
      const double lambda_rows = red.force_rows.row(0).dot(augmented(W, t, x, v));
      const Eigen::VectorXd zr = mode.reduce(t, x, v);
      const Eigen::VectorXd watch = red.watch->rows(0) * zr;
      e.force_rows = std::max(e.force_rows, std::abs(lambda_rows - lambda) / scale);
      e.watch = std::max({e.watch, std::abs(watch(1) + lambda) / scale,
                          std::abs(watch(0) - other_gap) / (std::abs(y) + 1.0)});
      // Section 4's rule (stated for A2 = 0, where F is the whole force): λ > 0 ⇔ F_i s_i > 0.
      if (p.A2 == 0.0 && std::abs(lambda) > 1e-9) {
        (lambda > 0 ? e.positive : e.negative) += 1;
        if ((lambda_rows > 0) != (F * s > 0)) ++e.sign_mismatch;
      }
    }
  }
  return e;
}

// =============================================================================================
// 4. The reduced flow is the constrained flow
// =============================================================================================

struct ConstrainedErrors {
  double position = 0.0;        // |wᵀx - s(t)|
  double rate = 0.0;            // |wᵀv - s'(t)|
  double constraint_acc = 0.0;  // |wᵀa - s''(t)| / max|a|, a from λ of force_rows
  double generator = 0.0;       // |d/dt (T z_r) - (v, a)| / max(|v|, |a|)
  double difference = 0.0;      // |5-point FD of v - a| / max|a|
  double watch = 0.0;           // |watch rows - (gaps, -λ)| / (1 + |λ|)
  double start = 0.0;           // |T reduce(x0, v0) - z0|
};

/// Propagates the sticking mode `set` of `scene` from (t0, x0, v0) (on the constraint) for
/// `span`, and compares the full motion with the constrained equations of motion
///     M a = f(t) - C v - K x - W λ,   Wᵀ x = s(t),
/// using only the system matrices and the stops' definitions.
ConstrainedErrors constrained_errors(const ImpactSystem& scene, const ContactSet& set, double t0,
                                     const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                                     double span) {
  const LinearSystem& sys = scene.system();
  const Eigen::Index n = sys.dof();
  const double W = sys.forcing().frequency;
  ContactModes modes(scene);
  const ContactMode& mode = modes.get(set);
  const auto& red = mode.reduced();
  const Eigen::MatrixXd Wn = normals_of(scene, set);
  const Eigen::LLT<Eigen::MatrixXd> mass(sys.mass());
  const Eigen::VectorXd zr0 = mode.reduce(t0, x0, v0);
  ConstrainedErrors e;
  e.start = max_abs(red.to_full * zr0 - augmented(W, t0, x0, v0));

  const double rate = red.flow->spectral_radius();
  const double h = 1e-2 / rate;  // FD step: h·ρ = 0.01
  Eigen::VectorXd zr(zr0.size()), zp(zr0.size());
  const auto full_velocity = [&](double tau) {
    red.flow->propagate(zr0, tau, zp);
    return Eigen::VectorXd((red.to_full * zp).segment(n, n));
  };
  double max_a = 0.0, max_v = 0.0;
  std::vector<double> acc_err, gen_err, fd_err;
  for (int j = 0; j <= 150; ++j) {
    const double tau = span * j / 150.0;
    const double t = t0 + tau;
    red.flow->propagate(zr0, tau, zr);
    const Eigen::VectorXd z = red.to_full * zr;
    const Eigen::VectorXd x = z.head(n), v = z.segment(n, n);
    const Eigen::VectorXd lambda = red.force_rows * z;
    const Eigen::VectorXd a = mass.solve(force_at(sys.forcing(), t) - sys.damping() * v -
                                         sys.stiffness() * x - Wn * lambda);
    max_a = std::max(max_a, a.lpNorm<Eigen::Infinity>());
    max_v = std::max(max_v, v.lpNorm<Eigen::Infinity>());
    for (std::size_t k = 0; k < set.size(); ++k) {
      const Stop& st = scene.stops()[static_cast<std::size_t>(set[k])];
      const auto col = static_cast<Eigen::Index>(k);
      e.position = std::max(e.position, std::abs(Wn.col(col).dot(x) - stop_s(st, W, t)));
      e.rate = std::max(e.rate, std::abs(Wn.col(col).dot(v) - stop_s(st, W, t, 1)));
      acc_err.push_back(std::abs(Wn.col(col).dot(a) - stop_s(st, W, t, 2)));
    }
    const Eigen::VectorXd dz = red.to_full * (red.flow->generator() * zr);
    gen_err.push_back(std::max((dz.head(n) - v).lpNorm<Eigen::Infinity>(),
                               (dz.segment(n, n) - a).lpNorm<Eigen::Infinity>()));
    const Eigen::VectorXd fd = (-full_velocity(tau + 2 * h) + 8 * full_velocity(tau + h) -
                                8 * full_velocity(tau - h) + full_velocity(tau - 2 * h)) /
                               (12 * h);
    fd_err.push_back((fd - a).lpNorm<Eigen::Infinity>());
    // Watch rows: gaps of the other stops (own formula), then -λ.
    const Eigen::VectorXd watch = red.watch->rows(0) * zr;
    for (Eigen::Index r = 0; r < watch.size(); ++r) {
      const int j_stop = red.watched[static_cast<std::size_t>(r)];
      const Stop& st = scene.stops()[static_cast<std::size_t>(j_stop)];
      double expected = 0.0;
      if (r < red.gap_rows) {
        expected = stop_w(st, n).dot(x) - stop_s(st, W, t);
      } else {
        const auto it = std::find(set.begin(), set.end(), j_stop);
        expected = -lambda(static_cast<Eigen::Index>(it - set.begin()));
      }
      e.watch = std::max(e.watch,
                         std::abs(watch(r) - expected) / (1.0 + lambda.lpNorm<Eigen::Infinity>()));
    }
  }
  for (double v : acc_err) e.constraint_acc = std::max(e.constraint_acc, v / max_a);
  for (double v : gen_err) e.generator = std::max(e.generator, v / std::max(max_a, max_v));
  for (double v : fd_err) e.difference = std::max(e.difference, v / max_a);
  return e;
}

/// 3-DOF chain with a stop between masses 0 and 1 (x0 - x1 ≤ 0.2) and an upper stop on mass 2,
/// forced with constant, cosine and sine terms; sticking mode {0} from a state on the stop.
ConstrainedErrors between_stop_errors() {
  vibro::models::Chain chain;
  chain.masses = {1.0, 1.5, 0.8};
  chain.springs = {2.0, 1.0};
  chain.dampers = {0.1, 0.2};
  chain.left_spring = 1.0;
  chain.left_damper = 0.05;
  chain.right_spring = 0.5;
  chain.force_constant = {0.1, -0.05, 0.0};
  chain.force_cosine = {0.5, 0.0, -0.3};
  chain.force_sine = {0.0, 0.2, 0.1};
  chain.frequency = 1.1;
  const ImpactSystem scene(vibro::models::build_chain(chain),
                           {Stop::between(0, 1, 0.2, 0.5), Stop::upper(2, 0.4, 0.6)});
  const Eigen::Vector3d x0(0.25, 0.05, -0.1), v0(0.3, 0.3, -0.2);
  return constrained_errors(scene, {0}, 0.6, x0, v0, 30.0);
}

/// Forced 2-DOF chain (Ω = 1.3) with mass 0 held on the moving upper stop
/// s(t) = 0.2 + 0.05 cos(1.3 t + 0.3).
ConstrainedErrors moving_stop_errors() {
  vibro::models::Chain chain;
  chain.masses = {1.0, 2.0};
  chain.springs = {1.5};
  chain.dampers = {0.1};
  chain.left_spring = 1.0;
  chain.left_damper = 0.05;
  chain.force_constant = {0.05, 0.0};
  chain.force_cosine = {0.3, 0.4};
  chain.force_sine = {0.1, -0.2};
  chain.frequency = 1.3;
  const Stop stop = Stop::upper(0, 0.2, 0.5).moving(0.05, 0.3);
  const ImpactSystem scene(vibro::models::build_chain(chain), {stop, Stop::lower(1, -1.0, 0.5)});
  const double t0 = 0.4;
  const Eigen::Vector2d x0(0.2 + 0.05 * std::cos(1.3 * t0 + 0.3), -0.1);
  const Eigen::Vector2d v0(-0.05 * 1.3 * std::sin(1.3 * t0 + 0.3), 0.2);
  return constrained_errors(scene, {0}, t0, x0, v0, 30.0);
}

/// Two stops held at once on a system with a full random SPD mass matrix, both moving: a stop
/// between masses 0 and 1 and an upper stop on mass 2 (with a full M and a between stop every
/// term of the reduced forcing, M P s'', C P s', K P s, reaches the free coordinates); the third,
/// free stop moves too, so its watched gap row carries the stop's motion.
ConstrainedErrors full_mass_moving_errors() {
  const ImpactSystem base = coupled_scene();
  HarmonicForcing f = HarmonicForcing::zero(4, 0.9);
  f.constant << 0.1, 0.0, -0.2, 0.05;
  f.cosine << 0.4, -0.3, 0.0, 0.2;
  f.sine << 0.0, 0.25, 0.1, -0.1;
  const LinearSystem& b = base.system();
  const std::vector<Stop> stops{Stop::between(0, 1, 0.1, 0.3).moving(0.02, 0.5),
                                Stop::upper(2, 0.2, 0.8).moving(0.03, -1.0),
                                Stop::lower(3, -0.2, 0.0).moving(0.04, 0.7)};
  const ImpactSystem scene(LinearSystem(b.mass(), b.damping(), b.stiffness(), f), stops);
  const double t0 = 0.8, W = 0.9;
  Eigen::Vector4d x0, v0;
  x0 << 0.05 + stop_s(stops[0], W, t0), 0.05, stop_s(stops[1], W, t0), 0.1;
  v0 << -0.2 + stop_s(stops[0], W, t0, 1), -0.2, stop_s(stops[1], W, t0, 1), 0.3;
  return constrained_errors(scene, {0, 1}, t0, x0, v0, 30.0);
}

// =============================================================================================
// 5. The contact LCP
// =============================================================================================

/// Random SPD matrix Q diag(d) Qᵀ, d log-uniform in [0.1, 10] (cond ≤ 100), Q orthogonal.
Eigen::MatrixXd random_spd(Eigen::Index m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd A(m, m);
  for (Eigen::Index i = 0; i < m; ++i)
    for (Eigen::Index j = 0; j < m; ++j) A(i, j) = u(rng);
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(A).householderQ();
  Eigen::VectorXd d(m);
  for (Eigen::Index i = 0; i < m; ++i) d(i) = std::pow(10.0, u(rng));
  Eigen::MatrixXd G = Q * d.asDiagonal() * Q.transpose();
  return 0.5 * (G + G.transpose());
}

/// Enumerates all 2^m active sets B: λ_B = G_BB⁻¹ q_B, λ_N = 0, and returns the one whose
/// worst violation of λ_B ≥ 0, (Gλ - q)_N ≥ 0 is smallest (for a P-matrix exactly one set has
/// none, up to ties at λ_i = w_i = 0, which give the same λ).
Eigen::VectorXd brute_force_lcp(const Eigen::MatrixXd& G, const Eigen::VectorXd& q) {
  const Eigen::Index m = q.size();
  Eigen::VectorXd best = Eigen::VectorXd::Zero(m);
  double best_violation = std::numeric_limits<double>::infinity();
  for (long mask = 0; mask < (1L << m); ++mask) {
    std::vector<Eigen::Index> B;
    for (Eigen::Index i = 0; i < m; ++i)
      if (mask & (1L << i)) B.push_back(i);
    const auto k = static_cast<Eigen::Index>(B.size());
    Eigen::VectorXd lambda = Eigen::VectorXd::Zero(m);
    if (k > 0) {
      Eigen::MatrixXd Gb(k, k);
      Eigen::VectorXd qb(k);
      for (Eigen::Index a = 0; a < k; ++a) {
        qb(a) = q(B[static_cast<std::size_t>(a)]);
        for (Eigen::Index b = 0; b < k; ++b)
          Gb(a, b) = G(B[static_cast<std::size_t>(a)], B[static_cast<std::size_t>(b)]);
      }
      const Eigen::VectorXd lb = Gb.partialPivLu().solve(qb);
      for (Eigen::Index a = 0; a < k; ++a) lambda(B[static_cast<std::size_t>(a)]) = lb(a);
    }
    const Eigen::VectorXd w = G * lambda - q;
    double violation = 0.0;
    for (Eigen::Index i = 0; i < m; ++i)
      violation = std::max(violation, (mask & (1L << i)) ? -lambda(i) : -w(i));
    if (violation < best_violation) {
      best_violation = violation;
      best = lambda;
    }
  }
  return best;
}

struct LcpErrors {
  double complementarity = 0.0;  // max over i of the violations, relative to the problem scale
  double brute_force = 0.0;      // |λ - λ_bf| / max(|λ_bf|, |q|/‖G‖)
  int active_total = 0, problems = 0;
};

/// Complementarity residual of λ for (G, q), relative to s = max(|q|, ‖G‖ |λ|):
/// max(-λ_i ‖G‖, -(Gλ - q)_i, min(λ_i ‖G‖, |Gλ - q|_i)) / s.
double complementarity_residual(const Eigen::MatrixXd& G, const Eigen::VectorXd& q,
                                const Eigen::VectorXd& lambda) {
  const double g = G.cwiseAbs().rowwise().sum().maxCoeff();
  const Eigen::VectorXd w = G * lambda - q;
  const double scale = std::max(q.lpNorm<Eigen::Infinity>(), g * lambda.lpNorm<Eigen::Infinity>());
  double worst = 0.0;
  for (Eigen::Index i = 0; i < q.size(); ++i)
    worst = std::max({worst, -lambda(i) * g, -w(i), std::min(lambda(i) * g, std::abs(w(i)))});
  return worst / scale;
}

LcpErrors lcp_errors() {
  std::mt19937_64 rng(31337);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LcpErrors e;
  for (Eigen::Index m = 1; m <= 8; ++m) {
    for (int trial = 0; trial < 150; ++trial) {
      const Eigen::MatrixXd G = random_spd(m, rng);
      Eigen::VectorXd q(m);
      for (Eigen::Index i = 0; i < m; ++i) q(i) = u(rng) + (trial % 3 == 0 ? 0.5 : 0.0);
      const Eigen::VectorXd lambda = vibro::solve_lcp(G, q);
      const Eigen::VectorXd reference = brute_force_lcp(G, q);
      e.complementarity = std::max(e.complementarity, complementarity_residual(G, q, lambda));
      const double g = G.cwiseAbs().rowwise().sum().maxCoeff();
      e.brute_force = std::max(e.brute_force, (lambda - reference).lpNorm<Eigen::Infinity>() /
                                                  std::max(reference.lpNorm<Eigen::Infinity>(),
                                                           q.lpNorm<Eigen::Infinity>() / g));
      for (Eigen::Index i = 0; i < m; ++i) e.active_total += reference(i) > 0 ? 1 : 0;
      ++e.problems;
    }
  }
  return e;
}

/// Worst relative change of λ when the LCP is rescaled: solve_lcp(G, α q) = α λ and
/// solve_lcp(β G, q) = λ / β for a change of units (α: accelerations, β: inverse masses).
double lcp_scale_error(double alpha, double beta) {
  std::mt19937_64 rng(4242);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0;
  for (Eigen::Index m = 1; m <= 6; ++m) {
    for (int trial = 0; trial < 40; ++trial) {
      const Eigen::MatrixXd G = random_spd(m, rng);
      Eigen::VectorXd q(m);
      for (Eigen::Index i = 0; i < m; ++i) q(i) = u(rng) + 0.3;
      const Eigen::VectorXd reference = brute_force_lcp(G, q);
      const Eigen::VectorXd scaled = vibro::solve_lcp(beta * G, alpha * q) * (beta / alpha);
      worst = std::max(worst, (scaled - reference).lpNorm<Eigen::Infinity>() /
                                  std::max(reference.lpNorm<Eigen::Infinity>(), 1e-300));
    }
  }
  return worst;
}

// =============================================================================================
// Tolerances (each justified where it is used in a test case)
// =============================================================================================

constexpr double kRestitutionTolerance = 1e-15;
constexpr double kModalTolerance = 4e-15;
constexpr double kCoupledTolerance = 1e-13;
constexpr double kClosedFormTolerance = 1e-11;
constexpr double kStaticTolerance = 1e-12;
constexpr double kForceTolerance = 1e-14;
constexpr double kConstraintTolerance = 1e-14;
constexpr double kAccelerationTolerance = 1e-12;
constexpr double kDifferenceTolerance = 1e-8;
constexpr double kLcpTolerance = 1e-12;
constexpr double kLcpReferenceTolerance = 1e-11;

}  // namespace

// =============================================================================================
// Test cases
// =============================================================================================

TEST_CASE("contact: the closed-form modal matrix diagonalises E (sanity of the reference)",
          "[contact][wagg2004]") {
  // The reference Ψ must be what eq. (4) means, else the modal checks below prove nothing:
  // orthogonal, ΨᵀEΨ = diag((3-√5)/2, (3+√5)/2), and E = K/k of the library's paper model.
  // Tolerance 1e-15: entries ≤ 2, two products of 2×2 matrices, a few roundings each.
  const Eigen::Matrix2d psi = paper_modal_matrix();
  Eigen::Matrix2d E;
  E << 2, -1, -1, 1;
  const Eigen::Matrix2d lambda =
      Eigen::Vector2d((3 - std::sqrt(5.0)) / 2, (3 + std::sqrt(5.0)) / 2).asDiagonal();
  CHECK(max_abs(psi.transpose() * psi - Eigen::Matrix2d::Identity()) <= 1e-15);
  CHECK(max_abs(psi.transpose() * E * psi - lambda) <= 1e-15);
  const ImpactSystem scene = vibro::models::wagg2004();
  CHECK(max_abs(scene.system().stiffness() - E) == 0.0);  // k = 1: exact
  // Ψ = [[a, b], [b, -a]] with a² = (5-√5)/10, b² = (5+√5)/10: the form the hand expansion uses.
  CHECK(std::abs(psi(0, 0) * psi(0, 0) - (5 - std::sqrt(5.0)) / 10) <= 1e-15);
  CHECK(std::abs(psi(1, 0) * psi(1, 0) - (5 + std::sqrt(5.0)) / 10) <= 1e-15);
  CHECK(std::abs(psi(0, 1) - psi(1, 0)) <= 1e-15);
  CHECK(std::abs(psi(1, 1) + psi(0, 0)) <= 1e-15);
}

TEST_CASE("contact: the paper's restitution matrices are eq. (8), and eq. (10) modally",
          "[contact][wagg2004]") {
  // Tolerance (physical) 1e-15: with M = I and unit normals R_S = I - (1 + r) w wᵀ, entries
  // 1, -r computed with ≤ 2 roundings of numbers ≤ 2 (error ≤ 4.4e-16).
  // Tolerance (modal) 4e-15: two 2×2 products of entries ≤ 1 plus an inverse (≈ 8 roundings
  // each ≤ 1.1e-16, times entries ≤ 1), and the hand formulas' own ≤ 4 roundings; a wrong sign
  // of an off-diagonal or r is off by ≥ 0.2.
  for (double r : {0.7, 0.0, 0.35, 1.0}) {
    CAPTURE(r);
    const PaperRestitutionErrors e = paper_restitution_errors(r);
    CHECK(e.physical <= kRestitutionTolerance);
    CHECK(e.modal <= kModalTolerance);
  }
}

TEST_CASE("contact: R_S of coupled contacts (full M, stops between masses) obeys Newton's law",
          "[contact]") {
  // Tolerance 1e-13 relative to |v|: M is a random SPD 4×4 (AAᵀ + I/2, cond(M) ≈ 7.5), so
  // G = WᵀM⁻¹W (cond ≲ 4·7.5) and its Cholesky solve lose ≲ cond(G)·ε ≈ 7e-15; a wrong restitution
  // or impulse direction shows up at the size of r or of |v|, O(0.1).
  const NewtonLawErrors e = newton_law_errors();
  CHECK(e.newton <= kCoupledTolerance);
  CHECK(e.direction <= kCoupledTolerance);
  CHECK(e.tangential <= kCoupledTolerance);
  CHECK(e.reflection <= kCoupledTolerance);
  CHECK(e.projection <= kCoupledTolerance);
}

TEST_CASE("contact: reduced sticking subsystems are eqs. (11) and (14)", "[contact][wagg2004]") {
  for (const Wagg2004& p : {Wagg2004{}, kOther}) {
    CAPTURE(p.m, p.k, p.c, p.A1, p.A2, p.s1, p.s2);
    const ImpactSystem scene = vibro::models::wagg2004(p);
    ContactModes modes(scene);
    // The reduced matrices are N^T M N etc. with N a column of 0 and 1, and the constant
    // -(K P s)_free = -(-k)(s1): exact in double except for at most one rounding (tolerance
    // 1 ulp of the value, 2.2e-16·|value|, rounded up to 1e-15·max(1, |value|)).
    const auto near = [](double got, double expected) {
      return std::abs(got - expected) <= 1e-15 * std::max(1.0, std::abs(expected));
    };
    // Mass 1 stuck at s1: coordinate x2; m x2'' + c x2' + k x2 = k s1 + A2 cos Ωt (eq. 11).
    const auto& r0 = modes.get({0}).reduced();
    REQUIRE(r0.free == std::vector<Eigen::Index>{1});
    REQUIRE(r0.dependent == std::vector<Eigen::Index>{0});
    REQUIRE(r0.mass.rows() == 1);
    CHECK(near(r0.mass(0, 0), p.m));
    CHECK(near(r0.damping(0, 0), p.c));
    CHECK(near(r0.stiffness(0, 0), p.k));
    CHECK(near(r0.forcing.constant(0), p.k * p.s1));
    CHECK(near(r0.forcing.cosine(0), p.A2));
    CHECK(near(r0.forcing.sine(0), 0.0));
    CHECK(r0.forcing.frequency == p.frequency);
    // Mass 2 stuck at s2: coordinate x1; m x1'' + 2c x1' + 2k x1 = k s2 + A1 cos Ωt (eq. 14).
    const auto& r1 = modes.get({1}).reduced();
    REQUIRE(r1.free == std::vector<Eigen::Index>{0});
    REQUIRE(r1.dependent == std::vector<Eigen::Index>{1});
    CHECK(near(r1.mass(0, 0), p.m));
    CHECK(near(r1.damping(0, 0), 2 * p.c));
    CHECK(near(r1.stiffness(0, 0), 2 * p.k));
    CHECK(near(r1.forcing.constant(0), p.k * p.s2));
    CHECK(near(r1.forcing.cosine(0), p.A1));
    CHECK(near(r1.forcing.sine(0), 0.0));
    // Both stuck: nothing free, the flow carries only the forcing oscillator.
    const auto& r01 = modes.get({0, 1}).reduced();
    CHECK(r01.free.empty());
    CHECK(r01.flow->dof() == 0);
  }
}

TEST_CASE("contact: the sticking flows follow the exact solutions (13) and (16, with +s2/2)",
          "[contact][wagg2004]") {
  // Tolerance 1e-11 absolute on |x|, |v| ≤ 1: flow.hpp bounds the spectral method's error by
  // cond(V)·ε ≲ 2e-12 of the state, and the closed forms cost ≈ 20 roundings (≈ 5e-15); the
  // sign error of eq. (16) would be off by s2 = 0.1.
  for (const Wagg2004& p : {Wagg2004{}, kOther}) {
    CAPTURE(p.m, p.k, p.c, p.A1, p.A2);
    CHECK(sticking_closed_form_error(p, 0) <= kClosedFormTolerance);
    CHECK(sticking_closed_form_error(p, 1) <= kClosedFormTolerance);
  }
}

TEST_CASE("contact: static equilibrium with mass 2 stuck is x1 = +s2/2 (eq. 16 prints -s2/2)",
          "[contact][wagg2004]") {
  // The transients decay as e^{-c t/m} (mass 2 stuck, eq. 14) and e^{-c t/(2m)} (mass 1 stuck,
  // eq. 11). After 1500 time units with the defaults (c/(2m) = 0.05) they are below e^{-75}, and
  // with c = 0.5, m = 2 (c/(2m) = 0.125) below e^{-187}: what remains is the flow's rounding,
  // ≲ 1e-14 of the state. Tolerance 1e-12; the printed -s2/2 would be off by s2 ≥ 0.1.
  Wagg2004 fast = kOther;
  fast.c = 0.5;
  for (const Wagg2004& p : {Wagg2004{}, fast}) {
    CAPTURE(p.m, p.c, p.s1, p.s2);
    CHECK(static_equilibrium_error(p, 1) <= kStaticTolerance);
    CHECK(static_equilibrium_error(p, 0) <= kStaticTolerance);
  }
}

TEST_CASE("contact: sticking forces are -F2 (eq. 12) and +F1 (eq. 15), λ > 0 iff F_i s_i > 0",
          "[contact][wagg2004]") {
  // Tolerance 1e-14 relative to the sum of the magnitudes of the terms: λ is a dot product of
  // 7 terms from a 1×1 solve (≈ 10 roundings, ≤ 2.2e-15); a wrong sign or a missing term is
  // off by a term, ≥ 1e-2 of the scale.
  for (const Wagg2004& p : {Wagg2004{}, kOther}) {
    CAPTURE(p.m, p.k, p.c, p.A1, p.A2);
    const ForceErrors e = contact_force_errors(p);
    CHECK(e.force_rows <= kForceTolerance);
    CHECK(e.watch <= kForceTolerance);
    if (p.A2 == 0.0) {
      CHECK(e.sign_mismatch == 0);
      // Both signs really occurred (the rule is tested, not vacuous).
      CHECK(e.positive > 50);
      CHECK(e.negative > 50);
    }
  }
}

TEST_CASE("contact: both masses stuck, λ is the static balance of eqs. (1)-(2)",
          "[contact][wagg2004]") {
  // x = (s1, s2), v = 0, a = 0:  mass 1: k(2 s1 - s2) = A1 cos Ωt + λ0,
  //                              mass 2: k(s2 - s1) = A2 cos Ωt - λ1.
  // Tolerance 1e-15·scale: a 2×2 Cholesky solve of G = I and 7-term dot products.
  for (const Wagg2004& p : {Wagg2004{}, kOther}) {
    const ImpactSystem scene = vibro::models::wagg2004(p);
    ContactModes modes(scene);
    const auto& red = modes.get({0, 1}).reduced();
    REQUIRE(red.gap_rows == 0);
    for (double t : {0.0, 1.3, 7.7, 40.1}) {
      CAPTURE(p.m, t);
      const double cw = std::cos(p.frequency * t);
      const Eigen::VectorXd lambda =
          red.force_rows *
          augmented(p.frequency, t, Eigen::Vector2d(p.s1, p.s2), Eigen::Vector2d::Zero());
      const double scale = 3 * p.k * (std::abs(p.s1) + std::abs(p.s2)) + p.A1 + p.A2;
      CHECK(std::abs(lambda(0) - (p.k * (2 * p.s1 - p.s2) - p.A1 * cw)) <= 1e-15 * scale);
      CHECK(std::abs(lambda(1) - (p.A2 * cw - p.k * (p.s2 - p.s1))) <= 1e-15 * scale);
      // The watch rows are -λ, evaluated on the reduced state [cos; sin; 1].
      const Eigen::Vector3d zr(cw, std::sin(p.frequency * t), 1.0);
      CHECK(max_abs(red.watch->rows(0) * zr + lambda) <= 1e-15 * scale);
    }
  }
}

TEST_CASE("contact: the reduced flow of a stop between masses is the constrained flow",
          "[contact]") {
  // Position/rate tolerance 1e-14 absolute (|x| ≤ 1): x_D is formed from x_F with one addition
  // and ±1 factors (A = ±1), so wᵀx - s is a few ulps of |x|.
  // Acceleration tolerance 1e-12 relative to max|a|: λ and the generator product are sums of
  // ≈ 20 terms with cond(M) ≈ 3 (≲ 1e-14), margin for the propagated state's size.
  // Finite differences (5-point, h·ρ = 0.01): truncation ≈ (hρ)⁴/30 ≈ 3e-10 and rounding
  // ≈ ε/(hρ)·|v|/|a| ≈ 1e-13 relative: tolerance 1e-8.
  const ConstrainedErrors e = between_stop_errors();
  CHECK(e.start <= kConstraintTolerance);
  CHECK(e.position <= kConstraintTolerance);
  CHECK(e.rate <= kConstraintTolerance);
  CHECK(e.constraint_acc <= kAccelerationTolerance);
  CHECK(e.generator <= kAccelerationTolerance);
  CHECK(e.difference <= kDifferenceTolerance);
  CHECK(e.watch <= kAccelerationTolerance);
}

TEST_CASE("contact: a mass held on a moving stop follows s(t) = p + a cos(Ωt + φ) exactly",
          "[contact]") {
  // Same tolerances and reasons as for the stop between masses; here s, s', s'' come from the
  // stop's definition, so a wrong Ω, φ or sign in the reduced forcing (the -M P s'' - C P s'
  // terms) or in T is off by ≈ a = 0.05, aΩ or aΩ².
  const ConstrainedErrors e = moving_stop_errors();
  CHECK(e.start <= kConstraintTolerance);
  CHECK(e.position <= kConstraintTolerance);
  CHECK(e.rate <= kConstraintTolerance);
  CHECK(e.constraint_acc <= kAccelerationTolerance);
  CHECK(e.generator <= kAccelerationTolerance);
  CHECK(e.difference <= kDifferenceTolerance);
  CHECK(e.watch <= kAccelerationTolerance);
}

TEST_CASE("contact: two moving stops held at once with a full mass matrix: constrained flow",
          "[contact]") {
  // Same tolerances and reasons as above (cond(M) ≈ 7.5 costs at most that factor on the
  // ≈ 1e-15 rounding of the acceleration, still far below 1e-12).
  const ConstrainedErrors e = full_mass_moving_errors();
  CHECK(e.start <= kConstraintTolerance);
  CHECK(e.position <= kConstraintTolerance);
  CHECK(e.rate <= kConstraintTolerance);
  CHECK(e.constraint_acc <= kAccelerationTolerance);
  CHECK(e.generator <= kAccelerationTolerance);
  CHECK(e.difference <= kDifferenceTolerance);
  CHECK(e.watch <= kAccelerationTolerance);
}

TEST_CASE("contact: solve_lcp satisfies complementarity and matches brute-force enumeration",
          "[contact][lcp]") {
  // Complementarity 1e-12 relative to max(|q|, ‖G‖|λ|): λ_B = G_BB⁻¹ q_B by LDLᵀ with
  // cond(G) ≤ 100 leaves residuals ≈ m·ε·scale ≈ 2e-15·scale.
  // Brute force 1e-11 relative: two solves of the same basis system, each ≲ cond·m·ε ≈ 2e-13.
  const LcpErrors e = lcp_errors();
  CHECK(e.complementarity <= kLcpTolerance);
  CHECK(e.brute_force <= kLcpReferenceTolerance);
  // The problems exercise both active and inactive contacts (about half of each).
  CHECK(e.active_total > e.problems / 2);
}

TEST_CASE("contact: solve_lcp closed-form cases", "[contact][lcp]") {
  // q ≤ 0: no contact pushes, λ = 0 exactly.
  std::mt19937_64 rng(5);
  const Eigen::MatrixXd G = random_spd(5, rng);
  CHECK(vibro::solve_lcp(G, -Eigen::VectorXd::LinSpaced(5, 0.1, 2.0)).isZero(0.0));
  // Diagonal G: decoupled, λ_i = max(q_i, 0)/G_ii (one division: 1 ulp).
  const Eigen::VectorXd d = Eigen::VectorXd::LinSpaced(4, 0.5, 3.0);
  const Eigen::Vector4d q(1.0, -0.5, 0.25, 0.0);
  const Eigen::VectorXd lambda = vibro::solve_lcp(d.asDiagonal().toDenseMatrix(), q);
  for (Eigen::Index i = 0; i < 4; ++i)
    CHECK(std::abs(lambda(i) - std::max(q(i), 0.0) / d(i)) <= 2.3e-16);
  // 2×2, G = [[2, 1], [1, 2]], q = (1, 1): both active, λ = G⁻¹q = (1/3, 1/3).
  // q = (1, -1): only the first, λ = (1/2, 0) and w2 = 1/2 + 1 > 0.
  Eigen::Matrix2d G2;
  G2 << 2, 1, 1, 2;
  CHECK((vibro::solve_lcp(G2, Eigen::Vector2d(1, 1)) - Eigen::Vector2d(1.0 / 3, 1.0 / 3)).norm() <=
        1e-15);
  CHECK((vibro::solve_lcp(G2, Eigen::Vector2d(1, -1)) - Eigen::Vector2d(0.5, 0.0)).norm() <= 1e-15);
  // q = (1, 0.4): the second would want 0.4 - 0.5 < 0, stays off: λ = (1/2, 0).
  CHECK((vibro::solve_lcp(G2, Eigen::Vector2d(1, 0.4)) - Eigen::Vector2d(0.5, 0.0)).norm() <=
        1e-15);
}

// A regression test: solve_lcp once used an absolute pivoting tolerance, 1e-14·max(1, |q|∞), so
// in small units every contact was released (G = [1], q = [1e-20] gave λ = 0) and a negative
// basic λ could survive (G = 1e8·[[1, 0.9], [0.9, 1]], q = 1e-10·(0.5, 1) gave λ = (0, 2.9e-18)).
TEST_CASE("contact: solve_lcp is invariant under a change of units", "[contact][lcp]") {
  // The two minimal cases above, tolerance 1e-15 relative (one division resp. a 1×1 solve).
  Eigen::MatrixXd G1(1, 1);
  G1 << 1.0;
  {
    const double lambda1 = vibro::solve_lcp(G1, Eigen::VectorXd::Constant(1, 1e-20))(0);
    INFO("G = [1], q = [1e-20]: lambda = " << lambda1 << ", expected 1e-20");
    CHECK(std::abs(lambda1 - 1e-20) / 1e-20 <= 1e-15);
  }
  {
    Eigen::MatrixXd G2(2, 2);
    G2 << 1e8, 0.9e8, 0.9e8, 1e8;
    const Eigen::VectorXd lambda2 = vibro::solve_lcp(G2, Eigen::Vector2d(0.5e-10, 1e-10));
    INFO("G = 1e8 [[1, 0.9], [0.9, 1]], q = 1e-10 (0.5, 1): lambda = ("
         << lambda2(0) << ", " << lambda2(1) << "), expected (0, 1e-18)");
    CHECK(std::abs(lambda2(0)) / 1e-18 <= 1e-15);
    CHECK(std::abs(lambda2(1) - 1e-18) / 1e-18 <= 1e-15);
  }
  // Random problems: solve_lcp(βG, αq) = (α/β) λ_bf(G, q). Tolerance 1e-11 relative, as for the
  // brute-force comparison (the rescaling by powers of ten adds ≤ 2 roundings).
  for (double alpha : {1.0, 1e-20, 1e-10, 1e10}) {
    for (double beta : {1.0, 1e-8, 1e8}) {
      const double error = lcp_scale_error(alpha, beta);
      INFO("alpha = " << alpha << ", beta = " << beta << ": relative error " << error);
      CHECK(error <= kLcpReferenceTolerance);
    }
  }
}

namespace {

/// 20 unit masses and springs (damping 0.02) fixed at the left, 0.3 cos(0.8 t) on the first.
LinearSystem twenty_mass_chain() {
  vibro::models::Chain chain;
  chain.masses.assign(20, 1.0);
  chain.springs.assign(19, 1.0);
  chain.dampers.assign(19, 0.02);
  chain.left_spring = 1.0;
  chain.force_cosine.assign(20, 0.0);
  chain.force_cosine[0] = 0.3;
  chain.frequency = 0.8;
  return vibro::models::build_chain(chain);
}

}  // namespace

TEST_CASE("contact: ContactModes builds only the sets asked for, reduced flows only on demand",
          "[contact]") {
  std::vector<Stop> stops;
  for (Eigen::Index i = 0; i < 20; ++i)
    stops.push_back(Stop::upper(i, 0.1 + 0.01 * static_cast<double>(i), 0.5));
  const ImpactSystem scene(twenty_mass_chain(), std::move(stops));
  ContactModes modes(scene);
  CHECK(modes.built() == 0);
  CHECK(modes.reduced_built() == 0);

  const ContactMode& a = modes.get({3});
  CHECK(modes.built() == 1);
  const ContactMode& b = modes.get({0, 19});
  CHECK(modes.built() == 2);
  CHECK(&modes.get({3}) == &a);  // cached, not rebuilt
  CHECK(modes.built() == 2);
  const ContactMode& none = modes.get({});
  CHECK(modes.built() == 3);
  CHECK(none.size() == 0);
  CHECK(max_abs(none.restitution_matrix() - Eigen::MatrixXd::Identity(20, 20)) == 0.0);
  CHECK(modes.reduced_built() == 0);
  CHECK_FALSE(a.reduced_built());
  CHECK_FALSE(b.reduced_built());

  const auto& red = b.reduced();
  CHECK(b.reduced_built());
  CHECK_FALSE(a.reduced_built());
  CHECK(modes.reduced_built() == 1);
  CHECK(red.free.size() == 18);
  CHECK(red.gap_rows == 18);
  CHECK(&b.reduced() == &red);  // built once
  CHECK(modes.reduced_built() == 1);
  CHECK(modes.built() == 3);

  (void)a.reduced();
  CHECK(modes.reduced_built() == 2);
  CHECK(modes.built() == 3);
  // Building a set's restitution data never builds its reduced flow.
  (void)modes.get({1, 2, 3}).restitution_matrix();
  CHECK(modes.built() == 4);
  CHECK(modes.reduced_built() == 2);
}

namespace {

/// Largest |Segment::evaluate(state rows) - (T z(τ)) of x and v| over τ ∈ [0, 5] and every mode
/// given, relative to the largest |x|, |v| there; also checks that a reset re-tabulates and that
/// evaluating leaves the search's count of evaluations alone.
/// Each set comes with the method its flow is expected to take (so every path is covered).
double state_rows_error(const ImpactSystem& scene, const std::vector<std::pair<ContactSet, vibro::FlowMethod>>& sets,
                        vibro::FlowOptions options) {
  ContactModes modes(scene, options);
  const Eigen::Index n = scene.dof();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0;
  for (const auto& [set, expected] : sets) {
    const ContactMode& mode = modes.get(set);
    const ContactMode::Reduced& red = mode.reduced();
    REQUIRE(red.flow->method() == expected);
    REQUIRE(red.flow->closed_form() == options.closed_form);
    const Eigen::Index size = red.flow->size();
    Eigen::VectorXd x(n), v(n), zr(size), zf(2 * n + 3), out(2 * n);
    for (auto& c : x) c = u(rng);
    for (auto& c : v) c = u(rng);
    vibro::Segment segment(*red.watch, 0.3, mode.reduce(0.3, x, v));
    for (int start = 0; start < 2; ++start) {
      if (start == 1) segment.reset(1.1, mode.reduce(1.1, -x, 2.0 * v));  // the table must follow
      double error = 0.0, scale = 0.0;
      for (int k = 0; k <= 200; ++k) {
        const double tau = 5.0 * k / 200.0;
        segment.state(tau, zr);
        mode.expand(zr, zf);
        const long before = segment.evaluations();
        segment.evaluate(mode.state_rows(), tau, out);
        if (red.flow->closed_form()) CHECK(segment.evaluations() == before);
        error = std::max(error, (out - zf.head(2 * n)).cwiseAbs().maxCoeff());
        scale = std::max(scale, zf.head(2 * n).cwiseAbs().maxCoeff());
      }
      worst = std::max(worst, error / scale);
    }
  }
  return worst;
}

}  // namespace

TEST_CASE("contact: a mode's state rows by Segment::evaluate are its expanded state, to rounding",
          "[contact][flow]") {
  // Both sides are the same exact form summed in another order (evaluate folds T and the basis
  // V into one table per segment, state() forms z_r and T multiplies it), so they differ by
  // rounding: a few ε times cond(V) and the size of the terms (measured: 3e-16 spectral, 1e-16
  // on the Schur cluster, 7e-16 on the chain, 0 on the Padé path, which multiplies the same
  // state by the same rows); 1e-13 leaves that margin and still fails for any wrong
  // coefficient, power or sign, which is off by O(1).
  const vibro::FlowOptions spectral;
  const ImpactSystem paper = vibro::models::wagg2004();
  using vibro::FlowMethod;
  const double e_spectral = state_rows_error(
      paper, {{{}, FlowMethod::spectral}, {{0}, FlowMethod::spectral}, {{1}, FlowMethod::spectral}, {{0, 1}, FlowMethod::spectral}},
      spectral);
  vibro::FlowOptions pade;
  pade.method = vibro::FlowMethod::exponential;
  pade.closed_form = false;
  const double e_pade = state_rows_error(
      paper, {{{}, FlowMethod::exponential}, {{0}, FlowMethod::exponential}, {{0, 1}, FlowMethod::exponential}}, pade);
  // A free mass under gravity (K = C = 0, unforced): Â is nilpotent, the closed form on one
  // Schur cluster with a τ² term; held, the reduced state is the forcing oscillator alone (Â = 0,
  // diagonal: spectral).
  Eigen::MatrixXd one = Eigen::MatrixXd::Identity(1, 1), zero = Eigen::MatrixXd::Zero(1, 1);
  HarmonicForcing gravity = HarmonicForcing::zero(1);
  gravity.constant(0) = -1.0;
  const ImpactSystem ball(LinearSystem(one, zero, zero, gravity), {Stop::lower(0, 0.0, 0.8)});
  const double e_cluster = state_rows_error(ball, {{{}, FlowMethod::exponential}, {{0}, FlowMethod::spectral}}, spectral);
  // A 20-mass chain with two stops held: 2n = 40 rows over a reduced flow of 39.
  const ImpactSystem chained(twenty_mass_chain(), {Stop::upper(0, 0.1, 0.5), Stop::upper(19, 0.2, 0.5)});
  const double e_chain = state_rows_error(chained, {{{}, FlowMethod::spectral}, {{0, 1}, FlowMethod::spectral}}, spectral);
  INFO("spectral " << e_spectral << ", Padé " << e_pade << ", Schur cluster " << e_cluster << ", chain " << e_chain);
  CHECK(e_spectral <= 1e-13);
  CHECK(e_pade <= 1e-13);
  CHECK(e_cluster <= 1e-13);
  CHECK(e_chain <= 1e-13);
}

TEST_CASE("contact accuracy report", "[.report]") {
  double physical = 0.0, modal = 0.0;
  for (double r : {0.7, 0.0, 0.35, 1.0}) {
    const PaperRestitutionErrors e = paper_restitution_errors(r);
    physical = std::max(physical, e.physical);
    modal = std::max(modal, e.modal);
  }
  std::printf("\ncontact accuracy report (error / tolerance)\n");
  std::printf("  restitution eq. (8)                       %9.2e / %.0e\n", physical,
              kRestitutionTolerance);
  std::printf("  restitution modal eq. (10)                %9.2e / %.0e\n", modal, kModalTolerance);
  const NewtonLawErrors n = newton_law_errors();
  std::printf("  coupled Newton law / direction / tangent  %9.2e %9.2e %9.2e / %.0e\n", n.newton,
              n.direction, n.tangential, kCoupledTolerance);
  std::printf("  coupled r=1 reflection / r=0 projection   %9.2e %9.2e / %.0e\n", n.reflection,
              n.projection, kCoupledTolerance);
  Wagg2004 fast = kOther;
  fast.c = 0.5;
  double closed = 0.0, stat = 0.0, force = 0.0, watch = 0.0;
  for (const Wagg2004& p : {Wagg2004{}, kOther}) {
    closed = std::max({closed, sticking_closed_form_error(p, 0), sticking_closed_form_error(p, 1)});
    const ForceErrors f = contact_force_errors(p);
    force = std::max(force, f.force_rows);
    watch = std::max(watch, f.watch);
  }
  for (const Wagg2004& p : {Wagg2004{}, fast})
    stat = std::max({stat, static_equilibrium_error(p, 0), static_equilibrium_error(p, 1)});
  std::printf("  sticking flow vs eqs. (13), (16)          %9.2e / %.0e\n", closed,
              kClosedFormTolerance);
  std::printf("  static equilibrium s1, +s2/2              %9.2e / %.0e\n", stat, kStaticTolerance);
  std::printf("  contact force rows / watch rows           %9.2e %9.2e / %.0e\n", force, watch,
              kForceTolerance);
  for (const auto& [name, e] : {std::pair{"between-masses stop", between_stop_errors()},
                                std::pair{"moving stop", moving_stop_errors()},
                                std::pair{"full M, 2 moving", full_mass_moving_errors()}}) {
    std::printf(
        "  %-20s start %8.1e pos %8.1e rate %8.1e  acc(constraint) %8.1e  acc(generator) %8.1e  "
        "acc(FD) %8.1e  watch %8.1e\n",
        name, e.start, e.position, e.rate, e.constraint_acc, e.generator, e.difference, e.watch);
  }
  const LcpErrors l = lcp_errors();
  std::printf("  LCP complementarity / brute force         %9.2e %9.2e  (%d problems, %d active)\n",
              l.complementarity, l.brute_force, l.problems, l.active_total);
  for (double alpha : {1e-20, 1e-10, 1e10})
    for (double beta : {1.0, 1e-8, 1e8})
      std::printf("  LCP rescaled alpha %7.0e beta %7.0e   %9.2e\n", alpha, beta,
                  lcp_scale_error(alpha, beta));
}
