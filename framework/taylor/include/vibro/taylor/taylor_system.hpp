#pragma once
/// \file taylor_system.hpp
/// A mechanical system with nonlinear forces, compiled for the Taylor engine:
///
///     M x'' + C x' + K x = F(x, v, t)      (n coordinates; F = forcing + nonlinear forces)
///
/// written first order in z = [x; v] (size 2n):
///
///     z' = [ v ;  A_x x + A_v v + M⁻¹ F(x, v, t) ],   A_x = −M⁻¹K,  A_v = −M⁻¹C.
///
/// F_i is an expression (expression.hpp) in x, v, t, Ω and the named parameters, compiled with
/// the guards into one Dag (common subexpressions shared between forces and guards). The linear
/// part stays out of the Dag, as the dense matrices A_x, A_v, M⁻¹: its k-th Taylor coefficient
/// is the matrix applied to the k-th coefficients, O(n²) per order with no convolution and no
/// per-node bookkeeping, while in the Dag it would be n² Multiply and Add nodes (each O(p) per
/// order for constant factors, plus their dispatch), and its Jacobian is the constant matrices
/// themselves. Only the forces that are not linear go through the Dag.
///
/// A guard g_j(x, v, t) is an expression whose Taylor polynomial over each step the event search
/// examines (e.g. a stop's gap n·x − p(t)).
///
/// Parameters: Ω is parameter 0 (spelled `Omega` in expressions); the named parameters follow
/// in the order given. The system is immutable once built; TaylorStep copies the values so a
/// continuation can change them per run.
///
/// Usage (a forced Duffing oscillator x'' + 0.1 x' + x + β x³ = 0.3 cos Ω t):
///     vibro::taylor::TaylorSystemSpec spec;
///     spec.mass = Eigen::MatrixXd::Identity(1, 1);
///     spec.damping = 0.1 * Eigen::MatrixXd::Identity(1, 1);
///     spec.stiffness = Eigen::MatrixXd::Identity(1, 1);
///     spec.frequency = 1.2;
///     spec.parameters = {{"beta", 1.0}};
///     spec.forces = {"-beta*x0^3 + 0.3*cos(Omega*t)"};
///     spec.guards = {"x0 - 1.5"};
///     vibro::taylor::TaylorSystem system(spec);   // throws ExpressionError / std::invalid_argument
#include "vibro/taylor/dag.hpp"

#include <Eigen/Dense>

#include <string>
#include <utility>
#include <vector>

namespace vibro::taylor {

struct TaylorSystemSpec {
  Eigen::MatrixXd mass;       ///< n × n, symmetric positive definite
  Eigen::MatrixXd damping;    ///< n × n, or empty for none
  Eigen::MatrixXd stiffness;  ///< n × n, or empty for none
  double frequency = 0.0;     ///< Ω
  std::vector<std::pair<std::string, double>> parameters;  ///< name, value
  std::vector<std::string> forces;           ///< F_i, n entries ("" for none) or empty
  std::vector<ExpressionSource> force_sources;  ///< optional: where each force's text starts
  std::vector<std::string> guards;
  std::vector<ExpressionSource> guard_sources;  ///< optional
};

class TaylorSystem {
 public:
  explicit TaylorSystem(const TaylorSystemSpec& spec);

  int coordinates() const { return n_; }
  int state_size() const { return 2 * n_; }
  const Dag& dag() const { return dag_; }
  /// Dag node of F_i, or −1 where coordinate i has no nonlinear force.
  const std::vector<int>& force_nodes() const { return force_nodes_; }
  const std::vector<int>& guard_nodes() const { return guard_nodes_; }
  int guard_count() const { return static_cast<int>(guard_nodes_.size()); }
  const Eigen::MatrixXd& position_matrix() const { return a_x_; }  ///< −M⁻¹K
  const Eigen::MatrixXd& velocity_matrix() const { return a_v_; }  ///< −M⁻¹C
  const Eigen::MatrixXd& inverse_mass() const { return m_inv_; }
  /// Ω, then the named parameters.
  const Eigen::VectorXd& parameter_values() const { return parameter_values_; }
  /// Index of a parameter by name ("Omega" is 0); −1 if unknown.
  int parameter_index(const std::string& name) const;

 private:
  int n_;
  Dag dag_;
  std::vector<int> force_nodes_, guard_nodes_;
  Eigen::MatrixXd a_x_, a_v_, m_inv_;
  Eigen::VectorXd parameter_values_;
};

}  // namespace vibro::taylor
