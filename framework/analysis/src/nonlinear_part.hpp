#pragma once
/// \file nonlinear_part.hpp
/// What the tangent map (linearisation.cpp) needs of nonlinear forces F(x, v, t) added to the
/// linear system M x'' + C x' + K x = f(t) (the Taylor engine, taylor_simulator.hpp):
///
///  * the acceleration M⁻¹F at a state, which enters the vector fields f∓ of the saltation
///    matrices (f = (v, a_lin + M⁻¹F) in free flight);
///  * the tangent map ∂z(t1)/∂z(t0) of the free flow over a segment between events, from the
///    variational equations Φ' = ∂f/∂z Φ of the Taylor core (taylor_step.hpp: forward-mode
///    differentiation of the same recurrences as the state's).
///
/// The rest of the tangent map — the reset R of every impact and its derivatives, the guards —
/// is the linear engines' code (mechanics.hpp): the Newton impact law depends on M, the normals
/// and the restitutions only, not on the forces.
#include "vibro/linearisation.hpp"
#include "vibro/observers.hpp"

#include <Eigen/Dense>

#include <functional>
#include <vector>

namespace vibro::detail {

class NonlinearPart {
 public:
  virtual ~NonlinearPart() = default;
  /// M⁻¹F(x, v, t).
  virtual Eigen::VectorXd acceleration(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) = 0;
  /// ∂z(t1)/∂z(t0) (2n × 2n) of the free flow (no stop held) from (t0, x, v); with a parameter
  /// derivative (the part was made with one) a last column ∂z(t1)/∂p at fixed z(t0), t0, t1.
  virtual Eigen::MatrixXd transition(double t0, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1) = 0;
  /// Interior local maxima of the gaps of `stops` along the free flow from (t0, x, v) to t1.
  virtual std::vector<GapPeak> gap_peaks(double t0, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1,
                                         const std::vector<int>& stops) = 0;
};

/// Runs `run` with the tangent recorder of linearisation.cpp as its observer, the vector fields
/// and the segments' tangent maps completed by `part`. Held stops (sticking) are refused with
/// InvalidInput (see linearisation.hpp, nonlinear forces).
using ObservedRun = std::function<RunSummary(const std::vector<Observer*>&)>;
/// With `log_growth`, the carried directions are re-orthonormalised after every event and the logs
/// of their growth added there (orthonormal_frame.hpp).
TangentMap linearise_nonlinear(const ImpactSystem& system, const SimulatorOptions& solver, NonlinearPart& part,
                               const ObservedRun& run, double t0, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& v0, const LinearisationOptions& options,
                               Eigen::VectorXd* log_growth = nullptr);

}  // namespace vibro::detail
