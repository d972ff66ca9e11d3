#include "vibro/taylor/taylor_system.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vibro::taylor {

namespace {

std::vector<std::string> parameter_names(const TaylorSystemSpec& spec) {
  std::vector<std::string> names = {"Omega"};
  for (const auto& [name, value] : spec.parameters) names.push_back(name);
  return names;
}

void check_square(const Eigen::MatrixXd& m, Eigen::Index n, const char* what) {
  if (m.size() == 0) return;
  if (m.rows() != n || m.cols() != n)
    throw std::invalid_argument(std::string(what) + " is " + std::to_string(m.rows()) + " x " +
                                std::to_string(m.cols()) + ", expected " + std::to_string(n) + " x " +
                                std::to_string(n) + " (the mass matrix's size)");
  if (!m.allFinite()) throw std::invalid_argument(std::string(what) + " has an entry that is not finite");
}

}  // namespace

TaylorSystem::TaylorSystem(const TaylorSystemSpec& spec)
    : n_(static_cast<int>(spec.mass.rows())), dag_(n_, parameter_names(spec)) {
  if (n_ < 1 || spec.mass.cols() != n_)
    throw std::invalid_argument("mass matrix must be square and non-empty, got " +
                                std::to_string(spec.mass.rows()) + " x " + std::to_string(spec.mass.cols()));
  check_square(spec.mass, n_, "mass matrix");
  check_square(spec.damping, n_, "damping matrix");
  check_square(spec.stiffness, n_, "stiffness matrix");
  Eigen::LLT<Eigen::MatrixXd> llt(spec.mass);
  if (llt.info() != Eigen::Success || !spec.mass.isApprox(spec.mass.transpose()))
    throw std::invalid_argument("mass matrix is not symmetric positive definite");
  m_inv_ = llt.solve(Eigen::MatrixXd::Identity(n_, n_));
  a_x_ = spec.stiffness.size() ? Eigen::MatrixXd(-m_inv_ * spec.stiffness) : Eigen::MatrixXd::Zero(n_, n_);
  a_v_ = spec.damping.size() ? Eigen::MatrixXd(-m_inv_ * spec.damping) : Eigen::MatrixXd::Zero(n_, n_);

  if (!std::isfinite(spec.frequency)) throw std::invalid_argument("forcing frequency Omega is not finite");
  parameter_values_.resize(1 + static_cast<Eigen::Index>(spec.parameters.size()));
  parameter_values_[0] = spec.frequency;
  Symbols symbols{.coordinates = n_, .parameters = {}};
  for (std::size_t j = 0; j < spec.parameters.size(); ++j) {
    const auto& [name, value] = spec.parameters[j];
    if (name.empty() || !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_'))
      throw std::invalid_argument("parameter name '" + name + "' is not an identifier");
    if (name == "Omega" || std::find(symbols.parameters.begin(), symbols.parameters.end(), name) != symbols.parameters.end() || name == "t" || name == "pi" ||
        ((name[0] == 'x' || name[0] == 'v') && name.size() > 1 &&
         name.find_first_not_of("0123456789", 1) == std::string::npos))
      throw std::invalid_argument("parameter name '" + name + "' is taken by a built-in symbol or another parameter");
    if (!std::isfinite(value)) throw std::invalid_argument("parameter '" + name + "' is not finite");
    for (Function f : {Function::Sin, Function::Cos, Function::Tan, Function::Atan, Function::Exp, Function::Log,
                       Function::Sqrt, Function::Tanh})
      if (name == function_name(f)) throw std::invalid_argument("parameter name '" + name + "' is a function's name");
    symbols.parameters.push_back(name);
    parameter_values_[static_cast<Eigen::Index>(j) + 1] = value;
  }

  if (!spec.forces.empty() && static_cast<int>(spec.forces.size()) != n_)
    throw std::invalid_argument("forces has " + std::to_string(spec.forces.size()) + " entries, expected n = " +
                                std::to_string(n_) + " (one per coordinate, \"\" for none)");
  ExpressionTree tree;
  force_nodes_.assign(n_, -1);
  for (std::size_t i = 0; i < spec.forces.size(); ++i) {
    if (spec.forces[i].find_first_not_of(" \t") == std::string::npos) continue;
    const ExpressionSource where = i < spec.force_sources.size() ? spec.force_sources[i] : ExpressionSource{};
    const int root = parse_expression(spec.forces[i], symbols, tree, where);
    const int node = dag_.compile(tree, root);
    if (!(dag_.nodes()[node].op == Op::Constant && dag_.nodes()[node].value == 0.0)) force_nodes_[i] = node;
  }
  for (std::size_t g = 0; g < spec.guards.size(); ++g) {
    const ExpressionSource where = g < spec.guard_sources.size() ? spec.guard_sources[g] : ExpressionSource{};
    const int root = parse_expression(spec.guards[g], symbols, tree, where);
    guard_nodes_.push_back(dag_.compile(tree, root));
  }
}

int TaylorSystem::parameter_index(const std::string& name) const {
  const auto& names = dag_.parameters();
  for (std::size_t j = 0; j < names.size(); ++j)
    if (names[j] == name) return static_cast<int>(j);
  return -1;
}

}  // namespace vibro::taylor
