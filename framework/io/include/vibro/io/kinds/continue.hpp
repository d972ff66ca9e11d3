#pragma once
/// \file kinds/continue.hpp
/// run.kind: continue — a scene's branch of periodic orbits followed in one parameter, with the
/// stability of every point and its bifurcations located (vibro/continuation.hpp), written to one
/// HDF5 file; optionally each located grazing or rising point followed in a second parameter.
///
///     run:
///       kind: continue
///       transient_periods: 200           # from `initial`, then Newton shooting at the start
///       continue:
///         path: forcing.frequency        # any number of the model, forcing or stops
///         range: [0.24, 0.28]            # the branch stops at these limits
///         curve: {path: forcing.cosine[0], range: [0.4, 0.6]}   # optional
///
/// Parameters. Every model, forcing and stop value enters the system data D (parameter.hpp)
/// affinely except the frequency and a stop's phase; their derivative dD/dp is exact: a
/// difference of two built systems for the affine ones (checked affine: the second difference
/// must vanish to rounding, else the path is refused), closed forms for the frequency and the
/// phases. A path that does not move the system (initial state, solver settings) is refused.
/// On a scene with nonlinear forces a named parameter `parameters.<name>` is a path too: it moves
/// only the forces (SystemDerivative::force_parameters).
///
/// Engines. The engine the scene resolves to (solver.engine) runs every point: the dense one, or
/// the modal chain engine (vibro/family_engine.hpp: the same continuation on its exact maps with
/// their full Jacobian; O(N²) memory and an O(N³) LU per corrector iteration, so chains of up to a
/// couple of thousand masses). On the modal engine a parameter that moves M, C or K (a mass, a
/// spring, a damper) is refused when the scene is loaded, naming run.continue.path (or
/// run.continue.curve.path) at its place in the file: those move the chain's modes. A scene with
/// nonlinear forces runs on the Taylor engine (taylor_family_engine: the variational equations'
/// maps); there a parameter that moves M is refused when the scene is loaded.
///
/// Progress: one line per branch point on stderr (p, k, stable, largest |μ|) and one per located
/// bifurcation. Layout of /branch, /branches, /bifurcations and /curve: docs/results.md.
#include "vibro/continuation.hpp"
#include "vibro/io/run_request.hpp"

#include <string>

namespace vibro::io {

/// dD/dp of the scene's system along `path` at the document's current value (see above).
/// Throws SceneError naming the path when it does not move the system or enters it nonlinearly.
SystemDerivative parameter_derivative(const SceneDocument& doc, const std::string& path);

/// The one-parameter family of the scene along `path`: at each value, `engine` (dense, modal or taylor) on
/// the scene there, with dD/dp and the solver settings `solver`.
ContinuationFamily continuation_family(const SceneDocument& doc, const std::string& path, EngineKind engine,
                                         const SimulatorOptions& solver);

/// Runs a scene whose run.kind is continue. Throws SceneError for bad input before any file exists.
RunReport run_continuation(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

}  // namespace vibro::io
