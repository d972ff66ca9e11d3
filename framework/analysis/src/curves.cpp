/// \file curves.cpp
/// Bifurcation points followed in a second parameter (continuation.hpp, "Curves in two
/// parameters"), and the codimension-two points met along the curves.
///
/// **Line crossing.** From the last curve point (p1, p2), in scaled coordinates (p1/P1, p2/P2),
/// a predictor step of h along the curve's secant d (at first along p2) gives a = (a1, a2); on
/// the line a + σ n through it along the normal n = (−d2, d1) the system is a one-parameter
/// family in σ with derivative n1 P1 ∂/∂p1 + n2 P2 ∂/∂p2, and the branch through the previous
/// curve point's orbit is continued along that line for σ ∈ [−4h, 4h] until the point of the
/// same kind (and stop) is located; the located point nearest the predictor is the next curve
/// point. h grows by 1.5 (to 4 × step) after a point and halves when none is found (for folds,
/// doublings and tori also when the nearest lies further than h/2 from the predictor: the lines
/// are long, and at a sharp turn the nearest point can lie on another part of the curve). Grazing,
/// rising, period-doubling and Neimark–Sacker points are followed so: their orbits exist on
/// both sides of the curve, and the previous point's orbit is a regular start at the predictor.
///
/// **Why every point is exact.** Each curve point is a bifurcation located on its line by
/// continuation's own location (bifurcation_location.cpp): the zero of the kind's test function
/// (a multiplier product, the tangent's dp/ds, a gap) bracketed to locate_tolerance in σ, so it
/// lies on the curve to locate_tolerance × (P1, P2), whatever the predictor's error. The lines
/// replace a defining system in (z, p1, p2) — the fold condition det(J − I) = 0, the doubling
/// condition det(J + I) = 0 or the bialternate product for a torus, bordered as in Kuznetsov
/// (Elements of Applied Bifurcation Theory, 3rd ed., 2004, §10.2) and Govaerts (Numerical
/// Methods for Bifurcations of Dynamical Equilibria, 2000) — which would need the map's second
/// derivatives; on a line only J and ∂P/∂σ enter, both exact (linearisation.hpp).
///
/// **Folds.** A line across a fold curve has two orbits on one side of it and none on the other,
/// so the predictor may lie where there is no orbit and the fold orbit is a singular start
/// (J − I has the multiplier 1). The line is reached from the side with orbits instead:
///  1. from the last curve point q along the segment to b = a + s h n (s the side with orbits,
///     ±1 relative to n, unknown at the first step: both are tried), a one-parameter family in
///     τ ∈ [0, 1]; its branch starts at q's fold orbit, where the bordered system [DF; tᵀ] is
///     regular (a fold of the segment, crossed transversally), and runs into the side with
///     orbits to b;
///  2. from that orbit at b, the line b − τ s n (scaled) for τ ∈ [−2h, 4h]: the branch crosses
///     the curve near τ = h, turns there, and the fold (dp/dτ changes sign) is located on it.
/// The located fold nearest the predictor a is the next point; s is kept (the orbits' side).
///
/// **Codimension-two points** (folds, doublings and tori only). Between consecutive curve
/// points (the step u = h along the secant d from the earlier one):
///  * a test function that changes sign — Π(1 + μ_i) on a fold curve (fold–flip), Π(1 − μ_i) on
///    a doubling curve (fold–flip), both and the pair's angle θ − 2π/3, θ − π/2 on a torus curve
///    — is located by the Illinois iteration on u, each evaluation the curve point located on
///    the line at step u (so the codimension-two point is a curve point, exact as above, where
///    the second condition holds to the iteration's tolerance in u);
///  * orbits with other events (a grazing: the smooth curve's orbit touches a stop) by
///    bisection on u, whether the curve point at u has the earlier point's events; a curve that
///    is lost (steps halved below 1e-6, or no orbit found) where its last orbit has an impact
///    slower than 1e-3 V or a gap maximum within 1e-3 L of a stop ends at a grazing (reported,
///    not located: near a grazing the map's Jacobian grows like 1/u, u the slowest impact's
///    speed, and the line's branch cannot be followed past it with the same events);
///  * a fold curve whose secant reverses (consecutive secants at more than 90°) is reported as a
///    cusp's turning (not located; the fold's quadratic coefficient is not computed);
///  * a torus curve that ends with its pair within 0.05 of θ = 0 or π is reported as near a 1:1
///    or 1:2 resonance (not located).
#include "vibro/continuation.hpp"

