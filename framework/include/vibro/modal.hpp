#pragma once
/// \file modal.hpp
/// Long chains: an event-driven engine in modal coordinates whose cost per event grows like N
/// (the number of masses) for a fixed number of stops, for proportionally damped chains.
///
/// **Why a second engine.** The general engine (flow.hpp, contact.hpp, simulator.hpp) works on the
/// dense augmented generator of size 2N + 3: an O(N³) eigendecomposition per contact set and O(N²)
/// per projected state. That is right for any C, but minutes at N = 1000 and out of reach at
/// N = 10 000. A chain has more structure: M is diagonal and K tridiagonal, and with Rayleigh
/// damping C = αM + βK the free system decouples exactly into N scalar oscillators.
///
/// **Modes (set-up, O(N²) with LAPACK's MRRR).** With A = M^{-1/2} K M^{-1/2} (symmetric
/// tridiagonal: A_ii = K_ii/m_i, A_{i,i+1} = K_{i,i+1}/√(m_i m_{i+1})) and A = Q diag(ω²) Qᵀ,
/// the mass-normalised modes are Φ = M^{-1/2} Q (ΦᵀMΦ = I, ΦᵀKΦ = diag ω², ΦΦᵀ = M⁻¹). The
/// eigenpairs come from LAPACK dstemr (Dhillon & Parlett's MRRR, O(N²) for all N vectors) when
/// LAPACK was found at configure time, else from Eigen's
/// SelfAdjointEigenSolver::computeFromTridiagonal (implicit QL, O(N³) for the vectors).
/// x = Φ q, and every mode obeys
///     q_k'' + 2σ_k q_k' + ω_k² q_k = φ_kᵀ f(t),   2σ_k = α + β ω_k².
///
/// **Exact flow of one mode, every damping regime.** Split q_k = p_k(t) + u_k with the periodic
/// particular solution p_k = c0_k + cc_k cos Ωt + cs_k sin Ωt (needs ω_k > 0 and no undamped
/// resonance ω_k = Ω with σ_k = 0: both are refused with InvalidInput). The homogeneous part is
///     u(τ) = e^{-στ} [(C + σS) u0 + S u0'],   u'(τ) = e^{-στ} [-ω² S u0 + (C - σS) u0'],
/// with D = ω² - σ², C = cos(√D τ), S = sin(√D τ)/√D (D > 0), C = 1, S = τ (D = 0),
/// C = cosh(√-D τ), S = sinh(√-D τ)/√-D (D < 0, written with the two real rates and expm1 so
/// that nothing cancels or overflows). These are continuous through critical damping, so no
/// regime needs a special method.
///
/// **Guards in O(N).** A stop j is g_j = w_jᵀ x - s_j(t) = Σ_k (Φᵀw_j)_k q_k - s_j(t); the rows
/// Φᵀw_j (one or two rows of Q scaled by 1/√m) are stored once, so a value costs the N mode
/// evaluations plus N multiply-adds per stop. The second-derivative bound the certified search
/// needs (events.hpp) comes from each mode's energy E_k = ½(u_k'² + ω_k² u_k²), which cannot
/// grow (E_k' = -2σ_k u_k'² ≤ 0):  |u_k''| = |2σ_k u_k' + ω_k² u_k| ≤ (2σ_k + ω_k)√(2E_k(a)) for
/// all τ ≥ a, so
///     |g_j''(τ)| ≤ Σ_k |Φᵀw_j|_k (2σ_k + ω_k) √(2 E_k(a)) + Ω² |harmonic amplitude of g_j|
/// on every [a, b]. The search (ModalChainSimulator::search) is that of events.hpp: an interval is
/// certified free when the Taylor bounds from its two ends stay ≤ ε, else it is halved. A
/// shortcut saves most halvings: when one guard is uncertified on [a, b] and exceeds ε at b, its
/// root r in [last point ≤ 0, b] is found by safeguarded Newton and accepted if the same bounds
/// certify [a, r]; otherwise halving goes on. Guarantee (same as the dense engine): every
/// excursion above ε is found; the root is located to a few ulps of t.
///
/// **Impacts in O(N).** An impulse Λ_j along -w_j changes v by -M⁻¹w_j Λ_j, i.e. the modal
/// velocities by -Φᵀw_j Λ_j (a rank-1 update). Simultaneous impacts use the generalised Newton
/// law of contact.hpp with the Delassus matrix G = WᵀM⁻¹W (k × k, read off the diagonal M) and
/// solve_lcp. Impacting gaps are then placed exactly at zero by moving x along M⁻¹w_j (again a
/// rank-1 modal update), as in the dense engine.
///
/// **What this engine does not do (yet): sticking.** A stop that would hold (post-impact normal
/// speed ≤ contact_velocity·V with the free gap acceleration pushing into it, r = 0, or a chatter
/// sequence whose next bounce would rise less than chatter_height·L) needs the constrained
/// dynamics (contact force λ(t) through the modal receptance, a rank-k secular problem). Instead
/// of stepping through it or approximating it silently, the run ends there with status
/// `sticking` or `chatter` and a message giving the time, the stop and, for chatter, the
/// Budd–Dux accumulation time. Likewise a Zeno run ends with `event_cap`. Use the dense
/// Simulator for such runs (feasible up to N of a few hundred).
///
/// Output: observers get segment views (exact state at any t inside, O(N²) for a full state,
/// O(N) for one gap) and events (vibro::Event, so EventLog works unchanged). SegmentView of
/// observers.hpp is bound to the dense ContactMode and cannot be built here without O(N²)-sized
/// dense data per contact set, hence ModalObserver; plain vibro::Observer objects receive the
/// events (and end()) only.
///
/// Usage:
///     auto chain = vibro::BandedChain::from_links(masses, springs, dampers, 1.0, 0.01, 0.0, 0.0,
///                                                 forcing);       // throws if C ≠ αM + βK
///     vibro::ChainModes modes(std::move(chain));                  // O(N²) with LAPACK
///     vibro::ModalChainSimulator sim(modes, {vibro::Stop::upper(0, 0.5, 0.8)});
///     vibro::EventLog log;
///     auto summary = sim.run(0.0, x0, v0, 100.0, {}, {&log});
#include "vibro/observers.hpp"
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <Eigen/Dense>

