#pragma once
// Private to vibro_analysis: the exact derivatives of an event's reset (mechanics.hpp's reset
// with its discrete decisions fixed) by forward-mode differentiation, for the saltation matrices
// of the dense engine's recorder (linearisation.cpp) and of the friction-with-stops one
// (friction_stops_tangent.cpp):
//   R_z (2n × 2n) column by column, c = R_z f⁻ + R_t along the flow f⁻, and R_p along the
//   parameter the Mechanics<Dual> carries.
#include "mechanics.hpp"

namespace vibro::detail {

inline VecT<Dual> seeded(const Eigen::VectorXd& value, const Eigen::VectorXd& direction) {
  VecT<Dual> out(value.size());
  for (Eigen::Index i = 0; i < value.size(); ++i) out(i) = Dual(value(i), direction.size() ? direction(i) : 0.0);
  return out;
}
inline Eigen::VectorXd derivative(const VecT<Dual>& a) {
  Eigen::VectorXd out(a.size());
  for (Eigen::Index i = 0; i < a.size(); ++i) out(i) = a(i).d;
  return out;
}
inline Eigen::MatrixXd derivative(const MatT<Dual>& a) {
  Eigen::MatrixXd out(a.rows(), a.cols());
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index k = 0; k < a.cols(); ++k) out(i, k) = a(i, k).d;
  return out;
}

struct ResetDerivative {
  Eigen::MatrixXd state;       ///< R_z
  Eigen::VectorXd along_flow;  ///< R_z f⁻ + R_t
};

/// The reset's derivatives at (x, v⁻, t) with the flow f⁻ = (ẋ, v̇) there; `mech` seeds no
/// parameter (its data's derivatives are zero).
inline ResetDerivative reset_derivative(const Mechanics<Dual>& mech, const ResetRule& rule, const Eigen::VectorXd& x,
                                        const Eigen::VectorXd& vm, double t, const Eigen::VectorXd& fm) {
  const Eigen::Index n = x.size(), N2 = 2 * n;
  auto reset_along = [&](const Eigen::VectorXd& dx, const Eigen::VectorXd& dv, double dt) {
    return derivative(mech.reset(rule, seeded(x, dx), seeded(vm, dv), Dual(t, dt)));
  };
  ResetDerivative out;
  out.state.resize(N2, N2);
  for (Eigen::Index i = 0; i < N2; ++i) {
    Eigen::VectorXd dx = Eigen::VectorXd::Zero(n), dv = Eigen::VectorXd::Zero(n);
    (i < n ? dx(i) : dv(i - n)) = 1.0;
    out.state.col(i) = reset_along(dx, dv, 0.0);
  }
  out.along_flow = reset_along(fm.head(n), fm.tail(n), 1.0);
  return out;
}

/// ∂R/∂p at fixed (x, v⁻, t), `mechp` carrying dD/dp.
inline Eigen::VectorXd reset_parameter(const Mechanics<Dual>& mechp, const ResetRule& rule, const Eigen::VectorXd& x,
                                       const Eigen::VectorXd& vm, double t) {
  return derivative(mechp.reset(rule, seeded(x, Eigen::VectorXd()), seeded(vm, Eigen::VectorXd()), Dual(t)));
}

}  // namespace vibro::detail