#include "vibro/bounded_wait.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <string>

namespace vibro {

const char* to_string(CodimTwoKind kind) {
  switch (kind) {
    case CodimTwoKind::fold_flip: return "fold_flip";
    case CodimTwoKind::grazing: return "grazing";
    case CodimTwoKind::cusp: return "cusp";
    case CodimTwoKind::fold_neimark_sacker: return "fold_neimark_sacker";
    case CodimTwoKind::flip_neimark_sacker: return "flip_neimark_sacker";
    case CodimTwoKind::resonance_1_1: return "resonance_1_1";
    case CodimTwoKind::resonance_1_2: return "resonance_1_2";
    case CodimTwoKind::resonance_1_3: return "resonance_1_3";
    case CodimTwoKind::resonance_1_4: return "resonance_1_4";
  }
  return "?";
}

std::vector<std::string> codim_two_kind_names() {
  std::vector<std::string> out;
  for (int i = 0; i <= static_cast<int>(CodimTwoKind::resonance_1_4); ++i)
    out.emplace_back(to_string(static_cast<CodimTwoKind>(i)));
  return out;
}

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

namespace {

using Eigen::Index;

/// Π(1 − μ_i) over the non-structural multipliers (real part): zero where one passes +1.
double fold_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i) p *= 1.0 - f.values(i);
  return p.real();
}
/// Π(1 + μ_i): zero where one passes −1 (as continuation's doubling test).
double flip_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i) p *= 1.0 + f.values(i);
  return p.real();
}
/// The angle θ ∈ (0, π) of the complex pair nearest the unit circle, NaN without a pair.
double pair_angle(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  double best = -1.0, theta = std::numeric_limits<double>::quiet_NaN();
  for (Index i = 0; i < d; ++i) {
    const std::complex<double> m = f.values(i);
    if (std::abs(m.imag()) <= 1e-12) continue;
    const double off = std::abs(std::abs(m) - 1.0);
    if (best < 0.0 || off < best) best = off, theta = std::abs(std::arg(m));
  }
  return theta;
}

/// Follows one curve: the predictor, the line crossings, and the codimension-two points.
class CurveFollower {
 public:
  CurveFollower(const PlaneContinuationFamily& family, const Bifurcation& start, const CurveOptions& options)
      : family_(family), start_(start), o_(options) {
    P1_ = o_.scale1 > 0.0 ? o_.scale1 : o_.p1_max - o_.p1_min;
    P2_ = o_.scale2 > 0.0 ? o_.scale2 : o_.p2_max - o_.p2_min;
  }

  Curve follow(double p2_start);

 private:
  /// The next curve point from `last` at the predictor step h along dir, or nullopt (failed
  /// says why when a run threw). `side`: the fold's side with orbits (updated).
  std::optional<CurvePoint> next(const CurvePoint& last, const Eigen::Vector2d& dir, double h, int& side,
                                 std::string& failed) const;
  std::optional<CurvePoint> across(const CurvePoint& last, const Eigen::Vector2d& dir, double h,
                                   std::string& failed) const;
  std::optional<CurvePoint> fold_across(const CurvePoint& last, const Eigen::Vector2d& dir, double h, int& side,
                                        std::string& failed) const;
  /// The options of a short continuation along a line or segment of the plane, in the line's own
  /// (already scaled) parameter over [lo, hi] from step: the branch's options with the orbit's
  /// period and phase, at most 60 points, no doubled branch followed.
  ContinuationOptions line_options(int period, double phase, double lo, double hi, double step) const;
  /// Whether the predictor follows a secant (from the second step on): the first step goes
  /// along p2, which may be far from the curve's tangent, so its point is not held to h/2.
  bool secant = false;
  /// The codimension-two points between prev and cur (cur at step h along dir from prev).
  void between(Curve& curve, int after, const CurvePoint& prev, const CurvePoint& cur, const Eigen::Vector2d& dir,
               double h, int side) const;
  void locate_sign_change(Curve& curve, int after, CodimTwoKind kind, const CurvePoint& prev, const CurvePoint& cur,
                          const Eigen::Vector2d& dir, double h, int side,
                          const std::function<double(const BranchPoint&)>& g) const;
  void locate_events(Curve& curve, int after, const CurvePoint& prev, const CurvePoint& cur, const Eigen::Vector2d& dir,
                     double h, int side) const;
  /// A lost curve whose last orbit nearly grazes a stop: reported as a grazing (not located).
  void grazing_at_end(Curve& curve) const;
  bool multiplier_kind() const {
    return start_.kind == BifurcationKind::fold || start_.kind == BifurcationKind::period_doubling ||
           start_.kind == BifurcationKind::neimark_sacker;
  }

