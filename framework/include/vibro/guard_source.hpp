#pragma once
/// \file guard_source.hpp
/// What the certified crossing search (events.hpp: CrossingFinder, minimize_row) needs of the
/// guard rows it watches. One search serves every engine whose guards provide this:
///  * the dense engine's Segment (flow.hpp): rows ℓᵢᵀz(τ) of an exact linear flow, bounds from
///    the exponential-polynomial form or the Padé path's norms;
///  * the modal chain engine's ModalGuardSource (modal.hpp): rows P_i·u + D_i·u' + harmonic of
///    a chain's homogeneous modal state, bounds from each mode's energy.
///
/// A guard source is a fixed family of smooth rows h_i(τ), τ ≥ 0 counted from an absolute time
/// t0 (the segment's start). It gives
///  * sample(τ): every row's value h, slope h' and curvature h'' at τ in one call, plus what its
///    own bounds need (SegmentSample::e, growth);
///  * row_jet(i, τ): one row's h, h', h'' at τ (the root refinement's Newton steps);
///  * derivative_bound(d, i, a, b): B_d ≥ max |h_i⁽ᵈ⁾| over [a.tau, b.tau] for d = 2 and 3 from
///    the samples at the two ends (the search's certification);
///  * value(i, τ, d) for d ∈ {0, 1, 2} and second_derivative_bound(i, a, b) ≥ max |h_i''| over
///    [a, b] from the times alone (the certified minimum of one row, minimize_row).
/// The bounds must be rigorous (rounding of the bound's own arithmetic included): the search's
/// guarantee (events.hpp) is only as good as them.
#include <Eigen/Dense>

namespace vibro {

/// Everything the certified event search needs of all rows of a guard source at one τ
/// (GuardSource::sample): sized on first use, then filled without allocation.
struct SegmentSample {
  double tau = 0.0;
  Eigen::VectorXd h, d, c;   ///< h_i(τ) and its first two derivatives in τ, per row
  /// What the source's derivative_bound reads. Segment: e^{λᵣτ} (e) and |e^{λᵣτ}| (growth) per
  /// term, or on the Padé path ‖z(τ)‖₂ and ‖D z(τ)‖₂ (growth). ModalGuardSource: growth holds
  /// per row B₂ then B₃, bounds of |h''| and |h'''| valid on [τ, ∞); e is unused.
  Eigen::VectorXcd e;
  Eigen::VectorXd growth;
};

/// A family of guard rows as the certified search sees them (see the file comment).
class GuardSource {
 public:
  virtual ~GuardSource() = default;

  /// Absolute time of τ = 0.
  virtual double t0() const = 0;
  /// dᵈ/dτᵈ h_i(τ); every source gives d ∈ {0, 1, 2}.
  virtual double value(Eigen::Index i, double tau, int derivative = 0) const = 0;
  /// An upper bound of |h_i''| over τ ∈ [a, b] (0 ≤ a ≤ b).
  virtual double second_derivative_bound(Eigen::Index i, double a, double b) const = 0;
  /// Values, slopes and curvatures of every row at τ, with what the bounds need; no allocation
  /// once `out` has been sized by a first call.
  virtual void sample(double tau, SegmentSample& out) const = 0;
  /// Value, slope and curvature of row i at τ.
  virtual void row_jet(Eigen::Index i, double tau, double* h, double* d, double* c) const = 0;
  /// An upper bound of |h_i⁽ᵈ⁾| over [a.tau, b.tau] (d = 2 or 3) from two samples, a.tau ≤ b.tau.
  virtual double derivative_bound(int derivative, Eigen::Index i, const SegmentSample& a,
                                  const SegmentSample& b) const = 0;

 protected:
  GuardSource() = default;
  GuardSource(const GuardSource&) = default;
  GuardSource& operator=(const GuardSource&) = default;
};

}  // namespace vibro
