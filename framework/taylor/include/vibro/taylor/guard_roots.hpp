#pragma once
/// \file guard_roots.hpp
/// Certified first crossing of a guard polynomial over a step.
///
/// Given G(τ) = Σ_{k=0}^{p} g_k τ^k on [0, h], a trigger level ε and a bound δ ≥ 0 with
/// |g(τ) − G(τ)| ≤ δ on [0, h] (the remainder of taylor_step.hpp, truncation and rounding), find
/// the first τ at which the true guard g rises above ε, i.e. the first root of q = G − ε at which
/// q goes from below to above, with the following guarantee:
///
///   - `none`: q(τ) < −δ on all of [0, h], so g < ε throughout: no event in the step;
///   - `crossing` at τ*: q < −δ is certified on [0, a]; on [a, b], q(a) < −δ, q(b) > δ and q has
///     exactly one root; τ* is that root to rounding (safeguarded Newton). The true guard rises
///     above ε within δ/|q'(τ*)| of τ* (reported as `uncertainty`);
///   - `at_start`: q(0) > δ — the guard is already above the trigger at τ = 0;
///   - `grazing` on [a, b]: before any certified crossing, q comes within δ of 0 on an interval
///     that cannot be split further (width ~ rounding of τ): the guard touches the trigger level
///     within the uncertainty and the caller applies its grazing rule. A transversal crossing
///     closer than δ/|q'| to the step's end h is reported so too (at [h − ulp, h]); the caller
///     then starts the next step there, where the crossing is `at_start` or certified.
///   - a guard that starts within δ(0) of the trigger level (|q(0)| ≤ δ(0), typically just after
///     its own event) leaves a first sliver [0, h·2⁻⁸⁰] (or [0, ~ulp]) that cannot be decided: it
///     is set aside (`start_touch`) and the rest of [0, h] is searched as above, so a crossing
///     later in the step is never hidden behind the contact at its start.
///
/// Why no crossing is missed in the part declared crossing-free. Let δ(τ) bound |g − G| over
/// [0, τ]: the tail's share δ_T (τ/h)^{p+1} and the rounding's, δ_R or, with `rounding_scales`,
/// δ_R Σ|g_k| τ^k / Σ|g_k| h^k (the evaluation-rounding bound of Higham 2002, §5.1, at τ; both
/// shares grow with τ, so over [a, b] ⊂ [0, h] their values at b bound them). An interval [a, b]
/// is discarded only when every Bernstein coefficient, plus the conversion's and the splits'
/// rounding (each coefficient within (2p + depth + 4)·2u Σ|q_k h^k| of its exact value), lies
/// below −δ(b): then G − ε < −δ(b) on [a, b] (convex hull) and g < ε there. The search visits
/// intervals left to right (depth first, left half first), so when it answers `crossing` at τ*
/// every point of [0, a] but the start sliver has been discarded; `none` means all of [0, h] but
/// that sliver. The sliver is never declared clear: `start_touch` says it was set aside, and it
/// can only be set aside when q(0) ≤ δ(0) (a guard above its band at τ = 0 is `at_start`), i.e. the
/// guard sits at its trigger level to within the band at the step's start — the contact the
/// caller has just resolved. The band δ_R models the rounding of the coefficients and of their
/// evaluation (as TaylorStep::remainder_parts states); it is not an interval enclosure.
///
/// Termination: the intervals form a binary tree of depth ≤ 80 searched depth first; each one
/// examined is discarded, answered (`crossing` or `grazing` end the search), set aside (the start
/// sliver, a leaf: once) or split into two of the next depth, so the search ends after finitely
/// many intervals. A caller that cuts its step at a grazing must make progress: the Taylor engine
/// (taylor_simulator.cpp) halves a step whose grazing lies at its start instead of cutting there,
/// and reports a numerical failure naming the stop and the time if 30 halvings do not decide it.
///
/// Method (never sampling): q is written in the Bernstein basis on [0, h],
/// q(h s) = Σ_i b_i C(p, i) s^i (1 − s)^{p−i}, b_i = Σ_{k≤i} [C(i, k)/C(p, k)] q_k h^k (Farouki &
/// Rajan 1988, eq. 6). By the convex-hull property min b_i ≤ q ≤ max b_i on the interval, and by
/// Descartes' rule of signs in the Bernstein basis the number of roots of q in the interval is at
/// most the number of sign changes of (b_i), with the same parity (Lane & Riesenfeld 1981). The
/// search is depth first, left half first, splitting by de Casteljau's algorithm at the midpoint:
/// an interval with max b_i < −δ is discarded; one with b_0 < −δ, b_p > δ and exactly one sign
/// change holds exactly one root, which is refined; any other is split. The scratch is allocated
/// once, the conversion's table of a degree on the first call that needs it (first_crossing
/// allocates at most once per degree over the finder's life). Rounding in the
/// conversion and the splits (convex combinations, each coefficient's error ≤ (p + depth) u Σ|b|)
/// is added to δ.
///
/// A guard that peaks 1e-10 below ε is discarded once the intervals near its peak are short
/// enough for the control polygon to lie within 1e-10 of q (width ~ √(1e-10) relative, ~17
/// splits); one that peaks 1e-10 above ε has two roots ~1e-5 apart, separated after as many.
/// A guard far below its trigger over the whole step (q(0) + Σ_{k≥1} |q_k| h^k < −δ, which
/// bounds every Bernstein coefficient) is answered `none` before the conversion; one whose
/// polynomial truncated to a degree m < p − 1, converted at degree m, lies below −δ by more than
/// the dropped terms' Σ_{k>m} |q_k| h^k is answered `none` after that O(m²) conversion.
///
/// Usage:
///     vibro::taylor::GuardRootFinder finder(step.order());
///     auto c = finder.first_crossing(step.guard_coefficients(0), step.order(), step.step_size(),
///                                    /*trigger=*/0.0, step.guard_remainder(0));
///     if (c.kind == vibro::taylor::CrossingKind::crossing) ... c.tau ...
#include <vector>

