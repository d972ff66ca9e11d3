#pragma once
/// \file known_branches.hpp
/// Whether an orbit lies on a branch already followed (private to the analysis layer;
/// continuation.hpp describes the method).
///
/// A periodic orbit of period kT is seen at the section phase θ at k states, one per forcing
/// period (z, P(z), …, P^{k−1}(z), P the map over one period T): the two directions of a
/// doubled branch from its period doubling are the same orbits shifted by k/2 periods, and a
/// doubled branch followed from each of the two doublings it joins is the same branch. So the
/// orbit of a point y (period K, section θ_y, parameter p) is compared with a known branch of
/// period K through each pair of its neighbouring points (q_i, q_{i+1}) that share a section
/// phase θ and bracket p:
///  * y's orbit is run to the first time t ≥ t0 with Ωt ≡ θ (mod 2π) and on for K − 1 periods,
///    giving the scaled states Y_j = (D⁻¹z_j, p/P), j = 0 … K − 1 (exact runs of the orbit);
///  * a Y_j within half the chord |Q_{i+1} − Q_i| of the chord (scaled) is tested exactly: the
///    known branch's corrector (period K, section θ) from the chord's point nearest Y_j, in the
///    hyperplane through Y_j normal to the chord. Two branches of zeros of P^K − I cross only at
///    bifurcation points, so if the known branch passes through Y_j that corrector lands on Y_j;
///  * it is the same orbit when they agree to max(|Δx|/L, |Δv|/V, |Δp|/P) ≤ 1e3 × tolerance
///    (the corrector's tolerance scaled by the state's scales, as the test that a doubled branch
///    closes after half its period).
#include "corrector.hpp"

#include <optional>

namespace vibro::detail {

struct KnownMatch {
  int branch = -1;        ///< index into result.branches, or the index given for `current`
  int shift = 0;          ///< j: periods between y's state and the known orbit's
  double distance = 0.0;  ///< max(|Δx|/L, |Δv|/V, |Δp|/P) between the two
  double p = 0.0;
};

/// Whether y's orbit is an orbit of `branch` (period c.k; `self`: the branch y is being added to,
/// where the orbit itself, j = 0, counts only against points more than ten behind the last: a
/// branch come round to where it was, not its own continuation).
std::optional<KnownMatch> orbit_on_branch(Continuer& c, const Node& y, const Branch& branch, bool self);

/// Whether y's orbit is an orbit of a branch of c.result_ of period c.k, or (if `current` is
/// given, with the index it will have) a shifted copy of one of `current`'s own orbits.
std::optional<KnownMatch> on_known_branch(Continuer& c, const Node& y, const Branch* current, int current_index);

}  // namespace vibro::detail
