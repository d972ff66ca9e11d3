#pragma once
// Private to vibro_analysis: what the tangent maps of friction runs without stops and with stops
// (friction_tangent.cpp, friction_stops_tangent.cpp) both need, written once: the data moved
// along a parameter derivative (the modes' rows are differentiated by differences of them), the
// augmented state and its oscillator's sensitivity to Ω, the basis of a mode's tangent space, and
// the sliding features: the interior minima of a slipping contact's σu (grazing-sliding) and of a
// stuck contact's margin μ_s N − |F| (adding-sliding).
#include "vibro/friction.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/parameter.hpp"

#include <Eigen/QR>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace vibro::detail {

template <class Derived>
double max_abs(const Eigen::MatrixBase<Derived>& a) {
  return a.size() ? a.cwiseAbs().maxCoeff() : 0.0;
}

/// The data D moved by h along dD (M fixed): C, K, the forcing, Ω, the contacts' N, μ_s, μ_k.
struct MovedData {
  Eigen::MatrixXd C, K;
  HarmonicForcing f;
  std::vector<FrictionContact> contacts;
};
inline MovedData moved(const LinearSystem& s, const std::vector<FrictionContact>& contacts, const SystemDerivative& d,
                       double h) {
  MovedData out{s.damping(), s.stiffness(), s.forcing(), contacts};
  for (std::size_t j = 0; j < d.friction.size(); ++j) {
    out.contacts[j].normal_load += h * d.friction[j].normal_load;
    out.contacts[j].static_coefficient += h * d.friction[j].static_coefficient;
    out.contacts[j].kinetic_coefficient += h * d.friction[j].kinetic_coefficient;
  }
  if (d.damping.size()) out.C += h * d.damping;
  if (d.stiffness.size()) out.K += h * d.stiffness;
  if (d.constant.size()) out.f.constant += h * d.constant;
  if (d.cosine.size()) out.f.cosine += h * d.cosine;
  if (d.sine.size()) out.f.sine += h * d.sine;
  for (std::size_t i = 0; i < out.f.harmonics.size(); ++i) {
    if (i < d.harmonic_cosine.size() && d.harmonic_cosine[i].size()) out.f.harmonics[i].cosine += h * d.harmonic_cosine[i];
    if (i < d.harmonic_sine.size() && d.harmonic_sine[i].size()) out.f.harmonics[i].sine += h * d.harmonic_sine[i];
  }
  out.f.frequency += h * d.frequency;
  return out;
}

/// The size of the data and of its move along d (the largest entries), for a difference step.
inline void data_and_move(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                          const SystemDerivative& d, double& size, double& move) {
  const HarmonicForcing& f = system.forcing();
  size = std::max({max_abs(system.damping()), max_abs(system.stiffness()), max_abs(f.constant), max_abs(f.cosine),
                   max_abs(f.sine), std::abs(f.frequency), 1e-300});
  move = std::max({max_abs(d.damping), max_abs(d.stiffness), max_abs(d.constant), max_abs(d.cosine), max_abs(d.sine),
                   std::abs(d.frequency)});
  for (const auto& v : d.harmonic_cosine) move = std::max(move, max_abs(v));
  for (const auto& v : d.harmonic_sine) move = std::max(move, max_abs(v));
  for (const ForcingHarmonic& hh : f.harmonics) size = std::max({size, max_abs(hh.cosine), max_abs(hh.sine)});
  for (const FrictionContact& c : contacts) size = std::max({size, c.normal_load, c.static_coefficient, c.kinetic_coefficient});
  for (const FrictionDerivative& c : d.friction)
    move = std::max({move, std::abs(c.normal_load), std::abs(c.static_coefficient), std::abs(c.kinetic_coefficient)});
}

/// z = [x; v; cos Ωt; sin Ωt; 1; cos k_hΩt; sin k_hΩt; …] (flow.hpp's layout).
inline Eigen::VectorXd augmented_of(const HarmonicForcing& f, Eigen::Index n, Eigen::Index N, double t,
                                    const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  Eigen::VectorXd z = Eigen::VectorXd::Zero(N);
  z << x, v, std::cos(f.frequency * t), std::sin(f.frequency * t), 1.0,
      Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(f.harmonics.size()));
  for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
    const double rate = f.harmonics[h].rate(f.frequency);
    z(2 * n + 3 + 2 * static_cast<Eigen::Index>(h)) = std::cos(rate * t);
    z(2 * n + 4 + 2 * static_cast<Eigen::Index>(h)) = std::sin(rate * t);
  }
  return z;
}

