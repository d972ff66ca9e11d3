/// \file grazing_corner.cpp
/// Continuing a branch through a grazing onto the orbits with the new impact (private to the
/// analysis layer; continuation.hpp describes the method).
///
/// Near a grazing of stop j (an interior maximum of its gap g = wᵀx − s(t) reaching zero at t_g)
/// the map with the new impact is, to first order in the impact's approach speed u,
///     P_u(z; p) = P(z; p) + C u,   C = Φ(t1, t_g) [0; Δv],   Δv = −(1 + r) M⁻¹w / (wᵀM⁻¹w),
/// P the map without it and Φ(t1, t_g) the tangent map from the grazing to the end of the period,
/// while u² = 2|g''| ĝ with ĝ(z, p) the gap maximum of the orbit without the impact: ĝ vanishes
/// to first order (A. B. Nordmark, "Non-periodic motion caused by grazing incidence in an impact
/// oscillator", J. Sound Vib. 145 (1991) 279–297; di Bernardo, Budd, Champneys & Kowalczyk,
/// "Piecewise-smooth Dynamical Systems", Springer 2008, ch. 4). So the
/// orbits with the new impact form a branch through the grazing point with the tangent (δz, δp, δu),
/// δu > 0, spanning the null space of
///     [ J − I   ∂P/∂p   C ]
///     [ ∇_z ĝ   ∂ĝ/∂p   0 ],     ∇_z ĝ = wᵀ Φ_x(t_g, t0),  ∂ĝ/∂p = wᵀ ∂x(t_g)/∂p − ∂s/∂p,
/// whether these orbits are stable or not (the derivative of P_u blows up like 1/u along it, its
/// points do not). The arclength steps stall against the grazing because Newton from the side
/// without the impact cannot see it; a predictor along this tangent starts the corrector on the
/// side with the impact, where it converges. Where the orbits with the impact leave the corner at a
/// small angle to the part followed, the first-order predictor's orbit falls short of the stop and
/// its corrector lands on the part followed; before the branch is given up there, the predictors
/// are lifted onto the impacting side to second order (the gap maximum raised to u²/(2|g''|)).
/// The branch may leave the corner on either side in p:
/// on the far one (the orbit persists with one more impact) or back on the near one (the grazing is
/// a non-smooth fold, the orbits with the impact coexisting with those without).
#include "branch_runner.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

