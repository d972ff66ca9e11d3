#include "vibro/system.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <sstream>

namespace vibro {
namespace {

void require_finite_matrix(const Eigen::MatrixXd& a, const char* name) {
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j)
      if (!std::isfinite(a(i, j)))
        throw InvalidInput(std::string(name) + ": entry (" + std::to_string(i) + "," +
                           std::to_string(j) + ") is " + number_text(a(i, j)) +
                           ": every entry must be a finite number");
}

void require_square(const Eigen::MatrixXd& a, Eigen::Index n, const char* name) {
  if (a.rows() != n || a.cols() != n)
    throw InvalidInput(std::string(name) + ": size is " + std::to_string(a.rows()) + "x" +
                       std::to_string(a.cols()) + ", expected " + std::to_string(n) + "x" +
                       std::to_string(n) + " (the mass matrix's size)");
}

void require_symmetric(const Eigen::MatrixXd& a, const char* name) {
  const double scale = a.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = i + 1; j < a.cols(); ++j)
      if (std::abs(a(i, j) - a(j, i)) > 1e-12 * scale)
        throw InvalidInput(std::string(name) + ": entry (" + std::to_string(i) + "," +
                           std::to_string(j) + ") = " + number_text(a(i, j)) + " but (" +
                           std::to_string(j) + "," + std::to_string(i) + ") = " +
                           number_text(a(j, i)) + ": the matrix must be symmetric");
}

/// Smallest eigenvalue must be ≥ -1e-12 ‖A‖ (semi-definite up to rounding).
void require_semidefinite(const Eigen::MatrixXd& a, const char* name) {
  if (a.size() == 0) return;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a, Eigen::EigenvaluesOnly);
  const double scale = std::max(a.cwiseAbs().maxCoeff(), 1e-300);
  const double lowest = eig.eigenvalues()(0);
  if (lowest < -1e-12 * scale)
    throw InvalidInput(std::string(name) + ": smallest eigenvalue is " + number_text(lowest) +
                       ": the matrix must be positive semi-definite");
}

void require_vector(const Eigen::VectorXd& v, Eigen::Index n, const std::string& name) {
  if (v.size() != n)
    throw InvalidInput(std::string("forcing.") + name + ": length is " + std::to_string(v.size()) +
                       ", expected " + std::to_string(n) + " (one entry per degree of freedom)");
  for (Eigen::Index i = 0; i < n; ++i)
    if (!std::isfinite(v(i)))
      throw InvalidInput(std::string("forcing.") + name + ": entry " + std::to_string(i) +
                         " is " + number_text(v(i)) + ": must be a finite number");
}

}  // namespace

std::string number_text(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

HarmonicForcing HarmonicForcing::zero(Eigen::Index n, double frequency) {
  return {Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n), frequency};
}

Eigen::VectorXd HarmonicForcing::at(double t) const {
  Eigen::VectorXd f = constant + cosine * std::cos(frequency * t) + sine * std::sin(frequency * t);
  for (const ForcingHarmonic& h : harmonics) {
    const double w = h.rate(frequency);
    f += h.cosine * std::cos(w * t) + h.sine * std::sin(w * t);
  }
  return f;
}

LinearSystem::LinearSystem(Eigen::MatrixXd mass, Eigen::MatrixXd damping, Eigen::MatrixXd stiffness,
                           HarmonicForcing forcing)
    : mass_(std::move(mass)),
      damping_(std::move(damping)),
      stiffness_(std::move(stiffness)),
      forcing_(std::move(forcing)) {
  const Eigen::Index n = mass_.rows();
  if (n == 0 || mass_.cols() != n)
    throw InvalidInput("mass matrix: size is " + std::to_string(mass_.rows()) + "x" +
                       std::to_string(mass_.cols()) + ": must be square with at least one row");
  require_square(damping_, n, "damping matrix");
  require_square(stiffness_, n, "stiffness matrix");
  require_finite_matrix(mass_, "mass matrix");
  require_finite_matrix(damping_, "damping matrix");
  require_finite_matrix(stiffness_, "stiffness matrix");
  for (Eigen::Index i = 0; i < n; ++i)
    if (!(mass_(i, i) > 0.0))
      throw InvalidInput("mass matrix: diagonal entry " + std::to_string(i) + " is " +
                         number_text(mass_(i, i)) + ": every mass must be positive");
  require_symmetric(mass_, "mass matrix");
  require_symmetric(damping_, "damping matrix");
  require_symmetric(stiffness_, "stiffness matrix");
  mass_llt_.compute(mass_);
  if (mass_llt_.info() != Eigen::Success)
    throw InvalidInput("mass matrix: not positive definite (Cholesky factorisation failed)");
  require_semidefinite(damping_, "damping matrix");
  require_semidefinite(stiffness_, "stiffness matrix");
  require_vector(forcing_.constant, n, "constant");
  require_vector(forcing_.cosine, n, "cosine");
  require_vector(forcing_.sine, n, "sine");
  for (std::size_t h = 0; h < forcing_.harmonics.size(); ++h) {
    const ForcingHarmonic& fh = forcing_.harmonics[h];
    const std::string who = "harmonics[" + std::to_string(h) + "]";
    if (fh.order < 2)
      throw InvalidInput("forcing." + who + ".order: is " + std::to_string(fh.order) +
                         ": an extra harmonic has order ≥ 2 (order 1 is forcing.cosine and forcing.sine)");
    for (std::size_t g = 0; g < h; ++g)
      if (forcing_.harmonics[g].order == fh.order)
        throw InvalidInput("forcing." + who + ".order: order " + std::to_string(fh.order) +
                           " is given twice (also harmonics[" + std::to_string(g) + "])");
    require_vector(fh.cosine, n, (who + ".cosine").c_str());
    require_vector(fh.sine, n, (who + ".sine").c_str());
  }
  if (!std::isfinite(forcing_.frequency) || forcing_.frequency < 0.0)
    throw InvalidInput("forcing.frequency: is " + number_text(forcing_.frequency) +
                       ": must be a finite number ≥ 0");
}

Eigen::VectorXd LinearSystem::acceleration(double t, const Eigen::VectorXd& x,
                                           const Eigen::VectorXd& v) const {
  return mass_llt_.solve(forcing_.at(t) - damping_ * v - stiffness_ * x);
}

double LinearSystem::energy(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
  return 0.5 * v.dot(mass_ * v) + 0.5 * x.dot(stiffness_ * x);
}

}  // namespace vibro