/// d/dp of (cos Ωt, sin Ωt, 1, cos k_hΩt, sin k_hΩt, …) at t: k t dΩ/dp (−sin, cos); `size` is
/// N − 2n.
inline Eigen::VectorXd oscillator_sensitivity_of(const HarmonicForcing& f, double dw, Eigen::Index size, double t) {
  const double w = f.frequency;
  Eigen::VectorXd out = Eigen::VectorXd::Zero(size);
  out(0) = -t * std::sin(w * t) * dw;
  out(1) = t * std::cos(w * t) * dw;
  for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
    const double rate = f.harmonics[h].rate(w), k = rate / w;
    out(3 + 2 * static_cast<Eigen::Index>(h)) = -k * t * std::sin(rate * t) * dw;
    out(4 + 2 * static_cast<Eigen::Index>(h)) = k * t * std::cos(rate * t) * dw;
  }
  return out;
}

/// An orthonormal basis (columns) of the complement of span(B) in Rⁿ, and rank B.
inline Eigen::MatrixXd complement_basis(const Eigen::MatrixXd& B, Eigen::Index n, Eigen::Index* rank = nullptr) {
  if (B.cols() == 0) {
    if (rank) *rank = 0;
    return Eigen::MatrixXd::Identity(n, n);
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(B);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(n, n);
  const Eigen::Index r = qr.rank();
  if (rank) *rank = r;
  return Q.rightCols(n - r);
}

/// The tangent map a friction recorder carries: K (the map since the last split, or the carried
/// directions' images), J_mid (the map up to that split) and the tangent basis there; J splits
/// where the run reaches its least tangent dimension (linearisation.hpp, structural zeros).
struct CarriedMap {
  Eigen::MatrixXd K, Jmid, basis;
  Eigen::Index min_dim = 0;

  void start(Eigen::Index N2, bool frame, const Eigen::MatrixXd& directions) {
    if (frame) K = directions;
    else K = Eigen::MatrixXd::Identity(N2, N2);
    Jmid = Eigen::MatrixXd::Identity(N2, N2);
    basis = Eigen::MatrixXd::Identity(N2, N2);
    min_dim = N2;
  }
  /// A segment in a mode of tangent dimension `dim` (basis `mode_basis`): J is split here when
  /// it is the least so far and `split` (the whole Jacobian is carried).
  void reached(Eigen::Index dim, const Eigen::MatrixXd& mode_basis, bool split) {
    if (dim >= min_dim) return;
    min_dim = dim;
    if (!split) return;
    Jmid = K * Jmid;
    K.setIdentity();
    basis = mode_basis;
  }
  /// J (or the products), the reduced map, its lift and the free dimension into `out`;
  /// `started` false: the run had no segment (the identity).
  void write(bool started, bool frame, bool jacobian, const Eigen::MatrixXd& directions, Eigen::Index N2,
             TangentMap& out) const {
    out.free_dimension = started ? min_dim : N2;
    if (started) {
      if (frame) {
        out.products = K;
      } else if (jacobian) {
        out.jacobian = K * Jmid;
        if (min_dim < N2) {
          out.reduced = basis.transpose() * Jmid * K * basis;
          out.lift = K * basis;
        } else {
          out.reduced = out.jacobian;
          out.lift = Eigen::MatrixXd::Identity(N2, N2);
        }
      }
    } else if (jacobian && !frame) {
      out.jacobian = out.reduced = out.lift = Eigen::MatrixXd::Identity(N2, N2);
    } else if (frame) {
      out.products = directions;
    }
  }
};

/// An interior local minimum, at t, of a row value ℓᵀz(t) of frictional contact `contact` over a
/// segment.
struct InteriorMinimum {
  int contact;
  double t, value;
};

/// The interior local minima of ℓᵀz(t) over a segment of length τ from z_b at t_b, for every
/// (contact, ℓ) of `rows`, on the exact flow z(t) = exp(A (t − t_b)) z_b of the mode of generator
/// A: 64 samples, each sign change of (ℓᵀz)' = ℓᵀA z from − to + refined by bisection (not
/// certified: two minima within one sample are seen as none; one at an end is not interior).
inline void interior_minima(const Eigen::MatrixXd& A, const std::vector<std::pair<int, Eigen::VectorXd>>& rows,
                            double tb, double tau, const Eigen::VectorXd& zb, std::vector<InteriorMinimum>& out) {
  if (rows.empty()) return;
  constexpr int samples = 64;
  const Eigen::MatrixXd step = (A * (tau / samples)).exp();
  std::vector<Eigen::VectorXd> z(samples + 1);
  z[0] = zb;
  for (int i = 0; i < samples; ++i) z[static_cast<std::size_t>(i + 1)] = step * z[static_cast<std::size_t>(i)];
  for (const auto& [contact, row] : rows) {
    const Eigen::VectorXd rate = A.transpose() * row;  // (ℓᵀz)' = ℓᵀ A z
    for (int i = 0; i < samples; ++i) {
      const double a = rate.dot(z[static_cast<std::size_t>(i)]), b = rate.dot(z[static_cast<std::size_t>(i + 1)]);
      if (!(a < 0.0 && b >= 0.0)) continue;
      double lo = i * tau / samples, hi = (i + 1) * tau / samples;
      for (int it = 0; it < 60 && hi - lo > 1e-15 * std::max(1.0, std::abs(tb) + tau); ++it) {
        const double mid = 0.5 * (lo + hi);
        const Eigen::VectorXd zm = (A * mid).exp() * zb;
        (rate.dot(zm) < 0.0 ? lo : hi) = mid;
      }
      const double s = 0.5 * (lo + hi);
      if (s <= 1e-9 * tau || s >= (1.0 - 1e-9) * tau) continue;  // an end, not an interior minimum
      out.push_back({contact, tb + s, row.dot((A * s).exp() * zb)});
    }
  }
}

/// The interior local minima of σ_j u_j of every slipping contact (u = relative z): → 0 at a
/// grazing-sliding bifurcation, where a stick phase is born inside a slip.
inline void slip_minima(const Eigen::MatrixXd& A, const Eigen::MatrixXd& relative, const std::vector<FrictionState>& states,
                        double tb, double tau, const Eigen::VectorXd& zb, std::vector<InteriorMinimum>& out) {
  std::vector<std::pair<int, Eigen::VectorXd>> rows;
  for (std::size_t j = 0; j < states.size(); ++j) {
    if (states[j] == FrictionState::stuck) continue;
    const double sigma = states[j] == FrictionState::slip_positive ? 1.0 : -1.0;
    rows.emplace_back(static_cast<int>(j), sigma * relative.row(static_cast<Eigen::Index>(j)).transpose());
  }
  interior_minima(A, rows, tb, tau, zb, out);
}

/// The margins μ_s N_j − |F_j| of every stuck contact (F = force z, the force holding it) at the
/// interior local maxima of |F_j|: → 0 at an adding-sliding bifurcation, where a slip is born
/// inside a stick phase (the sliding flow touches the boundary of the sliding region; di Bernardo
/// et al. 2008, ch. 8), the counterpart of a held stop's contact force dipping to zero. A contact
/// whose tangent the held stops already fix (`locked`, with stops) holds nothing of its own and
/// is skipped.
inline void stick_margins(const Eigen::MatrixXd& A, const Eigen::MatrixXd& force, const std::vector<FrictionState>& states,
                          const std::vector<FrictionContact>& contacts, const std::vector<char>* locked, double tb,
                          double tau, const Eigen::VectorXd& zb, std::vector<InteriorMinimum>& out) {
  std::vector<std::pair<int, Eigen::VectorXd>> rows;
  for (std::size_t j = 0; j < states.size(); ++j) {
    if (states[j] != FrictionState::stuck || (locked && (*locked)[j])) continue;
    const Eigen::VectorXd F = force.row(static_cast<Eigen::Index>(j)).transpose();
    rows.emplace_back(static_cast<int>(j), F);   // minima of F: |F| maxima where F < 0
    rows.emplace_back(static_cast<int>(j), -F);  // minima of −F: |F| maxima where F > 0
  }
  std::vector<InteriorMinimum> found;
  interior_minima(A, rows, tb, tau, zb, found);
  for (const InteriorMinimum& m : found) {
    if (!(m.value < 0.0)) continue;  // an extremum of F that is no maximum of |F|
    const FrictionContact& c = contacts[static_cast<std::size_t>(m.contact)];
    out.push_back({m.contact, m.t, c.static_coefficient * c.normal_load + m.value});  // μ_s N − |F|
  }
}

}  // namespace vibro::detail
