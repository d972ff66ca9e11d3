/// \file corrector.cpp
/// A branch point evaluated (F and ∂P/∂p from one tangent map over kT), its tangent, and the
/// Newton corrector of pseudo-arclength continuation (Keller 1977) in scaled variables: the
/// maths is in corrector.hpp.
#include "corrector.hpp"

#include "vibro/bounded_wait.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace vibro::detail {
namespace {

/// Systems of at least this many degrees of freedom factorise under run_bounded.
constexpr Index kBoundedFromCoordinates = 64;

}  // namespace

/// B's LU, the SVD when it fails, its eigenvalues: O(n³) and not pollable, so from kBoundedFromCoordinates on under
/// run_bounded with the run's interrupt flag, on copies of their inputs (bounded_wait.hpp): the
/// same bits; raising the flag throws Interrupted within 10 ms.
template <class F>
auto Continuer::bounded(F fn) const -> decltype(fn()) {
  return run_bounded(n_ >= kBoundedFromCoordinates ? o_.solver.interrupt : nullptr, std::move(fn));
}

Eval Continuer::evaluate(const VectorXd& z, double p) {
  Eval e;
  e.p = p;
  e.z = z;
  ++result_.maps;
  try {
    FamilyEngine& engine = engine_at(p);
    e.omega = engine.frequency();
    if (!(e.omega > 0.0)) throw InvalidInput("the forcing frequency must be > 0 at p = " + number_text(p));
    const double T = kTwoPi / e.omega;
    e.t0 = theta / e.omega;
    const double t1 = e.t0 + k * T;
    LinearisationOptions lo;
    lo.parameter = engine.derivative;
    lo.features = true;
    e.map = engine.linearise(e.t0, z.head(n_), z.tail(n_), t1, lo);
    if (e.map.summary.status != RunStatus::completed) {
      e.why = std::string("run stopped early (") + to_string(e.map.summary.status) + "): " + e.map.summary.message;
      return e;
    }
    const double dw = engine.derivative.frequency;
    const double dt0 = -theta / (e.omega * e.omega) * dw;
    const double dt1 = dt0 - k * kTwoPi / (e.omega * e.omega) * dw;
    e.Pp = e.map.parameter + e.map.rate_end * dt1 - e.map.jacobian * (e.map.rate_start * dt0);
    e.F = stacked(e.map.x1, e.map.v1) - z;
    e.residual = e.F.cwiseQuotient(D()).cwiseAbs().maxCoeff();
    e.ok = true;
  } catch (const InvalidInput& err) {
    e.why = err.what();
  }
  return e;
}

/// DF in scaled variables: [D⁻¹ (J − I) D, D⁻¹ ∂P/∂p P].
MatrixXd Continuer::jacobian(const Eval& e) const {
  const VectorXd d = D();
  MatrixXd A(2 * n_, 2 * n_ + 1);
  A.leftCols(2 * n_) = d.cwiseInverse().asDiagonal() * (e.map.jacobian - MatrixXd::Identity(2 * n_, 2 * n_)) * d.asDiagonal();
  A.col(2 * n_) = e.Pp.cwiseQuotient(d) * P;
  return A;
}

/// The unit null vector of DF oriented along `along`.
VectorXd Continuer::tangent(const Eval& e, const VectorXd& along) const {
  const Index N = 2 * n_ + 1;
  MatrixXd B(N, N);
  B.topRows(N - 1) = jacobian(e);
  B.row(N - 1) = along.transpose();
  VectorXd rhs = VectorXd::Zero(N);
  rhs(N - 1) = 1.0;
  VectorXd t = bounded([B, rhs] { return VectorXd(B.fullPivLu().solve(rhs)); });
  if (!t.allFinite() || t.norm() == 0.0)  // `along` ⟂ the null space: take it from the SVD (bounded as the LU)
    t = bounded([A = MatrixXd(jacobian(e)), N] {
      const Eigen::JacobiSVD<MatrixXd> svd(A, Eigen::ComputeFullV);
      return VectorXd(svd.matrixV().col(N - 1));
    });
  t.normalize();
  if (t.dot(along) < 0.0) t = -t;
  return t;
}

