#pragma once
/// \file chain.hpp
/// A chain of N masses joined by springs and dashpots, optionally tied to a left and/or right
/// wall, each mass driven by its own constant, cosine and sine force amplitudes:
///
///     wall ─k_L,c_L─ m_0 ─k_0,c_0─ m_1 ─k_1,c_1─ … ─ m_{N-1} ─k_R,c_R─ wall
///
/// giving tridiagonal K (and C):  K_ii = k_{i-1} + k_i (with k_{-1} = k_L, k_{N-1} = k_R),
/// K_{i,i+1} = K_{i+1,i} = -k_i.  Without walls K is singular (a free-free chain: one rigid-body
/// mode), which the framework handles exactly.
///
/// The system of Wagg (2004), eqs. (1)–(3), is the chain N = 2 with a left wall and
/// k_L = k_0 = k, c_L = c_0 = c, m_0 = m_1 = m: then K = k E, C = c E with E = [[2,-1],[-1,1]].
///
/// Usage:
///     auto sys = vibro::models::build_chain({.masses = {1, 1}, .springs = {1}, .dampers = {0.1},
///                                            .left_spring = 1, .left_damper = 0.1,
///                                            .force_cosine = {0.5, 0}, .frequency = 0.255});
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <vector>

namespace vibro::models {

struct Chain {
  std::vector<double> masses;          ///< m_i > 0, one per mass (N ≥ 1)
  std::vector<double> springs;         ///< k_i ≥ 0 between mass i and i+1 (N-1 entries)
  std::vector<double> dampers;         ///< c_i ≥ 0 between mass i and i+1 (N-1 entries, or empty = 0)
  double left_spring = 0.0, left_damper = 0.0;    ///< to a fixed wall left of mass 0
  double right_spring = 0.0, right_damper = 0.0;  ///< to a fixed wall right of mass N-1
  std::vector<double> force_constant;  ///< per mass, or empty = 0
  std::vector<double> force_cosine;    ///< per mass, or empty = 0
  std::vector<double> force_sine;      ///< per mass, or empty = 0
  double frequency = 0.0;              ///< Ω of the cosine and sine forces
};

/// Validates (names the field and index of a bad value) and assembles M, C, K, f.
LinearSystem build_chain(const Chain& chain);

/// Parameters of Wagg (2004), section 3, as defaults.
struct Wagg2004 {
  double m = 1.0, k = 1.0, c = 0.1;
  double A1 = 0.5, A2 = 0.0;
  double frequency = 0.255;
  double s1 = -0.3;  ///< stop below mass 1 (x1 ≥ s1)
  double s2 = 0.1;   ///< stop above mass 2 (x2 ≤ s2)
  double r = 0.7;    ///< restitution coefficient of both stops
};

Chain wagg2004_chain(const Wagg2004& p = {});

/// The paper's system with its two stops: stop 0 below mass 0 at s1 (x1 ≥ s1 in the paper's
/// numbering), stop 1 above mass 1 at s2 (x2 ≤ s2), both with restitution r.
ImpactSystem wagg2004(const Wagg2004& p = {});

}  // namespace vibro::models
