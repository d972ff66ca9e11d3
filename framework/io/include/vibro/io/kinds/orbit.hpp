#pragma once
/// \file kinds/orbit.hpp
/// run.kind: orbit — one periodic orbit by Newton shooting (vibro/shooting.hpp), stable or not,
/// with its Floquet multipliers, on either engine:
///
///     run:
///       kind: orbit
///       transient_periods: 20       # the guess: the state after these periods from `initial`
///       orbit:
///         period: 1                 # k: the orbit repeats after kT
///         phase: 0                  # section phase θ (radians); moved off events and held phases
///         tolerance: 1e-11          # max(|Δx|∞/L, |Δv|∞/V) at convergence
///         max_iterations: 40
///         multipliers: 6            # modal engine: the leading ones, by Arnoldi
///
/// The dense engine forms the exact Jacobian and gives all 2n multipliers (structural zeros of
/// sticking counted apart); the modal engine (long chains) solves the Newton steps by GMRES on
/// matrix-free tangent maps and gives the leading multipliers (analysis/modal_tangent.hpp). A run
/// that does not converge writes what it reached (status not_converged, the message says why) and
/// exits with code 1: never a false orbit. Layout of /orbit: docs/results.md.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// Runs a scene whose run.kind is orbit. Throws SceneError for bad input before any file exists.
RunReport run_orbit(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
