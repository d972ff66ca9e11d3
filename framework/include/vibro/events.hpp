#pragma once
/// \file events.hpp
/// Certified location of guard crossings along an exact segment.
///
/// A guard is a row h(τ) = ℓᵀ z(τ) of a Segment (a gap g_j of a free stop, or -λ_j of a stuck
/// one); an event is h rising above 0. The guarantee, for a trigger level ε ≥ 0:
///
///   every τ in the searched interval at which h(τ) > ε is found (the earliest such crossing is
///   returned, located at a root of h = 0 to within a few units of rounding in t); intervals in
///   which h never exceeds ε are passed over.
///
/// How: on an interval [a, b] with h, h' known at both ends and B ≥ max |h''| over [a, b] (a
/// rigorous bound from the Segment, built from the exact modal amplitudes), Taylor's theorem gives
///     h(τ) ≤ max(h(a), h(b)) + B (b - a)² / 8,
///     h(τ) ≤ h(a) + max(0, h'(a) + B (b - a)/2)(b - a)   and the same from b,
/// so if the smallest of these is ≤ ε the interval is certified free of events. Otherwise it is
/// halved (earliest half first), down to intervals of a few ulps of t. A grazing trajectory that
/// peaks at 1e-10 below the stop is certified clear once B (b - a)²/8 < 1e-10; one that peaks
/// 1e-10 above it has an interval of width ~ √(8·1e-10/B) above ε that the bisection must
/// sample. Rounding in h (~1e-16 of its scale) is covered by ε, set by the simulator to
/// 1e-13 of the problem's length (and force) scale.
#include "vibro/flow.hpp"

#include <optional>

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
  /// `triggers[i]` is ε for row i; `resolution` the smallest interval length.
  /// `triggers` is referenced, not copied: it must outlive the finder.
  CrossingFinder(const Segment& segment, const Eigen::Ref<const Eigen::VectorXd>& triggers,
                 double resolution);

  /// Earliest crossing over all rows in [a, b]; nullopt if none. Throws std::runtime_error if
  /// the subdivision budget runs out (a guard hugging zero over a long interval).
  std::optional<Crossing> first(double a, double b);

  /// Refines a root of row i bracketed by h(a) ≤ 0 < h(b) to a few ulps (safeguarded Newton).
  double refine_root(Eigen::Index row, double a, double b) const;

  long subdivisions() const { return subdivisions_; }

 private:
  std::optional<double> search(Eigen::Index row, double a, double b, double ha, double da,
                               double hb, double db);

  double from_last_below(Eigen::Index row, double above) const;

  const Segment* segment_;
  Eigen::Ref<const Eigen::VectorXd> triggers_;
  double last_below_ = 0.0;
  double search_start_ = 0.0;  // latest τ seen with h ≤ 0 in the current left-to-right search
  double resolution_;
  long subdivisions_ = 0;
};

/// Global minimum of sign·h_i over [a, b] (sign = ±1), certified by the same second-derivative
/// bound, to an absolute accuracy `tolerance` in value; the time is refined by regula falsi /
/// bisection on h' = 0.
struct Minimum {
  double value;  ///< min of sign·h
  double tau;
};
Minimum minimize_row(const Segment& segment, Eigen::Index row, double a, double b,
                     double tolerance, double sign = 1.0);

}  // namespace vibro
