#pragma once
/// \file continuation.hpp
/// Branches of periodic orbits followed in a parameter, through folds and along unstable parts,
/// with their bifurcations located by solving their defining conditions.
///
/// **Pseudo-arclength continuation** (Keller 1977). A branch is a curve y(s) = (z, p) of zeros
/// of F(z, p) = P(z; p) − z, P the stroboscopic map of period kT at the forcing phase θ (section
/// time t0 = θ/Ω, so that with p = Ω the section moves with the period). In scaled variables
/// (x/L, v/V, p/P) its tangent t spans the null space of DF = [J − I, ∂P/∂p], with
///     ∂P/∂p = ζ + f(z1, t1) dt1/dp − J f(z0, t0) dt0/dp          (linearisation.hpp)
/// (ζ the sensitivity at fixed times; the time terms move the section and the period with Ω).
///
/// procedure Continue(y0):
///     repeat: t ← null vector of DF(y) oriented along the previous t
///             y_pred ← y + h t
///             Newton on [F(y); tᵀ(y − y_pred)] = 0 from y_pred (the exact Jacobian)
///             failure (no convergence in max_corrector_iterations, a run that fails, an orbit
///                 that leaves the scan limits by more than a step, a corrector that travels
///                 further than the step: another branch crossing the hyperplane): h ← h/2,
///                 retry; h < min: stop
///             steps shrinking (h < 1e-2 max_step) while an event lies within a small margin of
///                 the section (an impact drifting through it makes the map jump): the section
///                 moved into the longest event-free stretch of the orbit, the tangent carried
///                 there by the stretch's tangent map
///             steps shrinking against a grazing (the map's derivative blows up on the side with
///                 the impact, and Newton from the other side cannot see it): the orbit beyond by
///                 Newton at fixed p; failing that, a step along the tangent of the branch of
///                 orbits with the new impact, from the null space of the map without it bordered
///                 by the impact's first-order effect and the grazing condition (Nordmark 1991),
///                 stable or not, whichever way in p it leaves the corner
///             a step that may have passed a change of events unseen is cut, h ← h/2, until
///                 h ≤ max(min_step, 1e-4 max_step): a step whose events differ from the last
///                 point's by more than one change (an impact, or a contact phase with its
///                 chatter, at one stop), so that a cascade of changes (the bounces a vanishing
///                 contact phase leaves, lost one by one) is crossed one change at a time; and a
///                 step across a grazing whose orbit with the impact is stable (near a grazing
///                 the impacting map's derivative grows like 1/u, u the impact's speed, so a
///                 multiplier leaves the unit circle, a fold or a doubling, between a stable
///                 impacting orbit and the grazing). A jump past several changes is brought back
///                 to the first by bisection in p
///             a step with the same events whose count of real multipliers above +1 changes
///                 while the tangent's p component keeps its sign has either gone round a fold
///                 unseen (the new point lies on the part already followed: its tangent,
///                 oriented along the last one, points back along the step's chord): h ← h/2;
///                 or crossed a branch point (its tangent points along the chord): taken
///             a jump, or a step at that floor, from a stable orbit across the grazing of one
///                 of its impacts has passed the fold (or doubling) between them: it is located
///                 on the impacting orbits by short steps from the last point (steps not kept
///                 with the branch), and the branch goes on from the jump
///             a step or jump that goes back is refused: the first step past a change of events
///                 onto the events before it (back across the same grazing or rising: at a corner
///                 both parts lie on one side in p), a step onto the events before the last
///                 multiple change while it is nearer to that change than to every point since
///                 (further on, a cascade may reach the same events again at another change), and
///                 a jump onto a part of the branch already followed (the search goes on)
///             success: h ← 1.5 h if ≤ 3 iterations, 0.6 h if ≥ 6; the point's multipliers,
///                 test functions and event signature; a change between neighbours is located
///     stop at the scan limits (the last point placed on the limit), after max_points, or when
///     the step falls below min_step (the reason is kept with the branch).
/// A fold is passed because the arclength, not p, parametrises the curve; unstable parts are
/// followed like stable ones (nothing here needs the orbit to attract).
///
/// **Bifurcations**, each by a test function that changes sign there, located by the Illinois
/// (modified regula falsi) iteration on the arclength between two neighbours, each evaluation a
/// corrected branch point, to |Δp| ≤ locate_tolerance where the function is smooth:
///  * fold (saddle-node): the p-component of the tangent; a multiplier passes through +1;
///  * branch point: a real multiplier passes through +1 while the tangent's p component keeps
///    its sign (another branch crosses this one there: a pitchfork where a symmetric orbit
///    loses its symmetry, or a transcritical point); test function (μ* − 1) times the signs of
///    the other real multipliers' μ − 1 (μ* the real one nearest +1: the sign of det(J − I) with
///    an O(1) magnitude), located by Illinois in p (the arclength's hyperplanes contain the
///    crossing branch's direction there). The branch is followed straight through, and the
///    crossing branch is continued from the located point along ±e, e the null direction of
///    DF = [J − I, ∂P/∂p] there orthogonal to the branch's tangent (branch_switching.hpp): two
///    new branches, within max_branches and max_total_points;
///  * period doubling: Π(1 + μ_i) over the non-structural multipliers; a multiplier at −1.
///    The doubled branch (period 2k) is then continued from the located point along the
///    multiplier's eigenvector (branch switching), recursively up to max_doublings deep. Each
///    branch is followed once: a switched branch whose first point's orbit lies on a branch of
///    the same period already followed (shifted by some periods, at the same p, to 1e3 ×
///    tolerance) is recorded as recognised instead, and a branch that reaches such orbits while
///    followed ends there (known_branches.hpp). max_branches and max_total_points bound the run;
///    reaching one is stated in ContinuationResult::budget;
///  * Neimark–Sacker: Π_{i<j}(μ_iμ_j − 1); kept only if a complex pair lies on the unit circle;
///  * grazing of stop j (the number of impacts on j per orbit changes, chatter excluded): the
///    orbit's nearest approach to the stop, continuous through the grazing — below it the
///    largest interior maximum of the gap (< 0), above it the height u²/(2|g''|) the slowest
///    impact's free parabola would rise past the stop (> 0; u the approach speed, g'' the gap's
///    free acceleration at impact); solved from the side without the impact (where its orbit
///    was met far from the grazing, whose flight there has no gap maximum of its own, from that
///    side's orbits nearer to it), or, where that side's orbit has no gap maximum at the stop,
///    from the side with it; failing both, bracketed by bisection;
///  * rising / multi-sliding of stop j (a contact phase of j splits): before it, the least
///    interior minimum of j's contact force (> 0); after it, the minimum of the force the held
///    flow continued past the release would need (< 0) (Wagg 2004; linearisation.hpp features);
///  * a contact phase of j appearing or vanishing, chatter on j appearing or vanishing, any
///    other change of the orbit's event signature: not smooth in p (they depend on the chatter
///    rule's thresholds), located by bisection to locate_tolerance and reported as such.
/// Each is reported with its kind, p, the stop, the branch, the test function's value at the
/// located point and the orbit there.
///
/// **Curves in two parameters.** A grazing, rising, fold, period-doubling or Neimark–Sacker
/// point located in p1 is followed in (p1, p2) by locating it again on lines across the curve:
/// from each curve point a predictor step along the curve's secant, then the same location on
/// the line through the predictor along the normal (a one-parameter family along that line: the
/// system at each point and its derivative n1 dD/dp1 + n2 dD/dp2), so every curve point is
/// located like a branch point. A fold line has orbits on one side only: there the line is
/// reached from the side with orbits (curves.cpp). Codimension-two points met along fold,
/// period-doubling and Neimark–Sacker curves (fold–flip, grazing, strong resonances, a cusp's
/// turning) are reported with the curve (CodimTwoPoint).
///
/// **Engines.** Continuation drives a FamilyEngine per parameter value (family_engine.hpp): the
/// dense engine (any system and parameter; the ParameterFamily overloads below) or the modal chain
/// engine (proportionally damped chains, parameters that leave M, C, K alone). Both give maps
/// with the full Jacobian, so the predictor, the bordered corrector, the tangents and the
/// multipliers are the same dense linear algebra on either, and a branch is the same on both up
/// to the maps' rounding (tests/analysis/test_continuation.cpp). Per corrector iteration that is
/// O(N²) memory and an O(N³) LU of the (2N + 1)² bordered system: a couple of thousand masses at
/// most; a matrix-free (Newton–Krylov) bordered corrector for longer chains is not built yet.
///
/// Usage:
///     vibro::ParameterFamily fam = [&](double omega) { return vibro::FamilyPoint{system_at(omega), d_domega}; };
///     vibro::ContinuationOptions o;  o.p_min = 0.24;  o.p_max = 0.28;
///     vibro::ContinuationResult r = vibro::continue_orbits(fam, 0.255, t, x, v, o);
///     for (const vibro::Bifurcation& b : r.bifurcations) … b.kind, b.p, b.stop, b.value …
#include "vibro/family_engine.hpp"
#include "vibro/shooting.hpp"

