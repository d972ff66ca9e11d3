/// \file branch_switching.cpp
/// Branch switching at a period doubling (at a branch point: switch_at_branch_points, below). At the located point the period-k map has a
/// multiplier μ = −1 with eigenvector e; the period-2k branch leaves it along e with p
/// stationary (p − p* ~ a², a the amplitude along e; a pitchfork of the 2k-map), while the old
/// branch, also 2k-periodic, crosses the same hyperplanes at p − p* ~ h. So the first point of
/// the new branch is the 2k corrector's from p* + h e in the hyperplane normal to e, for
/// h = 1e-2, 3e-3, … 3e-5 until it lands on an orbit whose k-map does not close (not the old
/// branch); the new branch is then followed from there like any other (branch_runner.hpp).
/// Only this one direction is followed: the other, along −e, gives the same orbits shifted by k
/// periods (one branch). A first point whose orbit lies on a branch already followed
/// (known_branches.hpp: a doubled branch often joins two doublings of its parent, and is met
/// again from the second) is recorded as recognised and not followed. The run's budget
/// (max_branches, max_total_points) ends the switching, and says so in ContinuationResult::budget.
#include "branch_switching.hpp"

#include "known_branches.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

namespace vibro::detail {

namespace {

long total_points(const ContinuationResult& result) {
  long total = 0;
  for (const Branch& b : result.branches) total += static_cast<long>(b.points.size());
  return total;
}

/// Whether the run's budget leaves room for another branch; if not, says so in result.budget
/// (`left` switches of `what` not made) and returns false.
bool budget_left(const ContinuationOptions& options, ContinuationResult& result, std::size_t left, const char* what) {
  if (static_cast<int>(result.branches.size()) < options.max_branches && total_points(result) + 2 <= options.max_total_points)
    return true;
  const bool branches = static_cast<int>(result.branches.size()) >= options.max_branches;
  const std::string reached = branches ? "max_branches (" + std::to_string(options.max_branches) + ") reached"
                                       : "max_total_points (" + std::to_string(options.max_total_points) + ") reached";
  if (result.budget.empty()) result.budget = reached;
  result.budget += ": " + std::to_string(left) + " " + what + (left == 1 ? "" : "s") + " not switched at";
  return false;
}

/// The bifurcation of `kind` recorded on branch `parent` at the located point `at` (its index),
/// or -1.
int recorded_at(const ContinuationResult& result, BifurcationKind kind, int parent, const Node& at) {
  int from = -1;
  for (std::size_t b = 0; b < result.bifurcations.size(); ++b)
    if (result.bifurcations[b].kind == kind && result.bifurcations[b].branch == parent &&
        result.bifurcations[b].point.p == at.b.p && result.bifurcations[b].point.t0 == at.b.t0)
      from = static_cast<int>(b);
  return from;
}

/// The depth in period doublings of a branch of period k (ContinuationOptions::max_doublings).
int doubling_depth(int k, int period) {
  return static_cast<int>(std::lround(std::log2(static_cast<double>(k) / period)));
}

/// Follows a switched branch b (its start point appended) from its first point, and appends it
/// to result.branches, noting where the run's budget of points cut it short. `o`: the options
/// the runner holds (their max_points the budget left).
void follow_switched(BranchRunner& runner, const Node& first, Branch b, int index, int depth,
                     const ContinuationOptions& options, const ContinuationOptions& o, SwitchPoints& doublings,
                     ContinuationResult& result) {
  runner.append(b, first);
  runner.follow(first, first.t, b, index, depth, depth < options.max_doublings ? &doublings : nullptr);
  if (o.max_points < options.max_points && static_cast<int>(b.points.size()) >= o.max_points) {
    b.end = "max_total_points (" + std::to_string(options.max_total_points) + ") reached: the run's budget of points";
    result.budget = "max_total_points (" + std::to_string(options.max_total_points) + ") reached (branch " +
                    std::to_string(index) + " cut short)";
  }
  result.branches.push_back(std::move(b));
}

}  // namespace

void switch_at_doublings(const ContinuationFamily& family, const ContinuationOptions& options, Continuer& c,
                         SwitchPoints& doublings, std::size_t first, SwitchPoints& branch_points,
                         ContinuationResult& result, const ContinuationProgress& progress) {
  const Index n = c.n_;
  const std::size_t stops = c.stops_;
  for (std::size_t i = first; i < doublings.size(); ++i) {
    const auto [at, parent] = doublings[i];
    const long used = total_points(result);
    if (!budget_left(options, result, doublings.size() - i, "period doubling")) return;
    // The period doubling it comes from: the located point recorded on the parent.
    const int from = recorded_at(result, BifurcationKind::period_doubling, parent, at);
    const TangentMap& m = at.e.map;
    Eigen::EigenSolver<MatrixXd> es(m.reduced);
    Index best = -1;
    for (Index j = 0; j < es.eigenvalues().size(); ++j)
      if (best < 0 || std::abs(es.eigenvalues()(j) + 1.0) < std::abs(es.eigenvalues()(best) + 1.0)) best = j;
    if (best < 0) continue;
    const VectorXd e = m.lift * es.eigenvectors().col(best).real();
    const int depth = static_cast<int>(std::log2(static_cast<double>(result.branches[static_cast<std::size_t>(parent)].k) /
                                                 options.period)) + 1;
    // The points budget bounds the new branch too (options' copy, which child and runner keep).
    ContinuationOptions o = options;
    o.max_points = static_cast<int>(std::min<long>(options.max_points, options.max_total_points - used));
    Continuer child(family, o, n, stops, result);
    child.theta = at.b.phase;  // the section where the doubling was found
    child.k = 2 * result.branches[static_cast<std::size_t>(parent)].k;
    child.L = c.L;
    child.V = c.V;
    child.P = c.P;
    BranchRunner child_runner(child, o, result, progress);
    child_runner.branch_points = &branch_points;
    Node s;
    s.e = child.evaluate(at.e.z, at.e.p);
    if (!s.e.ok) continue;
    VectorXd dir = VectorXd::Zero(2 * n + 1);
    dir.head(2 * n) = e.cwiseQuotient(child.D());
    dir.normalize();
    s.t = dir;
    s.b = child.point(s.e, dir, 0);
    s.b.located = true;
    // The doubled branch leaves the PD point along the eigenvector with p stationary
    // (p − p* ~ a², a the amplitude along e), while the old branch — also 2k-periodic — crosses
    // the same hyperplanes at p − p* ~ h: with h small enough the corrector lands on the new
    // branch. A point whose k-map already closes is the old one: retry with a smaller step.
    const int parent_k = result.branches[static_cast<std::size_t>(parent)].k;
    std::optional<Node> first;
    for (double h : {1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5}) {
      Node m;
      m.e = child.correct(child.scaled(s.e) + h * dir, dir);
      if (!m.e.ok) continue;
      if (c.closes_after(m.e, parent_k)) continue;
      m.t = child.tangent(m.e, dir);
      m.b = child.point(m.e, m.t, 0);
      first = std::move(m);
      break;
    }
    const int index = static_cast<int>(result.branches.size());
    if (first)
      if (const std::optional<KnownMatch> known = on_known_branch(child, *first, nullptr, index)) {
        result.recognised.push_back({parent, from, child.k, first->e.p, known->branch, known->shift, known->distance});
        continue;
      }
    Branch b;
    b.k = child.k;
    b.parent = parent;
    b.bifurcation = from;
    b.start = "period doubling at p = " + number_text(at.b.p) + " on branch " + std::to_string(parent) +
              (from >= 0 ? " (bifurcation " + std::to_string(from) + ")" : "");
    child_runner.append(b, s);
    if (!first) {
      b.end = "branch switching failed: every step along the eigenvector of μ = −1 fell back onto the period-" +
              std::to_string(parent_k) + "T branch";
      result.branches.push_back(std::move(b));
      continue;
    }
    follow_switched(child_runner, *first, std::move(b), index, depth, options, o, doublings, result);
  }
}

void switch_at_branch_points(const ContinuationFamily& family, const ContinuationOptions& options, Continuer& c,
                             SwitchPoints& branch_points, std::size_t first, SwitchPoints& doublings,
                             ContinuationResult& result, const ContinuationProgress& progress) {
  const Index n = c.n_;
  const Index N = 2 * n + 1;
  for (std::size_t i = first; i < branch_points.size(); ++i) {
    const auto [at, parent] = branch_points[i];
    const int from = recorded_at(result, BifurcationKind::branch_point, parent, at);
    const int k = result.branches[static_cast<std::size_t>(parent)].k;
    Continuer child(family, options, n, c.stops_, result);
    child.theta = at.b.phase;  // the section where the branch point was found
    child.k = k;
    child.L = c.L;
    child.V = c.V;
    child.P = c.P;
    Node s;
    s.e = child.evaluate(at.e.z, at.e.p);
    if (!s.e.ok) continue;
    // The crossing branch's direction: of the two right singular vectors of DF with the least
    // singular values (its null space at the branch point), the one with the larger part ⟂ t.
    const VectorXd& t = at.t;
    const Eigen::JacobiSVD<MatrixXd> svd(child.jacobian(s.e), Eigen::ComputeFullV);
    VectorXd e = VectorXd::Zero(N);
    for (const Index col : {N - 1, N - 2}) {
      const VectorXd v = svd.matrixV().col(col);
      const VectorXd w = v - v.dot(t) * t;
      if (w.norm() > e.norm()) e = w;
    }
    if (!(e.norm() > 0.5)) continue;  // no second null direction: not a simple branch point
    e.normalize();
    for (const double sign : {1.0, -1.0}) {
      if (!budget_left(options, result, 2 * (branch_points.size() - i) - (sign < 0.0), "branch point direction"))
        return;
      const VectorXd dir = sign * e;
      const int index = static_cast<int>(result.branches.size());
      std::optional<Node> first_point;
      std::optional<KnownMatch> known;
      for (const double h : {1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5}) {
        const VectorXd y_pred = child.scaled(s.e) + h * dir;
        Node m;
        m.e = child.correct(y_pred, dir);
        if (!m.e.ok || (child.scaled(m.e) - y_pred).norm() > 5.0 * h) continue;
        m.t = child.tangent(m.e, dir);
        m.b = child.point(m.e, m.t, 0);
        // Back on the branch of the branch point (where it curves into the hyperplane): a
        // shorter step. On another branch already followed: that branch, recognised below.
        known = on_known_branch(child, m, nullptr, index);
        if (known && known->branch == parent) {
          known.reset();
          continue;
        }
        first_point = std::move(m);
        break;
      }
      if (first_point && known) {
        result.recognised.push_back({parent, from, k, first_point->e.p, known->branch, known->shift, known->distance});
        continue;
      }
      ContinuationOptions o = options;
      o.max_points = static_cast<int>(std::min<long>(options.max_points, options.max_total_points - total_points(result)));
      BranchRunner runner(child, o, result, progress);
      runner.branch_points = &branch_points;
      Branch b;
      b.k = k;
      b.parent = parent;
      b.bifurcation = from;
      b.start = "branch point at p = " + number_text(at.b.p) + " on branch " + std::to_string(parent) +
                (from >= 0 ? " (bifurcation " + std::to_string(from) + ")" : "") + ", the crossing branch along " +
                (sign > 0.0 ? "+" : "−") + "e";
      s.t = dir;
      s.b = child.point(s.e, dir, 0);
      s.b.located = true;
      runner.append(b, s);
      if (!first_point) {
        b.end = "branch switching failed: no orbit off the branch found within 5h of the predictor along the crossing direction";
        result.branches.push_back(std::move(b));
        continue;
      }
      follow_switched(runner, *first_point, std::move(b), index, doubling_depth(k, options.period), options, o,
                      doublings, result);
    }
  }
}

}  // namespace vibro::detail