namespace vibro::taylor {

enum class CrossingKind { none, crossing, at_start, grazing };

struct GuardCrossing {
  CrossingKind kind = CrossingKind::none;
  double tau = 0.0;          ///< the root (crossing), 0 (at_start), the interval's start (grazing)
  double lower = 0.0;        ///< bracket [lower, upper] holding the crossing or the grazing contact
  double upper = 0.0;
  double uncertainty = 0.0;  ///< crossing: δ / |q'(τ)| — how far the true guard's root may lie
  int splits = 0;            ///< intervals examined
  bool start_touch = false;  ///< the guard starts within the band of the trigger (see the file comment)
};

class GuardRootFinder {
 public:
  /// Scratch for polynomials up to degree `max_degree` (allocated once; see the file comment).
  explicit GuardRootFinder(int max_degree);

  /// First crossing of Σ_{k≤degree} coefficients[k] τ^k − trigger over [0, h] with remainder
  /// bound `remainder` (see the file comment).
  /// With `truncation` > 0, the bound over [0, τ] is remainder + truncation · (τ/h)^{degree+1}
  /// (a Taylor step's tail, TaylorStep::remainder_parts): the band an interval is tested against
  /// narrows towards τ = 0, so a guard that starts just below its trigger and moves away is
  /// cleared in a few splits.
  /// With `rounding_scales`, `remainder` is an evaluation-rounding bound of the form C Σ |c_k| h^k
  /// (TaylorStep::remainder_parts' rounding) and is applied over [0, τ] as C Σ |c_k| τ^k: near the
  /// step's start only c_0's share is left, so a guard that starts at rounding distance of its
  /// trigger (just after its own event) is decided there even when the whole step's band is wider
  /// than the trigger level.
  GuardCrossing first_crossing(const double* coefficients, int degree, double h, double trigger,
                               double remainder, double truncation = 0.0, bool rounding_scales = false);

  /// Root of q(τ) = Σ c_k τ^k − trigger bracketed by q(a) < 0 < q(b) (or the reverse), to rounding:
  /// Newton steps, replaced by bisection when they leave the bracket or do not halve it.
  static double refine(const double* coefficients, int degree, double trigger, double a, double b);

 private:
  int max_degree_;
  std::vector<double> stack_;  // Bernstein coefficients of pending intervals, (degree+1) each
  std::vector<double> lo_, hi_;
  std::vector<double> absolute_;  // |c_k| h^k of the call (rounding_scales)
  std::vector<int> depth_;
  std::vector<double> work_;
  /// C(i, k) / C(d, k) at [i (d + 1) + k] for degree d (the Bernstein conversion), built on first use.
  const double* bernstein_ratios(int degree);
  std::vector<std::vector<double>> ratios_;  // by degree
};

}  // namespace vibro::taylor
