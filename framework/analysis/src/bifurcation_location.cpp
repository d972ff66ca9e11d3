/// \file bifurcation_location.cpp
/// Locating a bifurcation between two neighbouring branch points, each evaluation a corrected
/// branch point:
///  * Illinois (modified regula falsi) on the arclength σ between a and b, each point in the
///    hyperplane a + σ t_a normal to t_a: σ ← σ_hi − f_hi (σ_hi − σ_lo)/(f_hi − f_lo), the end
///    kept twice in a row having its f halved; to |Δσ| P ≤ locate_tolerance (at a fold p is
///    stationary in σ while the test function is not, so σ is what converges). A trial whose
///    corrector fails from the chord through a is tried from the nearer bracket end's orbit, then
///    the farther's, then moved towards the nearer end; and a point found is kept as located only
///    where its test function is small against the function's change over the tolerance around
///    it (small_against_scale: a sign change at a jump of the function is bracketed, not located);
///  * one-sided secant in p from the side where the test function is smooth (grazing, rising:
///    on the other side the map's derivative blows up), each point by Newton at fixed p; the
///    zero may lie beyond the good point, at a corner where both parts of the branch reach it
///    from the same side in p;
///  * bisection in p on a discrete property (the event signature) where the condition is not
///    smooth in p;
///  * for a branch point, Illinois in p, each point carried along a neighbour's tangent: the
///    arclength's hyperplanes contain the crossing branch's direction there.
/// record() runs the one asked for, falls back to bisection when the smooth one fails, and
/// appends the Bifurcation with its bracket, its test function's value and the orbit there.
#include "branch_runner.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vibro::detail {

/// The point between a and b (in the hyperplanes normal to a's tangent) where p = limit.
std::optional<Node> BranchRunner::on_limit(const Node& a, const Node& b, double limit) {
  auto f = [&](const Node& n) { return n.e.p - limit; };
  return illinois(a, b, f, true, nullptr);
}

