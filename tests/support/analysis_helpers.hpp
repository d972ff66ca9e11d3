#pragma once
/// \file analysis_helpers.hpp
/// Small helpers shared by the analysis layer's tests (tests only): states as one vector (x, v),
/// the state's scales, and the engine's map between two times.
#include "vibro/simulator.hpp"

#include <Eigen/Dense>

#include <stdexcept>

namespace vibro::test {

inline Eigen::VectorXd stack(const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  Eigen::VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// L for the n positions, V for the n velocities.
inline Eigen::VectorXd state_scale(Eigen::Index n, double L, double V) {
  Eigen::VectorXd s(2 * n);
  s << Eigen::VectorXd::Constant(n, L), Eigen::VectorXd::Constant(n, V);
  return s;
}

/// The engine's map (x0, v0) at t0 ↦ (x1, v1) at t1; throws if the run does not complete.
inline Eigen::VectorXd engine_map(const ImpactSystem& sys, const SimulatorOptions& o, double t0,
                                  const Eigen::VectorXd& z0, double t1) {
  const auto n = sys.dof();
  Simulator sim(sys, o);
  const RunSummary s = sim.run(t0, z0.head(n), z0.tail(n), t1);
  if (s.status != RunStatus::completed) throw std::runtime_error("engine_map: " + s.message);
  return stack(s.x, s.v);
}

}  // namespace vibro::test