namespace vibro::detail {

std::optional<std::pair<VectorXd, int>> BranchRunner::corner_tangent(const Node& cur) {
  const TangentMap& g = cur.e.map;
  const double L = g.summary.length_scale;
  const GapPeak* peak = nullptr;
  for (const GapPeak& q : g.gap_peaks)
    if (q.value > -1e-3 * L && (!peak || q.value > peak->value)) peak = &q;
  if (!peak) return std::nullopt;
  const int j = peak->stop;
  const Index n = c_.n_, N = 2 * n;
  TangentMap m1, m2;
  VectorXd w, dv;
  double dt0 = 0.0, ds = 0.0;
  try {
    FamilyEngine& engine = c_.engine_at(cur.e.p);
    LinearisationOptions lo;
    lo.parameter = engine.derivative;
    m1 = engine.linearise(cur.e.t0, cur.e.z.head(n), cur.e.z.tail(n), peak->t, lo);
    ++result_.maps;
    if (m1.summary.status != RunStatus::completed) return std::nullopt;
    m2 = engine.linearise(peak->t, m1.x1, m1.v1, g.t1, LinearisationOptions{});
    ++result_.maps;
    if (m2.summary.status != RunStatus::completed) return std::nullopt;
    std::tie(w, dv) = engine.impact_direction(j);
    if (dv.size() == 0) return std::nullopt;  // a compliant stop: no impact is born at its grazing
    dt0 = -c_.theta / (cur.e.omega * cur.e.omega) * engine.derivative.frequency;
    // ∂s_j/∂p at the grazing time (a moving stop's motion shifted by a change of Ω is left to
    // the corrector: this is a predictor).
    if (!engine.derivative.stops.empty()) {
      const StopDerivative& sd = engine.derivative.stops[static_cast<std::size_t>(j)];
      const double wt = cur.e.omega * peak->t;
      ds = sd.offset + sd.cosine * std::cos(wt) + sd.sine * std::sin(wt);
    }
  } catch (const InvalidInput&) {
    return std::nullopt;
  }
  // The bordered system in the branch's scaled variables (y = (D⁻¹z, p/P)) and u/V.
  const VectorXd d = c_.D();
  const VectorXd C = m2.jacobian.rightCols(n) * dv;
  const VectorXd dz_peak = m1.parameter - m1.jacobian * (m1.rate_start * dt0);
  MatrixXd A(N + 1, N + 2);
  A.topLeftCorner(N, N + 1) = c_.jacobian(cur.e);
  A.block(0, N + 1, N, 1) = C.cwiseQuotient(d) * c_.V;
  Eigen::RowVectorXd row(N + 2);
  row.head(N) = (w.transpose() * m1.jacobian.topRows(n)).cwiseProduct(d.transpose());
  row(N) = (w.dot(dz_peak.head(n)) - ds) * c_.P;
  row(N + 1) = 0.0;
  if (!(row.norm() > 0.0) || !row.allFinite() || !A.topRows(N).allFinite()) return std::nullopt;
  A.row(N) = row / row.norm();
  Eigen::JacobiSVD<MatrixXd> svd(A, Eigen::ComputeFullV);
  VectorXd t = svd.matrixV().col(N + 1);
  if (t(N + 1) < 0.0) t = -t;
  VectorXd along = t.head(N + 1);
  if (!(along.norm() > 0.0)) return std::nullopt;
  // The second-order part of the grazing condition ĝ = u²/(2|g''|): a step of h along the tangent
  // raises the gap maximum by (u h)²/(2|g''|), u the impact speed per unit step; `rise` is the
  // scaled shift that raises ĝ by one length unit (along its gradient).
  const double g2 = std::abs(w.dot(m1.rate_end.tail(n)));
  const Eigen::RowVectorXd grad = row.head(N + 1);
  corner_rise_ = grad.squaredNorm() > 0.0 ? VectorXd(grad.transpose() / grad.squaredNorm()) : VectorXd();
  corner_u_ = t(N + 1) / along.norm() * c_.V;
  corner_g2_ = g2;
  along.normalize();
  return std::pair{along, j};
}

std::optional<Node> BranchRunner::corner(const Node& cur, bool lifted) {
  const std::optional<std::pair<VectorXd, int>> tangent = corner_tangent(cur);
  if (!tangent) return std::nullopt;
  const auto& [along, j] = *tangent;
  const Index N = 2 * c_.n_;
  const auto stop = static_cast<std::size_t>(j);
  // Steps along it, shortest first: the first that lands on an orbit with the new impact.
  // Lifted, each predictor is raised onto the impacting side: the tangent keeps the gap maximum
  // at its value to first order only, and where the part with the impact leaves the corner at a
  // small angle to the part already followed (the clearance chain's doubled branch at
  // Ω ≈ 0.5673813: 3°), the predictor's second-order error leaves its orbit short of the stop,
  // without the impact, and the corrector lands on the part followed. The lift raises the gap
  // maximum from cur's value to (u h)²/(2|g''|), its value on the orbits with the impact (u the
  // impact's speed per unit step), along the gap maximum's gradient.
  double gap = -std::numeric_limits<double>::infinity();  // cur's, at the stop (≤ 0)
  for (const GapPeak& q : cur.e.map.gap_peaks)
    if (q.stop == j) gap = std::max(gap, q.value);
  if (lifted && (corner_rise_.size() == 0 || !(corner_g2_ > 0.0) || !std::isfinite(gap))) return std::nullopt;
  const VectorXd y = c_.scaled(cur.e);
  const int before = cur.b.signature.impacts[stop];
  for (double h = 1e-3 * o_.max_step; h <= o_.max_step; h *= 2.0) {
    VectorXd y_pred = y + h * along;
    if (lifted) {
      const double u = corner_u_ * h;
      y_pred += corner_rise_ * (u * u / (2.0 * corner_g2_) - gap);
    }
    int iterations = 0;
    Node next;
    next.e = c_.correct(y_pred, along, &iterations);
    if (!next.e.ok || (c_.scaled(next.e) - y_pred).norm() > h) continue;
    next.t = c_.tangent(next.e, along);
    next.b = c_.point(next.e, next.t, iterations);
    next.b.tangent_p = next.t(N);
    if (next.b.signature.impacts[stop] <= before) continue;
    if (c_.k > o_.period && c_.closes_after(next.e, c_.k / 2)) continue;
    return next;
  }
  return std::nullopt;
}

}  // namespace vibro::detail
