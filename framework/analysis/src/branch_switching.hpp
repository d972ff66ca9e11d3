#pragma once
/// \file branch_switching.hpp
/// Branch switching at period doublings (private to the analysis layer): from each located
/// period doubling of a period-k branch, the period-2k branch that bifurcates there is
/// continued, recursively up to ContinuationOptions::max_doublings deep.
#include "branch_runner.hpp"

#include <utility>
#include <vector>

namespace vibro::detail {

/// Continues the doubled branch from each entry of `doublings` (the located point and the index
/// of its branch in result.branches), appending the new branches to result.branches; doublings
/// found on them are appended to `doublings` and taken in turn. `c` is the first branch's
/// Continuer: its scales are the new branches', and its engine tells the old branch's orbits.
void switch_at_doublings(const ContinuationFamily& family, const ContinuationOptions& options,
                         Continuer& c, std::vector<std::pair<Node, int>>& doublings,
                         ContinuationResult& result, const ContinuationProgress& progress);

}  // namespace vibro::detail
