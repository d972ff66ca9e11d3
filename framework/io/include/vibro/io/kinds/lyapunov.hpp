#pragma once
/// \file kinds/lyapunov.hpp
/// run.kind: lyapunov — the Lyapunov spectrum through impacts and sticking (vibro/lyapunov.hpp:
/// QR method on the exact tangent maps) at the scene's values, or along one parameter.
///
///     run:
///       kind: lyapunov
///       transient_periods: 300             # at the first point (from initial)
///       lyapunov:
///         count: 0                         # the p largest exponents; 0: all 2n
///         transient: 100                   # periods onto the attractor at every point
///         align: 50                        # periods the frame turns before averaging
///         periods: 1000                    # periods averaged
///         path: forcing.frequency          # optional: a spectrum along this parameter
///         linspace: [1.70, 1.80, 101]
///
/// Along a parameter each grid point starts from the state the previous one ended in (the
/// attractor is followed, in the order the grid is given), so the points run in order; with
/// `follow: false` every point starts from the initial state (run.transient_periods + transient
/// periods) and the points run in parallel (OpenMP), written in grid order. The time restarts at
/// initial.time at every point. Structural exponents (stops held: −∞ exactly) are
/// written as 0 with `finite` 0 (HDF5 files hold finite values only). Both engines (on the modal
/// one the frame is carried matrix-free in modal coordinates, analysis/modal_tangent.hpp).
/// Layout of /lyapunov: docs/results.md.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// Runs a scene whose run.kind is lyapunov. Throws SceneError for bad input before any file exists.
RunReport run_lyapunov(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
