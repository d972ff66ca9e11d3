#pragma once
/// \file branch_switching.hpp
/// Branch switching (private to the analysis layer): from each located period doubling of a
/// period-k branch, the period-2k branch that bifurcates there is continued, recursively up to
/// ContinuationOptions::max_doublings deep; from each located branch point, the branch that
/// crosses there.
#include "branch_runner.hpp"

#include <utility>
#include <vector>

namespace vibro::detail {

/// Located points at which to switch branches: each the located point and the index of its
/// branch in result.branches.
using SwitchPoints = std::vector<std::pair<Node, int>>;

/// Continues the doubled branch from each entry of `doublings` from index `first` on,
/// appending the new branches to result.branches; doublings found on them are appended to
/// `doublings` and taken in turn, branch points to `branch_points` (for
/// switch_at_branch_points). `c` is the first branch's Continuer: its scales are the new
/// branches', and its engine tells the old branch's orbits.
void switch_at_doublings(const ContinuationFamily& family, const ContinuationOptions& options, Continuer& c,
                         SwitchPoints& doublings, std::size_t first, SwitchPoints& branch_points,
                         ContinuationResult& result, const ContinuationProgress& progress);

/// Continues the branch crossing each located branch point of `branch_points` from index
/// `first` on: at a simple branch point DF = [J − I, ∂P/∂p] has a two-dimensional null space,
/// the followed branch's tangent t and the crossing branch's e ⟂ t. The crossing branch is
/// entered along +e and along −e (at a symmetry-breaking pitchfork the two are the mirror
/// images of one another, at a transcritical point the two halves of one branch), each by the
/// corrector from the branch point + h e in the hyperplane normal to e, h = 1e-2, 3e-3, …
/// 3e-5 until it lands within 5h of its predictor and off the branch followed (which, tangent
/// to t, crosses that hyperplane only O(√h) away, if at all; the crossing branch's tangent lies
/// in span{t, e} at any angle to e, so it crosses there at h/cos of that angle), and followed
/// away from the branch point.
/// Doublings and branch points found on the new branches are appended to their lists.
void switch_at_branch_points(const ContinuationFamily& family, const ContinuationOptions& options, Continuer& c,
                             SwitchPoints& branch_points, std::size_t first, SwitchPoints& doublings,
                             ContinuationResult& result, const ContinuationProgress& progress);

}  // namespace vibro::detail