  const PlaneContinuationFamily& family_;
  const Bifurcation& start_;
  const CurveOptions& o_;
  double P1_ = 1.0, P2_ = 1.0;
};

/// The located point of `kind` (and stop) nearest to σ = target among r's bifurcations.
const Bifurcation* nearest(const ContinuationResult& r, BifurcationKind kind, int stop, double target) {
  const Bifurcation* best = nullptr;
  for (const Bifurcation& b : r.bifurcations)
    if (b.kind == kind && b.stop == stop && b.smooth &&
        (!best || std::abs(b.p - target) < std::abs(best->p - target)))
      best = &b;
  return best;
}

ContinuationOptions CurveFollower::line_options(int period, double phase, double lo, double hi, double step) const {
  ContinuationOptions o = o_.branch;
  o.period = period;
  o.phase = phase;
  o.p_min = lo;
  o.p_max = hi;
  o.parameter_scale = 1.0;
  o.step = step;
  o.max_points = 60;
  o.max_doublings = 0;
  return o;
}

std::optional<CurvePoint> CurveFollower::next(const CurvePoint& last, const Eigen::Vector2d& dir, double h, int& side,
                                              std::string& failed) const {
  if (start_.kind == BifurcationKind::fold) return fold_across(last, dir, h, side, failed);
  return across(last, dir, h, failed);
}

/// The line through the predictor along the normal, from the last point's orbit.
std::optional<CurvePoint> CurveFollower::across(const CurvePoint& last, const Eigen::Vector2d& dir, double h,
                                                std::string& failed) const {
  const double P1 = P1_, P2 = P2_;
  const Eigen::Vector2d normal(-dir(1), dir(0));
  const double a1 = last.p1 + h * dir(0) * P1, a2 = last.p2 + h * dir(1) * P2;
  // The family along the normal line through the predictor: σ in scaled units.
  const ContinuationFamily line = [&](double sigma) {
    const double q1 = a1 + sigma * normal(0) * P1, q2 = a2 + sigma * normal(1) * P2;
    PlaneEngine pe = family_(q1, q2);
    pe.engine->derivative = pe.d1.combined(normal(0) * P1, pe.d2, normal(1) * P2);
    return std::move(pe.engine);
  };
  const ContinuationOptions lo =
      line_options(last.point.k, last.point.phase, -4.0 * h, 4.0 * h, std::min(h, o_.branch.max_step));
  // Continue along the line from the previous curve point's orbit until the kind is found.
  // The last curve point's orbit may touch its stop: shooting from it at the predictor can fall
  // on the side with the impact, where Newton cannot converge from it; a shorter step then.
  ContinuationResult r;
  try {
    r = continue_orbits(line, 0.0, last.point.t0, last.point.x, last.point.v, lo);
  } catch (const InvalidInput& e) {
    failed = e.what();
  }
  const Bifurcation* best = nearest(r, start_.kind, start_.stop, 0.0);
  if (!best) return std::nullopt;
  // Folds, doublings and tori: a located point far off the predictor belongs to another part of
  // the curve (the lines reach ±4h): refused, and the step is halved.
  if (multiplier_kind() && secant && std::abs(best->p) > 0.5 * h) return std::nullopt;
  CurvePoint cp;
  cp.p1 = a1 + best->p * normal(0) * P1;
  cp.p2 = a2 + best->p * normal(1) * P2;
  cp.value = best->value;
  cp.point = best->point;
  return cp;
}

