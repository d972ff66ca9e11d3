#pragma once
/// \file system.hpp
/// The linear mechanical system between events:
///
///     M x'' + C x' + K x = f(t),   f(t) = F0 + Fc cos(Ω t) + Fs sin(Ω t)
///                                         + Σ_h (Fc_h cos(k_h Ω t) + Fs_h sin(k_h Ω t)),
///
/// the sum over the extra harmonics h of orders k_h ≥ 2 (distinct; none by default), so that
/// T = 2π/Ω stays the period of the drive.
/// with n degrees of freedom, M symmetric positive definite, C and K symmetric positive
/// semi-definite (a singular K means rigid-body modes; C = 0 is allowed). Units are the user's:
/// the framework only assumes they are consistent (mass, length, time).
///
/// A LinearSystem is immutable and validated on construction: once built it is correct, and
/// everything downstream (flows, contact sets, simulators) takes it by const reference.
///
/// Usage:
///     vibro::HarmonicForcing f{.constant = Eigen::VectorXd::Zero(2),
///                              .cosine = Eigen::Vector2d(0.5, 0.0),
///                              .sine = Eigen::VectorXd::Zero(2), .frequency = 0.255};
///     vibro::LinearSystem sys(M, C, K, f);     // throws vibro::InvalidInput on bad data
#include <Eigen/Dense>

#include <stdexcept>
#include <string>
#include <vector>

namespace vibro {

/// A number as text with all 17 significant digits, for messages that must give the exact value.
std::string number_text(double v);

/// Bad user input: a message that names the quantity, the index and the value.
class InvalidInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// One extra harmonic of the drive: cosine cos(k Ω t) + sine sin(k Ω t), order k ≥ 2.
struct ForcingHarmonic {
  int order = 2;
  Eigen::VectorXd cosine;
  Eigen::VectorXd sine;
  /// Its angular frequency k Ω, computed once as this product (every evaluation of cos(k Ω t)
  /// in the framework uses rate(Ω) · t, so all agree bit for bit).
  double rate(double frequency) const { return static_cast<double>(order) * frequency; }
};

/// f(t) = constant + cosine cos(Ω t) + sine sin(Ω t) + Σ_h harmonics[h] at k_h Ω;
/// Ω = frequency ≥ 0 (rad per unit time). The first harmonic is always cosine and sine; the
/// vector `harmonics` holds the higher orders only (k ≥ 2, distinct), in any order: each adds
/// two components to the augmented state of the flow (augmented_size).
struct HarmonicForcing {
  Eigen::VectorXd constant;
  Eigen::VectorXd cosine;
  Eigen::VectorXd sine;
  double frequency = 0.0;
  std::vector<ForcingHarmonic> harmonics = {};

  /// No forcing at all on n degrees of freedom.
  static HarmonicForcing zero(Eigen::Index n, double frequency = 0.0);
  Eigen::VectorXd at(double t) const;
};

/// Size of the augmented state [x; v; cos Ωt; sin Ωt; 1; cos k₁Ωt; sin k₁Ωt; …] of n degrees of
/// freedom under a drive with `extra` harmonics of order ≥ 2: 2n + 3 + 2·extra (flow.hpp).
constexpr Eigen::Index augmented_size(Eigen::Index n, std::size_t extra = 0) {
  return 2 * n + 3 + 2 * static_cast<Eigen::Index>(extra);
}
/// The same for a given forcing.
inline Eigen::Index augmented_size(Eigen::Index n, const HarmonicForcing& f) {
  return augmented_size(n, f.harmonics.size());
}

class LinearSystem {
 public:
  /// Validates and stores. Throws InvalidInput naming the matrix, the entry and the value when
  /// sizes disagree, an entry is not finite, a matrix is not symmetric (relative 1e-12), M is not
  /// positive definite (a non-positive mass is reported as such) or C, K is not semi-definite,
  /// or a harmonic's order is < 2 or repeated.
  LinearSystem(Eigen::MatrixXd mass, Eigen::MatrixXd damping, Eigen::MatrixXd stiffness,
               HarmonicForcing forcing);

  Eigen::Index dof() const { return mass_.rows(); }
  const Eigen::MatrixXd& mass() const { return mass_; }
  const Eigen::MatrixXd& damping() const { return damping_; }
  const Eigen::MatrixXd& stiffness() const { return stiffness_; }
  const HarmonicForcing& forcing() const { return forcing_; }

  /// Acceleration M⁻¹ (f(t) - C v - K x).
  Eigen::VectorXd acceleration(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) const;
  /// Kinetic plus elastic energy ½ vᵀMv + ½ xᵀKx.
  double energy(const Eigen::VectorXd& x, const Eigen::VectorXd& v) const;

 private:
  Eigen::MatrixXd mass_, damping_, stiffness_;
  HarmonicForcing forcing_;
  Eigen::LLT<Eigen::MatrixXd> mass_llt_;
};

}  // namespace vibro
