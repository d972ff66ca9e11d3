#pragma once
/// \file kinds/basin.hpp
/// run.kind: basin — basins of attraction: which attractor each start of a 2-D grid of two scene
/// values (usually components of the initial state) ends on, written as an integer image and the
/// list of attractors found.
///
///     run:
///       kind: basin
///       basin:
///         parameters:                      # rows, then columns of the image
///           - {path: initial.x[0], linspace: [-0.29, 0.6, 256]}
///           - {path: initial.v[0], linspace: [-0.6, 0.6, 256]}
///         max_period: 8                    # periods kT looked for
///         max_periods: 1000                # budget per point: "not converged" after it
///         tolerance: 1e-8                  # |z_n − z_{n−k}| that makes a new attractor
///         match: 1e-5                      # |z_n − a_j| that puts a run on a known attractor
///         seed_stride: 16                  # the seeds: every 16th point of both axes
///
/// procedure Basin(grid):
///     L, V ← length and velocity scales of one period run from the scene's own initial state
///     for each grid point, one forcing period at a time, z_n = (x, v)(t0 + nT):
///         if z_n, z_{n+1}, …, z_{n+k} lie within `match` of consecutive points a_j, a_{j+1}, …
///             of a known attractor a of period k (k + 1 points in its order): label a; stop
///         if |z_n − z_{n−k}| ≤ tolerance for the least k ≤ max_period (no proper divisor of k
///             repeating too): a new attractor (k, z_{n−k+1} … z_n); stop
///         after max_periods: label −1 (not converged: chaotic, quasi-periodic or slow)
///     a run that stops early (numerical failure, event cap, interruption): label −2
/// Distances are max(|Δx|∞ / L, |Δv|∞ / V). Determinism: the seeds (every seed_stride-th point of
/// both axes) run first against no known attractor; their attractors, in grid order and without
/// repeats (same k, a point within `match`), are the catalogue every other point is matched
/// against; attractors found after that are appended in grid order. So labels, periods_used and
/// the attractors are the same for any number of threads and processes.
///
/// Points run in parallel with OpenMP (dynamic schedule: chaotic points run their whole budget)
/// and, under `mpirun -np K`, across processes (point i on rank i mod K; rank 0 gathers the
/// results and writes the file). Every point's scene is rebuilt from the document and validated;
/// when both paths are of `initial.` the engine of the base scene is reused for all points of a
/// thread (its set-up is paid once). Layout of /basin and /attractors: docs/results.md.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// Runs a scene whose run.kind is basin. Throws SceneError for bad input before any file exists.
RunReport run_basin(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