#include <string>
#include <vector>

namespace vibro {

/// A proportionally damped chain in banded form: M = diag(mass), K symmetric tridiagonal,
/// C = αM + βK, forcing f(t) as in system.hpp.
struct BandedChain {
  Eigen::VectorXd mass;                ///< m_i > 0 (n)
  Eigen::VectorXd stiffness_diagonal;  ///< K_ii (n)
  Eigen::VectorXd stiffness_off;       ///< K_{i,i+1} (n - 1)
  double rayleigh_mass = 0.0;          ///< α ≥ 0
  double rayleigh_stiffness = 0.0;     ///< β ≥ 0
  HarmonicForcing forcing;

  Eigen::Index dof() const { return mass.size(); }
  /// Throws InvalidInput naming the field, the index and the value.
  void validate() const;

  /// A chain as in models/chain.hpp (links k_i, c_i; optional wall links). Throws InvalidInput
  /// naming the first damper that is not β × its spring (β from the first damped link), since
  /// the modal engine needs C = βK exactly (to 1e-12 relative).
  static BandedChain from_links(const std::vector<double>& masses,
                                const std::vector<double>& springs,
                                const std::vector<double>& dampers, double left_spring,
                                double left_damper, double right_spring, double right_damper,
                                HarmonicForcing forcing);
  /// From a dense system (e.g. a scene): M diagonal, K tridiagonal, C = αM + βK (α, β fitted,
  /// checked to 1e-12 of max |C|). Throws InvalidInput saying which property fails. O(n²).
  static BandedChain from_system(const LinearSystem& system);
  /// The same system as a dense LinearSystem (for comparisons; O(n²) memory).
  LinearSystem dense() const;
};

enum class TridiagonalSolver { automatic, eigen, lapack };

/// True when this build can use LAPACK's dstemr.
bool lapack_available();

/// The free chain's modes and each mode's exact flow. Immutable after construction.
class ChainModes {
 public:
  /// Validates, then decomposes (automatic = LAPACK when available). Throws InvalidInput for a
  /// rigid-body mode (ω_k² ≤ 1e-13 ω_max²: give the chain a wall) or an undamped resonance, and
  /// std::runtime_error if the eigensolver fails.
  explicit ChainModes(BandedChain chain, TridiagonalSolver solver = TridiagonalSolver::automatic);

