#pragma once
/// \file section.hpp
/// Poincaré sections on a hyperplane in the positions: the state each time the motion crosses
///     h(x) = nᵀx − c = 0
/// in a chosen direction (upwards: h from ≤ 0 to > 0; downwards; or both), e.g. x₁ = 0 with
/// x₁' > 0 (n = e₁, c = 0, upwards).
///
/// **A passive guard.** h is watched like a stop's gap but never acted on: each segment the
/// engine reports (observers.hpp) is searched for crossings after the engine has taken it, by
/// the certified search of the events (events.hpp, CrossingFinder) on the rows h and −h written
/// in the segment's own exact flow (SegmentView::plane_crossings: the dense engine's reduced
/// flow, the modal engine's modes). The engine's step sequence and arithmetic are those of a run
/// without the section, bit for bit; the search has the events' guarantee (no excursion of h
/// beyond the trigger ε is missed) and their accuracy (the root of h = 0 to a few ulps of t).
///
/// **What counts as a crossing.** Crossings alternate in direction (hysteresis of width ε): an
/// upward crossing is h rising above ε after it was last ≤ 0, recorded at the root of h = 0
/// before it; a downward one is −h rising above ε likewise. ε = trigger·L·‖n‖₂, the stops'
/// trigger level (SimulatorOptions::trigger) measured along n. Hence
///  * a touch that stays within ε of the hyperplane is no crossing; in particular a stop lying
///    in the hyperplane (an impact on it, a sticking phase held on it) crosses nothing unless the
///    motion goes through to the other side by more than ε;
///  * positions are continuous at impacts, so a crossing is found whether or not an impact falls
///    on it; a crossing whose root is an impact instant is recorded at that instant with the
///    state of the segment in which h leaves the band (after the impact: the velocity after it);
///  * sticking and sliding phases (the reduced flow of the held stops) are searched like free
///    flight;
///  * the run's start counts as below the hyperplane when h(t0) ≤ 0 (a start on it, moving
///    up, is an upward crossing at t0), above it otherwise; a run that starts where the same
///    Section's last run ended (a run continued in pieces) carries on its alternation instead.
///
/// Usage:
///     vibro::Section section({Eigen::VectorXd::Unit(n, 1), 0.0}, vibro::Section::Direction::up);
///     sim.run(0.0, x0, v0, 100.0, {&section});
///     section.t, section.phase, section.x, section.v   // one entry per crossing
#include "vibro/guard_source.hpp"
#include "vibro/observers.hpp"

#include <limits>
#include <vector>

namespace vibro {

class Section : public Observer {
 public:
  enum class Direction { up, down, both };
  /// Throws InvalidInput for a normal that is empty, zero or not finite, or a value that is not
  /// finite; its size is checked against the run's in begin().
  explicit Section(Hyperplane plane, Direction direction = Direction::both);
  void begin(const RunContext& run, double t0) override;
  void segment(const SegmentView& view) override;
  void end(double t_end) override { last_end_ = t_end; }

  const Hyperplane& plane() const { return plane_; }
  Direction direction() const { return direction_; }

  std::vector<double> t;
  std::vector<double> phase;  ///< Ωt mod 2π in [0, 2π) (0 when unforced), as ImpactMap
  std::vector<int> crossing;  ///< +1 upwards, −1 downwards
  std::vector<Eigen::VectorXd> x, v;  ///< the state at the crossing, from the exact flow

 private:
  Hyperplane plane_;
  Direction direction_;
  double omega_ = 0.0, trigger_ = 0.0;
  int side_ = 0;  // 0: not yet known (the first segment's start decides)
  double last_end_ = std::numeric_limits<double>::quiet_NaN();  // where the last run ended
  std::vector<PlaneCrossing> found_;
};

/// The name of a direction in scenes and results ("up", "down", "both").
const char* to_string(Section::Direction direction);

/// The alternating search behind SegmentView::plane_crossings, for any guard source whose row 0
/// is h and row 1 is −h with τ = 0 at t_begin: the crossings over τ ∈ [0, span] into `out`,
/// `side` updated (observers.hpp). `step` is the length of one step of the search (1/ρ, ρ the
/// fastest rate of the flow), `trigger` ε > 0.
void locate_plane_crossings(const GuardSource& source, double t_begin, double span, double step,
                            double trigger, int& side, std::vector<PlaneCrossing>& out);

}  // namespace vibro
