#pragma once
/// \file kinds/diagram.hpp
/// run.kind: diagram — a brute-force bifurcation diagram: the attractor followed along one
/// parameter, up and down in one run, with its stroboscopic points, its least period and its
/// impacts per period at every grid point.
///
///     run:
///       kind: diagram
///       transient_periods: 300             # at the first point of each direction (from initial)
///       diagram:
///         path: forcing.frequency
///         linspace: [0.24, 0.28, 401]
///         transient: 100                   # at every later point (from the previous end)
///         points: 32                       # P stroboscopic points recorded per grid point
///         directions: both                 # up (increasing), down, or both
///
/// procedure Diagram(grid):
///     for each direction (up: the grid in increasing order, down: decreasing), in parallel:
///         (x, v) ← initial state; transient ← run.transient_periods
///         for each grid value p in that order:
///             run `transient` periods of the scene at p from (x, v); transient ← diagram.transient
///             record z_i = (x, v)(t0 + (N + i)T), i = 1 … P, and the impacts of those P periods
///             k ← least k ≤ max_period with |z_i − z_{i−k}| ≤ tolerance for every i > k (x in L,
///                 v in V, the run's scales); 0 if none ("not periodic")
///             (x, v) ← z_P: the next value starts on this attractor (hysteresis shows)
/// The time restarts at initial.time at every grid point (the forcing phase of the section is
/// that of t0 at every point). Each direction is one chain of runs (one thread each). A run that
/// stops early (event cap, numerical failure) ends its direction: the points after it are marked
/// not reached. Layout of /diagram: docs/results.md.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// Runs a scene whose run.kind is diagram. Throws SceneError for bad input before any file exists.
RunReport run_diagram(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
