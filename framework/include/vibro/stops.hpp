#pragma once
/// \file stops.hpp
/// Rigid stops: unilateral constraints on a LinearSystem, and the validated ImpactSystem.
///
/// Every stop j is written in one canonical form, a gap function that must stay ≤ 0:
///
///     g_j(x, t) = w_jᵀ x - s_j(t) ≤ 0,
///     s_j(t) = s0_j + a_j cos(Ω t + φ_j) + Σ_h (c_jh cos(k_h Ω t) + d_jh sin(k_h Ω t)),
///
/// where Ω is the forcing frequency of the system (a moving stop is driven by the same source as
/// the forcing) and the k_h ≥ 2 are the orders of the stop's higher harmonics (none by default).
/// The stop's motion is then a finite sum of harmonics of Ω like the drive, so the reduced
/// sticking equations stay in the drive's family and every flow stays exact: ImpactSystem gives
/// the system's forcing a harmonic (zero if the drive has none) of every order a stop moves at,
/// so that cos k Ωt and sin k Ωt are components of the augmented state (flow.hpp) and a gap is
/// a linear function of it.
/// The three physical kinds map onto it as
///   * upper stop on mass i at p (x_i ≤ p):        w = e_i,        s = p
///   * lower stop on mass i at p (x_i ≥ p):        w = -e_i,       s = -p
///   * stop between masses i, k (x_i - x_k ≤ gap): w = e_i - e_k,  s = gap
///   * general stop along n at p (nᵀx ≤ p):         w = n,          s = p
/// The general stop holds any linear combination of the coordinates (a tip h + l·α of a
/// pitch–plunge section, a relative rotation, a rotated frame); the other three are its
/// shorthands. n is used as given, not normalised: g is in the units of nᵀx, and the offsets,
/// amplitudes and tolerances are in the same units.
/// A stop in contact pushes with a force λ_j ≥ 0 along -w_j: M x'' + C x' + K x = f - W λ.
/// At an impact the relative normal velocity g'_j = w_jᵀ v - s_j'(t) obeys Newton's law
/// g'_j⁺ = -r_j g'_j⁻ with r_j ∈ [0, 1] (Wagg 2004, eq. 6, generalised to moving stops and to
/// simultaneous impacts through the contact LCP, see contact.hpp). For a general normal the
/// impulse acts along M⁻¹ n: the law holds in the metric of M, whatever the angle between normals.
///
/// Compliant stops (law = compliant). Instead of Newton's law a stop may be a Kelvin–Voigt
/// spring-dashpot of stiffness k_s > 0, damping c_s ≥ 0 and preload F_p ≥ 0. It is *engaged*
/// while its gap is positive (g > 0: the stop is penetrated by g) and then pushes on the masses
/// with the force −w N, where
///
///     N = k_s g + c_s g' + F_p,     g' = wᵀv − s'(t),
///
/// so F_p is the force at zero penetration (N > 0 pushes the masses back out along −w), and it
/// acts only while the stop is engaged. Open (g ≤ 0) the stop exerts nothing. Engaged, the
/// motion is again linear: M x'' + (C + c_s w wᵀ) x' + (K + k_s w wᵀ) x = f + w (k_s s + c_s s'
/// − F_p). The model is the piecewise-linear one: it engages when g crosses 0 upwards and
/// disengages when g crosses 0 downwards, whatever N is then. Near separation a dashpot may
/// therefore pull (N < 0 while g > 0 when c_s g' < −k_s g − F_p): this is the plain
/// Kelvin–Voigt contact, kept so that every mode is a linear flow and every switch a zero of a
/// gap. Engaging and disengaging are not impacts: the state is continuous, only the mode (the
/// set of engaged compliant stops and held rigid stops, contact.hpp) changes. Restitution has
/// no meaning for a compliant stop (its energy loss is c_s's).
///
/// Usage:
///     std::vector<vibro::Stop> stops{vibro::Stop::lower(0, -0.3, 0.7), vibro::Stop::upper(1, 0.1, 0.7)};
///     stops.push_back(vibro::Stop::general(Eigen::Vector2d(1.0, 0.5), 0.2, 0.8));  // x0 + 0.5 x1 ≤ 0.2
///     vibro::ImpactSystem scene(std::move(system), std::move(stops));   // validated
#include "vibro/system.hpp"