/// Illinois iteration on σ ∈ [0, σ_b] for a zero of f between a and b (f(a) f(b) < 0), each
/// evaluation the branch point in the hyperplane a + σ t_a (normal t_a). With bisect, or
/// where f is NaN, it halves instead.
std::optional<Node> BranchRunner::illinois(const Node& a, const Node& b, const TestFunction& f, bool smooth,
                                           int* count, const std::function<bool(const Node&)>& same_as_a) {
  const VectorXd ya = c_.scaled(a.e);
  double s_lo = 0.0, s_hi = a.t.dot(c_.scaled(b.e) - ya);
  double f_lo = smooth ? f(a) : -1.0, f_hi = smooth ? f(b) : 1.0;
  if (smooth && (!std::isfinite(f_lo) || !std::isfinite(f_hi))) smooth = false, f_lo = -1.0, f_hi = 1.0;
  Node lo = a, hi = b;
  int side = 0;
  double s_last = std::numeric_limits<double>::infinity();
  // A trial whose tangent turns from a's by far more than b's does lies on another branch that
  // crosses the hyperplane (at a branch point the crossing branch's direction lies in it): taken
  // as a failed corrector. (Between two neighbours the tangent turns by no more than from a to b,
  // give or take the curvature's change.)
  const double least_turn = std::min(a.t.dot(b.t), 1.0) - 0.25;
  const auto correct = [&](const VectorXd& y) {
    Eval e = c_.correct(y, a.t);
    if (e.ok && c_.tangent(e, a.t).dot(a.t) < least_turn) {
      e.ok = false;
      e.why = "the corrector found another branch crossing the hyperplane";
    }
    return e;
  };
  for (int it = 0; it < 100; ++it) {
    double s = 0.5 * (s_lo + s_hi);
    if (smooth) s = s_hi - f_hi * (s_hi - s_lo) / (f_hi - f_lo);
    if (!(s > s_lo && s < s_hi)) s = 0.5 * (s_lo + s_hi);
    Node m;
    m.e = correct(ya + s * a.t);
    if (count) ++*count;
    // A corrector that fails from the chord through a (near a grazing the branch bends away from
    // it within the bracket) is tried again from the nearer bracket end's orbit carried to the
    // hyperplane along t_a, then from the farther end's; failing those, the trial moves half way
    // towards the nearer end (up to four times), so that the bracket still closes where the orbits
    // exist.
    for (int shrink = 0; !m.e.ok && shrink <= 4; ++shrink) {
      if (shrink > 0) {
        const double s_near = s - s_lo <= s_hi - s ? s_lo : s_hi;
        s = s_near + 0.5 * (s - s_near);
        m.e = correct(ya + s * a.t);
        if (count) ++*count;
      }
      const bool lo_nearer = s - s_lo <= s_hi - s;
      for (const Node* end : {lo_nearer ? &lo : &hi, lo_nearer ? &hi : &lo}) {
        if (m.e.ok) break;
        const double s_end = end == &lo ? s_lo : s_hi;
        m.e = correct(c_.scaled(end->e) + (s - s_end) * a.t);
        if (count) ++*count;
      }
    }
    if (!m.e.ok) return std::nullopt;
    m.t = c_.tangent(m.e, a.t);
    m.b = c_.point(m.e, m.t, 0);
    m.b.located = true;
    double fm = smooth ? f(m) : kNaN;
    if (smooth && !std::isfinite(fm)) smooth = false;
    bool to_lo;
    if (smooth) {
      to_lo = (fm < 0.0) == (f_lo < 0.0);
    } else {
      to_lo = same_as_a ? same_as_a(m) : (m.e.p - a.e.p) * (b.e.p - a.e.p) < 0.0;
    }
    if (to_lo) {
      s_lo = s;
      f_lo = smooth ? fm : f_lo;
      lo = m;
      if (smooth && side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      s_hi = s;
      f_hi = smooth ? fm : f_hi;
      hi = m;
      if (smooth && side == +1) f_lo *= 0.5;
      side = +1;
    }
    // In σ (scaled arclength): |Δp| ≤ |Δσ| P, and at a fold p is stationary in σ while the
    // test function (t_p) is not, so converging σ is what locates every kind.
    const double width = std::abs(s_hi - s_lo) * c_.P;
    const double s_step = std::abs(s - s_last) * c_.P;
    s_last = s;
    if (width <= o_.locate_tolerance || (smooth && (fm == 0.0 || s_step <= 0.1 * o_.locate_tolerance))) {
      Node best = smooth ? m : (same_as_a ? lo : m);
      best.b.p = best.e.p;
      bracket_low_ = std::min(lo.e.p, hi.e.p);
      bracket_high_ = std::max(lo.e.p, hi.e.p);
      located_smooth_ = smooth;
      return best;
    }
  }
  return std::nullopt;
}

/// The branch point at p (the hyperplane p = const), Newton from `from`'s state.
std::optional<Node> BranchRunner::at_p(const Node& from, double p, const VectorXd& along) {
  VectorXd y = c_.scaled(from.e);
  y(y.size() - 1) = p / c_.P;
  VectorXd n = VectorXd::Zero(y.size());
  n(n.size() - 1) = 1.0;
  Node m;
  int it = 0;
  m.e = c_.correct(y, n, &it);
  if (!m.e.ok) return std::nullopt;
  m.t = c_.tangent(m.e, along);
  m.b = c_.point(m.e, m.t, it);
  m.b.located = true;
  return m;
}

/// The orbit at p of the branch through `from`: Newton at fixed p from `from`'s point carried
/// along its tangent to p, so that it starts O(Δp²) from the branch. (Near a branch point the
/// crossing branch passes within O(√|p − p*|) of this one: Newton from `from`'s own state at the
/// new p, or in a hyperplane normal to the tangent, which contains the crossing branch's
/// direction there, may fall onto it.)
std::optional<Node> BranchRunner::along_to_p(const Node& from, double p) {
  const Index last = from.t.size() - 1;
  if (!(std::abs(from.t(last)) > 1e-6)) return at_p(from, p, from.t);  // at a fold p cannot be stepped along t
  VectorXd y = c_.scaled(from.e) + ((p - from.e.p) / c_.P / from.t(last)) * from.t;
  y(last) = p / c_.P;
  VectorXd n = VectorXd::Zero(y.size());
  n(last) = 1.0;
  Node m;
  int it = 0;
  m.e = c_.correct(y, n, &it);
  if (!m.e.ok) return std::nullopt;
  m.t = c_.tangent(m.e, from.t);
  m.b = c_.point(m.e, m.t, it);
  m.b.located = true;
  return m;
}

/// A zero of f between a and b (f(a) f(b) < 0) by Illinois in p, each trial carried from the
/// nearer bracket end along its tangent (along_to_p), to |Δp| ≤ locate_tolerance: for a branch
/// point, where the branch crosses p transversally but the arclength iteration's hyperplanes
/// contain the crossing branch's direction. The point is kept as located (located_smooth_) only
/// if f 10 × the tolerance to either side in p (carried from it the same way) has opposite signs
/// and |f| there at most a tenth of half their difference (the check small_against_scale makes
/// in σ); `why` says what failed.
std::optional<Node> BranchRunner::illinois_in_p(const Node& a, const Node& b, const TestFunction& f, int* count,
                                                std::string* why) {
  Node lo = a, hi = b;
  double f_lo = f(a), f_hi = f(b);
  if (!(f_lo * f_hi < 0.0)) return std::nullopt;
  int side = 0;
  double p_last = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 100; ++it) {
    double p = hi.e.p - f_hi * (hi.e.p - lo.e.p) / (f_hi - f_lo);
    if (!(p > std::min(lo.e.p, hi.e.p) && p < std::max(lo.e.p, hi.e.p))) p = 0.5 * (lo.e.p + hi.e.p);
    const bool lo_nearer = std::abs(p - lo.e.p) <= std::abs(p - hi.e.p);
    std::optional<Node> m = along_to_p(lo_nearer ? lo : hi, p);
    if (count) ++*count;
    if (!m) {
      m = along_to_p(lo_nearer ? hi : lo, p);
      if (count) ++*count;
    }
    if (!m) return std::nullopt;
    const double fm = f(*m);
    if (!std::isfinite(fm)) return std::nullopt;
    if ((fm < 0.0) == (f_lo < 0.0)) {
      lo = *m;
      f_lo = fm;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = *m;
      f_hi = fm;
      if (side == +1) f_lo *= 0.5;
      side = +1;
    }
    const double step = std::abs(p - p_last);
    p_last = p;
    if (std::abs(hi.e.p - lo.e.p) > o_.locate_tolerance && fm != 0.0 && step > 0.1 * o_.locate_tolerance) continue;
    bracket_low_ = std::min(lo.e.p, hi.e.p);
    bracket_high_ = std::max(lo.e.p, hi.e.p);
    double sides[2];
    for (int i = 0; i < 2; ++i) {
      const std::optional<Node> s = along_to_p(*m, m->e.p + (i == 0 ? -10.0 : 10.0) * o_.locate_tolerance);
      if (count) ++*count;
      if (!s) {
        *why = "its test function's change around the point could not be checked (no orbit found 10 × the tolerance away)";
        located_smooth_ = true;
        return m;
      }
      sides[i] = f(*s);
    }
    const double change = 0.5 * std::abs(sides[1] - sides[0]);
    located_smooth_ = sides[0] * sides[1] < 0.0 && std::abs(fm) <= 0.1 * change;
    if (!located_smooth_)
      *why = "its test function at the point found (" + number_text(fm) + ") is not small against its change over " +
             "10 × the tolerance around it in p (" + number_text(sides[0]) + " … " + number_text(sides[1]) +
             "): bracketed, not located";
    return m;
  }
  return std::nullopt;
}

