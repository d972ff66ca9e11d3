#pragma once
/// \file nonlinear_part.hpp
/// What the tangent map (linearisation.cpp) needs of nonlinear forces F(x, v, t) added to the
/// linear system M x'' + C x' + K x = f(t) (the Taylor engine, taylor_simulator.hpp):
///
///  * the acceleration M⁻¹F at a state, which enters the vector fields f∓ of the saltation
///    matrices (f = (v, a_lin + M⁻¹F) in free flight; with a held set S the recorder projects it,
///    a_S = a_lin,S + (I − M⁻¹W G⁻¹Wᵀ) M⁻¹F, the Gauss principle of taylor_step.hpp);
///  * the tangent map ∂z(t1)/∂z(t0) of the flow over a segment between events, free or with a
///    held set S, from the variational equations Φ' = ∂f_S/∂z Φ of the Taylor core
///    (taylor_step.hpp: forward-mode differentiation of the same recurrences as the state's). The
///    held vector field f_S is defined on the whole state space, as the linear engines' generator
///    Â_S is (mechanics.hpp): its flow keeps the constraint manifold invariant, and the saltation
///    at the start of sticking projects onto it;
///  * a held stop's contact force λ_a (its −λ_a is the release guard): its gradient, its rate
///    along the held flow and its parameter derivative, which the linear engines read off their
///    force rows L (λ = L z) and which here carry the forces' part G⁻¹WᵀM⁻¹F.
///
/// The rest of the tangent map — the reset R of every impact and its derivatives, the guards —
/// is the linear engines' code (mechanics.hpp): the Newton impact law depends on M, the normals
/// and the restitutions only, not on the forces.
///
/// A mode is named by its key S (contact.hpp): its held rigid stops and its engaged compliant
/// stops. The engaged stops' forces −w N, N = k_s g + c_s g' + F_p, are linear and enter the
/// linear engines' generator of S (mechanics.hpp); the flows below carry them too.
#include "vibro/contact.hpp"
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
  /// ∂z(t1)/∂z(t0) (2n × 2n) of the flow of the mode `key` (its rigid stops held, its compliant
  /// stops engaged; none: free flight) from
  /// (t0, x, v); with a parameter derivative (the part was made with one) a last column
  /// ∂z(t1)/∂p at fixed z(t0), t0, t1.
  virtual Eigen::MatrixXd transition(const ContactSet& key, double t0, const Eigen::VectorXd& x,
                                     const Eigen::VectorXd& v, double t1) = 0;
  /// The a-th held rigid stop's contact force λ_a (a = a_free − M⁻¹W λ) of the mode `key` at (t, x, v):
  /// ∂λ_a/∂z (2n), dλ_a/dt along the held flow, and ∂λ_a/∂p at fixed z, t (0 without a
  /// parameter derivative).
  struct HeldForce {
    Eigen::VectorXd gradient;
    double rate = 0.0, dp = 0.0;
  };
  virtual HeldForce held_force(const ContactSet& key, int a, double t, const Eigen::VectorXd& x,
                               const Eigen::VectorXd& v) = 0;
  /// Interior local maxima of the gaps of `stops` along the flow of the mode `key` from
  /// (t0, x, v) to t1.
  virtual std::vector<GapPeak> gap_peaks(const ContactSet& key, double t0, const Eigen::VectorXd& x,
                                         const Eigen::VectorXd& v, double t1, const std::vector<int>& stops) = 0;
  /// Interior local minima of the held rigid stops' contact forces along the flow of the mode
  /// `key` from (t0, x, v) to t1 (ForceDip::past false).
  virtual std::vector<ForceDip> force_minima(const ContactSet& key, double t0, const Eigen::VectorXd& x,
                                             const Eigen::VectorXd& v, double t1) = 0;
};

/// Runs `run` with the tangent recorder of linearisation.cpp as its observer, the vector fields
/// and the segments' tangent maps completed by `part`.
using ObservedRun = std::function<RunSummary(const std::vector<Observer*>&)>;
/// With `log_growth`, the carried directions are re-orthonormalised after every event and the logs
/// of their growth added there (orthonormal_frame.hpp).
TangentMap linearise_nonlinear(const ImpactSystem& system, const SimulatorOptions& solver, NonlinearPart& part,
                               const ObservedRun& run, double t0, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& v0, const LinearisationOptions& options,
                               Eigen::VectorXd* log_growth = nullptr);

}  // namespace vibro::detail