/// A fold: the line reached from the side with orbits (the file's header).
std::optional<CurvePoint> CurveFollower::fold_across(const CurvePoint& last, const Eigen::Vector2d& dir, double h,
                                                     int& side, std::string& failed) const {
  const double P1 = P1_, P2 = P2_;
  const Eigen::Vector2d normal(-dir(1), dir(0));
  const double a1 = last.p1 + h * dir(0) * P1, a2 = last.p2 + h * dir(1) * P2;
  const int first = side != 0 ? side : 1;
  for (const int s : {first, -first}) {
    // 1. The segment from the last point to b = a + s h n.
    const double b1 = a1 + s * h * normal(0) * P1, b2 = a2 + s * h * normal(1) * P2;
    const double u1 = b1 - last.p1, u2 = b2 - last.p2;
    const ContinuationFamily segment = [&](double tau) {
      PlaneEngine pe = family_(last.p1 + tau * u1, last.p2 + tau * u2);
      pe.engine->derivative = pe.d1.combined(u1, pe.d2, u2);
      return std::move(pe.engine);
    };
    ContinuationOptions so = line_options(last.point.k, last.point.phase, -1e-3, 1.0, 0.05);
    so.max_step = std::max(so.max_step, 0.25);
    so.locate = false;  // the fold at τ = 0 is the last point's
    // Its start is the located fold orbit, whose residual may lie a little above the tolerance
    // (the corrector's floor, 100 ε ‖J‖), where shooting's Newton would meet J − I singular: a
    // looser tolerance on the segment, a path to b only (stage 2 polishes b's orbit to the
    // tolerance and locates the fold with it).
    so.tolerance = std::max(so.tolerance, 1e-9);
    ContinuationResult r1;
    try {
      r1 = continue_orbits(segment, 0.0, last.point.t0, last.point.x, last.point.v, so);
    } catch (const InvalidInput& e) {
      failed = e.what();
      continue;
    }
    if (r1.branches.empty() || r1.branches[0].points.empty()) continue;
    const Branch& b = r1.branches[0];
    const BranchPoint* end = nullptr;
    for (const BranchPoint* q : {&b.points.front(), &b.points.back()})
      if (q->p >= 1.0 - 1e-6 && (!end || q->p > end->p)) end = q;
    if (!end) continue;
    // 2. The line from b back across the curve, −s n (scaled τ).
    const ContinuationFamily line = [&](double tau) {
      const double q1 = b1 - s * tau * normal(0) * P1, q2 = b2 - s * tau * normal(1) * P2;
      PlaneEngine pe = family_(q1, q2);
      pe.engine->derivative = pe.d1.combined(-s * normal(0) * P1, pe.d2, -s * normal(1) * P2);
      return std::move(pe.engine);
    };
    const ContinuationOptions lo = line_options(end->k, end->phase, -2.0 * h, 4.0 * h, std::min(h, o_.branch.max_step));
    ContinuationResult r2;
    try {
      r2 = continue_orbits(line, 0.0, end->t0, end->x, end->v, lo);
    } catch (const InvalidInput& e) {
      failed = e.what();
      continue;
    }
    const Bifurcation* best = nearest(r2, BifurcationKind::fold, -1, h);
    if (!best || (secant && std::abs(best->p - h) > 0.5 * h)) continue;
    side = s;
    CurvePoint cp;
    cp.p1 = b1 - s * best->p * normal(0) * P1;
    cp.p2 = b2 - s * best->p * normal(1) * P2;
    cp.value = best->value;
    cp.point = best->point;
    return cp;
  }
  return std::nullopt;
}

