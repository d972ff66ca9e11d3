#pragma once
// Private to vibro_core: a run's scales and tolerances, and how an event is resolved, shared by the dense engine (simulator.cpp)
// and the modal chain engine (modal_simulator.cpp). The rules are stated once here; each engine
// supplies the stops' algebra in physical coordinates (ContactAlgebra): the dense engine from
// per-run tables of its normals, the modal engine from the sparse normals, diagonal M and
// tridiagonal K of a chain (O(N) per event).
//
// Nothing here allocates once an EventWorkspace has been sized for the run's stops (reserve):
// sets are vectors whose capacity is the number of stops, vectors and matrices are sized to it
// and used through head() / topLeftCorner(), the small symmetric positive definite solves are
// written out (spd_solve), and the LCP has its own workspace (contact.hpp).
#include "vibro/simulator.hpp"

#include <functional>
#include <string>
#include <vector>

namespace vibro::detail {

/// The stops' algebra at an event, in physical coordinates (x, v). Sets are sorted stop indices.
/// Outputs are written into the caller's storage (sized by the caller), never allocated.
class ContactAlgebra {
 public:
  virtual ~ContactAlgebra() = default;
  /// g_j(x, t), and the normal rates g'_j = w_jᵀ v - s_j'(t) of every stop into `out` (size m).
  virtual double gap(int j, double t, const Eigen::VectorXd& x) const = 0;
  virtual void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const = 0;
  /// The acceleration LCP (contact.hpp): which candidates hold at (t, x, v) into `held`, and the
  /// forces of all candidates into `forces` (size candidates.size()).
  virtual void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                      const ContactSet& candidates, ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) = 0;
  /// G = Wᵀ M⁻¹ W of a set into `G` (k × k); its diagonal entry of one stop.
  virtual void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const = 0;
  virtual double delassus_diagonal(int j) const = 0;
  /// v -= M⁻¹ W_set Λ.
  virtual void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                             Eigen::VectorXd& v) const = 0;
  /// z -= M⁻¹ w_j s for the a-th stop j of `set`.
  virtual void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const = 0;
  /// May `held` be the next contact set? False, with the reason, if the engine cannot represent
  /// it (the modal engine's unsupported sets); the dense engine accepts every set.
  virtual bool accept(const ContactSet& held, std::string* why) = 0;
  /// Chatter rules (simulator.hpp, ChatterRule): the gap's local coefficients α_j and β_j; the
  /// slope λ_j' and curvature λ_j'' of stop j's contact force along the flow with `held` stuck
  /// from (t, x, v); and the pieces of the state correction (resolve_event): w_jᵀ y;
  /// d = M⁻¹ C M⁻¹ w_j; and e = M⁻¹ C d − M⁻¹ K M⁻¹ w_j for a given d.
  virtual double chatter_alpha(int j) const = 0;
  virtual double chatter_beta(int j) const = 0;
  virtual void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x,
                           const Eigen::VectorXd& v, double* slope, double* curvature) = 0;
  virtual double normal_dot(int j, const Eigen::VectorXd& y) const = 0;
  virtual void damped_normal(int j, Eigen::VectorXd& d) = 0;
  virtual void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) = 0;
};

/// Thresholds of the rules, in absolute units (SimulatorOptions × the run's scales).
struct EventRules {
  double v_chatter = 0.0;   ///< approach speeds below this are chatter
  double h_chatter = 0.0;   ///< bounces rising less than this are chatter
  double v_contact = 0.0;   ///< post-impact speeds below this are resting
  ChatterRule chatter_rule = ChatterRule::third_order;
  double t_tolerance = 0.0;  ///< trigger·T: the third-order rule's tail is summed to this
};

/// A run's scales and the absolute tolerances they give (SimulatorOptions documents each):
/// L = the options' length_scale, or the largest of the stops' offsets and amplitudes, |x0|,
/// |v0|/ω and f/k (k = max(‖K‖, ‖M‖ω²)); V = Lω, or a stop's largest speed if its higher harmonics
/// move it faster (Stop::motion_speed: k Ω per harmonic's amplitude); F = max(kL, f); T = 2π/ω.
struct RunScales {
  double L = 0.0, V = 0.0, F = 0.0, T = 0.0;
  /// The stops' own scale (largest offset or amplitude; 0 if every stop sits at 0 unmoving) and
  /// what set L (for messages): "solver.length_scale", "the stops", "initial.x", "initial.v"
  /// (|v0|/ω) or "the forcing" (its static deflection f/k).
  double L_stops = 0.0;
  const char* L_from = "the stops";
  double eps_gap = 0.0, eps_force = 0.0;  ///< trigger·L, trigger·F
  double dt_simultaneous = 0.0;           ///< simultaneity·T
  double window = 0.0;                    ///< the Zeno guard's window (event_window, or T)
  EventRules rules;
};

