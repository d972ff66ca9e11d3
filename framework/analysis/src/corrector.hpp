#pragma once
/// \file corrector.hpp
/// The continuation's evaluation of a branch point and its corrector (private to the analysis
/// layer; continuation.hpp describes the method).
///
/// A branch is a curve of zeros of F(z, p) = P(z; p) − z, P the map over kT from the section
/// t0 = θ/Ω. Everything here works in scaled variables y = (D⁻¹z, p/P), D = diag(L…, V…), so
/// that positions, velocities and the parameter weigh alike in norms and in the arclength:
///  * evaluate: F and ∂P/∂p = ζ + f(z1, t1) dt1/dp − J f(z0, t0) dt0/dp at (z, p), with
///    dt0/dp = −θ/Ω² dΩ/dp and dt1/dp = dt0/dp − 2πk/Ω² dΩ/dp (the section and the period move
///    with Ω);
///  * jacobian: DF = [D⁻¹(J − I)D, D⁻¹ ∂P/∂p P], (2n) × (2n + 1);
///  * tangent: the unit null vector t of DF, from the bordered system [DF; aᵀ] t = e_{2n+1}
///    (a the previous tangent; the SVD's last right singular vector where a ⟂ null space),
///    oriented along a;
///  * correct: Newton on G(y) = [F(y); nᵀ(y − y_pred)] = 0 (Keller 1977's pseudo-arclength
///    condition for n = t): y ← y + Δ, [DF; nᵀ] Δ = −G, with the exact Jacobian. It accepts at
///    max(|F_i|/D_i) ≤ max(tolerance, 100 ε ‖D⁻¹(J − I)D‖∞) (the map's rounding amplified by J
///    is a floor: near grazing J grows like 1/u) and gives up when the residual does not halve
///    from the third iteration on.
#include "vibro/continuation.hpp"

#include <limits>
#include <memory>
#include <numbers>
#include <string>

namespace vibro::detail {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

inline constexpr double kTwoPi = 2.0 * std::numbers::pi;
/// When the steps stall with an event within this fraction of T of the section (an impact drifting
/// through it with p makes the map over kT jump), continuation moves its section. Only then:
/// moving it whenever an event came near (tried at 1 % and 5 % of T) lost folds of the paper's
/// branch, since the guard against steps landing back on the branch cannot compare states across
/// sections and is reset at each move.
inline constexpr double kSectionMargin = 0.01;
/// An event within this fraction of T of the section is on it (shooting.cpp's test): the map over
/// kT jumps right there, whatever else the orbit is near.
inline constexpr double kSectionOnEvent = 1e-6;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

inline VectorXd stacked(const VectorXd& x, const VectorXd& v) {
  VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// One evaluated point (z, p): the map over kT at the branch's section phase.
struct Eval {
  bool ok = false;
  std::string why;
  double p = 0.0;
  VectorXd z;
  double t0 = 0.0, omega = 0.0;
  TangentMap map;
  VectorXd F, Pp;     ///< P(z) − z and ∂P/∂p (with the section and period moving with Ω)
  double residual = std::numeric_limits<double>::infinity();
};

/// The continuation of one branch family; holds the scales and the section.
class Continuer {
 public:
  Continuer(const ContinuationFamily& family, const ContinuationOptions& o, Index n, std::size_t stops,
            ContinuationResult& result)
      : family_(family), o_(o), n_(n), stops_(stops), result_(result) {}

  /// The engine at p: the last one made if it was made at this p (Newton at fixed p, shooting
  /// then evaluating, a section move: the modal engine's set-up and its contact sets' modes are
  /// paid once), else a new one. Valid until the next call with another p. Throws as the family.
  /// fn() under run_bounded for large systems (corrector.cpp).
  template <class F>
  auto bounded(F fn) const -> decltype(fn());

  FamilyEngine& engine_at(double p) {
    if (!engine_ || !(engine_p_ == p)) {
      engine_.reset();
      engine_ = family_(p);
      engine_p_ = p;
    }
    return *engine_;
  }
  /// Takes `engine`, made at p, as the last one made.
  void adopt(double p, std::unique_ptr<FamilyEngine> engine) {
    engine_ = std::move(engine);
    engine_p_ = p;
  }

  double theta = 0.0;  ///< the section phase of the branch being followed
  int k = 1;
  double L = 1.0, V = 1.0, P = 1.0;

  VectorXd D() const {
    VectorXd d(2 * n_);
    d << VectorXd::Constant(n_, L), VectorXd::Constant(n_, V);
    return d;
  }
  VectorXd scaled(const Eval& e) const {
    VectorXd y(2 * n_ + 1);
    y << e.z.cwiseQuotient(D()), e.p / P;
    return y;
  }
  VectorXd scaled(const BranchPoint& b) const {
    VectorXd y(2 * n_ + 1);
    y << stacked(b.x, b.v).cwiseQuotient(D()), b.p / P;
    return y;
  }

  /// F and ∂P/∂p at (z, p); a failed Eval (with the reason) where the run or the family fails.
  Eval evaluate(const VectorXd& z, double p);
  /// DF in scaled variables: [D⁻¹ (J − I) D, D⁻¹ ∂P/∂p P].
  MatrixXd jacobian(const Eval& e) const;
  /// The unit null vector of DF oriented along `along`.
  VectorXd tangent(const Eval& e, const VectorXd& along) const;
  /// Newton on [F(y); nᵀ(y − y_pred)] = 0 from y_pred: a point on the branch in the hyperplane
  /// through y_pred normal to n. Returns a failed Eval when it does not converge.
  Eval correct(const VectorXd& y_pred, const VectorXd& n, int* iterations = nullptr);
  /// Whether the orbit of e already closes after `periods` forcing periods (to 1e3 × tolerance).
  bool closes_after(const Eval& e, int periods);
  /// The branch point of e with its multipliers, signature and sticking fractions.
  BranchPoint point(const Eval& e, const VectorXd& t, int iterations) const;

  const ContinuationFamily& family_;
  const ContinuationOptions& o_;
  Index n_;
  std::size_t stops_;
  ContinuationResult& result_;

 private:
  std::unique_ptr<FamilyEngine> engine_;
  double engine_p_ = kNaN;
};

/// A point of the branch as continuation keeps it: evaluated, with its tangent.
struct Node {
  Eval e;
  VectorXd t;
  BranchPoint b;
};

}  // namespace vibro::detail