void CurveFollower::between(Curve& curve, int after, const CurvePoint& prev, const CurvePoint& cur,
                            const Eigen::Vector2d& dir, double h, int side) const {
  const BifurcationKind kind = start_.kind;
  if (!(prev.point.signature == cur.point.signature)) {
    locate_events(curve, after, prev, cur, dir, h, side);
    return;  // the multipliers jump across the change of events: no sign changes to compare
  }
  const auto mult = [](double (*f)(const FloquetMultipliers&)) {
    return [f](const BranchPoint& b) { return f(b.multipliers); };
  };
  const auto angle_minus = [](double target) {
    return [target](const BranchPoint& b) { return pair_angle(b.multipliers) - target; };
  };
  const double pi = std::numbers::pi;
  struct Test {
    CodimTwoKind kind;
    std::function<double(const BranchPoint&)> g;
  };
  std::vector<Test> tests;
  if (kind == BifurcationKind::fold) tests.push_back({CodimTwoKind::fold_flip, mult(flip_test)});
  if (kind == BifurcationKind::period_doubling) tests.push_back({CodimTwoKind::fold_flip, mult(fold_test)});
  if (kind == BifurcationKind::neimark_sacker) {
    tests.push_back({CodimTwoKind::fold_neimark_sacker, mult(fold_test)});
    tests.push_back({CodimTwoKind::flip_neimark_sacker, mult(flip_test)});
    tests.push_back({CodimTwoKind::resonance_1_3, angle_minus(2.0 * pi / 3.0)});
    tests.push_back({CodimTwoKind::resonance_1_4, angle_minus(pi / 2.0)});
  }
  for (const Test& t : tests) {
    const double g0 = t.g(prev.point), g1 = t.g(cur.point);
    if (std::isfinite(g0) && std::isfinite(g1) && g0 * g1 < 0.0)
      locate_sign_change(curve, after, t.kind, prev, cur, dir, h, side, t.g);
  }
}

/// Illinois on the step u ∈ (0, h) along dir from prev, each evaluation the curve point at u.
void CurveFollower::locate_sign_change(Curve& curve, int after, CodimTwoKind kind, const CurvePoint& prev,
                                       const CurvePoint& cur, const Eigen::Vector2d& dir, double h, int side,
                                       const std::function<double(const BranchPoint&)>& g) const {
  double u_lo = 0.0, u_hi = h, g_lo = g(prev.point), g_hi = g(cur.point);
  CurvePoint lo = prev, hi = cur;
  int last_side = 0;
  bool located = false;
  std::string note;
  for (int it = 0; it < 60; ++it) {
    if (u_hi - u_lo <= 1e-10) {
      located = true;
      break;
    }
    double u = u_hi - g_hi * (u_hi - u_lo) / (g_hi - g_lo);
    if (!(u > u_lo && u < u_hi)) u = 0.5 * (u_lo + u_hi);
    int s = side;
    std::string failed;
    const std::optional<CurvePoint> m = next(prev, dir, u, s, failed);
    const double gm = m ? g(m->point) : std::numeric_limits<double>::quiet_NaN();
    if (!m || !std::isfinite(gm) || !(m->point.signature == prev.point.signature)) {
      note = "no curve point with the same events inside the bracket: bracketed only";
      break;
    }
    if (gm == 0.0) {
      lo = hi = *m;
      u_lo = u_hi = u;
      located = true;
      break;
    }
    if ((gm < 0.0) == (g_lo < 0.0)) {
      u_lo = u, g_lo = gm, lo = *m;
      if (last_side == -1) g_hi *= 0.5;
      last_side = -1;
    } else {
      u_hi = u, g_hi = gm, hi = *m;
      if (last_side == +1) g_lo *= 0.5;
      last_side = +1;
    }
  }
  const CurvePoint& at = std::abs(g(lo.point)) <= std::abs(g(hi.point)) ? lo : hi;
  CodimTwoPoint c;
  c.kind = kind;
  c.after = after;
  c.p1 = at.p1;
  c.p2 = at.p2;
  c.located = located;
  c.width = u_hi - u_lo;
  c.value = g(at.point);
  c.point = at.point;
  c.note = note;
  curve.special.push_back(c);
}

