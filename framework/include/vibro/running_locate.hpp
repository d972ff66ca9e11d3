#pragma once
/// \file running_locate.hpp
/// Locating the bifurcations of sticking orbits along a parameter: rising (multi-sliding), a part
/// of a split sticking phase vanishing, a change of period, a loss of periodicity.
///
/// Rising (Wagg 2004, sections 3–4; Toulemonde & Gontier 1998): while a stop holds, its contact
/// force λ(t) stays positive; as the parameter moves, an interior minimum of λ can fall to zero.
/// There the sticking orbit touches the boundary ∂S = {λ = 0} of the sticking region
/// tangentially (the multi-sliding bifurcation of di Bernardo et al. 2002), and beyond it the
/// mass lifts off mid-phase: one sticking phase becomes two. Further on, the second part can
/// shrink to nothing. Both show as a change in the number of contact phases a stop has per orbit,
/// which is discrete and exactly computable, so they are located by bisection on it:
///
/// procedure ScanAndLocate(grid p_0 < … < p_m):
///     orbit_0 ← periodic orbit at p_0 from the given state
///     for i = 1 … m: orbit_i ← periodic orbit at p_i from orbit_{i-1}'s state   # continuation
///     for i = 1 … m: Explore(orbit_{i-1}, orbit_i)
///
/// procedure Explore(lo, hi):                                  # bisection into every change
///     if hi.p − lo.p ≤ tolerance: record a transition if signatures differ (or a jump, below)
///     else if signature(lo) ≠ signature(hi) or a sticking fraction differs by > jump:
///         mid ← periodic orbit at (lo.p + hi.p)/2 from lo's state
///         Explore(lo, mid); Explore(mid, hi)
///
/// Both halves are explored, so a grid step holding several changes yields them all; a half
/// with equal ends and no jump ends at once, so the cost is about log2(step/tolerance) orbits
/// per transition.
///
/// signature = (periodic?, k, phases per orbit of each stop). A transition where stop j has one
/// phase more on one side is classified by what vanishes at it, measured at the bracket ends:
///   rising:    on the side with fewer phases, the least interior contact force of j's phases
///              → 0 (in force scale F) — the phase is about to split;
///   vanishing: on the side with more phases, the shortest phase of j → 0 (in units of kT).
/// Whichever of the two normalised limits is smaller names the transition; both are reported,
/// so a reader can see how clear the call is. Other changes: period (k differs), periodicity
/// (one side not periodic within RunningOrbitOptions::max_periods), several stops at once (other);
/// a doubling of the period seen through orbits not periodic within the budget is one `period`
/// transition (merge_doublings).
///
/// A sticking phase can also be cut short at a tangency without splitting: the mass rises and
/// does not come back to stick in that phase, so the phase counts stay equal and only the
/// sticking time jumps (Wagg's "drop in sticking time", after Toulemonde & Gontier). Between
/// neighbouring points whose sticking fraction differs by more than ScanOptions::jump, Explore
/// bisects on; a difference still larger than jump/2 across a bracket of the tolerance is a jump,
/// recorded as rising when the longer side's least interior force → 0 there (force_limit), else
/// as a drop; duration_limit is then the jump in the fraction. A steep but continuous change
/// shrinks away under bisection and is not reported.
///
/// The signature being discrete, the bracket is exact up to the periodicity tolerance: the
/// located value is within tolerance/2 of where the computed orbits change, and the reported
/// limit (e.g. a force minimum of order slope × tolerance) shows that nothing else happened in
/// between.
///
/// Usage:
///     auto family = [&](double omega) { return system_at(omega); };   // builds ImpactSystem
///     vibro::ScanResult r = vibro::scan_and_locate(family, grid, 0.0, x0, v0, {});
///     for (const vibro::Transition& t : r.transitions) ... t.kind, t.p, t.stop, t.limit
#include "vibro/running_orbit.hpp"

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vibro {

/// The system at parameter value p.
using SystemFamily = std::function<ImpactSystem(double p)>;
/// The engine at parameter value p (engine.hpp): any engine, e.g. the modal one for long chains.
using EngineFamily = std::function<std::unique_ptr<Engine>(double p)>;
/// A SystemFamily run on the dense engine with `solver`.
EngineFamily dense_family(SystemFamily family, const SimulatorOptions& solver);

struct ScanOptions {
  RunningOrbitOptions orbit;            ///< per point (continuation points start near their orbit)
  long first_transient = 200;    ///< periods run at the first point before testing periodicity
  double tolerance = 1e-8;       ///< final bracket width in p
  int max_transitions = 64;      ///< located per scan, at most (a guard against chaos)
  /// A stop's sticking fraction changing by more than this between neighbouring points with the
  /// same signature is searched for a jump (0: never).
  double jump = 0.02;
  /// Called after each grid point of scan() with the number of points done (may be empty).
  std::function<void(std::size_t)> on_point;

  void validate() const;
};

struct ScanPoint {
  double p = 0.0;
  RunningOrbit orbit;
};

enum class TransitionKind { rising, vanishing, drop, period, periodicity, other };
const char* to_string(TransitionKind kind);

struct Transition {
  TransitionKind kind = TransitionKind::other;
  int stop = -1;            ///< the stop whose phase count changes (rising, vanishing), else -1
  double p = 0.0;           ///< (p_low + p_high)/2
  double p_low = 0.0, p_high = 0.0;
  ScanPoint low, high;      ///< the orbits at the bracket ends
  /// rising/vanishing: least interior contact force of the stop's phases on the side with fewer
  /// phases, and shortest phase / kT on the side with more. Jumps (see above): the least
  /// interior force on the side that sticks longer, and the jump in the sticking fraction.
  double force_limit = 0.0, duration_limit = 0.0;
  int evaluations = 0;      ///< bisection depth: orbits computed from the grid step down to it
};

struct ScanResult {
  std::vector<ScanPoint> points;  ///< the grid, in order
  std::vector<Transition> transitions;  ///< in order of p
  long orbits_computed = 0;
};

/// See the file comment. `grid` must be strictly monotonic (a descending grid sweeps down).
/// (t0, x0, v0) is the start of the first point; every later orbit search starts at t = 0 from
/// the previous orbit's state, which lies at forcing phase 0. Throws InvalidInput.
ScanResult scan_and_locate(const SystemFamily& family, const std::vector<double>& grid, double t0,
                           const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                           const ScanOptions& options);
ScanResult scan_and_locate(const EngineFamily& family, const std::vector<double>& grid, double t0,
                           const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                           const ScanOptions& options);

/// The transitions between two neighbouring scan points (Explore of the file comment), in order
/// of p. Independent for different pairs: callers may run pairs in parallel. Adds the orbits it
/// computed to *orbits_computed if given.
std::vector<Transition> locate_between(const SystemFamily& family, const ScanPoint& lo,
                                       const ScanPoint& hi, const ScanOptions& options,
                                       long* orbits_computed = nullptr);
std::vector<Transition> locate_between(const EngineFamily& family, const ScanPoint& lo,
                                       const ScanPoint& hi, const ScanOptions& options,
                                       long* orbits_computed = nullptr);

/// Period doublings seen through the running method's budget: near a doubling a multiplier
/// near −1 makes the runs converge slowly (|μ|ⁿ), so the orbits on both sides of it are not
/// periodic within max_periods and bisection returns two `periodicity` transitions, from a
/// period-kT orbit to a slowly converging one and from it to a period-2kT orbit (either order in
/// p). Each such pair, neighbours in `sorted` (in order of p) with no other change between them and
/// both inner orbits nearly closing (least residual ≤ 1e-3), becomes one `period` transition whose
/// bracket spans both: the doubling lies in it.
void merge_doublings(std::vector<Transition>& sorted);

/// Only the continuation (no location): the orbits at the grid points. Interrupted
/// (options.orbit.solver.interrupt, or Interrupted from the family's set-up of an engine after
/// the first point: bounded_wait.hpp), the points scanned so far; Interrupted at the first point
/// is thrown.
std::vector<ScanPoint> scan(const SystemFamily& family, const std::vector<double>& grid, double t0,
                            const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            const ScanOptions& options);
std::vector<ScanPoint> scan(const EngineFamily& family, const std::vector<double>& grid, double t0,
                            const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            const ScanOptions& options);

}  // namespace vibro
