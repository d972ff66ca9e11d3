#pragma once
/// \file recorded_gaps.hpp
/// A recording's states are checked against the stops before anything is written. The engines
/// keep every gap within the trigger tolerance trigger × L (SimulatorOptions::trigger, L the
/// run's length scale, RunSummary::length_scale); a recorded state further past a stop than that
/// means the run failed, and it says so rather than storing the state as a result.
#include "vibro/io/results.hpp"
#include "vibro/io/scene.hpp"

namespace vibro::io {

/// Checks every state `rec` holds (samples, Poincaré points, the final state) against every rigid
/// stop of `scene` (a compliant stop is penetrated while engaged, stops.hpp): a gap g_j(t, x) above trigger × L, plus what the event search's time resolution
/// lets it move (|g_j'| · 32 ε max(|t|, T): an event is placed to 8 ε max(|t|, T) in time) and
/// the rounding of its own evaluation (16 ε (|wᵀx| + |s_j|)), marks the run numerical_failure
/// with a message naming the stop, the time and the depth (the deepest such state). A run already
/// not completed is left as it is. O(stops) per recorded state.
void check_recorded_gaps(const Scene& scene, Recording& rec);

}  // namespace vibro::io
