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
///  * a held stop's contact force λ_a (its −λ_a is the release guard): its value, its gradient,
///    its rate along the held flow and its parameter derivative, which the linear engines read
///    off their force rows L (λ = L z) and which here carry the forces' part G⁻¹WᵀM⁻¹F.
///
/// The rest of the tangent map — the reset R of every impact and its derivatives, the guards —
/// is the linear engines' code (mechanics.hpp): the Newton impact law depends on M, the normals
/// and the restitutions only, not on the forces. One part of a reset reads a force: the second-
/// and third-order chatter rules' capture scales the skipped bounces' displacement by the held
/// stop's contact acceleration A = G_jj λ_j (mechanics.hpp, reset step 2), which the Taylor
/// engine takes with the forces in it; chatter_forces() gives the reset that λ, from held_force.
///
/// A mode is named by its key S (contact.hpp): its held rigid stops and its engaged compliant
/// stops. The engaged stops' forces −w N, N = k_s g + c_s g' + F_p, are linear and enter the
/// linear engines' generator of S (mechanics.hpp); the flows below carry them too.
#include "mechanics.hpp"
#include "vibro/contact.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/observers.hpp"

#include <Eigen/Dense>

#include <functional>
#include <type_traits>
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
  /// its value, ∂λ_a/∂z (2n), ∂λ_a/∂t at fixed z, dλ_a/dt along the held flow, and ∂λ_a/∂p at
  /// fixed z, t (0 without a parameter derivative).
  struct HeldForce {
    double value = 0.0;
    Eigen::VectorXd gradient;
    double time = 0.0, rate = 0.0, dp = 0.0;
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

/// The held rigid stops' forces λ of a mode with the forces' part, for Mechanics<T>::
/// set_chatter_forces on the Mechanics `mech` (its held_part): part.held_force's values for
/// T = double; for T = Dual along the seeds' direction ∂λ/∂z δz + ∂λ/∂t δt, plus ∂λ/∂p when
/// `parameter` (mech carries the parameter direction the part was made with). `mech` and `part`
/// must outlive the function.
template <class T>
typename Mechanics<T>::ChatterForces chatter_forces(const Mechanics<T>& mech, NonlinearPart& part, bool parameter) {
  return [&mech, &part, parameter](const ContactSet& key, const VecT<T>& x, const VecT<T>& v, const T& t) {
    const ContactSet held = mech.held_part(key);
    const Eigen::Index n = x.size();
    Eigen::VectorXd xv(n), vv(n), dz(2 * n);
    for (Eigen::Index i = 0; i < n; ++i) {
      xv(i) = value_of(x(i));
      vv(i) = value_of(v(i));
      if constexpr (!std::is_same_v<T, double>) {
        dz(i) = x(i).d;
        dz(n + i) = v(i).d;
      }
    }
    VecT<T> out(static_cast<Eigen::Index>(held.size()));
    for (std::size_t a = 0; a < held.size(); ++a) {
      const NonlinearPart::HeldForce f = part.held_force(key, static_cast<int>(a), value_of(t), xv, vv);
      if constexpr (std::is_same_v<T, double>) {
        out(static_cast<Eigen::Index>(a)) = f.value;
      } else {
        out(static_cast<Eigen::Index>(a)) = T(f.value, f.gradient.dot(dz) + f.time * t.d + (parameter ? f.dp : 0.0));
      }
    }
    return out;
  };
}

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