/// A zero of f located from the side of `good` only, where f is defined and smooth (on_good
/// says whether a point is on that side): secant steps in p through the two nearest good
/// points (the first step goes half way towards `bad`). A trial point that has no orbit or
/// lies on the other side halves the step back towards the last good point. The zero may lie
/// beyond the good point, away from `bad`: at a grazing corner both branches reach the grazing
/// from the same side in p. Ends when the secant's next step is below half the tolerance; the
/// zero is that step's end, the orbit the last good point's.
std::optional<Node> BranchRunner::one_sided(const Node& good, const Node& bad, const TestFunction& f,
                                            const std::function<bool(const Node&)>& on_good, int* count,
                                            double solved) {
  struct Good {
    double p, f;
    Node node;
  };
  std::vector<Good> g{{good.e.p, f(good), good}};
  double toward = bad.e.p;
  const VectorXd along = good.t;
  // The zero lies within the bracket or, at a corner, beyond one of its ends: after a jump from
  // the unstable side of a fold onto the branch without the impact, the corner lies below both
  // points by a few times their distance (the paper's system at A1 = 0.4939: 2.6 ×, where a
  // reach of 2 × left only a bisection between two branches). Where the steps that crossed the
  // corner were cut short (step control near a cascade of grazings), the zero lies further
  // beyond, by 8 … 20 × their distance (the three-mass chain of experiments/examples at Ω ≈
  // 0.17984, 0.18025): a root beyond the reach is approached by steps to its end, the reach
  // doubling each time, every point on the good side with f on its smooth graph, up to 2 % of the
  // parameter scale (as far as a jump looks). A secant that leads further has left the family.
  double reach = 8.0 * std::abs(bad.e.p - good.e.p);
  const double first_reach = reach, max_reach = std::max(reach, 0.02 * c_.P);
  double lo = std::min(good.e.p, bad.e.p) - reach, hi = std::max(good.e.p, bad.e.p) + reach;
  const bool doubled = c_.k > o_.period;
  bool polishing = false;  // the zero found in p; its orbit sought within `solved` of it
  for (int it = 0; it < 60; ++it) {
    const Good& last = g.back();
    double p = 0.5 * (last.p + toward);
    if (g.size() >= 2) {
      const Good& prev = g[g.size() - 2];
      if (last.f == prev.f) break;
      const double root = last.p - last.f * (last.p - prev.p) / (last.f - prev.f);
      if (std::abs(root - last.p) <= 0.5 * o_.locate_tolerance) {
        located_p_ = root;
        bracket_low_ = std::min(last.p, root);
        bracket_high_ = std::max(last.p, root);
        // Where f is steep (the gap peak after the last bounce of a fast sequence moves by ~1e3
        // lengths per unit of p), the last good orbit, within the tolerance of the zero in p, may
        // still be well off it in f (1.2e-7 L at 5e-11 in Ω): the secant goes on below the
        // tolerance until the orbit is within `solved` of the zero, so that the orbit kept and
        // the p reported agree; failing that, the zero is bracketed.
        if (!(std::abs(last.f) > solved)) return last.node;
        polishing = true;
      }
      if (!std::isfinite(root) || (!(root >= lo && root <= hi) && reach >= max_reach)) return std::nullopt;
      p = std::clamp(root, lo, hi);
      if (p != root) {
        const double grown = std::min(2.0 * reach, max_reach) - reach;
        reach += grown;
        lo -= grown;
        hi += grown;
      }
    }
    bool stepped = false;
    for (int attempt = 0; attempt < 40 && !stepped; ++attempt) {
      if (!polishing && std::abs(p - last.p) <= 0.5 * o_.locate_tolerance) break;
      if (p == last.p) break;
      std::optional<Node> m = at_p(last.node, p, along);
      if (count) ++*count;
      const double fm = m ? f(*m) : kNaN;
      // f is a least distance over the orbit's features (its highest gap peak, …): a value far
      // beyond every one met so far means the feature going to zero is no longer seen there (a
      // gap peak between two slow bounces merged away): not a point on f's smooth graph.
      double seen = 0.0;
      for (const Good& q : g) seen = std::max(seen, std::abs(q.f));
      const bool jumped = std::abs(fm) > 100.0 * seen;
      if (m && on_good(*m) && std::isfinite(fm) && !jumped && !(doubled && c_.closes_after(m->e, c_.k / 2))) {
        g.push_back({p, fm, *m});
        stepped = true;
      } else {
        p = last.p + 0.5 * (p - last.p);
      }
    }
    if (!stepped && polishing) {  // the zero found in p, its orbit not within `solved` of it
      one_sided_solved_ = false;
      return g.back().node;
    }
    if (!stepped) {  // the good side ends within the tolerance of the last good point
      // Beyond the first reach, only where f has come down to its zero there (not where the
      // family merely ends: at a fold of its own, or where no orbit is found).
      if (reach > first_reach) {
        double seen = 0.0;
        for (const Good& q : g) seen = std::max(seen, std::abs(q.f));
        if (!(std::abs(g.back().f) <= 1e-3 * seen)) return std::nullopt;
      }
      // Where f is still short of its zero there (the secant through the last two good points
      // puts it further than the tolerance), the good side ends for another reason than the
      // grazing or rising: the change is bracketed there, not solved.
      if (g.size() >= 2) {
        const Good& l = g.back();
        const Good& q = g[g.size() - 2];
        const double root = l.p - l.f * (l.p - q.p) / (l.f - q.f);
        one_sided_solved_ = l.f != q.f && std::abs(root - l.p) <= o_.locate_tolerance && !(std::abs(l.f) > solved);
      }
      located_p_ = p;
      bracket_low_ = std::min(g.back().p, p);
      bracket_high_ = std::max(g.back().p, p);
      return g.back().node;
    }
  }
  if (polishing) {
    one_sided_solved_ = false;
    return g.back().node;
  }
  return std::nullopt;
}