#include <functional>
#include <string>
#include <vector>

namespace vibro {

/// The system at one value of the parameter and the derivative of its data there. A family
/// throws InvalidInput where p gives no valid system (Ω ≤ 0, a negative mass …): continuation
/// takes that as no orbit there, like a run that fails.
struct FamilyPoint {
  ImpactSystem system;
  SystemDerivative derivative;
};
using ParameterFamily = std::function<FamilyPoint(double p)>;

enum class BifurcationKind {
  fold,
  period_doubling,
  neimark_sacker,
  grazing,
  rising,
  phase_change,    ///< a contact phase appears or vanishes (not by rising)
  chatter_change,  ///< chatter into sticking appears or vanishes
  other,           ///< another change of the event signature, or of the period
  branch_point     ///< another branch crosses (a multiplier at +1 without a fold)
};
const char* to_string(BifurcationKind kind);
/// All kinds in enum order (for file attributes).
std::vector<std::string> bifurcation_kind_names();

struct ContinuationOptions {
  double p_min = 0.0, p_max = 0.0;  ///< scan limits (required: p_min < p_max)
  int direction = +1;               ///< initial direction of p: +1 up, −1 down
  int period = 1;                   ///< k of the first branch
  double phase = 0.0;               ///< section phase θ (moved off held stops, as shooting does)
  double step = 0.01;               ///< first arclength step (scaled variables)
  double min_step = 1e-7, max_step = 0.05;
  int max_points = 400;             ///< per branch
  double tolerance = 1e-11;         ///< corrector residual, max(|Δx|/L, |Δv|/V)
  int max_corrector_iterations = 8;
  double parameter_scale = 0.0;     ///< P of the scaled p; 0: p_max − p_min
  bool locate = true;               ///< locate bifurcations (else only detect them)
  double locate_tolerance = 1e-10;  ///< |Δp| of a located point (absolute, in p's units)
  int max_doublings = 3;            ///< depth of branch switching at period doublings (0: none)
  /// The run's budget: at most this many branches, and this many points over all branches.
  /// Once either is reached no further branch is switched onto (a branch being followed stops at
  /// the points budget), and ContinuationResult::budget says which was hit and what was left.
  int max_branches = 64;
  long max_total_points = 40000;
  /// The start orbit is a period doubling (a restart from a located one): follow only the
  /// period-2k branch that bifurcates there (branch 1; branch 0 is the start orbit alone), not the
  /// period-k branch through it. The start must have a multiplier within 1e-3 of −1.
  bool switch_at_start = false;
  /// The dense engine's settings (the ParameterFamily overloads); an ContinuationFamily's engines carry
  /// their own (family_engine.hpp).
  SimulatorOptions solver;
  void validate() const;            ///< throws InvalidInput naming the field
};

/// Per stop, per orbit: impacts outside chatter sequences, chatter sequences caught by the
/// chatter rule, contact phases. Two orbits with different signatures differ in their events.
struct Signature {
  int k = 1;
  std::vector<int> impacts, chatters, phases;
  bool operator==(const Signature& o) const = default;
  std::string text() const;  ///< e.g. "k=1 s0:i1c1h1 s1:i2c1h1"
};

struct BranchPoint {
  double p = 0.0;
  double phase = 0.0, t0 = 0.0;  ///< section
  Eigen::VectorXd x, v;          ///< on the orbit at t0
  int k = 1;
  FloquetMultipliers multipliers;
  Signature signature;
  Eigen::VectorXd sticking;      ///< per stop: the fraction of kT it is held
  double tangent_p = 0.0;        ///< dp/ds (scaled): its sign change is a fold
  /// The orbit's state at the fixed phase ContinuationResult::fixed_phase (Ωt ≡ phase mod 2π, the
  /// first such time ≥ t0), carried there from (x, v) by an exact run of the orbit: unlike
  /// (x, v), whose section phase moves along a branch where continuation moves its section, it
  /// is continuous in p along a smooth stretch. NaN where that run fails.
  Eigen::VectorXd x_fixed, v_fixed;
  double residual = 0.0;
  int corrector_iterations = 0;
  bool located = false;          ///< a located bifurcation point (not a regular step)
};

struct Bifurcation {
  BifurcationKind kind = BifurcationKind::other;
  double p = 0.0;
  int stop = -1;          ///< the stop concerned (grazing, rising, phase and chatter changes)
  int branch = 0;         ///< index into ContinuationResult::branches
  double value = 0.0;     ///< the test function at the located point (→ 0)
  bool smooth = true;     ///< located by solving a smooth condition (else by bisection)
  double p_low = 0.0, p_high = 0.0;  ///< the final bracket
  int evaluations = 0;    ///< branch points computed to locate it
  BranchPoint point;      ///< the orbit there
  std::string note;
};

struct Branch {
  int k = 1;
  int parent = -1;        ///< the branch it was switched from (period doubling, branch point), or −1
  int bifurcation = -1;   ///< the bifurcation (index into bifurcations) it was switched at, or −1
  int joins = -1;         ///< the branch it ran onto (then it ends there: already followed), or −1
  std::vector<BranchPoint> points;  ///< in arclength order
  std::string start;      ///< how it began
  std::string end;        ///< why it stopped
};

/// A branch switching that found a branch already followed: its first point lies on the orbits
/// of a known branch of the same period (orbit_on_branch), so it was not followed again.
struct RecognisedBranch {
  int parent = -1;        ///< the branch of the period doubling or branch point
  int bifurcation = -1;   ///< that bifurcation (index into bifurcations)
  int k = 1;              ///< the period of the new branch (doubled at a period doubling)
  double p = 0.0;         ///< the parameter of its first point
  int known = -1;         ///< the branch it lies on
  int shift = 0;          ///< forcing periods between its state and the known orbit's
  double distance = 0.0;  ///< max(|Δx|/L, |Δv|/V) between the two there
};

struct ContinuationResult {
  std::vector<Branch> branches;
  std::vector<Bifurcation> bifurcations;  ///< in the order found
  std::vector<RecognisedBranch> recognised;  ///< switchings onto branches already followed
  std::string budget;     ///< empty, or which budget (max_branches, max_total_points) stopped the run and what it left
  double fixed_phase = 0.0;  ///< the phase of BranchPoint::x_fixed, v_fixed (ContinuationOptions::phase)
  long maps = 0;          ///< tangent maps computed (one per Newton iteration)
};

/// Called after every accepted point (for progress lines).
using ContinuationProgress = std::function<void(const Branch&, const BranchPoint&)>;

/// Continues the branch through the periodic orbit found by shooting from the guess
/// (t_guess, x, v) at p0, in options.direction and then the other way (both halves form one
/// branch, in order of arclength), switching at period doublings. Throws InvalidInput for bad
/// options, or if shooting at p0 fails (the message says why).
ContinuationResult continue_orbits(const ParameterFamily& family, double p0, double t_guess,
                                   const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                   const ContinuationOptions& options,
                                   const ContinuationProgress& progress = {});
/// The same on any engine (family_engine.hpp); the ParameterFamily form runs the dense engine
/// with options.solver.
ContinuationResult continue_orbits(const ContinuationFamily& family, double p0, double t_guess,
                                   const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                   const ContinuationOptions& options,
                                   const ContinuationProgress& progress = {});

/// The signature of an orbit from its map (events over kT).
Signature orbit_signature(const TangentMap& m, int k, std::size_t stops);

/// A point of a two-parameter curve.
struct CurvePoint {
  double p1 = 0.0, p2 = 0.0;
  double value = 0.0;
  BranchPoint point;
};
/// A codimension-two point met along a curve of folds, period doublings or Neimark–Sacker points
/// (curves.cpp says how each is found):
///  * fold_flip: on a fold curve a multiplier passes −1, on a period-doubling curve one passes +1;
///  * grazing: the curve's orbits change their events (a stop is grazed: the orbit's nearest
///    approach to it passes 0), where the smooth curve ends or continues with other events;
///  * cusp: the fold curve turns back in the plane (only the turning is detected, not the sign
///    change of the fold's quadratic coefficient; located = false);
///  * fold_neimark_sacker, flip_neimark_sacker: on a Neimark–Sacker curve a real multiplier
///    passes +1 or −1;
///  * resonance_1_3, resonance_1_4: the unit pair e^{±iθ} of a Neimark–Sacker curve passes
///    θ = 2π/3 or π/2 (strong resonances);
///  * resonance_1_1, resonance_1_2: a Neimark–Sacker curve ends with its pair near +1 or −1
///    (θ within 0.05 of 0 or π; not located).
enum class CodimTwoKind {
  fold_flip,
  grazing,
  cusp,
  fold_neimark_sacker,
  flip_neimark_sacker,
  resonance_1_1,
  resonance_1_2,
  resonance_1_3,
  resonance_1_4
};
const char* to_string(CodimTwoKind kind);
/// All kinds in enum order (for file attributes).
std::vector<std::string> codim_two_kind_names();

struct CodimTwoPoint {
  CodimTwoKind kind = CodimTwoKind::fold_flip;
  int stop = -1;          ///< grazing: the stop whose events changed (the first), else −1
  int after = 0;          ///< index of the curve point before it
  double p1 = 0.0, p2 = 0.0;
  /// Located: a curve point solved at the step along the curve where the codimension-two
  /// condition holds, to `width` (scaled step units); else bracketed between two curve points.
  bool located = false;
  double width = 0.0;     ///< the final bracket along the curve, in scaled (p1/P1, p2/P2)
  double value = 0.0;     ///< the codimension-two test function there (→ 0 where located)
  BranchPoint point;      ///< the curve's orbit there (the good side's)
  std::string note;
};

struct Curve {
  BifurcationKind kind = BifurcationKind::grazing;
  int stop = -1;
  std::vector<CurvePoint> points;
  std::vector<CodimTwoPoint> special;  ///< codimension-two points (folds, doublings, tori only)
  std::string end;
};

/// The system at (p1, p2) and the derivatives of its data along p1 and along p2.
struct PlanePoint {
  ImpactSystem system;
  SystemDerivative d1, d2;
};
using PlaneFamily = std::function<PlanePoint(double p1, double p2)>;
/// The same on any engine: the engine at (p1, p2) (its own `derivative` is not used) and the
/// derivatives of the data along p1 and p2.
struct PlaneEngine {
  std::unique_ptr<FamilyEngine> engine;
  SystemDerivative d1, d2;
};
using PlaneContinuationFamily = std::function<PlaneEngine(double p1, double p2)>;

struct CurveOptions {
  double p2_min = 0.0, p2_max = 0.0;  ///< limits of the second parameter
  double p1_min = 0.0, p1_max = 0.0;  ///< limits of the first (the curve stops outside)
  double step = 0.02;                 ///< along the curve, in scaled (p1/P1, p2/P2)
  int max_points = 100;
  int direction = +1;                 ///< initial direction of p2
  double scale1 = 0.0, scale2 = 0.0;  ///< P1, P2 (0: the limits' widths)
  ContinuationOptions branch;         ///< tolerances, solver, period and locate_tolerance
  void validate() const;
};

/// Follows a located grazing, rising, fold, period-doubling or Neimark–Sacker point (`start`,
/// found with p2 = p2_start) in (p1, p2). Throws InvalidInput for another kind.
Curve follow_curve(const PlaneFamily& family, const Bifurcation& start, double p2_start,
                   const CurveOptions& options);
/// The same on any engine (the PlaneFamily form runs the dense engine with options.branch.solver).
Curve follow_curve(const PlaneContinuationFamily& family, const Bifurcation& start, double p2_start,
                   const CurveOptions& options);

}  // namespace vibro