/// The scales of a run at frequency `omega` (the forcing's, or the fastest mode's when unforced;
/// not > 0 counts as 1) of a system with max |K_ij| = kmax, max |M_ij| = mmax and forcing
/// amplitudes summing to fmax. Shared by both engines so that their tolerances agree.
RunScales run_scales(const SimulatorOptions& options, double omega, double kmax, double mmax, double fmax,
                     const std::vector<Stop>& stops, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0);

/// x = G⁻¹ b for a small symmetric positive definite G (k × k), by LDLᵀ in `scratch` (≥ k × k):
/// no allocation. Returns false if a pivot is not positive (x untouched).
bool spd_solve(const Eigen::Ref<const Eigen::MatrixXd>& G, const Eigen::Ref<const Eigen::VectorXd>& b,
               Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::MatrixXd> scratch);

/// Everything resolve_event needs besides the algebra, sized once per run for m stops.
struct EventWorkspace {
  struct ChatterLimit {
    int stop;
    double t;
  };
  ContactSet candidates, chatter, slow, test, held, all, next, scratch_set;
  Eigen::VectorXd g_before, g_after, g_now, hold_force, forces, q, impulse, gn, rhs;
  Eigen::VectorXd chatter_d, chatter_e;  // n: the chatter rule's correction
  Eigen::MatrixXd G, factor;
  LcpWorkspace lcp;
  std::vector<ChatterLimit> chatter_limits;
  /// Sizes everything for m stops and n degrees of freedom (allocates; once per run).
  void reserve(Eigen::Index m, Eigen::Index n);
};

/// Checks that a run over [t0, t_end] with scales `s` can meet its tolerances in doubles, and
/// that an explicit solver.length_scale is sane against the scene's own (`automatic`, the L of
/// the same run with length_scale = 0). Throws InvalidInput where the result would be
/// meaningless (errors above 1e-6 L); appends a warning where it only misses the trigger.
/// The stops themselves must be resolved too: where the motion's scale (a large initial
/// velocity or position, or forcing) dwarfs the stops' own scale L_stops, the rounding of an
/// event's place — a gap moves V·ulp(t) per spacing of doubles in time, and a position near L
/// is known to ε·L — must stay below 1e-6 L_stops, or the stops would be crossed between two
/// representable times (events below the time resolution) and states recorded far past them.
void check_resolution(const RunScales& s, const RunScales& automatic, const SimulatorOptions& options,
                      double t0, double t_end, std::vector<std::string>& warnings);

/// Search steps per period (T × the fastest rate) above which a run is called stiff: it warns,
/// with the count, so that a run taking minutes per period says why from its start.
inline constexpr double kStiffStepsPerPeriod = 1e5;
std::string stiff_warning(double steps_per_period, double periods);

/// Resolves an event at t on the state (x, v): impacts on `impacting` (generalised Newton law
/// over the held and impacting stops, contact.hpp), releases of `releasing`, and `resting` stops
/// touching with zero normal speed (at the start of a run); chatter caught by the chatter rule;
/// then the acceleration LCP decides which stops hold, and `stuck` becomes that set. Emits the
/// events and counts them in `summary`. Each impact set is passed to `impact_set` (if given).
/// Returns false, with the reason in `why`, if the algebra does not accept the next set; (x, v)
/// then hold the post-impact state and `stuck` is unchanged. Allocates nothing once `work` is
/// reserved (the observers called through `emit` may).
bool resolve_event(ContactAlgebra& algebra, const std::vector<Stop>& stops, const EventRules& rules,
                   double t, Eigen::VectorXd& x, Eigen::VectorXd& v, ContactSet& stuck,
                   const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting,
                   const std::function<void(const Event&)>& emit, RunSummary& summary, std::string* why,
                   EventWorkspace& work, const std::function<void(const ContactSet&)>& impact_set = {});

/// The compliant stops' switches of an event (contact_law.hpp, CompliantStopLaw): of the stops
/// the frame put in `impacting` and `releasing`, each compliant one engages (joins `engaged`) or
/// disengages (leaves it) unless it is in that state already, and is emitted as an event with
/// its normal rate g' before and after and, on engaging, its force N = k_s g + c_s g' + F_p
/// (stops.hpp); the state is unchanged. The rigid stops are copied into `rigid_impacts` and
/// `rigid_releases` (cleared first) for resolve_event. `rates` (size m) is scratch. Returns
/// whether a compliant stop switched. Allocates nothing once the sets have capacity m.
bool compliant_switches(const ContactAlgebra& algebra, const std::vector<Stop>& stops, double t,
                        const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& impacting,
                        const ContactSet& releasing, ContactSet& engaged, ContactSet& rigid_impacts,
                        ContactSet& rigid_releases, Eigen::VectorXd& rates,
                        const std::function<void(const Event&)>& emit);

}  // namespace vibro::detail