  const BandedChain& chain() const { return chain_; }
  Eigen::Index dof() const { return chain_.dof(); }
  double frequency() const { return chain_.forcing.frequency; }
  TridiagonalSolver solver() const { return solver_; }
  double setup_seconds() const { return setup_seconds_; }

  const Eigen::VectorXd& omega_squared() const { return omega2_; }  ///< ascending
  const Eigen::VectorXd& omega() const { return omega_; }
  const Eigen::VectorXd& decay() const { return sigma_; }  ///< σ_k
  /// Q: orthonormal eigenvectors of M^{-1/2} K M^{-1/2}, one per column (n × n).
  const Eigen::MatrixXd& vectors() const { return q_; }
  /// Row i of Φ = M^{-1/2} Q (the modal amplitudes of x_i).
  Eigen::VectorXd phi_row(Eigen::Index i) const;

  /// Particular solution amplitudes: p(t) = c0 + cc cos Ωt + cs sin Ωt (per mode).
  const Eigen::VectorXd& particular_constant() const { return c0_; }
  const Eigen::VectorXd& particular_cosine() const { return cc_; }
  const Eigen::VectorXd& particular_sine() const { return cs_; }

  /// Homogeneous modal state (u, u') at t from the physical (x, v). O(n²).
  void to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                Eigen::Ref<Eigen::VectorXd> ud) const;
  /// Physical (x, v) at t from the homogeneous modal state. O(n²).
  void to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                   const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                   Eigen::Ref<Eigen::VectorXd> v) const;

  /// Advances every mode's homogeneous part by τ ≥ 0: (u, ud) → (u_out, ud_out). O(n).
  /// If `bound` is non-empty it receives (2σ_k + ω_k)·√(ud² + ω² u²) at τ (see the header).
  void advance(double tau, const Eigen::Ref<const Eigen::VectorXd>& u,
               const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> u_out,
               Eigen::Ref<Eigen::VectorXd> ud_out, double* bound = nullptr) const;

 private:
  BandedChain chain_;
  TridiagonalSolver solver_;
  double setup_seconds_ = 0.0;
  Eigen::VectorXd omega2_, omega_, sigma_, root_, inv_sqrt_mass_, sqrt_mass_;
  Eigen::VectorXi regime_;  // +1 under-, 0 critically, -1 over-damped
  Eigen::MatrixXd q_;
  Eigen::VectorXd c0_, cc_, cs_;
};

struct ModalSimulatorOptions {
  double trigger = 1e-13;          ///< as SimulatorOptions (fraction of L)
  double simultaneity = 1e-12;     ///< fraction of T
  double chatter_height = 1e-9;    ///< fraction of L: a bounce lower than this ends the run (chatter)
  double chatter_velocity = 0.0;   ///< fraction of V
  double contact_velocity = 1e-11; ///< fraction of V: slower post-impact speeds would stick
  long max_events = 100000;        ///< within event_window (0: T): more ends the run (event_cap)
  double event_window = 0.0;
  double length_scale = 0.0;       ///< 0 = automatic (as the dense Simulator)
  /// End the run (status completed, message saying so) after this many impacts; 0 = no limit.
  /// For benchmarks that want a fixed amount of work.
  long stop_after_impacts = 0;
  /// Throws InvalidInput naming the field, the value and the rule.
  void validate() const;
};

enum class ModalRunStatus { completed, event_cap, chatter, sticking, numerical_failure };
const char* to_string(ModalRunStatus s);

struct ModalRunSummary {
  ModalRunStatus status = ModalRunStatus::completed;
  std::string message;
  double t = 0.0;
  Eigen::VectorXd x, v;  ///< state reached (O(n²) to form, once per run)
  long impacts = 0, segments = 0;
  long evaluations = 0;  ///< evaluations of all modes at one time (the O(N) unit of work)
  std::size_t contact_sets_built = 0;  ///< distinct sets of simultaneously impacting stops
  double length_scale = 0.0, velocity_scale = 0.0, time_scale = 0.0;
};

class ModalChainSimulator;

/// Exact motion between two events, seen by observers.
class ModalSegmentView {
 public:
  ModalSegmentView(const ModalChainSimulator& sim, double t_begin, double t_end)
      : sim_(&sim), t_begin_(t_begin), t_end_(t_end) {}
  double t_begin() const { return t_begin_; }
  double t_end() const { return t_end_; }
  Eigen::Index dof() const;
  /// Full state at t ∈ [t_begin, t_end]: O(n²).
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const;
  /// Gap g_j at t: O(n).
  double gap(int stop, double t) const;

