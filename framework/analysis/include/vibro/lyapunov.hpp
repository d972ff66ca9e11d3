#pragma once
/// \file lyapunov.hpp
/// Lyapunov exponents through impacts, chatter, sticking and releases.
///
/// The QR method of Benettin et al. (1980) and Shimada & Nagashima (1979): an orthonormal frame
/// Q of p tangent vectors is carried along the trajectory by the exact tangent map of
/// linearisation.hpp — the flow's propagator between events and the saltation matrix at every
/// event, so the tangent dynamics cross impacts, sticks, releases and chatter limits exactly
/// (plain event callbacks in an ODE solver leave them out) — and re-orthonormalised (Q R = J Q,
/// Householder): on the dense engine after every event and at the end of every forcing period,
/// on the modal engine once per period; the exponents are the time averages of log R_ii,
///
///     λ_i = (1 / (N T)) Σ_k log |R_ii^{(k)}|,    λ_1 ≥ λ_2 ≥ … ≥ λ_p.
///
/// Why after every event: one period's product of flows and saltation matrices can have a
/// condition number beyond 1/ε (4e17 on the paper's system made conservative, dozens of impacts
/// per period), and one QR of that product returns rounding noise for the smallest R_ii; a QR
/// after each factor keeps every direction (the spectrum of that system then sums to 0 and pairs
/// up to 1e-16 over 4000 periods).
///
/// Directions removed by sticking. While stops are held the tangent map annihilates the held
/// stops' normal position and velocity (linearisation.hpp, structural zeros): with d the least
/// tangent dimension along the measured run, at least 2n − d exponents are −∞ exactly. They are
/// reported as −infinity (not as the large negative number rounding would give), and counted in
/// `structural`; the d others come from the frame's first d columns, which the killed directions
/// never feed (QR keeps the leading subspaces).
///
/// Checks (tests/analysis/test_lyapunov.cpp): on a periodic orbit the exponents are
/// log|μ_i|/(kT) of its Floquet multipliers; a conservative system (r = 1, C = 0) has a spectrum
/// symmetric about zero that sums to zero; the largest exponent against the divergence of two
/// nearby trajectories.
///
/// Usage:
///     vibro::LyapunovOptions o;  o.transient = 100;  o.periods = 2000;
///     vibro::LyapunovResult r = vibro::lyapunov_spectrum(system, solver, 0.0, x0, v0, o);
///     // r.exponents (per unit time, −inf for the structural ones)
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"

#include <string>
#include <vector>

namespace vibro {

struct LyapunovOptions {
  int count = 0;        ///< exponents wanted (the p largest); 0: all 2n
  long transient = 100; ///< forcing periods run before the frame starts (onto the attractor)
  long align = 50;      ///< periods the frame is carried before averaging starts (it turns onto the
                        ///< leading directions; the average then converges like 1/N, not 1/N + bias)
  long periods = 1000;  ///< forcing periods averaged
  /// Every this many periods a running estimate is kept (convergence history); 0: none.
  long history_every = 0;
  void validate() const;
};

struct LyapunovResult {
  RunStatus status = RunStatus::completed;  ///< a run that stopped early leaves the exponents invalid
  std::string message;
  Eigen::VectorXd exponents;     ///< per unit time, decreasing; −infinity for the structural ones
  int structural = 0;            ///< exponents that are −∞ because stops are held
  Eigen::Index least_free_dimension = 0;  ///< d over the measured run
  double period = 0.0;           ///< T
  std::vector<Eigen::VectorXd> history;   ///< running estimates (finite ones), every history_every periods
  double t_end = 0.0;
  Eigen::VectorXd x_end, v_end;  ///< where the trajectory ended
};

/// The spectrum along the trajectory from (t0, x0, v0) (see the file comment). Ω must be > 0.
/// Throws InvalidInput for bad options or state.
LyapunovResult lyapunov_spectrum(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                                 const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                                 const LyapunovOptions& options = {});

/// The same on the Taylor engine: `system` with the nonlinear `forces` (taylor_simulator.hpp), the
/// frame carried by the variational equations and the saltation matrices of linearisation.hpp.
/// A stop held along the run (sticking, a chatter caught by its rule) is refused with
/// InvalidInput (its tangent map is not derived for nonlinear forces).
LyapunovResult lyapunov_spectrum(const ImpactSystem& system, const NonlinearForces& forces,
                                 const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options = {});

/// The same on the modal engine (long chains): the frame is carried by the matrix-free tangent
/// map of modal_tangent.hpp in the free chain's modal coordinates (O(N p) per free flight and
/// free-flight impact instead of O(N² p)). Exponents do not depend on the (fixed) coordinates
/// the frame lives in; for unit masses the two engines' frames are the same up to an orthogonal
/// change of basis, and their spectra agree to rounding (tests/analysis/test_modal_tangent.cpp).
LyapunovResult lyapunov_spectrum(ModalEngine& engine, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options = {});

}  // namespace vibro
