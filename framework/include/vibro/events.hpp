#pragma once
/// \file events.hpp
/// Certified location of guard crossings: the one event search of the engines whose guards are
/// a GuardSource (guard_source.hpp), the dense engine's Segment (flow.hpp) and the modal chain
/// engine's ModalGuardSource (modal.hpp).
///
/// A guard is a row h(τ) of the source (a gap g_j of a free stop, or -λ_j of a stuck one); an
/// event is h rising above 0. The guarantee, for a trigger level ε ≥ 0:
///
///   every τ in the searched interval at which h(τ) > ε is found (the earliest such crossing is
///   returned, located at a root of h = 0 to within a few units of rounding in t); intervals in
///   which h never exceeds ε are passed over.
///
/// How: on an interval [a, b] with h, h', h'' known at both ends and B₂ ≥ max |h''|,
/// B₃ ≥ max |h'''| over [a, b] (rigorous bounds from the source: the Segment's from the exact
/// spectral amplitudes, the modal source's from each mode's energy), Taylor's theorem gives
/// upper bounds of h on [a, b]:
///     h(τ) ≤ max(h(a), h(b)) + B₂ (b - a)² / 8                                  (chord),
///     h(τ) ≤ h(a) + max(0, h'(a) + B₂ (b - a)/2)(b - a)   and the same from b,
///     h(a + s) ≤ h(a) + h'(a) s + h''(a) s²/2 + B₃ s³/6 on s ≤ (b - a)/2 and the same from b
///                                                               (the cubic model of each half),
/// so if the smallest of these is ≤ ε the interval is certified free of events. The cubic model
/// uses the exact curvature at the ends, so it certifies a short bounce in one piece where the
/// quadratic bounds (B₂ ≫ |h''| where modes cancel) need many halvings. Otherwise the interval
/// is split — at a guard's predicted extremum when one is moving away from its surface or
/// turning inside, else in half — down to intervals of a few ulps of t. Where a guard rises
/// above ε at the right end, its root is found first (safeguarded Newton on the local quadratic
/// model, bracketed from the last point seen ≤ 0) and accepted if every guard is certified up to
/// it; that is the event. A grazing trajectory that peaks at 1e-10 below the stop is certified
/// clear once the bounds around the peak are below ε; one that peaks 1e-10 above it has an
/// interval of width ~ √(8·1e-10/B₂) above ε that the splitting must sample. Rounding in h, h'
/// and h'' (~1e-16 of their scales, times s² ≤ 1/ρ² for the curvature) is covered by ε, set by
/// the simulator to 1e-13 of the problem's length (and force) scale.
#include "vibro/flow.hpp"
#include "vibro/guard_source.hpp"

#include <optional>
#include <vector>

namespace vibro {

struct Crossing {
  double tau;       ///< time after the segment start, at the root of h = 0
  Eigen::Index row;
};

struct CrossingSearch {
  double trigger = 0.0;           ///< ε of the row (absolute)
  double time_resolution = 0.0;   ///< smallest interval worth halving (absolute, > 0)
  long max_subdivisions = 200000;  ///< beyond this the search reports trouble
};

class CrossingFinder {
 public:
  /// `triggers[i]` is ε for row i; `resolution` the smallest interval length. The triggers are
  /// copied.
  CrossingFinder(const GuardSource& source, const Eigen::Ref<const Eigen::VectorXd>& triggers,
                 double resolution);
  /// A finder to be aimed with retarget() (the dense event loop keeps one per contact mode, the
  /// modal one a single finder, every mode having one row per stop, so that searching a new
  /// segment allocates nothing). The source must outlive the finder's use.
  CrossingFinder() = default;
  /// With `rearm_leaving`, a row that starts inside its band (0 < h ≤ ε) while moving away (h' ≤ 0)
  /// is re-armed at ε + h(start), so that rounding cannot re-fire a guard just left (the event
  /// loop's use, just after an impact or a release).
  void retarget(const GuardSource& source, const Eigen::Ref<const Eigen::VectorXd>& triggers,
                double resolution, bool rearm_leaving = false);
  /// The trigger levels in use (after re-arming, once the search has started).
  const Eigen::VectorXd& triggers() const { return triggers_; }

  /// Earliest crossing over all rows in [a, b]; nullopt if none. Successive calls on adjacent
  /// intervals [a, b], [b, c], … continue one search (the sample at b is reused). Throws
  /// std::runtime_error if the subdivision budget runs out (a guard hugging zero over a long
  /// interval).
  std::optional<Crossing> first(double a, double b);

  /// Refines a root of row i bracketed by h(a) ≤ 0 < h(b) to a few ulps (safeguarded Newton).
  double refine_root(Eigen::Index row, double a, double b) const;

  long subdivisions() const { return subdivisions_; }
  /// All rows at the last crossing returned by first() (its values and slopes there).
  const SegmentSample& crossing_sample() const { return pool_[hit_]; }

 private:
  /// One end of a root bracket: τ and the row's value, slope and curvature there; `leaving`:
  /// the search's start, where the guard is on its surface and moving away (h ≤ 0 but within
  /// rounding of a root just left, so its local model must not propose that root).
  struct Jet {
    double tau, h, d, c;
    bool leaving = false;
  };
  bool search(std::size_t ia, std::size_t ib, std::size_t free, Crossing* out);
  bool certified(Eigen::Index row, const SegmentSample& a, const SegmentSample& b) const;
  void note_below(const SegmentSample& s);
  double split_point(const SegmentSample& a, const SegmentSample& b) const;
  double root(Eigen::Index row, Jet lo, Jet hi) const;
  double from_last_below(Eigen::Index row, double above) const;

  const GuardSource* source_ = nullptr;
  Eigen::VectorXd triggers_;
  std::vector<SegmentSample> pool_;  // [0] the left end of the current step, [1] its right end
  std::vector<Jet> below_;           // per row: the latest sample with h ≤ 0 (τ = -∞: none)
  std::vector<char> leaving_;        // per row: on its surface and moving away at the start
  double search_start_ = 0.0;
  bool started_ = false, rearm_ = false;
  std::size_t hit_ = 0;
  double resolution_ = 0.0;
  long subdivisions_ = 0;
};

/// Global minimum of sign·h_i over [a, b] (sign = ±1), certified by the same second-derivative
/// bound, to an absolute accuracy `tolerance` in value; the time is refined by regula falsi /
/// bisection on h' = 0.
struct Minimum {
  double value;  ///< min of sign·h
  double tau;
};
Minimum minimize_row(const GuardSource& source, Eigen::Index row, double a, double b,
                     double tolerance, double sign = 1.0);

}  // namespace vibro
