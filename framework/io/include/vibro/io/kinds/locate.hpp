#pragma once
/// \file kinds/locate.hpp
/// run.kind: locate — the bifurcations of a scene's periodic orbits along one parameter, found
/// and located automatically (vibro/running_locate.hpp), written to one HDF5 file.
///
///     run:
///       kind: locate
///       transient_periods: 200             # before the first grid point's orbit is tested
///       locate:
///         path: forcing.frequency          # any number the scene sets
///         linspace: [0.24, 0.28, 81]       # the scan grid (or logspace / values)
///         tolerance: 1e-8                  # bracket width of each located transition
///
/// The scan is a continuation (each grid point starts from the previous orbit), so it runs in
/// order; the bisections between grid points are independent and run in parallel (OpenMP).
/// Layout of /scan, /phases and /transitions: docs/results.md.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// Runs a scene whose run.kind is locate. Throws SceneError for bad input before any file exists.
RunReport run_locate(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