/// An orbit of good's side nearer to the zero of f than `good`, where good's f is not yet the
/// feature that goes to zero there: far from a grazing the flight whose impact is lost may have no
/// interior gap maximum at all (its maximum merges with the flight's end), and the orbit's largest
/// gap maximum, f there, is another flight's, far from zero and flat in p (the paper's system at
/// Ω ≈ 0.2574644: −0.44 L, 1.8e-6 above the grazing corner, where the secant had nothing to follow).
/// The side's orbits are followed by Newton at fixed p from good towards `bad` and beyond it, up to
/// 6 times their distance (at a corner both parts of the branch lie on one side in p): a bisection
/// on whether an orbit of that side exists there, each point from the nearest one found, until one
/// has |f| ≤ 1e-3 |f(good)| (the grazing flight's own maximum, near zero). nullopt if none does.
std::optional<Node> BranchRunner::nearer_feature(const Node& good, const Node& bad, const TestFunction& f,
                                                 const std::function<bool(const Node&)>& on_good, int* count) {
  const double f_good = f(good);
  if (!std::isfinite(f_good) || f_good == 0.0) return std::nullopt;
  const double dir = bad.e.p > good.e.p ? 1.0 : -1.0;
  Node lo = good;
  // (6, not 8: the bisection's points then never fall on bad's p itself, from where the secant
  // towards bad would have no step to take.)
  double hi = good.e.p + dir * 6.0 * std::abs(bad.e.p - good.e.p);
  const bool doubled = c_.k > o_.period;
  for (int it = 0; it < 60 && std::abs(hi - lo.e.p) > o_.locate_tolerance; ++it) {
    const double p = 0.5 * (lo.e.p + hi);
    std::optional<Node> m = at_p(lo, p, lo.t);
    if (count) ++*count;
    const double fm = m ? f(*m) : kNaN;
    if (!m || !on_good(*m) || !std::isfinite(fm) || (doubled && c_.closes_after(m->e, c_.k / 2))) {
      hi = p;
      continue;
    }
    if (std::abs(fm) <= 1e-3 * std::abs(f_good)) return m;
    lo = std::move(*m);
  }
  return std::nullopt;
}