/// Bisection on u: whether the curve point at u has prev's events.
void CurveFollower::locate_events(Curve& curve, int after, const CurvePoint& prev, const CurvePoint& cur,
                                  const Eigen::Vector2d& dir, double h, int side) const {
  double u_lo = 0.0, u_hi = h;
  CurvePoint lo = prev;
  const Signature& s0 = prev.point.signature;
  int stop = -1;
  for (std::size_t j = 0; j < s0.impacts.size() && stop < 0; ++j)
    if (s0.impacts[j] != cur.point.signature.impacts[j] || s0.chatters[j] != cur.point.signature.chatters[j] ||
        s0.phases[j] != cur.point.signature.phases[j])
      stop = static_cast<int>(j);
  while (u_hi - u_lo > 1e-9) {
    const double u = 0.5 * (u_lo + u_hi);
    int s = side;
    std::string failed;
    const std::optional<CurvePoint> m = next(prev, dir, u, s, failed);
    if (m && m->point.signature == s0) {
      u_lo = u;
      lo = *m;
    } else {
      u_hi = u;
    }
  }
  CodimTwoPoint c;
  c.kind = CodimTwoKind::grazing;
  c.stop = stop;
  c.after = after;
  c.p1 = lo.p1;
  c.p2 = lo.p2;
  c.located = true;
  c.width = u_hi - u_lo;
  c.value = 0.0;
  c.point = lo.point;
  c.note = "events " + s0.text() + " → " + cur.point.signature.text();
  curve.special.push_back(c);
}

/// The last point's orbit run once more with its features: an impact slower than 1e-3 V or a
/// gap maximum within 1e-3 L of its stop (continuation's test for a nearby grazing) marks the
/// end of the smooth curve at a grazing.
void CurveFollower::grazing_at_end(Curve& curve) const {
  const CurvePoint& last = curve.points.back();
  TangentMap m;
  try {
    PlaneEngine pe = family_(last.p1, last.p2);
    LinearisationOptions lo;
    lo.jacobian = false;
    lo.features = true;
    const double T = 2.0 * std::numbers::pi / pe.engine->frequency();
    m = pe.engine->linearise(last.point.t0, last.point.x, last.point.v, last.point.t0 + last.point.k * T, lo);
  } catch (const InvalidInput&) {
    return;
  }
  if (m.summary.status != RunStatus::completed) return;
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  int stop = -1;
  double how = 0.0;
  std::string what;
  for (const ImpactRecord& r : m.impacts)
    if (r.speed < 1e-3 * V && (stop < 0 || r.speed / V < how))
      stop = r.stop, how = r.speed / V, what = "an impact of speed " + number_text(r.speed);
  for (const GapPeak& g : m.gap_peaks)
    if (g.value > -1e-3 * L && (stop < 0 || -g.value / L < how))
      stop = g.stop, how = -g.value / L, what = "a gap maximum of " + number_text(g.value);
  if (stop < 0) return;
  CodimTwoPoint c;
  c.kind = CodimTwoKind::grazing;
  c.stop = stop;
  c.after = static_cast<int>(curve.points.size()) - 1;
  c.p1 = last.p1;
  c.p2 = last.p2;
  c.value = how;
  c.point = last.point;
  c.note = "the curve ends where its orbit grazes (the last point has " + what + "; not located)";
  curve.special.push_back(c);
}

