/// \file bifurcation_detection.cpp
/// What changed between two neighbouring branch points a → b, and how each change is located
/// (continuation.hpp lists the kinds):
///  * on a smooth stretch (same event signature): a fold where the tangent's p component
///    changes sign; a branch point where a real multiplier passes +1 while it does not; period
///    doubling and Neimark–Sacker where their test functions (test_functions.hpp) change sign —
///    each located by Illinois on the arclength;
///  * across a change of the event signature, per stop: a change in free impacts is a grazing
///    (located from the side without the impact, where the nearest approach is smooth in p), a
///    change in contact phases a rising if the force test function has opposite signs on the
///    two sides (else a phase change), a change in chatter sequences a chatter change; those
///    that are not smooth in p are bracketed by bisection on the signature.
/// After a change of signature, b's tangent is turned to point away from the point located
/// between a and b (at a corner both parts of the branch lie on the same side in p).
#include "branch_runner.hpp"

#include "test_functions.hpp"

#include <algorithm>
#include <cmath>

namespace vibro::detail {

bool BranchRunner::examine(const Node& a, Node& b, int branch_index, int depth,
                           std::vector<std::pair<Node, int>>* doublings, bool refuse_hidden_fold) {
  const std::size_t stops = a.b.signature.impacts.size();
  // Fold: the tangent's p component changes sign on a smooth stretch. Across a change of the
  // event signature a sign change is the corner where two branches meet (at a grazing the
  // branches with and without the impact reach it from the same side in p).
  const bool turns = a.t(a.t.size() - 1) * b.t(b.t.size() - 1) < 0.0;
  if (turns && a.b.signature == b.b.signature) {
    const TestFunction f = [](const Node& n) { return n.t(n.t.size() - 1); };
    record(BifurcationKind::fold, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
  }
  const FloquetMultipliers& ma = a.b.multipliers;
  const FloquetMultipliers& mb = b.b.multipliers;
  if (ma.structural_zeros == mb.structural_zeros && a.b.signature == b.b.signature) {
    // Period doubling and Neimark–Sacker need a smooth map between the points.
    if (doubling_test(ma) * doubling_test(mb) < 0.0) {
      const TestFunction f = [](const Node& n) { return doubling_test(n.b.multipliers); };
      record(BifurcationKind::period_doubling, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
      if (doublings && depth < o_.max_doublings && result_.bifurcations.back().smooth)
        doublings->push_back({last_located_, branch_index});
    }
    // A real multiplier through +1 without a fold: another branch crosses this one (the step
    // that crossed it was taken because its tangent kept pointing along the step's chord).
    if (!turns && BranchRunner::real_above_one(ma) % 2 != BranchRunner::real_above_one(mb) % 2 &&
        branch_point_test(ma) * branch_point_test(mb) < 0.0) {
      const TestFunction f = [](const Node& n) { return branch_point_test(n.b.multipliers); };
      record(BifurcationKind::branch_point, -1, a, b, branch_index, f, Mode::in_p, {}, "");
      // With a's tangent: at the branch point itself DF's null space is two-dimensional and the
      // tangent computed there is any vector of it; a's, one step away, is this branch's.
      if (branch_points && result_.bifurcations.back().smooth) {
        Node at = last_located_;
        at.t = a.t;
        branch_points->push_back({std::move(at), branch_index});
      }
    }
    if (torus_test(ma) * torus_test(mb) < 0.0) {
      const TestFunction f = [](const Node& n) { return torus_test(n.b.multipliers); };
      const std::size_t before = result_.bifurcations.size();
      record(BifurcationKind::neimark_sacker, -1, a, b, branch_index, f, Mode::two_sided, {}, "");
      if (result_.bifurcations.size() > before && !has_unit_pair(result_.bifurcations.back().point.multipliers, 1e-6))
        result_.bifurcations.pop_back();  // a neutral saddle (real μ_i μ_j = 1), not a torus
    }
  }
  const Signature& sa = a.b.signature;
  const Signature& sb = b.b.signature;
  if (sa == sb) return true;
  const std::size_t first_new = result_.bifurcations.size();
  bool explained = false;
  for (std::size_t j = 0; j < stops; ++j) {
    const int stop = static_cast<int>(j);
    if (sa.impacts[j] != sb.impacts[j] && sa.chatters[j] == sb.chatters[j] && sa.phases[j] == sb.phases[j]) {
      explained = true;
      const int fewer = std::min(sa.impacts[j], sb.impacts[j]), more = std::max(sa.impacts[j], sb.impacts[j]);
      const TestFunction f = [stops = c_.stops_, j, fewer, more](const Node& n) { return grazing_function(n, stops, j, fewer, more); };
      // Located from the side without the grazing impact, where the orbit's nearest approach
      // (its largest gap maximum) is smooth in p; the impacting side's map is not (its
      // Jacobian grows like 1/u as the impact speed u → 0).
      const auto fewer_side = [j, fewer](const Node& n) { return n.b.signature.impacts[j] == fewer; };
      const Node& good = fewer_side(a) ? a : b;
      const Node& other = fewer_side(a) ? b : a;
      const bool ok = std::isfinite(f(good)) && f(good) < 0.0;
      // Without a gap maximum there (a jump landed where the lost impact's flight has none), the
      // side with the impact, where the height its slowest impact would rise past the stop is
      // defined (> 0), locates it instead; failing that, it is bracketed by bisection.
      // (Only a solved location is kept from that side: one that ends bracketed is replaced by
      // the bisection between the two points.)
      const auto more_side = [j, more](const Node& n) { return n.b.signature.impacts[j] == more; };
      const bool ok_more = !ok && std::isfinite(f(other)) && f(other) > 0.0;
      if (ok) {
        record(BifurcationKind::grazing, stop, a, b, branch_index, f, Mode::one_sided, fewer_side, "");
        // Bracketed where the side without the impact ends: its f at `good` may be another
        // flight's gap maximum (nearer_feature); from an orbit of that side where f is the grazing
        // flight's own, the location is solved. Kept only if it is.
        if (o_.locate && !result_.bifurcations.back().smooth) {
          const Bifurcation first = result_.bifurcations.back();
          const Node first_at = last_located_;
          int count = 0;
          if (const std::optional<Node> near = nearer_feature(good, other, f, fewer_side, &count)) {
            result_.bifurcations.pop_back();
            record(BifurcationKind::grazing, stop, *near, other, branch_index, f, Mode::one_sided, fewer_side,
                   "the side without the impact first reached where its largest gap maximum is another flight's: "
                   "located from its orbits nearer to the grazing");
            result_.bifurcations.back().evaluations += first.evaluations + count;
            if (!result_.bifurcations.back().smooth) {
              result_.bifurcations.back() = first;
              result_.bifurcations.back().evaluations += count;
              last_located_ = first_at;
            }
          } else {
            result_.bifurcations.back().evaluations += count;
          }
        }
      } else {
        bool solved = false;
        if (ok_more) {
          record(BifurcationKind::grazing, stop, a, b, branch_index, f, Mode::one_sided, more_side,
                 "no gap maximum on the side without the impact: located from the side with it");
          solved = result_.bifurcations.back().smooth;
          if (!solved) result_.bifurcations.pop_back();
        }
        if (!solved)
          record(BifurcationKind::grazing, stop, a, b, branch_index, f, Mode::bisection, same_counts(sa, j, &Signature::impacts),
                 "no gap maximum on the side without the impact: bracketed by bisection");
      }
    }
    if (sa.phases[j] != sb.phases[j]) {
      explained = true;
      const int fewer = std::min(sa.phases[j], sb.phases[j]);
      const TestFunction f = [j, fewer](const Node& n) { return rising_function(n, j, fewer); };
      const auto fewer_side = [j, fewer](const Node& n) { return n.b.signature.phases[j] == fewer; };
      const Node& good = fewer_side(a) ? a : b;
      const Node& other = fewer_side(a) ? b : a;
      // Rising: on the unsplit side an interior force minimum falls to zero; on the split side
      // the held flow continued past the release needs a negative force. (The new part of the
      // split phase usually starts with a chatter, so the chatter count moves with it.)
      const bool rising = std::isfinite(f(good)) && f(good) > 0.0 && std::isfinite(f(other)) && f(other) < 0.0;
      // A frictional contact whose side with fewer switches is the sticking one: a reversal
      // (then a short slip and a stick) turned into a stick, located by the arrival's margin,
      // ≤ 0 at the stick of the fewer side, > 0 at the reversal of the other.
      const TestFunction g = [j, fewer](const Node& n) { return arrival_function(n, j, fewer); };
      const bool arrival = !rising && frictional(a, j) && frictional(b, j) && std::isfinite(g(good)) &&
                           g(good) < 0.0 && std::isfinite(g(other)) && g(other) > 0.0;
      const std::string how = sa.chatters[j] != sb.chatters[j] ? "entered by chatter" : "entered by an impact";
      if (arrival)
        record(BifurcationKind::rising, stop, a, b, branch_index, g, Mode::one_sided, fewer_side, "");
      else
        record(rising ? BifurcationKind::rising : BifurcationKind::phase_change, stop, a, b, branch_index, f,
               rising ? Mode::one_sided : Mode::bisection, rising ? fewer_side : same_counts(sa, j, &Signature::phases),
               rising ? "" : "a contact phase (" + how + ") appears or vanishes; not smooth in p (it depends on the chatter rule): bracketed by bisection");
    } else if (sa.chatters[j] != sb.chatters[j]) {
      explained = true;
      record(BifurcationKind::chatter_change, stop, a, b, branch_index, {}, Mode::bisection,
             same_counts(sa, j, &Signature::chatters), "not smooth in p: bracketed by bisection");
    }
  }
  if (!explained) {
    const Signature sig = sa;
    record(BifurcationKind::other, -1, a, b, branch_index, {}, Mode::bisection,
           [sig](const Node& n) { return n.b.signature == sig; }, "event signature changed: " + sa.text() + " → " + sb.text());
  }
  point_away(a, b, first_new);
  if (refuse_hidden_fold && fold_beside_grazing(a, b, first_new)) {
    result_.bifurcations.resize(first_new);
    return false;
  }
  if (a.t(a.t.size() - 1) * b.t(b.t.size() - 1) < 0.0)
    for (std::size_t i = first_new; i < result_.bifurcations.size(); ++i)
      result_.bifurcations[i].note += std::string(result_.bifurcations[i].note.empty() ? "" : "; ") +
                                      "the branch turns back in p here (a corner)";
  return true;
}

/// Whether the step a → b across a grazing (located smoothly, the last bifurcation recorded from
/// `first` on, its orbit last_located_) has passed a fold unseen: p is not monotone along either
/// part of the branch between its point and the grazing. Each part is compared in the direction
/// of travel (a's tangent; b's, turned away from the grazing by point_away), the tangents at the
/// grazing oriented by continuity: the part without the impact by its own tangent there, the part
/// with the impact by the tangent of the orbits with the impact at the grazing (corner_tangent,
/// pointing into that part). Where they disagree in the sign of their p component a fold lies
/// between (the clearance chain at Ω ≈ 0.34057: the orbits with three impacts turn at a fold
/// 1.1e-4 in Ω below the grazing that ends them, and one step of 0.02 passed both).
bool BranchRunner::fold_beside_grazing(const Node& a, const Node& b, std::size_t first) {
  if (result_.bifurcations.size() != first + 1) return false;
  const Bifurcation& g = result_.bifurcations.back();
  if (g.kind != BifurcationKind::grazing || !g.smooth || g.stop < 0) return false;
  const auto j = static_cast<std::size_t>(g.stop);
  const bool a_fewer = a.b.signature.impacts[j] < b.b.signature.impacts[j];
  const Node& fewer = a_fewer ? a : b;
  const Node& more = a_fewer ? b : a;
  const Index last = a.t.size() - 1;
  // The part without the impact: from its point to the grazing orbit (or back).
  const VectorXd at_grazing = c_.tangent(last_located_.e, fewer.t);
  if (fewer.t(last) * at_grazing(last) < 0.0) return true;
  // The part with the impact: leaving the grazing along the corner's tangent.
  const std::optional<std::pair<VectorXd, int>> corner = corner_tangent(last_located_);
  if (!corner || corner->second != g.stop) return false;
  const double leaving = corner->first(last);
  // b travels away from the grazing (as the corner's tangent points); a travels towards it.
  return a_fewer ? leaving * more.t(last) < 0.0 : leaving * more.t(last) > 0.0;
}

/// The part of the branch beyond a grazing or a rising leaves the non-smooth point: b's tangent
/// is turned to point away from the nearest of the points located between a and b (from
/// result_.bifurcations[first] on) by solving their condition. The orientation b had, along
/// the step in p, is right where the step crossed the point in p, but at a corner whose two
/// parts lie on the same side in p, a step that lands between a and the point in p turns b
/// back into it (the three-mass chain of experiments/examples at Ω ≈ 0.18063: the branch with
/// one impact of s3 fewer was followed down into the grazing until the steps gave out).
/// Unchanged where nothing was located smoothly (bisected changes, locate off), or where b
/// lies on the point (within 1e-3 of the step: the chord's direction is then rounding).
void BranchRunner::point_away(const Node& a, Node& b, std::size_t first) const {
  const VectorXd yb = c_.scaled(b.e);
  VectorXd chord;
  for (std::size_t i = first; i < result_.bifurcations.size(); ++i) {
    const Bifurcation& f = result_.bifurcations[i];
    if (!f.smooth) continue;
    const VectorXd from_point = yb - c_.scaled(f.point);
    if (chord.size() == 0 || from_point.norm() < chord.norm()) chord = from_point;
  }
  if (chord.size() == 0 || chord.norm() <= 1e-3 * (yb - c_.scaled(a.e)).norm()) return;
  if (b.t.dot(chord) < 0.0) {
    b.t = -b.t;
    b.b.tangent_p = b.t(b.t.size() - 1);
  }
}

std::function<bool(const Node&)> BranchRunner::same_counts(const Signature& s, std::size_t j,
                                                           std::vector<int> Signature::*field) {
  const int count = (s.*field)[j];
  return [count, j, field](const Node& n) { return (n.b.signature.*field)[j] == count; };
}

}  // namespace vibro::detail
