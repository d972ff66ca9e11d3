/// \file branch_switching.cpp
/// Branch switching at a period doubling. At the located point the period-k map has a
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

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

namespace vibro::detail {

void switch_at_doublings(const ContinuationFamily& family, const ContinuationOptions& options,
                         Continuer& c, std::vector<std::pair<Node, int>>& doublings,
                         ContinuationResult& result, const ContinuationProgress& progress) {
  const Index n = c.n_;
  const std::size_t stops = c.stops_;
  auto total_points = [&result] {
    long total = 0;
    for (const Branch& b : result.branches) total += static_cast<long>(b.points.size());
    return total;
  };
  for (std::size_t i = 0; i < doublings.size(); ++i) {
    const auto [at, parent] = doublings[i];
    const long used = total_points();
    const int left = static_cast<int>(doublings.size() - i);
    if (static_cast<int>(result.branches.size()) >= options.max_branches || used + 2 > options.max_total_points) {
      const bool branches = static_cast<int>(result.branches.size()) >= options.max_branches;
      const std::string what = branches ? "max_branches (" + std::to_string(options.max_branches) + ") reached"
                                        : "max_total_points (" + std::to_string(options.max_total_points) + ") reached";
      if (result.budget.empty()) result.budget = what;
      result.budget += ": " + std::to_string(left) + " period doubling" + (left == 1 ? "" : "s") + " not switched at";
      return;
    }
    // The period doubling it comes from: the located point recorded on the parent.
    int from = -1;
    for (std::size_t b = 0; b < result.bifurcations.size(); ++b)
      if (result.bifurcations[b].kind == BifurcationKind::period_doubling && result.bifurcations[b].branch == parent &&
          result.bifurcations[b].point.p == at.b.p && result.bifurcations[b].point.t0 == at.b.t0)
        from = static_cast<int>(b);
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
    child_runner.append(b, *first);
    child_runner.follow(*first, first->t, b, index, depth, depth < options.max_doublings ? &doublings : nullptr);
    if (o.max_points < options.max_points && static_cast<int>(b.points.size()) >= o.max_points) {
      b.end = "max_total_points (" + std::to_string(options.max_total_points) + ") reached: the run's budget of points";
      result.budget = "max_total_points (" + std::to_string(options.max_total_points) + ") reached (branch " +
                      std::to_string(index) + " cut short)";
    }
    result.branches.push_back(std::move(b));
  }
}

}  // namespace vibro::detail
