#pragma once
/// \file running_orbit.hpp
/// Periodic orbits of a forced vibro-impact system, found by running to convergence, and what
/// happens on them: each contact phase (a stop held) with its duration and its least interior
/// contact force, and the impacts.
///
/// procedure RunToPeriodicOrbit(t, x, v):
///     repeat one forcing period at a time (at most max_periods):
///         z_n ← state at t0 + nT                         # exact: the end of a simulator run
///         k ← least k ≤ max_period with |z_n − z_{n−k}| ≤ tolerance   (x in L, v in V)
///         if k exists: the orbit has period kT; stop
///     record the orbit over [t_n, t_n + 2kT]: contact intervals (ContactLog) that START in the
///     first kT (so each is complete even if it straddles t_n + kT), impacts in the first kT
///
/// Convergence by running, not by Newton shooting: sticking collapses the held masses' state,
/// so the sticking orbits this is built for contract fast, and running needs no derivatives
/// through impacts, chatter limits and releases. An orbit that does not settle within
/// max_periods is reported as not periodic (with the least residual seen), never forced.
///
/// Usage:
///     vibro::RunningOrbit orbit = vibro::run_to_periodic_orbit(scene, {}, 0.0, x0, v0);
///     if (orbit.periodic) for (const vibro::ContactPhase& p : orbit.phases) ...
#include "vibro/engine.hpp"
#include "vibro/simulator.hpp"

#include <string>
#include <vector>

namespace vibro {

struct RunningOrbitOptions {
  int max_period = 8;         ///< periods kT looked for: k = 1 … max_period
  long max_periods = 2000;    ///< forcing periods run before giving up
  long min_periods = 0;       ///< run at least this many periods before testing (transient)
  /// z(t + kT) and z(t) agree when |Δx|∞ ≤ tolerance·L and |Δv|∞ ≤ tolerance·V (the
  /// simulator's length and velocity scales).
  double tolerance = 1e-10;
  SimulatorOptions solver;

  void validate() const;  ///< throws InvalidInput naming the field
};

/// One phase of contact on the orbit: stop `stop` held over [t_start, t_start + duration].
struct ContactPhase {
  int stop = -1;
  double t_start = 0.0;    ///< absolute time (within the orbit's first kT)
  double phase = 0.0;      ///< t_start modulo kT, in [0, kT): where in the forcing cycle it starts
  double duration = 0.0;
  double force_min = 0.0;  ///< least interior contact force (ContactInterval::force_min)
  double t_force_min = 0.0;
};

/// An impact on the orbit (the recorded first kT).
struct OrbitImpact {
  int stop = -1;
  double t = 0.0;
  double speed = 0.0;  ///< approach speed g'⁻ > 0
};

struct RunningOrbit {
  bool periodic = false;
  int k = 0;                  ///< period kT (0 if not periodic)
  double residual = 0.0;      ///< max(|Δx|∞/L, |Δv|∞/V) at the accepted k (least seen if not periodic)
  long periods_run = 0;       ///< periods simulated to converge (not counting the recording)
  double period = 0.0;        ///< T = 2π/Ω
  double t_start = 0.0;       ///< the orbit is recorded from here, over kT
  Eigen::VectorXd x, v;       ///< state at t_start
  std::vector<ContactPhase> phases;  ///< in order of t_start
  std::vector<OrbitImpact> impacts;  ///< in time order
  long chatter_limits = 0;
  double length_scale = 0.0, velocity_scale = 0.0, force_scale = 0.0;  ///< the simulator's L, V, F
  RunStatus status = RunStatus::completed;  ///< of the simulator; not completed: see message
  std::string message;

  /// Fraction of kT each stop is held (sum over its phases).
  Eigen::VectorXd sticking_fraction(std::size_t stops) const;
  /// Phases of stop j per orbit.
  int phase_count(int stop) const;
  /// Impacts of stop j per orbit faster than `min_speed` (chatter bounces resolved below a
  /// solver threshold are not physical counts; filter them with this).
  int impact_count(int stop, double min_speed = 0.0) const;
};

/// Runs from (t0, x0, v0) until the motion is periodic (see the file comment), then records it.
/// Throws InvalidInput for bad options or an inadmissible start; Ω must be > 0.
RunningOrbit run_to_periodic_orbit(const ImpactSystem& scene, const RunningOrbitOptions& options, double t0,
                          const Eigen::VectorXd& x0, const Eigen::VectorXd& v0);
/// The same on any engine (engine.hpp); options.solver is then the engine's business, unused.
RunningOrbit run_to_periodic_orbit(Engine& engine, const RunningOrbitOptions& options, double t0,
                          const Eigen::VectorXd& x0, const Eigen::VectorXd& v0);

}  // namespace vibro