 private:
  const ModalChainSimulator* sim_;
  double t_begin_, t_end_;
};

class ModalObserver {
 public:
  virtual ~ModalObserver() = default;
  virtual void begin(const ModalChainSimulator& /*sim*/, double /*t0*/) {}
  virtual void segment(const ModalSegmentView& /*view*/) {}
  virtual void event(const Event& /*event*/) {}
  virtual void end(double /*t_end*/) {}
};

/// Exact states at requested times (ascending).
class ModalSamples : public ModalObserver {
 public:
  explicit ModalSamples(std::vector<double> times) : times_(std::move(times)) {}
  void segment(const ModalSegmentView& view) override;
  std::vector<double> t;
  std::vector<Eigen::VectorXd> x, v;

 private:
  std::vector<double> times_;
  std::size_t next_ = 0;
};

/// Free flight and impacts of a proportionally damped chain with stops, in modal coordinates.
/// Stops are validated here (mass indices, r ∈ [0, 1], finite values, moving stops need Ω > 0);
/// the scratch data of a run is allocated once in the constructor. Not thread-safe: one
/// simulator per thread (they may share one const ChainModes).
class ModalChainSimulator {
 public:
  ModalChainSimulator(const ChainModes& modes, std::vector<Stop> stops,
                      ModalSimulatorOptions options = {});

  /// Throws InvalidInput for wrong sizes, non-finite values or x0 violating a stop by more than
  /// the trigger tolerance. Other trouble ends the run with a status and a message.
  ModalRunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                      double t_end, const std::vector<ModalObserver*>& observers = {},
                      const std::vector<Observer*>& event_observers = {});

  const ChainModes& modes() const { return *modes_; }
  const std::vector<Stop>& stops() const { return stops_; }
  /// Seconds spent building the stop rows Φᵀw_j (O(N) per stop), in the constructor.
  double stop_setup_seconds() const { return stop_setup_seconds_; }

  // For ModalSegmentView: the current segment's start and homogeneous modal state.
  double segment_start() const { return seg_t0_; }
  const Eigen::VectorXd& segment_u() const { return u0_; }
  const Eigen::VectorXd& segment_ud() const { return ud0_; }
  /// Gap j at absolute time t from the homogeneous modal state (u) at that time. O(n).
  double gap_from(int stop, double t, const Eigen::Ref<const Eigen::VectorXd>& u) const;

 private:
  struct Point {
    double tau = 0.0;
    Eigen::VectorXd h, d, bound;  // per stop: value, slope, |h''| bound valid on [tau, ∞)
  };
  void evaluate(double tau, Point& p, int only = -1);
  bool certified(int j, const Point& a, const Point& b) const;
  double refine_root(int j, double lo, double hi);
  bool search(int ia, int ib, int free, double* tau_hit, int* stop_hit);
  void harmonic(int j, double t, double* value, double* slope) const;

  const ChainModes* modes_;
  std::vector<Stop> stops_;
  ModalSimulatorOptions options_;
  double stop_setup_seconds_ = 0.0;
  // Per stop: row Φᵀw_j (as row j of phi_), its absolute values, w_jᵀM⁻¹w_j, and the stop's
  // entries (mass i with weight +1/-1, optionally the other mass k).
  Eigen::MatrixXd phi_, abs_phi_;
  Eigen::VectorXd h_const_, h_cos_, h_sin_;  // g_j = Φᵀw_j·u + h_const + h_cos cos Ωt + h_sin sin Ωt
  Eigen::VectorXd curvature_;                // Ω² √(h_cos² + h_sin²)

  // Run scratch (allocated once).
  double seg_t0_ = 0.0;
  Eigen::VectorXd u0_, ud0_, u_, ud_, bnd_;
  Eigen::MatrixXd modal_block_;  // n × 3: u, ud, bound at the last evaluation
  std::vector<Point> stack_;
  Eigen::VectorXd trig_, last_below_;
  std::vector<bool> leaving_;  // per stop: on its surface and moving away at the segment start
  double resolution_ = 0.0;
  long evaluations_ = 0;
};

}  // namespace vibro
