#pragma once
/// \file orthonormal_frame.hpp
/// Tangent directions carried over [t0, t1] as an orthonormal frame (private to the analysis
/// layer; the Lyapunov spectrum's step, lyapunov.hpp). The directions D are carried like
/// LinearisationOptions::directions (flows between events, saltation matrices at events), but
/// after every event the frame is re-orthonormalised, K = Q R (Householder), K ← Q, and log|R_ii|
/// added up: at t1
///
///     J D = F U,    F = map.products (the frame carried since the last event),
///     U upper triangular with log|U_ii| = log_growth(i)
///
/// (the product of the events' R factors). The product of a period's saltation matrices and
/// flows is never formed: on a chaotic orbit with dozens of impacts per period its condition
/// can pass 1/ε, and its small singular directions would then be rounding.
#include "vibro/linearisation.hpp"

namespace vibro::detail {

struct CarriedFrame {
  TangentMap map;             ///< the run's map: products = F, jacobian empty
  Eigen::VectorXd log_growth; ///< log|U_ii|, one per direction (−∞ for one an event annihilated)
};

/// Throws InvalidInput as linearise() (directions must have 2n rows).
CarriedFrame carry_orthonormal_frame(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                                     const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
                                     const Eigen::MatrixXd& directions);

/// The same on the Taylor engine: `system` with the nonlinear `forces` (taylor_tangent.cpp).
CarriedFrame carry_orthonormal_frame(const ImpactSystem& system, const NonlinearForces& forces,
                                     const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0,
                                     const Eigen::VectorXd& v0, double t1, const Eigen::MatrixXd& directions);

}  // namespace vibro::detail