/// Bisection in p on a discrete property (same_as_a: whether a point is on a's side), each
/// point by Newton at fixed p from the nearer bracket end's orbit (or the farther one's if
/// that fails). Returns a's-side end of the final bracket; where no orbit can be found inside
/// the bracket it stops there and reports the bracket reached.
std::optional<Node> BranchRunner::bisect(const Node& a, const Node& b,
                                         const std::function<bool(const Node&)>& same_as_a, int* count) {
  Node lo = a, hi = b;
  for (int it = 0; it < 80 && std::abs(hi.e.p - lo.e.p) > o_.locate_tolerance; ++it) {
    const double p = 0.5 * (lo.e.p + hi.e.p);
    std::optional<Node> m = at_p(lo, p, lo.t);
    if (count) ++*count;
    if (!m) {
      m = at_p(hi, p, hi.t);
      if (count) ++*count;
    }
    if (!m) break;
    if (same_as_a(*m)) lo = *m;
    else hi = *m;
  }
  bracket_low_ = std::min(lo.e.p, hi.e.p);
  bracket_high_ = std::max(lo.e.p, hi.e.p);
  located_smooth_ = false;
  return lo;
}

/// Whether the zero Illinois found at `at` (between a and b, in the hyperplanes normal to a's
/// tangent) is a zero of f within the tolerance: f at `at` small against f's change over the
/// tolerance around it. The points at σ ± δ (δ the tolerance in p, times 10, so that f's change
/// there stands above its rounding) must have f of opposite signs, and |f(at)| at most a tenth of
/// half their difference (the linear model through them puts the zero within 2 × the tolerance of
/// the point). A sign change of f that is a jump (the test function discontinuous inside the
/// bracket) leaves |f| there as large as the jump, and fails. `why` says what failed, or that the
/// check could not be made (a corrector failed at σ ± δ: the location is then kept, so noted).
bool BranchRunner::small_against_scale(const Node& a, const Node& at, const TestFunction& f, int* count,
                                       std::string* why) {
  const double delta = 10.0 * o_.locate_tolerance / c_.P;
  const VectorXd y = c_.scaled(at.e);
  double side[2];
  for (int i = 0; i < 2; ++i) {
    Node m;
    m.e = c_.correct(y + (i == 0 ? -delta : delta) * a.t, a.t);
    if (count) ++*count;
    if (!m.e.ok) {  // not checked (noted with the point): Illinois's location stands
      *why = "its test function's change around the point could not be checked (no orbit found 10 × the tolerance away)";
      return true;
    }
    m.t = c_.tangent(m.e, a.t);
    m.b = c_.point(m.e, m.t, 0);
    side[i] = f(m);
  }
  const double f0 = f(at), change = 0.5 * std::abs(side[1] - side[0]);
  if (std::isfinite(f0) && side[0] * side[1] < 0.0 && std::abs(f0) <= 0.1 * change) return true;
  *why = "its test function at the point found (" + number_text(f0) + ") is not small against its change over " +
         "10 × the tolerance around it (" + number_text(side[0]) + " … " + number_text(side[1]) + ")";
  return false;
}

