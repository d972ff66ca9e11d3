#pragma once
// Private to vibro_core: the modal chain engine's pieces shared by its files: the stops' sparse
// normals and harmonic motions, the chain's banded products, a contact set's modal form
// (build_mode, modal_modes.cpp), the basis changes between physical and modal states and the
// guards' values (modal_modes.cpp). The guards' crossings are located by events.hpp's
// CrossingFinder on a ModalGuardSource (modal.hpp, modal_guards.cpp).
#include "vibro/modal.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace vibro::detail {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The nonzero entries of a stop's normal w: (mass, weight) pairs, or for a stop along a general
/// normal (Stop::Kind::normal) the whole vector.
struct Normal {
  Eigen::Index i = 0, k = -1;
  double wi = 1.0, wk = 0.0;
  Eigen::VectorXd dense;  ///< w itself for a general normal; empty otherwise (i, k, wi, wk unused then)

  bool general() const { return dense.size() > 0; }
  /// f(l, w_l) for each nonzero entry (the two sparse ones, or the general normal's).
  template <class F>
  void for_each(F&& f) const {
    if (general()) {
      for (Eigen::Index l = 0; l < dense.size(); ++l)
        if (dense(l) != 0.0) f(l, dense(l));
      return;
    }
    f(i, wi);
    if (k >= 0) f(k, wk);
  }
  /// w_l.
  double entry(Eigen::Index l) const {
    if (general()) return dense(l);
    return (l == i ? wi : 0.0) + (k >= 0 && l == k ? wk : 0.0);
  }
};

inline Normal normal_of(const Stop& s) {
  switch (s.kind) {
    case Stop::Kind::upper: return {s.mass, -1, 1.0, 0.0, {}};
    case Stop::Kind::lower: return {s.mass, -1, -1.0, 0.0, {}};
    case Stop::Kind::between: return {s.mass, s.other, 1.0, -1.0, {}};
    case Stop::Kind::normal: return {0, -1, 0.0, 0.0, s.direction};
  }
  return {};
}

/// w_aᵀ M⁻¹ w_b for diagonal M: O(1) for sparse normals, O(N) with a general one.
inline double delassus_entry(const Normal& a, const Normal& b, const Eigen::VectorXd& mass) {
  double sum = 0.0;
  if (a.general() && b.general()) return a.dense.dot(b.dense.cwiseQuotient(mass));
  const Normal& sparse = a.general() ? b : a;
  const Normal& other = a.general() ? a : b;
  sparse.for_each([&](Eigen::Index l, double w) { sum += w * other.entry(l) / mass(l); });
  return sum;
}

/// c0 + cc cos Ωt + cs sin Ωt.
struct Harmonic {
  double c0 = 0.0, cc = 0.0, cs = 0.0;
  Harmonic derivative(double W) const { return {0.0, W * cs, -W * cc}; }
  Harmonic& operator+=(const Harmonic& o) {
    c0 += o.c0;
    cc += o.cc;
    cs += o.cs;
    return *this;
  }
  friend Harmonic operator*(double a, const Harmonic& h) { return {a * h.c0, a * h.cc, a * h.cs}; }
};

/// A harmonic part with the drive's extra harmonics: first + Σ_h (c_h cos r_h t + s_h sin r_h t),
/// the rates r_h kept by the caller (empty c, s: none). For building guards, not for hot loops.
struct Periodic {
  Harmonic first;
  Eigen::VectorXd c, s;
  static Periodic of(const Harmonic& h, Eigen::Index extra) {
    return {h, Eigen::VectorXd::Zero(extra), Eigen::VectorXd::Zero(extra)};
  }
  Periodic derivative(double W, const Eigen::VectorXd& rates) const {
    return {first.derivative(W), rates.cwiseProduct(s), -rates.cwiseProduct(c)};
  }
  Periodic& operator+=(const Periodic& o) {
    first += o.first;
    c += o.c;
    s += o.s;
    return *this;
  }
  Periodic& operator+=(const Harmonic& o) {
    first += o;
    return *this;
  }
  friend Periodic operator*(double a, const Periodic& p) { return {a * p.first, a * p.c, a * p.s}; }
};

inline Harmonic stop_motion(const Stop& s) { return {s.s0(), s.s_cos(), s.s_sin()}; }