Curve CurveFollower::follow(double p2_start) {
  const Bifurcation& start = start_;
  const CurveOptions& options = o_;
  const double P1 = P1_, P2 = P2_;
  const bool smooth_kind = start.kind == BifurcationKind::fold || start.kind == BifurcationKind::period_doubling ||
                           start.kind == BifurcationKind::neimark_sacker;
  Curve curve;
  curve.kind = start.kind;
  curve.stop = start.stop;
  CurvePoint c0;
  c0.p1 = start.p;
  c0.p2 = p2_start;
  c0.value = start.value;
  c0.point = start.point;
  curve.points.push_back(c0);
  // Direction along the curve in scaled (p1/P1, p2/P2): first p2, then the secant.
  Eigen::Vector2d dir(0.0, options.direction);
  double h = options.step;
  int side = 0;
  auto finish = [&](const std::string& end) {
    curve.end = end;
    if (smooth_kind && (curve.end.find("lost") != std::string::npos || curve.end.find("no orbit") != std::string::npos))
      grazing_at_end(curve);
    if (start.kind == BifurcationKind::neimark_sacker && curve.end.find("lost") != std::string::npos) {
      const double theta = pair_angle(curve.points.back().point.multipliers);
      if (std::isfinite(theta) && (theta < 0.05 || theta > std::numbers::pi - 0.05)) {
        CodimTwoPoint c;
        c.kind = theta < 0.05 ? CodimTwoKind::resonance_1_1 : CodimTwoKind::resonance_1_2;
        c.after = static_cast<int>(curve.points.size()) - 1;
        c.p1 = curve.points.back().p1;
        c.p2 = curve.points.back().p2;
        c.value = theta;
        c.point = curve.points.back().point;
        c.note = "the curve ends with its pair at θ = " + number_text(theta) + " (not located)";
        curve.special.push_back(c);
      }
    }
    return curve;
  };
  // Interrupted (the run's flag, or an engine's set-up under run_bounded, bounded_wait.hpp): the
  // curve ends where it is, with the points so far.
  const std::atomic<bool>* stop = options.branch.solver.interrupt;
  while (static_cast<int>(curve.points.size()) < options.max_points) {
    if (stop && stop->load(std::memory_order_relaxed)) return finish("interrupted");
    const CurvePoint last = curve.points.back();
    Eigen::Vector2d previous_dir = dir;
    if (curve.points.size() >= 2) {
      const CurvePoint& prev = curve.points[curve.points.size() - 2];
      Eigen::Vector2d s((last.p1 - prev.p1) / P1, (last.p2 - prev.p2) / P2);
      if (s.norm() > 0.0) dir = s.normalized();
      secant = true;
    }
    // A fold curve whose secant reverses has turned back (a cusp passed between the points).
    if (start.kind == BifurcationKind::fold && curve.points.size() >= 3 && previous_dir.dot(dir) < 0.0) {
      CodimTwoPoint c;
      c.kind = CodimTwoKind::cusp;
      c.after = static_cast<int>(curve.points.size()) - 2;
      const CurvePoint& turn = curve.points[curve.points.size() - 2];
      c.p1 = turn.p1;
      c.p2 = turn.p2;
      c.point = turn.point;
      c.note = "the fold curve turns back here (a cusp's turning; not located)";
      curve.special.push_back(c);
    }
    const double a1 = last.p1 + h * dir(0) * P1, a2 = last.p2 + h * dir(1) * P2;
    if (a2 < options.p2_min || a2 > options.p2_max || a1 < options.p1_min || a1 > options.p1_max)
      return finish("left the parameter limits");
    std::string failed;
    const int side_before = side;
    std::optional<CurvePoint> cp;
    try {
      cp = next(last, dir, h, side, failed);
    } catch (const Interrupted&) {
      return finish("interrupted");
    }
    if (stop && stop->load(std::memory_order_relaxed)) {  // a point located before it is kept
      if (cp) curve.points.push_back(*cp);
      return finish("interrupted");
    }
    if (!cp) {
      h *= 0.5;
      if (h < 1e-6)
        return finish(failed.empty() ? "the curve was lost (no located point on the line across it)"
                                     : "no orbit near the predictor: " + failed);
      continue;
    }
    try {
      if (smooth_kind) between(curve, static_cast<int>(curve.points.size()) - 1, last, *cp, dir, h, side_before);
    } catch (const Interrupted&) {
      curve.points.push_back(*cp);
      return finish("interrupted");
    }
    curve.points.push_back(*cp);
    h = std::min(1.5 * h, 4.0 * options.step);
  }
  return finish("max_points reached");
}

}  // namespace

Curve follow_curve(const PlaneContinuationFamily& family, const Bifurcation& start, double p2_start,
                   const CurveOptions& options) {
  options.validate();
  switch (start.kind) {
    case BifurcationKind::grazing:
    case BifurcationKind::rising:
    case BifurcationKind::fold:
    case BifurcationKind::period_doubling:
    case BifurcationKind::neimark_sacker: break;
    default:
      throw InvalidInput(std::string("curve: only grazing, rising, fold, period-doubling and Neimark–Sacker points "
                                     "can be followed, not ") + to_string(start.kind));
  }
  CurveFollower follower(family, start, options);
  return follower.follow(p2_start);
}

}  // namespace vibro
