#pragma once
/// \file chains.hpp
/// Chains shared by the modal engine's tests (tests only).
#include "vibro/modal.hpp"

#include <vector>

namespace vibro::test {

/// A uniform chain m = k = 1 tied to a left wall, C = βK, driven by A cos Ωt on mass 0.
inline BandedChain uniform_chain(int n, double beta, double amplitude, double frequency) {
  std::vector<double> masses(static_cast<std::size_t>(n), 1.0), springs(static_cast<std::size_t>(n - 1), 1.0);
  std::vector<double> dampers(springs.size(), beta);
  HarmonicForcing f = HarmonicForcing::zero(n, frequency);
  f.cosine(0) = amplitude;
  return BandedChain::from_links(masses, springs, dampers, 1.0, beta, 0.0, 0.0, f);
}

}  // namespace vibro::test