#include <string>
#include <vector>

namespace vibro {

/// One higher harmonic of a stop's motion: cosine cos(k Ω t) + sine sin(k Ω t), order k ≥ 2,
/// in the units and the sense of the stop's position (a lower stop's harmonic moves the stop,
/// not its canonical offset s, like its position).
struct StopHarmonic {
  int order = 2;
  double cosine = 0.0;
  double sine = 0.0;
  /// k Ω, computed as ForcingHarmonic::rate does (bit for bit the flow's rate).
  double rate(double frequency) const { return static_cast<double>(order) * frequency; }
};

struct Stop {
  enum class Kind { upper, lower, between, normal };
  /// The contact law: rigid (Newton's impact law, restitution r) or compliant (k_s, c_s, F_p).
  enum class Law { rigid, compliant };
  Kind kind = Kind::upper;
  Eigen::Index mass = 0;        ///< i
  Eigen::Index other = -1;      ///< k, for Kind::between
  Eigen::VectorXd direction;    ///< n (length n, nonzero), for Kind::normal; empty otherwise
  double position = 0.0;        ///< p (upper/lower/normal) or gap (between), at rest
  double restitution = 1.0;     ///< r ∈ [0, 1]
  double amplitude = 0.0;       ///< a of a harmonically moving stop (0 = fixed)
  double phase = 0.0;           ///< φ, radians
  std::string name;             ///< for messages and output; defaulted by ImpactSystem
  Law law = Law::rigid;         ///< rigid (default) or compliant
  double stiffness = 0.0;       ///< k_s > 0 of a compliant stop
  double damping = 0.0;         ///< c_s ≥ 0 of a compliant stop
  double preload = 0.0;         ///< F_p ≥ 0 of a compliant stop: its push at zero penetration
  /// Higher harmonics of the motion (orders ≥ 2, distinct), added to position + amplitude
  /// cos(Ω t + phase): the stop's position is p(t) = position + amplitude cos(Ω t + phase)
  /// + Σ_h (cosine_h cos(k_h Ω t) + sine_h sin(k_h Ω t)).
  std::vector<StopHarmonic> harmonics = {};

  static Stop upper(Eigen::Index mass, double position, double restitution);
  static Stop lower(Eigen::Index mass, double position, double restitution);
  static Stop between(Eigen::Index mass, Eigen::Index other, double gap, double restitution);
  /// nᵀx ≤ position for any nonzero n of length dof (Kind::normal; mass and other unused).
  static Stop general(Eigen::VectorXd normal, double position, double restitution);
  /// The same stop, moving as position + amplitude cos(Ω t + phase).
  Stop moving(double amplitude, double phase) const;
  /// The same stop with these higher harmonics (orders ≥ 2) added to its motion.
  Stop with_harmonics(std::vector<StopHarmonic> higher) const;
  /// The same stop, compliant with stiffness k_s, damping c_s and preload F_p (its restitution
  /// is unused).
  Stop compliant(double stiffness, double damping, double preload = 0.0) const;
  bool is_compliant() const { return law == Law::compliant; }