/// Newton on [F(y); nᵀ(y − y_pred)] = 0 from y_pred: a point on the branch in the hyperplane
/// through y_pred normal to n. Returns a failed Eval when it does not converge.
Eval Continuer::correct(const VectorXd& y_pred, const VectorXd& n, int* iterations) {
  const Index N = 2 * n_ + 1;
  const VectorXd d = D();
  VectorXd y = y_pred;
  Eval e;
  double last = std::numeric_limits<double>::infinity();
  for (int it = 0; it <= o_.max_corrector_iterations; ++it) {
    e = evaluate(d.cwiseProduct(y.head(2 * n_)), y(2 * n_) * P);
    if (!e.ok) return e;
    const double g = n.dot(y - y_pred);
    const double r = std::max(e.residual, std::abs(g));
    if (iterations) *iterations = it;
    // The map's own rounding, amplified by J, sets a floor under the residual: near grazing
    // (J ~ 1/u) it can exceed the tolerance, and the orbit is then as periodic as it can be.
    const MatrixXd A = jacobian(e);
    const double floor = 100.0 * std::numeric_limits<double>::epsilon() *
                         std::max(1.0, A.leftCols(2 * n_).cwiseAbs().rowwise().sum().maxCoeff());
    if (e.residual <= std::max(o_.tolerance, floor) && std::abs(g) <= 1e3 * o_.tolerance) return e;
    if (it >= 2 && r > 0.5 * last) {  // not converging (quadratically or at all): give up
      e.ok = false;
      e.why = "corrector stalled at residual " + number_text(r);
      return e;
    }
    last = r;
    MatrixXd B(N, N);
    B.topRows(N - 1) = A;
    B.row(N - 1) = n.transpose();
    VectorXd rhs(N);
    rhs << -e.F.cwiseQuotient(d), -g;
    VectorXd delta;
    try {
      delta = bounded([B, rhs] { return VectorXd(B.fullPivLu().solve(rhs)); });
    } catch (const Interrupted&) {  // as an interrupted map: this correction fails
      e.ok = false;
      e.why = "interrupted";
      return e;
    }
    if (!delta.allFinite()) {
      e.ok = false;
      e.why = "singular corrector system";
      return e;
    }
    y += delta;
  }
  e.ok = false;
  e.why = "corrector did not converge in " + std::to_string(o_.max_corrector_iterations) + " iterations";
  return e;
}

/// Whether the orbit of e already closes after `periods` forcing periods (to 1e3 × tolerance).
bool Continuer::closes_after(const Eval& e, int periods) {
  const RunSummary r = engine_at(e.p).run(e.t0, e.z.head(n_), e.z.tail(n_), e.t0 + periods * kTwoPi / e.omega);
  if (r.status != RunStatus::completed) return false;
  const double res = std::max((r.x - e.z.head(n_)).cwiseAbs().maxCoeff() / L,
                              (r.v - e.z.tail(n_)).cwiseAbs().maxCoeff() / V);
  return res <= 1e3 * o_.tolerance;
}

BranchPoint Continuer::point(const Eval& e, const VectorXd& t, int iterations) const {
  BranchPoint b;
  b.p = e.p;
  b.phase = theta;
  b.t0 = e.t0;
  b.x = e.z.head(n_);
  b.v = e.z.tail(n_);
  b.k = k;
  b.multipliers = bounded([m = e.map, k = k] { return floquet_multipliers(m, k); });
  b.signature = orbit_signature(e.map, k, stops_);
  b.sticking = Eigen::VectorXd::Zero(static_cast<Index>(stops_));
  const double span = e.map.t1 - e.map.t0;
  for (const HeldPhase& h : e.map.phases)
    b.sticking(h.stop) += std::max(0.0, std::min(h.t_end, e.map.t1) - std::max(h.t_start, e.map.t0)) / span;
  b.tangent_p = t.size() ? t(2 * n_) : 0.0;
  b.residual = e.residual;
  b.corrector_iterations = iterations;
  return b;
}

}  // namespace vibro::detail
