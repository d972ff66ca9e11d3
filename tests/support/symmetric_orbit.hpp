#pragma once
/// \file symmetric_orbit.hpp
/// The reference for symmetry-breaking branch points (tests only). A one-degree-of-freedom system
/// unchanged by x → −x, t → t + T/2 has the half-period map H(z) = −z(T/2) of the run from
/// (0, z): a symmetric orbit is a fixed point of H, its period map is H∘H and its multipliers the
/// squares of H's, so where it loses its symmetry a multiplier of H passes −1.
#include <catch2/catch.hpp>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <utility>

namespace vibro::test {

/// The fixed point of the 2 × 2 map H by Newton from z, its Jacobians by central differences with
/// `step` (plain runs: no analysis code), to |H(z) − z| < 1e-13; and H's real multiplier nearest
/// −1 there. Fails the test if Newton does not get there in 30 iterations.
inline std::pair<Eigen::VectorXd, double> symmetric_fixed_point(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& H, Eigen::VectorXd z, double step) {
  for (int it = 0; it < 30; ++it) {
    Eigen::Matrix2d J;
    for (Eigen::Index i = 0; i < 2; ++i) {
      Eigen::VectorXd zp = z, zm = z;
      zp(i) += step;
      zm(i) -= step;
      J.col(i) = (H(zp) - H(zm)) / (2.0 * step);
    }
    const Eigen::VectorXd r = H(z) - z;
    if (r.norm() < 1e-13) {
      double nearest = std::numeric_limits<double>::infinity();
      for (const std::complex<double>& m : Eigen::Vector2cd(J.eigenvalues()))
        if (std::abs(m.imag()) < 1e-9 && std::abs(m.real() + 1.0) < std::abs(nearest + 1.0)) nearest = m.real();
      return {z, nearest};
    }
    z -= (J - Eigen::Matrix2d::Identity()).partialPivLu().solve(r);
  }
  FAIL("no fixed point of the half-period map");
  return {};
}

}  // namespace vibro::test
