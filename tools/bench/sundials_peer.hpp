#pragma once
/// \file sundials_peer.hpp
/// A peer written by others for the work-precision report: SUNDIALS (Hindmarsh et al., "SUNDIALS:
/// Suite of nonlinear and differential/algebraic equation solvers", ACM TOMS 31, 2005; Debian's
/// libsundials-dev, version 6.4), its integrators and their built-in root finding, in a thin
/// event loop with the framework's rules:
///
///  * ARKODE ERKStep (Reynolds et al., ARKODE) with its Butcher tables ARKODE_DORMAND_PRINCE_7_4_5
///    (Dormand–Prince 5(4)) or ARKODE_FEHLBERG_13_7_8 (Fehlberg 7(8), the 8th-order explicit
///    table of SUNDIALS 6.4; Verner's 8(7) tables came with SUNDIALS 7), dense output by
///    ARKODE's Hermite interpolant;
///  * CVODE (Adams–Moulton, variable order 1–12, fixed-point corrector, no Jacobian).
/// Between events: the same index-reduced right-hand side as the RK baselines (baseline_flow.hpp,
/// fixed-size tables behind the N_Vector's data). Events: the guards g_j − trigger_j as SUNDIALS
/// root functions (direction +1: upward crossings), located by its own root finder (sign changes
/// at step ends, then the Illinois method on its interpolant, to ~100 ulp of t); then the
/// framework's resolve_event (baseline_events.hpp) and a restart of the integrator (ReInit) from
/// the post-event state. Samples: the integrator's own output at each sample time (ARK_NORMAL /
/// CV_NORMAL: it steps past and interpolates). Tolerances: SUNDIALS' own weighted RMS norm with
/// reltol = rtol, abstol = rtol · min(L, V), as the RK baselines.
#include "rk_baseline.hpp"

#include <vector>

namespace vibro::bench {

enum class SundialsMethod { arkode_dp5, arkode_f78, cvode_adams };
const char* to_string(SundialsMethod m);

struct SundialsOptions {
  SundialsMethod method = SundialsMethod::arkode_dp5;
  double rtol = 1e-6;
  long max_steps = 50000000;
  BaselineRules rules;
};

/// Runs from (t0, x0, v0) to t_end, states recorded at `sample_times` (ascending).
RkResult run_sundials(const ImpactSystem& scene, const SundialsOptions& options, double t0,
                      const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                      const std::vector<double>& sample_times);

}  // namespace vibro::bench
