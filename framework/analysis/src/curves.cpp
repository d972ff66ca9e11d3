/// \file curves.cpp
/// Grazing and rising points followed in two parameters (continuation.hpp, "Curves in two
/// parameters"). From the last curve point (p1, p2), in scaled coordinates (p1/P1, p2/P2), a
/// predictor step of h along the curve's secant d (at first along p2) gives a = (a1, a2); on
/// the line a + σ n through it along the normal n = (−d2, d1) the system is a one-parameter
/// family in σ with derivative n1 P1 ∂/∂p1 + n2 P2 ∂/∂p2, and the branch through the previous
/// curve point's orbit is continued along that line for σ ∈ [−4h, 4h] until the point of the
/// same kind and stop is located; the located point nearest the predictor is the next curve
/// point. h grows by 1.5 (to 4 × step) after a point and halves when none is found.
#include "vibro/continuation.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace vibro {

void CurveOptions::validate() const {
  if (!(p2_min < p2_max) || !std::isfinite(p2_min) || !std::isfinite(p2_max))
    throw InvalidInput("curve.range: p2_min < p2_max required");
  if (!(p1_min < p1_max) || !std::isfinite(p1_min) || !std::isfinite(p1_max))
    throw InvalidInput("curve: p1 limits: p1_min < p1_max required");
  if (!(step > 0.0) || !std::isfinite(step)) throw InvalidInput("curve.step = " + number_text(step) + ": must be > 0");
  if (max_points < 2) throw InvalidInput("curve.max_points must be ≥ 2");
  if (direction != 1 && direction != -1) throw InvalidInput("curve.direction must be +1 or −1");
}

Curve follow_curve(const PlaneFamily& family, const Bifurcation& start, double p2_start, const CurveOptions& options) {
  const SimulatorOptions solver = options.branch.solver;
  const PlaneContinuationFamily engines = [&family, solver](double p1, double p2) {
    PlanePoint pp = family(p1, p2);
    std::unique_ptr<FamilyEngine> engine = dense_family_engine(std::move(pp.system), pp.d1, solver);
    return PlaneEngine{std::move(engine), std::move(pp.d1), std::move(pp.d2)};
  };
  return follow_curve(engines, start, p2_start, options);
}

Curve follow_curve(const PlaneContinuationFamily& family, const Bifurcation& start, double p2_start,
                   const CurveOptions& options) {
  options.validate();
  if (start.kind != BifurcationKind::grazing && start.kind != BifurcationKind::rising)
    throw InvalidInput(std::string("curve: only grazing and rising points can be followed, not ") + to_string(start.kind));
  Curve curve;
  curve.kind = start.kind;
  curve.stop = start.stop;
  const double P1 = options.scale1 > 0.0 ? options.scale1 : options.p1_max - options.p1_min;
  const double P2 = options.scale2 > 0.0 ? options.scale2 : options.p2_max - options.p2_min;
  CurvePoint c0;
  c0.p1 = start.p;
  c0.p2 = p2_start;
  c0.value = start.value;
  c0.point = start.point;
  curve.points.push_back(c0);
  // Direction along the curve in scaled (p1/P1, p2/P2): first p2, then the secant.
  Eigen::Vector2d dir(0.0, options.direction);
  double h = options.step;
  while (static_cast<int>(curve.points.size()) < options.max_points) {
    const CurvePoint& last = curve.points.back();
    if (curve.points.size() >= 2) {
      const CurvePoint& prev = curve.points[curve.points.size() - 2];
      Eigen::Vector2d s((last.p1 - prev.p1) / P1, (last.p2 - prev.p2) / P2);
      if (s.norm() > 0.0) dir = s.normalized();
    }
    const Eigen::Vector2d normal(-dir(1), dir(0));
    const double a1 = last.p1 + h * dir(0) * P1, a2 = last.p2 + h * dir(1) * P2;
    if (a2 < options.p2_min || a2 > options.p2_max || a1 < options.p1_min || a1 > options.p1_max) {
      curve.end = "left the parameter limits";
      return curve;
    }
    // The family along the normal line through the predictor: σ in scaled units.
    const ContinuationFamily line = [&](double sigma) {
      const double q1 = a1 + sigma * normal(0) * P1, q2 = a2 + sigma * normal(1) * P2;
      PlaneEngine pe = family(q1, q2);
      pe.engine->derivative = pe.d1.combined(normal(0) * P1, pe.d2, normal(1) * P2);
      return std::move(pe.engine);
    };
    ContinuationOptions lo = options.branch;
    lo.period = last.point.k;
    lo.phase = last.point.phase;
    lo.p_min = -4.0 * h;
    lo.p_max = 4.0 * h;
    lo.parameter_scale = 1.0;
    lo.step = std::min(h, lo.max_step);
    lo.max_points = 60;
    lo.max_doublings = 0;
    // Continue along the line from the previous curve point's orbit until the kind is found.
    bool found = false;
    ContinuationResult r;
    // The last curve point's orbit touches its stop: shooting from it at the predictor can fall
    // on the side with the impact, where Newton cannot converge from it; a shorter step then.
    std::string failed;
    try {
      r = continue_orbits(line, 0.0, last.point.t0, last.point.x, last.point.v, lo);
    } catch (const InvalidInput& e) {
      failed = e.what();
    }
    // The located point of the kind nearest to the predictor.
    const Bifurcation* best = nullptr;
    for (const Bifurcation& b : r.bifurcations)
      if (b.kind == start.kind && b.stop == start.stop && b.smooth && (!best || std::abs(b.p) < std::abs(best->p)))
        best = &b;
    if (best) {
      CurvePoint cp;
      cp.p1 = a1 + best->p * normal(0) * P1;
      cp.p2 = a2 + best->p * normal(1) * P2;
      cp.value = best->value;
      cp.point = best->point;
      curve.points.push_back(cp);
      found = true;
    }
    if (!found) {
      h *= 0.5;
      if (h < 1e-6) {
        curve.end = failed.empty() ? "the curve was lost (no located point on the line across it)"
                                   : "no orbit near the predictor: " + failed;
        return curve;
      }
    } else {
      h = std::min(1.5 * h, 4.0 * options.step);
    }
  }
  curve.end = "max_points reached";
  return curve;
}

}  // namespace vibro