void BranchRunner::record(BifurcationKind kind, int stop, const Node& a, const Node& b, int branch_index,
                          const TestFunction& f, Mode mode, const std::function<bool(const Node&)>& same_as_a,
                          const std::string& note) {
  Bifurcation bif;
  bif.kind = kind;
  bif.stop = stop;
  bif.branch = branch_index;
  bif.note = note;
  bif.p_low = std::min(a.e.p, b.e.p);
  bif.p_high = std::max(a.e.p, b.e.p);
  bif.p = 0.5 * (a.e.p + b.e.p);
  bif.smooth = false;
  bif.value = kNaN;
  bif.point = b.b;
  if (!o_.locate) {
    result_.bifurcations.push_back(bif);
    return;
  }
  int count = 0;
  std::optional<Node> at;
  located_p_ = kNaN;
  if (mode == Mode::one_sided) {
    const bool a_good = same_as_a(a);  // same_as_a tells the good side here
    one_sided_solved_ = true;
    // A grazing's orbit is kept only within 1e-9 L of touching its stop (its gap peak's value).
    const double solved = kind == BifurcationKind::grazing ? 1e-9 * c_.L : std::numeric_limits<double>::infinity();
    at = a_good ? one_sided(a, b, f, same_as_a, &count, solved) : one_sided(b, a, f, same_as_a, &count, solved);
    located_smooth_ = at.has_value() && one_sided_solved_;
    if (at && !one_sided_solved_) {
      located_p_ = kNaN;
      bif.note += std::string(bif.note.empty() ? "" : "; ") +
                  "the side where its test function is smooth ends before the function reaches zero: bracketed where it ends";
    }
    if (!at) {
      at = bisect(a, b, same_as_a, &count);
      bif.note += std::string(bif.note.empty() ? "" : "; ") + "the smooth location failed: bracketed by bisection";
    }
  } else if (mode == Mode::bisection) {
    at = bisect(a, b, same_as_a, &count);
  } else if (mode == Mode::in_p) {
    std::string why;
    at = illinois_in_p(a, b, f, &count, &why);
    if (!why.empty()) bif.note += (bif.note.empty() ? "" : "; ") + why;
    if (!at) {
      const double fa = f(a);
      at = bisect(a, b, [&f, fa](const Node& n) { return f(n) * fa > 0.0; }, &count);
      bif.note += std::string(bif.note.empty() ? "" : "; ") + "the location in p failed: bracketed by bisection";
    }
  } else {
    at = illinois(a, b, f, true, &count, same_as_a);
    if (at && located_smooth_) {
      std::string why;
      if (!small_against_scale(a, *at, f, &count, &why)) {
        located_smooth_ = false;
        bif.note += (bif.note.empty() ? "" : "; ") + why + ": bracketed, not located";
      } else if (!why.empty()) {
        bif.note += (bif.note.empty() ? "" : "; ") + why;
      }
    }
  }
  bif.evaluations = count;
  if (!at) {
    bif.note += (bif.note.empty() ? "" : "; ") + std::string("not located (a corrector failed in the bracket)");
  } else {
    bif.p = std::isfinite(located_p_) ? located_p_ : at->e.p;
    bif.point = at->b;
    bif.smooth = located_smooth_;
    bif.p_low = bracket_low_;
    bif.p_high = bracket_high_;
    bif.value = located_smooth_ ? f(*at) : kNaN;
    if (!located_smooth_) bif.p = 0.5 * (bif.p_low + bif.p_high);
    last_located_ = *at;
  }
  result_.bifurcations.push_back(bif);
}

}  // namespace vibro::detail
