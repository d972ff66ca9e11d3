#pragma once
/// \file test_functions.hpp
/// The test functions of continuation's bifurcations (private to the analysis layer;
/// continuation.hpp lists them): scalars of a branch point that change sign at the bifurcation,
/// located as their zeros between two neighbours. Over the d non-structural Floquet
/// multipliers μ_i (the structural zeros of held coordinates left out):
///  * period doubling: Π_i (1 + μ_i), zero where a multiplier passes −1;
///  * branch point: (μ* − 1) Π_{i≠*} sign(μ_i − 1) over the real μ_i, μ* the one nearest +1:
///    the sign of det(J − I) (complex pairs contribute |μ − 1|² > 0) with the magnitude of the
///    crossing multiplier's distance, O(1) in any dimension;
///  * Neimark–Sacker:  Π_{i<j} (μ_i μ_j − 1), zero where a complex pair crosses the unit circle
///    (μ μ̄ = 1), and also at a real pair with μ_i μ_j = 1 (a neutral saddle, told apart by
///    has_unit_pair);
///  * grazing of stop j: the orbit's nearest approach to the stop, continuous through the
///    grazing: with `fewer` free impacts the largest interior maximum of the gap (< 0), with
///    `more` the least u²/(2|g''|) over the free impacts (> 0: the height the slowest impact's
///    free parabola would rise past the stop, u its approach speed, g'' the gap's free
///    acceleration at impact);
///    for a compliant stop (stops.hpp; its engagements counted as impacts) the gap's maxima are
///    continuous through the grazing on both sides: with `fewer` engagements the largest gap
///    maximum of the free flights (< 0), with `more` the least penetration maximum of an engaged
///    phase (> 0). With c_s = 0 and no preload the vector field is continuous across g = 0 and
///    the grazing's discontinuity map is of order 3/2 in the distance (Nordmark 1991; di
///    Bernardo, Budd, Champneys & Kowalczyk 2008, ch. 4), not 1/2 as at a rigid stop; with a
///    dashpot or a preload it is of order 1. Located from the side without the contact either way;
///  * rising of stop j (Wagg 2004): with `fewer` contact phases the least interior minimum of
///    its contact force (> 0), with more the least force the held flow continued past a
///    release would need (< 0);
///  * a frictional contact j whose arrival at u = 0 turns from a reversal (followed by a short
///    slip and a stick) into a stick (a crossing-sliding bifurcation where the side with fewer
///    switches is the sticking one): the margin |F_hold| − μ_s N at the arrival, with `fewer`
///    switches the largest margin of a stick (≤ 0), with more the least margin of a reversal or
///    sliding feature (> 0; friction_tangent.hpp's force dips).
/// The fold's test function, the tangent's p component, is read off the node directly.
/// NaN where the function is not defined at a point (location then falls back to bisection).
#include "corrector.hpp"

#include <cstddef>

namespace vibro::detail {

double doubling_test(const FloquetMultipliers& f);
double torus_test(const FloquetMultipliers& f);
double branch_point_test(const FloquetMultipliers& f);
/// Whether a complex pair (|Im μ| > tol) lies on the unit circle to tol.
bool has_unit_pair(const FloquetMultipliers& f, double tol);
/// Grazing of stop j of a system with `stops` stops (see above).
double grazing_function(const Node& n, std::size_t stops, std::size_t j, int fewer, int more);
/// Rising of stop j (see above).
double rising_function(const Node& n, std::size_t j, int fewer);
/// A frictional contact's arrival turning from a reversal into a stick (see above).
double arrival_function(const Node& n, std::size_t j, int fewer);
/// Whether signature index j is a frictional contact (its events are friction switches).
bool frictional(const Node& n, std::size_t j);

}  // namespace vibro::detail