  /// Canonical form: w (dense, length n), and s(t) = s0 + sc cos Ωt + ss sin Ωt
  /// + Σ_h (h_cos(h) cos k_h Ωt + h_sin(h) sin k_h Ωt).
  Eigen::VectorXd normal(Eigen::Index n) const;
  double s0() const;
  double s_cos() const;
  double s_sin() const;
  double h_cos(std::size_t h) const;
  double h_sin(std::size_t h) const;
  /// Whether the stop moves with a harmonic of order ≥ 2.
  bool has_higher_harmonics() const { return !harmonics.empty(); }
  /// A bound on |p(t) − position|: amplitude + Σ_h hypot(cosine_h, sine_h) (the amplitude
  /// itself when there are no higher harmonics).
  double motion_extent() const;
  /// A bound on |p'(t)| at forcing frequency Ω: Ω (amplitude + Σ_h k_h hypot(cosine_h, sine_h))
  /// (Ω · amplitude without higher harmonics).
  double motion_speed(double frequency) const;
};

/// The part of the canonical offset s_j(t) (derivative 0), its rate s_j'(t) (1) or its
/// acceleration s_j''(t) (2) that the stop's higher harmonics contribute; 0 without them. Each
/// reader adds it to its own first-harmonic terms, so a stop without higher harmonics gives the
/// same numbers bit for bit.
double stop_higher_motion(const Stop& stop, double frequency, double t, int derivative);

/// The canonical offset s_j(t) (derivative 0), s_j'(t) (1) or s_j''(t) (2), exactly.
double stop_motion(const Stop& stop, double frequency, double t, int derivative);

/// The index h in forcing.harmonics of the harmonic of `order` (≥ 2); throws std::logic_error
/// when the forcing has none (ImpactSystem adds one for every order a stop moves at).
std::size_t forcing_slot(const HarmonicForcing& forcing, int order);

/// The checks of ImpactSystem's constructor, without a LinearSystem and without the n × m matrix
/// of normals: O(m log m) for m stops on n degrees of freedom, forcing frequency Ω. Gives unnamed
/// stops their default names ("upper x3", "between x3-x4", "normal 1·x0 + 0.5·x1") and returns
/// them; throws InvalidInput with the same messages as ImpactSystem (for long chains, whose dense
/// system is never built). General stops add O(g m n) for g of them: each is compared with every
/// other stop (parallel normals on the same side, antiparallel ones without room).
std::vector<Stop> validated_stops(std::vector<Stop> stops, Eigen::Index n, double frequency);

/// g_j(x, t) = w_jᵀ x - s_j(t) of one stop, O(1 + its harmonics).
double stop_gap(const Stop& stop, double frequency, double t,
                const Eigen::Ref<const Eigen::VectorXd>& x);

/// Whether any stop is compliant.
bool has_compliant(const std::vector<Stop>& stops);

/// ImpactSystem::length_scale and ImpactSystem::check_admissible for validated stops, O(m);
/// compliant stops may be penetrated, so check_admissible skips them.
double stops_length_scale(const std::vector<Stop>& stops, double extra = 0.0);
void check_admissible(const std::vector<Stop>& stops, double frequency, double t,
                      const Eigen::Ref<const Eigen::VectorXd>& x, double tolerance);

/// A LinearSystem with its stops, validated together.
class ImpactSystem {
 public:
  /// Gives the system's forcing a zero harmonic of every order ≥ 2 that a stop moves at and the
  /// drive lacks (appended in the order the stops name them), so that the flows hold it.
  /// Throws InvalidInput naming the stop (index and name) when a mass index is out of range,
  /// r ∉ [0, 1], a value is not finite, a general normal has the wrong length or is zero, two
  /// stops are the same constraint (parallel normals on the same side), or two opposing stops
  /// (an upper and a lower stop on one mass, antiparallel normals) leave no room (their least
  /// clearance over a period ≤ 0, including the stops' motion: exact for the first harmonic, a
  /// certified search of the trigonometric polynomial with higher harmonics). A compliant stop needs k_s > 0, c_s ≥ 0 and F_p ≥ 0, finite;
  /// it may share its normal with a rigid stop (a two-stage stop) and is exempt from the
  /// clearance check.
  ImpactSystem(LinearSystem system, std::vector<Stop> stops);

  const LinearSystem& system() const { return system_; }
  const std::vector<Stop>& stops() const { return stops_; }
  Eigen::Index dof() const { return system_.dof(); }
  std::size_t stop_count() const { return stops_.size(); }
  /// n × m matrix of the stop normals w_j.
  const Eigen::MatrixXd& normals() const { return normals_; }

  /// g_j(x, t) for every stop.
  Eigen::VectorXd gaps(double t, const Eigen::Ref<const Eigen::VectorXd>& x) const;
  /// g'_j = w_jᵀ v - s_j'(t).
  Eigen::VectorXd gap_rates(double t, const Eigen::Ref<const Eigen::VectorXd>& v) const;

  /// A length of the problem: the largest of the stops' offsets and amplitudes and `extra`
  /// (e.g. the initial displacement); used to make tolerances relative. Never below 1e-300.
  double length_scale(double extra = 0.0) const;

  /// Throws InvalidInput when x violates a stop by more than `tolerance` (names stop, value).
  void check_admissible(double t, const Eigen::Ref<const Eigen::VectorXd>& x, double tolerance) const;

 private:
  LinearSystem system_;
  std::vector<Stop> stops_;
  Eigen::MatrixXd normals_;
};

}  // namespace vibro
