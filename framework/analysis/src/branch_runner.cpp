/// \file branch_runner.cpp
/// Following one branch by pseudo-arclength steps (Keller 1977): from the point y with unit
/// tangent t, the predictor y + h t, the corrector in the hyperplane through it normal to t
/// (corrector.hpp), the step h grown by 1.5 after ≤ 3 corrector iterations and cut by 0.6 after
/// ≥ 6, halved on failure, and halved too, down to a floor, while the step may have passed a change
/// of the orbit's events unseen (unseen_crossing). Around that loop the guards that keep it on this branch: a corrector
/// that travels further than the step, or a point nearer to an earlier point than to the last,
/// is refused; where the steps stall at a grazing or rising corner (the map's derivative blows up
/// on one side) the branch is continued by a jump in p with Newton at fixed p (shooting.hpp),
/// and a fold that a jump from a stable orbit passes beside a grazing is located on the side;
/// where an event drifts into the section, the section is moved into the longest event-free
/// stretch of the orbit and the tangent carried to it by the tangent map of the stretch.
#include "branch_runner.hpp"

#include "known_branches.hpp"
#include "section.hpp"
#include "test_functions.hpp"

#include <algorithm>
#include <cmath>
#include <complex>

namespace vibro::detail {

/// Follows the branch from `start` along `t` (unit, scaled), appending to `branch`.
void BranchRunner::follow(Node start, VectorXd t, Branch& branch, int branch_index, int depth,
                          std::vector<std::pair<Node, int>>* doublings) {
  Node cur = std::move(start);
  cur.t = c_.tangent(cur.e, t);
  double h = std::min(std::max(o_.step, o_.min_step), o_.max_step);
  double last_dp = h * c_.P;
  bool jump_tried = false, resection_tried = false;
  // A step that may pass a change of the orbit's events unseen (unseen_crossing) is accepted
  // only once it is this short.
  const double crossing_step = std::max(o_.min_step, 1e-4 * o_.max_step);
  behind_ = undo_ = Signature{};
  behind_at_ = 0;
  std::vector<VectorXd> trail{c_.scaled(cur.e)};  // the points of this half, scaled
  while (static_cast<int>(branch.points.size()) < o_.max_points) {
    int iterations = 0;
    Node next;
    bool stepped = true;  // next is the corrector's (not a jump's)
    const VectorXd y_pred = c_.scaled(cur.e) + h * cur.t;
    next.e = c_.correct(y_pred, cur.t, &iterations);
    // A corrector that travels further than the step has found another branch crossing the
    // hyperplane (near corners and folds): not the continuation of this one.
    if (next.e.ok && (c_.scaled(next.e) - y_pred).norm() > h) {
      next.e.ok = false;
      next.e.why = "the corrector left the predictor by more than the step";
    }
    // A step back onto the events before the last multiple change crossed is the way the branch
    // came (past a contact phase that vanishes, a step may turn back across it): not taken.
    if (next.e.ok && !(behind_ == cur.b.signature) && orbit_signature(next.e.map, c_.k, c_.stops_) == behind_ &&
        back_to_change(trail, c_.scaled(next.e))) {
      next.e.ok = false;
      next.e.why = "the step lands back on the events before the change just crossed";
    }
    // Likewise the first step past a single change: straight back onto the events before it is
    // back across the same grazing or rising (at a corner the part already followed lies on the
    // same side in p, beside the new one, and a corrector drawn by its steep map lands there).
    if (next.e.ok && !(undo_ == cur.b.signature) && orbit_signature(next.e.map, c_.k, c_.stops_) == undo_) {
      next.e.ok = false;
      next.e.why = "the step lands back across the change just crossed";
    }
    if (!next.e.ok) {
      h *= 0.5;
      // Across a grazing or a rising the branch has a corner and the map's derivative blows up
      // on one side: arclength steps shrink towards it. Past a few halvings near such a point,
      // step over it in p (the orbit on the far side is found by Newton at fixed p).
      // An event drifting into the section faster than the margin allows makes the map jump
      // within the step: move the section further from it (once per stall) and go on.
      // Near a grazing or a rising the jump comes first (it keeps the section, and with it the
      // guard against landing back on the branch); once it has failed, or landed on the part
      // already followed, an event on the section is the cause left. (The three-mass chain of
      // experiments/examples at Ω ≈ 0.18446: an impact of s3 reaches the section on the
      // unstable side of a fold, where every orbit found at fixed p is the stable one; and
      // near_nonsmooth holds all along that branch, whose chatter bounces are slow.)
      const bool on_event =
          detail::section_clearance(cur.e.map) < kSectionOnEvent * kTwoPi / cur.e.omega;
      if (h < 1e-2 * o_.max_step && !resection_tried && (!near_nonsmooth(cur) || (jump_tried && on_event))) {
        resection_tried = true;
        const double old_theta = c_.theta;
        if (std::optional<Node> moved = resection(cur, kSectionMargin)) {
          cur = std::move(*moved);
          carry(trail, old_theta);
          behind_at_ = std::min(behind_at_, trail.size() - 1);
          trail.push_back(c_.scaled(cur.e));
          continue;
        }
      }
      std::optional<Node> jumped;
      if (h < 1e-3 * o_.max_step && !jump_tried && near_nonsmooth(cur)) {
        jump_tried = true;
        jumped = jump(cur, last_dp, trail);
        // Against a grazing with no orbit found at fixed p: along the branch of orbits with the
        // new impact, from the corner (grazing_corner.cpp).
        if (!jumped) jumped = corner(cur);
        // A jump that lands beyond more than one change of events is brought back to the
        // first, so that it passes no further change (nor the folds beside them) unseen.
        else if (!single_change(cur.b.signature, jumped->b.signature))
          jumped = nearest_across(cur, std::move(*jumped), crossing_step * c_.P);
      }
      // Before the branch is given up at a grazing, the corner's steps once more from predictors
      // lifted onto the impacting side (grazing_corner.cpp): where the part with the impact leaves
      // the corner at a small angle to the part followed, the steps along the tangent land on the
      // latter. (Only here, at the end: elsewhere the branch goes on as the steps above find it.)
      if (!jumped && h < o_.min_step && near_nonsmooth(cur)) jumped = corner(cur, true);
      if (!jumped) {
        if (h < o_.min_step) {
          branch.end = "step below min_step at p = " + number_text(cur.e.p) + " (" + next.e.why + ")";
          if (near_nonsmooth(cur)) locate_at_end(cur, last_dp, branch_index);
          return;
        }
        continue;
      }
      next = std::move(*jumped);
      stepped = false;
      h = std::clamp(std::abs(next.e.p - cur.e.p) / c_.P, o_.min_step, o_.max_step);
    } else {
      // Oriented along cur's tangent on a smooth stretch; where the step crossed a grazing or
      // a rising (the events changed) the branch may turn back in p at the corner: for now
      // along the step in p, and examine() turns it away from the point it locates there.
      next.b = c_.point(next.e, cur.t, iterations);
      // With the same events and without a fold (the tangent, oriented along cur's, keeps the
      // sign of its p component) a real multiplier crosses +1 only at a branch point, where
      // another branch crosses this one and this one goes straight on: the new point's tangent
      // then points along the step's chord. A step that changes how many lie above +1 and whose
      // tangent points back along the chord has gone round a fold onto the part of the branch
      // already followed (its orientation along cur's is the reverse of the way the branch
      // runs there; where a fold and a grazing are too close for the steps to see the part
      // between them).
      const auto went_round = [&] {
        const VectorXd tn = c_.tangent(next.e, cur.t);
        return tn(tn.size() - 1) * cur.t(cur.t.size() - 1) > 0.0 &&
               tn.dot(c_.scaled(next.e) - c_.scaled(cur.e)) <= 0.0;
      };
      if (next.b.signature == cur.b.signature && real_above_one(next.b.multipliers) % 2 != real_above_one(cur.b.multipliers) % 2 &&
          went_round()) {
        next.e.ok = false;
        next.e.why = "the step went round a fold it did not see";
        h *= 0.5;
        if (h < o_.min_step) {
          branch.end = "step below min_step at p = " + number_text(cur.e.p) + " (" + next.e.why + ")";
          return;
        }
        continue;
      }
      // A step that may have passed changes of the orbit's events unseen (several at once, or
      // a fold beside a grazing) is cut back until it is short.
      if (h > crossing_step && !unseen_crossing(cur.b, next.b).empty()) {
        h *= 0.5;
        continue;
      }
      VectorXd along = cur.t;
      if (!(next.b.signature == cur.b.signature)) {
        along.setZero();
        along(along.size() - 1) = next.e.p > cur.e.p ? 1.0 : -1.0;
      }
      next.t = c_.tangent(next.e, along);
      next.b.tangent_p = next.t(next.t.size() - 1);
    }
    // Near a fold beside a corner the two parts of the branch come close: a step (or a jump)
    // that lands back on a part already followed is not the continuation. Refused if the new
    // point is nearer to an earlier point than to the last one.
    // (The last few points are left out: at a sharp corner the new part starts beside them.)
    if (lands_back(trail, c_.scaled(next.e))) {
      h *= 0.5;
      if (h < o_.min_step) {
        branch.end = "step below min_step at p = " + number_text(cur.e.p) + " (steps land on the branch already followed)";
        return;
      }
      continue;
    }
    // A doubled branch that closes after half its period has merged back into its parent
    // (at a period doubling of the parent: doubled branches often join two of them).
    if (c_.k > o_.period && c_.closes_after(next.e, c_.k / 2)) {
      branch.end = "merged into the period-" + std::to_string(c_.k / 2) + "T branch near p = " + number_text(next.e.p);
      return;
    }
    // A switched branch that reaches the orbits of a branch already followed, or its own orbits
    // shifted by some periods (it has come round through a doubling of its parent), is that
    // branch from here on: it ends there (known_branches.hpp).
    if (branch_index > 0)
      if (const std::optional<KnownMatch> m = on_known_branch(c_, next, &branch, branch_index)) {
        branch.joins = m->branch;
        branch.end = m->branch == branch_index
                         ? "closes on itself near p = " + number_text(next.e.p) + " (its own orbits shifted by " +
                               std::to_string(m->shift) + " periods)"
                         : "joins branch " + std::to_string(m->branch) + " (already followed) near p = " + number_text(next.e.p);
        return;
      }
    // Leaving the scan limits: place the last point on the limit.
    const bool out = next.e.p < o_.p_min || next.e.p > o_.p_max;
    if (out) {
      const double limit = next.e.p > o_.p_max ? o_.p_max : o_.p_min;
      if (auto last = on_limit(cur, next, limit)) {
        examine(cur, *last, branch_index, depth, doublings);
        append(branch, *last);
      }
      branch.end = std::string("reached p_") + (limit == o_.p_max ? "max" : "min") + " = " + number_text(limit);
      return;
    }
    // A step across a grazing that passed a fold beside it unseen is cut like the steps above
    // (examine() removes what it recorded for it).
    if (!examine(cur, next, branch_index, depth, doublings, stepped && h > crossing_step)) {
      h *= 0.5;
      continue;
    }
    // A jump, or a step at the floor, from a stable orbit across the grazing of one of its own
    // impacts has passed the fold (or doubling) between them (unseen_crossing): it is located
    // on the impacting orbits by short steps from cur (fold_before_grazing).
    if ((!stepped || h <= crossing_step) && cur.b.multipliers.stable && loses_impact(cur.b.signature, next.b.signature))
      fold_before_grazing(cur, h, branch_index);
    append(branch, next);
    last_dp = std::max(std::abs(next.e.p - cur.e.p), 1e-9 * c_.P);
    trail.push_back(c_.scaled(next.e));
    // Past a multiple change (a contact phase vanishing, its bounces turned free), no step or
    // jump goes back to the events before it. (A single change may be undone further on: an
    // impact lost at one grazing and regained at the next.)
    if (!single_change(cur.b.signature, next.b.signature)) {
      behind_ = cur.b.signature;
      behind_at_ = trail.size() - 2;  // cur's place in the trail
    }
    undo_ = next.b.signature == cur.b.signature ? Signature{} : cur.b.signature;
    cur = std::move(next);
    jump_tried = resection_tried = false;
    if (iterations <= 3) h = std::min(1.5 * h, o_.max_step);
    else if (iterations >= 6) h = std::max(0.6 * h, o_.min_step);
  }
  branch.end = "max_points (" + std::to_string(o_.max_points) + ") reached";
}

/// The fold (or period doubling) that lies on the impacting orbits between a stable orbit cur
/// and the grazing that ends one of its impacts, where the branch has passed it by a jump or a
/// step at the floor: corrector steps from cur along its tangent, h halved where one fails or
/// where the orbit loses the impact, until the tangent's p component or the doubling test
/// changes sign; the bifurcation is then located between the two last orbits (record). These
/// orbits are not added to the branch. Nothing is recorded if the steps give out (below
/// min_step, or 80 correctors) first.
void BranchRunner::fold_before_grazing(const Node& cur, double h, int branch_index) {
  if (!o_.locate) return;
  const Index last = cur.t.size() - 1;
  const Node saved = last_located_;
  Node a = cur;
  h = std::max(h, o_.min_step);
  for (int evaluations = 0; evaluations < 80; ++evaluations) {
    const VectorXd y_pred = c_.scaled(a.e) + h * a.t;
    int iterations = 0;
    Node b;
    b.e = c_.correct(y_pred, a.t, &iterations);
    bool ok = b.e.ok && (c_.scaled(b.e) - y_pred).norm() <= h;
    if (ok) {
      b.b = c_.point(b.e, a.t, iterations);
      ok = b.b.signature == a.b.signature;
    }
    if (!ok) {
      h *= 0.5;
      if (h < o_.min_step) break;
      continue;
    }
    b.t = c_.tangent(b.e, a.t);
    b.b.tangent_p = b.t(last);
    const std::string note = "on the impacting orbits the branch passes by a jump across the grazing beside it (located by steps not kept with the branch)";
    if (a.t(last) * b.t(last) < 0.0) {
      const TestFunction f = [](const Node& n) { return n.t(n.t.size() - 1); };
      record(BifurcationKind::fold, -1, a, b, branch_index, f, Mode::two_sided, {}, note);
      break;
    }
    if (doubling_test(a.b.multipliers) * doubling_test(b.b.multipliers) < 0.0) {
      const TestFunction f = [](const Node& n) { return doubling_test(n.b.multipliers); };
      record(BifurcationKind::period_doubling, -1, a, b, branch_index, f, Mode::two_sided, {}, note);
      break;
    }
    a = std::move(b);
    if (iterations <= 3) h = std::min(1.5 * h, o_.max_step);
  }
  last_located_ = saved;
}

/// How many of the multipliers are real and above +1 (a fold changes it by one).
int BranchRunner::real_above_one(const FloquetMultipliers& m) {
  int count = 0;
  for (const std::complex<double>& mu : m.values)
    count += std::abs(mu.imag()) <= 1e-12 * std::abs(mu) && mu.real() > 1.0;
  return count;
}

/// Whether b's events differ from a's by one change at one stop at most: an impact more or
/// fewer (a grazing), or a contact phase more or fewer with its chatter (a rising, a phase
/// entered by chatter appearing or vanishing) and no impact count changed.
bool BranchRunner::single_change(const Signature& a, const Signature& b) {
  if (a.k != b.k || a.impacts.size() != b.impacts.size()) return false;
  int changed = 0;
  for (std::size_t j = 0; j < a.impacts.size(); ++j) {
    const int di = std::abs(a.impacts[j] - b.impacts[j]), dc = std::abs(a.chatters[j] - b.chatters[j]),
              dh = std::abs(a.phases[j] - b.phases[j]);
    if (di == 0 && dc == 0 && dh == 0) continue;
    ++changed;
    const bool grazing = di == 1 && dc == 0 && dh == 0;
    const bool phase = di == 0 && dc <= 1 && dh == 1;
    if (!grazing && !phase) return false;
  }
  return changed <= 1;
}

/// Whether b's events are a's with one impact fewer at one stop (a grazing that ends a's impact).
bool BranchRunner::loses_impact(const Signature& a, const Signature& b) {
  if (!single_change(a, b)) return false;
  for (std::size_t j = 0; j < a.impacts.size(); ++j)
    if (a.impacts[j] == b.impacts[j] + 1 && a.phases[j] == b.phases[j] && a.chatters[j] == b.chatters[j]) return true;
  return false;
}

/// Why a step from a to b may have passed a change of the orbit's events unseen (empty: it
/// cannot have):
///  * the events differ by more than one change (single_change): a long step may cross a
///    cascade of changes (the bounces a vanishing contact phase leaves, lost one by one) and
///    the folds between them;
///  * the events differ by one impact of a stop (a grazing) and the orbit with the impact is
///    stable. Near a grazing the map with the impact has a derivative that grows like 1/u, u the
///    impact's speed (Nordmark 1991; grazing_corner.cpp): along the impacting branch a
///    multiplier leaves the unit circle on the way to the grazing, through +1 (a fold) or −1 (a
///    period doubling). A stable impacting point next to the orbit without the impact has that
///    bifurcation between it and the grazing, not yet passed.
std::string BranchRunner::unseen_crossing(const BranchPoint& a, const BranchPoint& b) {
  const Signature& sa = a.signature;
  const Signature& sb = b.signature;
  if (sa == sb) return {};
  if (!single_change(sa, sb)) return "more than one change of events";
  for (std::size_t j = 0; j < sa.impacts.size(); ++j) {
    if (sa.impacts[j] == sb.impacts[j] || sa.phases[j] != sb.phases[j] || sa.chatters[j] != sb.chatters[j]) continue;
    const BranchPoint& impacting = sa.impacts[j] > sb.impacts[j] ? a : b;
    if (impacting.multipliers.stable) return "a grazing next to a stable impacting orbit";
  }
  return {};
}

/// An orbit near a grazing (an impact slower than 1e-3 V, or a gap maximum within 1e-3 L of
/// its stop) or a rising (an interior contact-force minimum within 1e-3 F of zero).
bool BranchRunner::near_nonsmooth(const Node& n) {
  const TangentMap& m = n.e.map;
  const double L = m.summary.length_scale, F = m.summary.force_scale;
  if (m.least_guard_rate < 1e-3) return true;
  for (const GapPeak& g : m.gap_peaks)
    if (g.value > -1e-3 * L) return true;
  for (const ForceDip& d : m.force_dips)
    if (!d.past_release && d.value < 1e-3 * F) return true;
  return false;
}

/// Whether y (scaled), an orbit with the events before the last multiple change, lies at that
/// change: nearer to the last point before it than to every point followed since. (Further on
/// the branch may meet the same events again, at another change: a cascade of bounces lost one
/// by one after a contact phase vanished, gained back one by one until chatter holds again.)
bool BranchRunner::back_to_change(const std::vector<VectorXd>& trail, const VectorXd& y) const {
  if (behind_at_ >= trail.size()) return true;
  const double to_change = (y - trail[behind_at_]).norm();
  for (std::size_t i = behind_at_ + 1; i < trail.size(); ++i)
    if ((y - trail[i]).norm() <= to_change) return false;
  return true;
}

/// Whether y (scaled) is nearer to an earlier point of the trail than a quarter of its distance
/// from the last one (the last four points left out: at a sharp corner the new part of the
/// branch starts beside them): a point on the part of the branch already followed.
bool BranchRunner::lands_back(const std::vector<VectorXd>& trail, const VectorXd& y) {
  if (trail.size() < 5) return false;
  const double from_cur = (y - trail.back()).norm();
  for (std::size_t i = 0; i + 4 < trail.size(); ++i)
    if ((y - trail[i]).norm() < 0.25 * from_cur) return true;
  return false;
}

/// The orbit a little further in p, by Newton at fixed p from cur's state: steps of 4, 8, 16 …
/// times the last step in p, up to 2 % of the parameter scale, first onwards; then backwards,
/// where only an orbit with other events counts (at a grazing corner the branch beyond the
/// non-smooth point turns back in p; an orbit with cur's events there is the way we came).
/// A doubled branch accepts no orbit that closes after half its period (its parent's).
std::optional<Node> BranchRunner::jump(const Node& cur, double last_dp, const std::vector<VectorXd>& trail) {
  const double dir = cur.t(cur.t.size() - 1);
  if (std::abs(dir) < 1e-6) return std::nullopt;  // at a fold p cannot be stepped
  for (const double sign : {1.0, -1.0}) {
    for (double dp = 4.0 * last_dp; dp <= 0.02 * c_.P; dp *= 2.0) {
      const double p = cur.e.p + sign * (dir > 0.0 ? dp : -dp);
      // The far side's tangent points away from the non-smooth point: along the jump in p.
      VectorXd away = VectorXd::Zero(cur.t.size());
      away(away.size() - 1) = p > cur.e.p ? 1.0 : -1.0;
      std::optional<Node> m = shoot_at(cur, p, away);
      if (!m) continue;
      if (sign < 0.0 && m->b.signature == cur.b.signature) continue;
      // Onwards, the same events with another count of real multipliers above +1: the other
      // side of a fold just passed (the part already followed), not the continuation; the
      // branch goes on backwards, with other events (past the fold, to a grazing corner).
      if (m->b.signature == cur.b.signature && real_above_one(m->b.multipliers) % 2 != real_above_one(cur.b.multipliers) % 2)
        break;
      if (m->b.signature == behind_ && !(behind_ == cur.b.signature) && back_to_change(trail, c_.scaled(m->e))) continue;
      if (m->b.signature == undo_ && !(undo_ == cur.b.signature)) continue;
      if (c_.k > o_.period && c_.closes_after(m->e, c_.k / 2)) continue;
      // An orbit on the part of the branch already followed is not the way on: look further.
      if (lands_back(trail, c_.scaled(m->e))) continue;
      return m;
    }
  }
  return std::nullopt;
}

/// The orbit beyond the change of events between cur and `far` nearest in p to cur, to `width`
/// in p: a bisection in p between the two, each point by Newton at fixed p from cur's orbit
/// (past a contact phase that vanishes, cur's orbit runs on into the orbit that starts the far
/// side) or failing that from the far end's; a point with cur's events, or none, moves the near
/// end. Each orbit is oriented along the jump in p (away from cur).
std::optional<Node> BranchRunner::nearest_across(const Node& cur, Node far, double width) {
  double near_p = cur.e.p;
  VectorXd away = VectorXd::Zero(cur.t.size());
  away(away.size() - 1) = far.e.p > cur.e.p ? 1.0 : -1.0;
  const bool doubled = c_.k > o_.period;
  const auto beyond = [&](const std::optional<Node>& m) {
    return m && !(m->b.signature == cur.b.signature) && !(m->b.signature == behind_) && !(doubled && c_.closes_after(m->e, c_.k / 2));
  };
  for (int it = 0; it < 60 && std::abs(far.e.p - near_p) > width; ++it) {
    const double p = 0.5 * (near_p + far.e.p);
    std::optional<Node> m = shoot_at(cur, p, away);
    if (!beyond(m)) m = shoot_at(far, p, away);
    if (beyond(m))
      far = std::move(*m);
    else
      near_p = p;
  }
  return far;
}

/// The orbit at p by Newton shooting with its trust region (shooting.hpp) from `from`'s state:
/// more patient than the corrector where the map is steep on one side (near grazing).
std::optional<Node> BranchRunner::shoot_at(const Node& from, double p, const VectorXd& along) {
  ShootingOptions so;
  so.period = c_.k;
  so.phase = c_.theta;
  so.free_section = false;
  so.tolerance = o_.tolerance;
  so.solver = o_.solver;
  const Index n = c_.n_;
  ShootingResult r;
  try {
    r = c_.engine_at(p).shoot(so, from.e.t0, from.e.z.head(n), from.e.z.tail(n));
  } catch (const InvalidInput&) {
    return std::nullopt;
  }
  if (!r.converged()) return std::nullopt;
  Node m;
  m.e = c_.evaluate(stacked(r.x, r.v), p);
  if (!m.e.ok) return std::nullopt;
  m.t = c_.tangent(m.e, along);
  m.b = c_.point(m.e, m.t, r.iterations);
  return m;
}

/// Where a branch cannot be continued past a grazing or a rising (its steps shrink to nothing
/// against the non-smooth point), the point is still located, from this side: the orbit's
/// nearest approach to a stop (or its least interior contact force) extrapolated to zero.
void BranchRunner::locate_at_end(const Node& cur, double last_dp, int branch_index) {
  const TangentMap& m = cur.e.map;
  const double L = m.summary.length_scale, F = m.summary.force_scale;
  int graze = -1, rise = -1;
  double best_gap = -1e-3 * L, best_force = 1e-3 * F;
  for (const GapPeak& g : m.gap_peaks)
    if (g.value > best_gap) best_gap = g.value, graze = g.stop;
  for (const ForceDip& d : m.force_dips)
    if (!d.past_release && d.value < best_force) best_force = d.value, rise = d.stop;
  const double dir = cur.t(cur.t.size() - 1) > 0.0 ? 1.0 : -1.0;
  Node beyond = cur;
  beyond.e.p = cur.e.p + dir * std::max(last_dp, 1e-9 * c_.P);
  const std::string note = "the branch could not be continued past it; located from this side";
  if (graze >= 0) {
    const auto j = static_cast<std::size_t>(graze);
    const int fewer = cur.b.signature.impacts[j];
    const TestFunction f = [stops = c_.stops_, j, fewer](const Node& n) { return grazing_function(n, stops, j, fewer, fewer + 1); };
    record(BifurcationKind::grazing, graze, cur, beyond, branch_index, f, Mode::one_sided,
           same_counts(cur.b.signature, j, &Signature::impacts), note);
  }
  if (rise >= 0) {
    const auto j = static_cast<std::size_t>(rise);
    const int fewer = cur.b.signature.phases[j];
    const TestFunction f = [j, fewer](const Node& n) { return rising_function(n, j, fewer); };
    record(BifurcationKind::rising, rise, cur, beyond, branch_index, f, Mode::one_sided,
           same_counts(cur.b.signature, j, &Signature::phases), note);
  }
}

/// The branch's section moved into the middle of the longest stretch of cur's orbit free of
/// events and held phases, if an event has come within margin·T of it (events drift with p; an
/// impact crossing the section makes the map over kT jump, and a section on a held stop is not
/// free). The state there is cur's orbit at the new time; the tangent is carried to it by the
/// tangent map of the stretch between and the section's own motion with Ω, so the orientation
/// along the branch survives a move at a fold. nullopt (the section unchanged) when no move is
/// needed or none is better.
std::optional<Node> BranchRunner::resection(const Node& cur, double margin) {
  const TangentMap& g = cur.e.map;
  const double T = kTwoPi / cur.e.omega, clearance = detail::section_clearance(g);
  if (clearance >= margin * T) return std::nullopt;
  const auto [mid, half] = detail::free_section(g);
  if (half <= clearance || mid <= cur.e.t0) return std::nullopt;
  const Index n = c_.n_, N = 2 * n;
  FamilyEngine& engine = c_.engine_at(cur.e.p);
  LinearisationOptions lo;
  lo.parameter = engine.derivative;
  const TangentMap m = engine.linearise(cur.e.t0, cur.e.z.head(n), cur.e.z.tail(n), mid, lo);
  ++result_.maps;
  if (m.summary.status != RunStatus::completed) return std::nullopt;
  // z'(p) = φ(t'(p); t0(p), z(p), p) with t0 = θ/Ω and t' = θ'/Ω (θ' = Ω·mid, unwrapped).
  // (`engine` is not used after the corrector below, which may replace it.)
  const double w = cur.e.omega, dw = engine.derivative.frequency, theta_mid = w * mid;
  const double dt0 = -c_.theta / (w * w) * dw, dt1 = -theta_mid / (w * w) * dw;
  const VectorXd Pp = m.parameter + m.rate_end * dt1 - m.jacobian * (m.rate_start * dt0);
  const VectorXd d = c_.D();
  VectorXd along(N + 1);
  along.head(N) = (m.jacobian * d.cwiseProduct(cur.t.head(N)) + Pp * (c_.P * cur.t(N))).cwiseQuotient(d);
  along(N) = cur.t(N);
  along.normalize();
  const double old_theta = c_.theta;
  c_.theta = std::fmod(theta_mid, kTwoPi);
  VectorXd y(N + 1);
  y << stacked(m.x1, m.v1).cwiseQuotient(d), cur.e.p / c_.P;
  Node moved;
  int iterations = 0;
  moved.e = c_.correct(y, along, &iterations);  // a polish: it starts on the orbit
  if (!moved.e.ok || std::abs(moved.e.p - cur.e.p) > 1e-6 * c_.P) {
    c_.theta = old_theta;
    return std::nullopt;
  }
  moved.t = c_.tangent(moved.e, along);
  moved.b = c_.point(moved.e, moved.t, iterations);
  return moved;
}

/// The trail's points (scaled, at the section phase old_theta) carried to the branch's section
/// now, each by a run of its own orbit from the old section time to the new one, so that the
/// guard against steps landing back on the branch still sees the part followed before a move
/// (reset instead, it let a jump from the unstable side of a fold land on the stable side
/// already followed and retrace it). The last point (cur, in the old section) is dropped: the
/// caller appends its moved state. A point whose run fails is dropped too.
void BranchRunner::carry(std::vector<VectorXd>& trail, double old_theta) const {
  const Index n = c_.n_, N = 2 * n;
  const VectorXd d = c_.D();
  double turn = std::fmod(c_.theta - old_theta, kTwoPi);
  if (turn < 0.0) turn += kTwoPi;
  std::vector<VectorXd> carried;
  for (std::size_t i = 0; i + 1 < trail.size(); ++i) {
    const double p = trail[i](N) * c_.P;
    FamilyEngine& engine = c_.engine_at(p);
    const double w = engine.frequency();
    const VectorXd z = trail[i].head(N).cwiseProduct(d);
    RunSummary r;
    try {
      r = engine.run(old_theta / w, z.head(n), z.tail(n), (old_theta + turn) / w);
    } catch (const InvalidInput&) {
      continue;
    }
    if (r.status != RunStatus::completed) continue;
    VectorXd y(N + 1);
    y << stacked(r.x, r.v).cwiseQuotient(d), trail[i](N);
    carried.push_back(std::move(y));
  }
  trail = std::move(carried);
}

void BranchRunner::append(Branch& branch, const Node& n) {
  branch.points.push_back(n.b);
  if (progress_) progress_(branch, n.b);
}

}  // namespace vibro::detail