inline double value_at(const Harmonic& h, double W, double t) {
  return h.c0 + h.cc * std::cos(W * t) + h.cs * std::sin(W * t);
}

inline bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

inline std::string stop_text(const std::vector<Stop>& stops, int j) {
  return "stops[" + std::to_string(j) + "] (" + stops[static_cast<std::size_t>(j)].name + ")";
}

/// out = K x for the chain's tridiagonal K. O(n).
inline void stiffness_times(const BandedChain& ch, const Eigen::VectorXd& x, Eigen::VectorXd& out) {
  const Eigen::Index n = ch.dof();
  out = ch.stiffness_diagonal.cwiseProduct(x);
  for (Eigen::Index i = 0; i + 1 < n; ++i) {
    out(i) += ch.stiffness_off(i) * x(i + 1);
    out(i + 1) += ch.stiffness_off(i) * x(i);
  }
}

/// K_{l,l'} of the tridiagonal K (0 off the band).
inline double stiffness_entry(const BandedChain& ch, Eigen::Index l, Eigen::Index lp) {
  if (l == lp) return ch.stiffness_diagonal(l);
  if (std::abs(l - lp) == 1) return ch.stiffness_off(std::min(l, lp));
  return 0.0;
}

/// Chains of at least this many masses build their contact sets' modes by the secular equation
/// (ModalSimulatorOptions::contact_modes = automatic): at N = 1000 both routes take ~0.05 s,
/// beyond it the tridiagonal one grows as N² in time and memory, the secular one in time only.
inline constexpr Eigen::Index kSecularFromMasses = 1000;

/// Buffers of the free chain's size for the basis changes and guard values of an event, so that
/// no event allocates once they are warm (each use takes the head it needs).
struct Buffers {
  explicit Buffers(Eigen::Index n) : y(n), yd(n), u(n), ud(n), udd(n), fu(n), fud(n), z(n), kz(n), ox(n), ov(n) {}
  Eigen::VectorXd y, yd, u, ud, udd, fu, fud, z, kz, ox, ov;
  ChainModes::Workspace work;
};

/// The offsets' higher harmonics at t (ModalContactMode::oxc, oxs), position into `x` and rate
/// into `v` (length N); only for a mode whose oxc is not empty. O(N H).
void offset_extra(const ModalContactMode& mode, double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v);

/// Full physical state from a mode's homogeneous modal state at t. O(n·n_r).
void to_physical(const ModalContactMode& mode, double W, double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                 const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                 Eigen::Ref<Eigen::VectorXd> v, Buffers& b);

/// A mode's homogeneous modal state from the full state at t: each reduced coordinate is the
/// mass-weighted mean of its masses (less their offsets), the M-orthogonal projection onto the
/// constraints, so rounding drift off them is projected away. O(n·n_r).
/// `u`, `ud` have the mode's size.
void to_modal(const ModalContactMode& mode, const Eigen::VectorXd& mass, double W, double t,
              const Eigen::VectorXd& x, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> u,
              Eigen::Ref<Eigen::VectorXd> ud, Buffers& b);

/// Value and slope of guard `row` at t0 + τ from the homogeneous state (u0, ud0) at t0, and
/// its second derivative if `curvature` is given. O(n_r).
void guard_at(const ModalContactMode& mode, double W, double t0, const Eigen::Ref<const Eigen::VectorXd>& u0,
              const Eigen::Ref<const Eigen::VectorXd>& ud0, double tau, Eigen::Index row, double* value, double* slope,
              Buffers& b, double* curvature = nullptr);

/// The chain with the engaged compliant stops `engaged` (stops on one mass or between
/// neighbours, c_s = β k_s): K + Σ k_s w wᵀ, and f + Σ w (k_s s + c_s s' − F_p) (stops.hpp).
BandedChain engaged_chain(const BandedChain& chain, const std::vector<Stop>& stops, const ContactSet& engaged);

/// Builds the modal form of contact set `set` (held rigid stops and engaged compliant ones) (modal.hpp, ModalContactMode), or returns null and
/// says why in `why_not` when the set is one the modal engine cannot reduce (modal_modes.cpp).
std::unique_ptr<ModalContactMode> build_mode(const ChainModes& free, const std::vector<Stop>& stops,
                                             const ContactSet& set, std::string* why_not,
                                             TridiagonalSolver route = TridiagonalSolver::automatic);

}  // namespace vibro::detail
