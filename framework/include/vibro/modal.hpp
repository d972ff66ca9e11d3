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
/// particular solution p_k = c0_k + cc_k cos Ωt + cs_k sin Ωt + Σ_h (ch_hk cos k_hΩt + sh_hk sin k_hΩt),
/// one term per harmonic of the drive (system.hpp: orders k_h ≥ 2 besides the first), each
/// mode's response to φ_kᵀ f_h at k_hΩ by harmonic_response (needs ω_k > 0 and no undamped
/// resonance ω_k = k_hΩ with σ_k = 0 of a forced mode: both are refused with InvalidInput). The
/// homogeneous flow below does not depend on the drive, so each extra harmonic costs one cosine
/// and sine per time (and two numbers per guard row) in every state or guard evaluation, and
/// nothing per mode. The homogeneous part is
///     u(τ) = e^{-στ} [(C + σS) u0 + S u0'],   u'(τ) = e^{-στ} [-ω² S u0 + (C - σS) u0'],
/// with D = ω² - σ², C = cos(√D τ), S = sin(√D τ)/√D (D > 0), C = 1, S = τ (D = 0),
/// C = cosh(√-D τ), S = sinh(√-D τ)/√-D (D < 0, written with the two real rates and expm1 so
/// that nothing cancels or overflows). These are continuous through critical damping, so no
/// regime needs a special method.
///
/// **Guards in O(N).** A stop j is g_j = w_jᵀ x - s_j(t) = Σ_k (Φᵀw_j)_k q_k - s_j(t); the rows
/// Φᵀw_j (one or two rows of Q scaled by 1/√m) are stored once, so a value costs the N mode
/// evaluations plus N multiply-adds per stop. The bounds on |g_j''| and |g_j'''| the certified
/// search needs come from each mode's energy, which cannot grow (ModalGuardSource gives the
/// derivation). The search is events.hpp's CrossingFinder, the one both engines use, on the
/// guards as a ModalGuardSource: the same certification (quadratic and cubic Taylor bounds),
/// splitting, root refinement and re-arming, so the same guarantee: every excursion above ε is
/// found; the root is located to a few ulps of t.
///
/// **Impacts in O(N).** An impulse Λ_j along -w_j changes v by -M⁻¹w_j Λ_j, i.e. the modal
/// velocities by -Φᵀw_j Λ_j (a rank-1 update). Simultaneous impacts use the generalised Newton
/// law of contact.hpp with the Delassus matrix G = WᵀM⁻¹W (k × k, read off the diagonal M) and
/// solve_lcp. Impacting gaps are then placed exactly at zero by moving x along M⁻¹w_j (again a
/// rank-1 modal update), as in the dense engine.
///
/// **Sticking: contact sets as reduced chains.** While stops hold, a stop on one mass prescribes
/// it (x_i = ±s_j(t)) and a stop between neighbours i, i+1 joins them (x_i - x_{i+1} = s_j(t)).
/// The masses left free form groups of neighbours moving as one: x = T y + o(t), T_{l,r} = 1 for
/// mass l in group r, o(t) harmonic (the held stops' motion). The reduced system
///     TᵀMT y'' + TᵀCT y' + TᵀKT y = Tᵀ(f - M o'' - C o' - K o)
/// is again a chain: TᵀMT diagonal (group masses), TᵀKT tridiagonal (a prescribed mass cuts
/// the chain, its springs become walls), TᵀCT = α TᵀMT + β TᵀKT (proportionality survives any
/// such constraint) and a harmonic right-hand side. Each contact set gets its own ChainModes,
/// built on the set's first visit (ModalContactMode) and cached (ModalSimulatorOptions::
/// mode_cache_bytes bounds the cache; the least recently used set is dropped first), by one of
/// two routes (ModalSimulatorOptions::contact_modes):
///  * the reduced chain's own tridiagonal eigenproblem, O(n_r²) time and memory (chains of
///    fewer than 1000 masses by default);
///  * the free modes restricted by each held stop in turn (ChainModes' second constructor): in
///    the free modal coordinates q (x = Φ q) a held stop is the constraint (Φᵀw_j)ᵀ q = 0, a
///    rank-one restriction of diag(ω²) whose modes are the roots μ of the secular equation
///    Σ_k (φ_kᵀw_j)² / (ω_k² - μ) = 0 and the vectors (ω² - μ)⁻¹ Φᵀw_j (Golub 1973; solved with
///    the deflation, root finding and Löwner weights of Gu & Eisenstat 1995, src/secular.hpp).
///    The vectors are never formed: O(k N²) time, O(k N) memory for k held stops (N = 10 000:
///    a few MB per set instead of 0.8 GB), and a basis change is two O(N²) products. Default
///    from 1000 masses. The same eigenvalues and reduced coordinates as the tridiagonal route to
///    rounding (tests/framework/test_modal.cpp).
/// **Compliant stops** (stops.hpp, law = compliant): an engaged stop adds k_s w wᵀ to K, c_s w wᵀ
/// to C and w (k_s s + c_s s' − F_p) to f. On one mass or between neighbours, k_s w wᵀ stays on
/// K's band, and with c_s = β k_s the damping stays C = αM + βK: the engaged set's chain is a
/// chain again (compliant_refusal says why another stop is refused). Its modes are built on the
/// set's first visit by its own tridiagonal eigenproblem, and held rigid stops reduce it as they
/// reduce the free chain (a two-stage stop: a rigid stop held while a spring is engaged). A
/// contact set is keyed by its held and engaged stops; its guards are the gaps of the others,
/// −λ of the held ones and −g of the engaged ones (rising through 0 when the gap reopens),
/// searched as every guard is; a switch leaves the state as it is and enters the next set.
/// A stop between masses that are not neighbours, or two held stops fixing one group (redundant
/// forces), would break the tridiagonal form: the run then ends with RunStatus::unsupported
/// and says which stops (the dense Simulator handles those).
///
/// **General normals** (Stop::Kind::normal, nᵀx ≤ p with any n): the guard row is nᵀ written in
/// each set's modes, Φ_Sᵀ Tᵀn (one O(N n_r) product when the set is first built, as
/// ModalSegmentView::plane_crossings writes a section's plane), searched and bounded as any other
/// row; an impact's impulse acts along M⁻¹n, O(N) per event (the rank-1 update of the modal
/// velocities in free flight, event_resolution.cpp's rules otherwise). A stop held along a
/// general normal would couple the masses of n in the reduced chain, which is then no chain: a
/// run in which one would stick ends with RunStatus::unsupported, naming the stop (the dense
/// Simulator holds it).
/// **Contact forces in O(n_r).** With the residual ρ_l = m_l x_l'' + (C x')_l + (K x)_l - f_l of
/// mass l, the held stops of a group G satisfy W_G λ_G = -ρ_G (W_G the normals restricted to G,
/// full column rank), so -λ_G = W_G⁺ ρ_G. Each ρ_l involves masses l-1, l, l+1 only, and in the
/// homogeneous modal state u of the reduced chain, with u'' = -2σ∘u' - ω²∘u,
///     ρ_l = P_l·u + D_l·u' + harmonic,  P_l = -m_l φ_l∘ω² + Σ_l' K_ll' φ_l',  D_l = β P_l
/// (2σ = α + βω²). A release guard -λ_j is therefore a guard like a gap, plus a u' term whose
/// derivatives are bounded through those of u' (ModalGuardSource).
///
/// **Events.** A single impact in free flight after which the stop leaves (no chatter, no rest)
/// is the O(N) rank-1 update above. Every other event (an impact while stops hold, a release,
/// several simultaneous impacts, a stop coming to rest, chatter caught by the chatter rule) is
/// resolved in physical coordinates with the dense engine's rules (event_resolution.cpp: the
/// generalised Newton law over held and impacting stops, the acceleration LCP, the chatter
/// rule), each O(N) there with diagonal M and tridiagonal K, plus two
/// basis changes, O(N n_r) (ModalRunSummary::general_events counts these events). Between
/// events the motion in any contact set is the exact modal flow. The event loop around them (the
/// checks of the input, the statuses and their messages, the Zeno guard ending a run with
/// `event_cap`, interruption, observers) is the dense engine's, written once for both.
///
/// Output: the observers of observers.hpp, through ModalSegmentView (a full state O(N n_r), one
/// gap or force O(n_r); force minima by the same certified search as events, on the guards'
/// slopes).
///
/// Usage:
///     auto chain = vibro::BandedChain::from_links(masses, springs, dampers, 1.0, 0.01, 0.0, 0.0,
///                                                 forcing);       // throws if C ≠ αM + βK
///     vibro::ChainModes modes(std::move(chain));                  // O(N²) with LAPACK
///     vibro::ModalChainSimulator sim(modes, {vibro::Stop::upper(0, 0.5, 0.8)});
///     vibro::EventLog log;
///     auto summary = sim.run(0.0, x0, v0, 100.0, {&log});
#include "vibro/guard_source.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"  // RunSummary, ChatterRule
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <Eigen/Dense>

#include <memory>
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

/// secular: the modes of a contact set's reduced chain from the free chain's, by the secular
/// equation (ChainModes' second constructor; never for a free chain).
enum class TridiagonalSolver { automatic, eigen, lapack, secular };

/// How a contact set's reduced chain sits in the free chain (see "Sticking" above): the masses
/// of each reduced coordinate (first…last: a group joined by held stops between neighbours; a
/// mass held by a stop on it belongs to none) and each held stop's normal, as (mass, weight)
/// pairs. x = T y + o(t) with T_{l,r} = 1 for mass l in group r.
struct ChainReduction {
  std::vector<Eigen::Index> first, last;
  std::vector<std::vector<std::pair<Eigen::Index, double>>> normals;
};

/// True when this build can use LAPACK's dstemr.
bool lapack_available();

/// The periodic response q = c0 + cc cos Ωt + cs sin Ωt of one mode,
///     q'' + 2σ q' + ω² q = p0 + pc cos Ωt + ps sin Ωt:
/// c0 = p0/ω² and, with d = ω² − Ω², e = 2σΩ and det = d² + e²,
///     cc = (d pc − e ps)/det,   cs = (d ps + e pc)/det
/// (0 when det = 0, an undamped resonance, which ChainModes refuses unless the mode is not forced).
/// Written once for double (ChainModes) and for dual numbers (the derivative of the particular
/// solution along Ω and the forcing, analysis/modal_tangent.cpp).
template <class T>
struct HarmonicResponse {
  T c0, cc, cs, det;
};
template <class T>
HarmonicResponse<T> harmonic_response(double omega2, double sigma, const T& frequency, const T& p0, const T& pc,
                                      const T& ps) {
  const T detune = omega2 - frequency * frequency, friction = 2.0 * sigma * frequency;
  const T det = detune * detune + friction * friction;
  HarmonicResponse<T> out{p0 / omega2, T(0.0), T(0.0), det};
  if (det > 0.0) {
    out.cc = (detune * pc - friction * ps) / det;
    out.cs = (detune * ps + friction * pc) / det;
  }
  return out;
}

/// The free chain's modes and each mode's exact flow. Immutable after construction.
class ChainModes {
 public:
  /// Validates, then decomposes (automatic = LAPACK when available). Throws InvalidInput for a
  /// rigid-body mode (ω_k² ≤ 1e-13 ω_max²: give the chain a wall) or an undamped resonance, and
  /// std::runtime_error if the eigensolver fails.
  explicit ChainModes(BandedChain chain, TridiagonalSolver solver = TridiagonalSolver::automatic);
  /// The modes of `reduced`, a contact set's reduced chain placed in `free`'s chain by
  /// `reduction`, without a tridiagonal eigenproblem: the free modes restricted by each held
  /// stop's constraint w_jᵀ x = 0 in turn (a rank-one restriction, solved by the secular
  /// equation; src/secular.hpp gives the method and its safeguards), so the constrained modes
  /// are Φ Ψ with Ψ a product of implicit Cauchy-like factors: O(k N²) time and O(k N) memory
  /// for k held stops on N masses (the tridiagonal route is O(N²) in both), and no eigenvector
  /// matrix (vectors() is empty). Each basis change (to_modal, to_physical) costs two O(N²)
  /// products (the free modes' and the factors'). Same eigenvalues and the same reduced
  /// coordinates y as the tridiagonal route, to rounding. `free` must outlive these modes.
  /// Throws InvalidInput as the first constructor (rigid-body mode, undamped resonance).
  ChainModes(BandedChain reduced, const ChainModes& free, ChainReduction reduction);

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
  /// The rows of Φ for several coordinates (rows of the result, in the order given); the
  /// secular route forms them in one pass.
  Eigen::MatrixXd phi_rows(const std::vector<Eigen::Index>& coordinates) const;
  /// Bytes held by these modes (for a secular route, not counting the free modes it refers to).
  std::size_t bytes() const;

  /// Particular solution amplitudes: p(t) = c0 + cc cos Ωt + cs sin Ωt (per mode), plus
  /// Σ_h (column h of particular_harmonic_cosine) cos r_h t + (… sine) sin r_h t for the extra
  /// harmonics of the chain's forcing, in its order, r_h = harmonic_rates()(h) = k_h Ω
  /// (ForcingHarmonic::rate). No columns without extra harmonics.
  const Eigen::VectorXd& particular_constant() const { return c0_; }
  const Eigen::VectorXd& particular_cosine() const { return cc_; }
  const Eigen::VectorXd& particular_sine() const { return cs_; }
  const Eigen::MatrixXd& particular_harmonic_cosine() const { return hc_; }
  const Eigen::MatrixXd& particular_harmonic_sine() const { return hs_; }
  const Eigen::VectorXd& harmonic_rates() const { return rates_; }
  /// The extra harmonics' part of p(t), p'(t) added to (sign +1) or taken from (−1) q, q'. O(n H).
  void add_particular(double t, double sign, Eigen::Ref<Eigen::VectorXd> q, Eigen::Ref<Eigen::VectorXd> qd) const;

  /// Scratch for the basis changes below: storage that grows to the largest size asked for,
  /// then is reused, so that an event loop changing basis allocates nothing once warm. One per
  /// thread (the modes themselves stay const and shareable).
  class Workspace {
   public:
    /// An n × k view of buffer `slot` (0 ≤ slot < 6), grown if needed.
    Eigen::Map<Eigen::MatrixXd> matrix(int slot, Eigen::Index n, Eigen::Index k);

   private:
    Eigen::VectorXd store_[6];
  };

  /// Homogeneous modal state (u, u') at t from the physical (x, v). O(n²).
  void to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                Eigen::Ref<Eigen::VectorXd> ud) const;
  void to_modal(double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& v, Eigen::Ref<Eigen::VectorXd> u,
                Eigen::Ref<Eigen::VectorXd> ud, Workspace& work) const;
  /// Physical (x, v) at t from the homogeneous modal state. O(n²).
  void to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                   const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                   Eigen::Ref<Eigen::VectorXd> v) const;
  void to_physical(double t, const Eigen::Ref<const Eigen::VectorXd>& u,
                   const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> x,
                   Eigen::Ref<Eigen::VectorXd> v, Workspace& work) const;

  /// The linear parts of to_modal and to_physical on k columns at once, without the particular
  /// solution: U = Φ⁻¹ Y and Y = Φ U (Φ⁻¹ = Φᵀ M). For tangent vectors, whose flow is the
  /// homogeneous one (analysis/modal_tangent.hpp). O(n² k).
  void tangent_to_modal(const Eigen::Ref<const Eigen::MatrixXd>& y, Eigen::Ref<Eigen::MatrixXd> u,
                        Workspace& work) const;
  void tangent_to_physical(const Eigen::Ref<const Eigen::MatrixXd>& u, Eigen::Ref<Eigen::MatrixXd> y,
                           Workspace& work) const;

  /// Advances every mode's homogeneous part by τ ≥ 0: (u, ud) → (u_out, ud_out). O(n).
  /// If `bound` is non-empty it receives (2σ_k + ω_k)·√(ud² + ω² u²) at τ (see the header).
  void advance(double tau, const Eigen::Ref<const Eigen::VectorXd>& u,
               const Eigen::Ref<const Eigen::VectorXd>& ud, Eigen::Ref<Eigen::VectorXd> u_out,
               Eigen::Ref<Eigen::VectorXd> ud_out, double* bound = nullptr) const;
  /// Mode k's homogeneous propagator over τ: (u, u')(τ) = P (u, u')(0), P 2 × 2 (row-major:
  /// p[0] p[1] / p[2] p[3]).
  void mode_propagator(Eigen::Index k, double tau, double p[4]) const;
  /// The same on k columns at once (tangent vectors; each mode's propagator evaluated once). O(n k).
  void advance_columns(double tau, Eigen::Ref<Eigen::MatrixXd> u, Eigen::Ref<Eigen::MatrixXd> ud) const;

 private:
  struct Implicit;
  /// e^{-στ} C(τ) and e^{-στ} S(τ) of mode k (see the header).
  void propagator(Eigen::Index k, double tau, double* ec, double* es) const;
  /// Regimes, rates and the particular solution from ω² and the modal forcing (both routes).
  /// Pc, Ps: the modal forcing of the extra harmonics, one column each (n × H).
  void finish(const Eigen::VectorXd& p0, const Eigen::VectorXd& pc, const Eigen::VectorXd& ps,
              const Eigen::MatrixXd& Pc, const Eigen::MatrixXd& Ps);

  BandedChain chain_;
  TridiagonalSolver solver_;
  std::shared_ptr<const Implicit> implicit_;  // the secular route (null for the tridiagonal one)
  double setup_seconds_ = 0.0;
  Eigen::VectorXd omega2_, omega_, sigma_, root_, inv_sqrt_mass_, sqrt_mass_;
  Eigen::VectorXi regime_;  // +1 under-, 0 critically, -1 over-damped
  Eigen::MatrixXd q_;
  Eigen::VectorXd c0_, cc_, cs_;
  Eigen::MatrixXd hc_, hs_;  // extra harmonics' particular amplitudes (n × H)
  Eigen::VectorXd rates_;    // k_h Ω
};

/// The dense engine's settings (simulator.hpp: trigger, simultaneity, chatter thresholds and
/// rule, contact_velocity, the Zeno guard, length_scale) with the same meaning and rules; `flow`
/// is the dense flow's and unused here. Plus what only the modal engine has:
struct ModalSimulatorOptions : SimulatorOptions {
  /// Sticking subsystems kept at once, in bytes (each holds its reduced chain's n_r² modes):
  /// beyond it the least recently used one is dropped and rebuilt if visited again
  /// (ModalRunSummary::modes_rebuilt counts that). The free chain's modes are not counted.
  double mode_cache_bytes = 2.0 * 1024.0 * 1024.0 * 1024.0;
  /// How a contact set's modes are built: automatic (the secular equation from the free modes
  /// for chains of 1000 masses or more, O(k N) memory per set; else the reduced chain's own
  /// tridiagonal eigenproblem), secular, or a tridiagonal solver (lapack, eigen).
  TridiagonalSolver contact_modes = TridiagonalSolver::automatic;
  /// End the run (status completed, message saying so) after this many impacts; 0 = no limit.
  /// For benchmarks that want a fixed amount of work.
  long stop_after_impacts = 0;
  /// Throws InvalidInput naming the field, the value and the rule.
  void validate() const;
};

/// A run's summary (as the dense Simulator's, simulator.hpp) and the modal engine's work.
struct ModalRunSummary : RunSummary {
  long evaluations = 0;              ///< evaluations of all modes at one time (the O(n) unit)
  long general_events = 0;           ///< events resolved in physical coordinates (O(N²), see header)
  std::size_t modes_rebuilt = 0;     ///< sticking subsystems rebuilt after the cache dropped them
  double mode_build_seconds = 0.0;   ///< spent building sticking subsystems (tridiagonal solves)
  double mode_build_max_seconds = 0.0;  ///< the slowest single build
};

/// Guard functions of the homogeneous modal state (u, u') of one set of modes:
///     value_i(t) = P_i·u + D_i·u' + h0_i + hc_i cos Ωt + hs_i sin Ωt
///                  + Σ_h (xc_ih cos r_h t + xs_ih sin r_h t),
/// where D has rows only for the last D.rows() guards (the contact forces; gaps have D = 0) and
/// the sum runs over the drive's extra harmonics (rates r_h = k_h Ω; none: no columns). An event
/// is a guard rising above its trigger ε.
struct ModalGuards {
  Eigen::MatrixXd P, D, abs_P, abs_D;
  Eigen::VectorXd h0, hc, hs;
  Eigen::MatrixXd xc, xs;     ///< the extra harmonics' amplitudes (rows × H; H = 0: empty)
  Eigen::VectorXd rates;      ///< r_h (H)
  /// Ω² A_i + Σ_h r_h² A_ih (A the amplitudes √(c² + s²)), the harmonic part's bound on |value''|
  Eigen::VectorXd curvature;
  /// Ω³ A_i + Σ_h r_h³ A_ih, its bound on |value'''|
  Eigen::VectorXd jerk;
  Eigen::Index rows() const { return P.rows(); }
  Eigen::Index harmonics() const { return rates.size(); }
  /// Fills abs_P, abs_D, curvature and jerk from the rest (xc, xs and rates may be left empty
  /// for a drive without extra harmonics).
  void finish(double frequency);
  /// The extra harmonics' part of row i at absolute time t added to value, slope and curvature
  /// (if not null). O(H).
  void add_extra_row(Eigen::Index i, double t, double* value, double* slope, double* curvature) const;
  /// The same for every row. O(rows H).
  void add_extra(double t, Eigen::Ref<Eigen::VectorXd> value, Eigen::Ref<Eigen::VectorXd> slope,
                 Eigen::Ref<Eigen::VectorXd> curvature) const;
};

/// The guards of one set of modes along a segment of their motion, as the certified crossing
/// search sees them (guard_source.hpp; the search is events.hpp's CrossingFinder). Row i is
///     h_i(τ) = P_i·u(τ) + D_i·u'(τ) + h0_i + hc_i cos Ωt + hs_i sin Ωt,   t = t0 + τ,
/// with (u, u')(τ) the homogeneous modal state flowed from (u0, u0') at t0 (ChainModes::advance),
/// and its derivatives from u⁽ᵏ⁺²⁾ = −2σ∘u⁽ᵏ⁺¹⁾ − ω²∘u⁽ᵏ⁾ (elementwise per mode). O(n_r) per
/// row and time, n_r the number of modes.
///
/// **Bounds.** Each mode obeys u'' + 2σu' + ω²u = 0 with σ ≥ 0, ω > 0, so its energy
/// E = ½(u'² + ω²u²) has E' = −2σu'² ≤ 0, and a(τ) = √(2E(τ)) = √(u'² + ω²u²) cannot grow: for
/// every τ ≥ τ_a, |u'(τ)| ≤ a(τ_a) and ω|u(τ)| ≤ a(τ_a). Applying u⁽ᵏ⁺²⁾ = −2σu⁽ᵏ⁺¹⁾ − ω²u⁽ᵏ⁾
/// repeatedly,
///     |u''|   ≤ 2σ|u'| + ω²|u|     ≤ (2σ + ω) a              =: β₂ a,
///     |u'''|  ≤ 2σ|u''| + ω²|u'|   ≤ (2σβ₂ + ω²) a           =: β₃ a,
///     |u''''| ≤ 2σ|u'''| + ω²|u''| ≤ (2σβ₃ + ω²β₂) a         =: β₄ a,
/// all with a = a(τ_a), on [τ_a, ∞). The harmonic part of amplitude A_i = √(hc_i² + hs_i²) (the
/// forced response and the stops' motion) has |dᵏ/dτᵏ| ≤ Ωᵏ A_i, and each extra harmonic of
/// amplitude A_ih at rate r_h adds r_hᵏ A_ih (ModalGuards::curvature, jerk). Hence on every [τ_a, τ_b]
///     |h_i''|  ≤ B₂ᵢ = Σ_k (|P_ik| β₂ₖ + |D_ik| β₃ₖ) a_k + Ω² A_i (+ Σ_h r_h² A_ih),
///     |h_i'''| ≤ B₃ᵢ = Σ_k (|P_ik| β₃ₖ + |D_ik| β₄ₖ) a_k + Ω³ A_i (+ Σ_h r_h³ A_ih),
/// from the state at τ_a alone; both are enlarged by 1 + 1e-12 + 2(n_r + 8)ε to cover the
/// rounding of their own sums. A sample (sample()) holds B₂ then B₃ per row in
/// SegmentSample::growth; derivative_bound reads those of the interval's left end.
class ModalGuardSource final : public GuardSource {
 public:
  /// `capacity`: the largest mode count it will see (the free chain's N), so that retargeting
  /// allocates nothing (a larger count grows the buffers).
  explicit ModalGuardSource(Eigen::Index capacity = 0);
  /// Aims at guards `guards` of `modes` (null: no mass is free, only the harmonic part) from the
  /// homogeneous state (u0, ud0) at absolute time t0, Ω = `frequency`. The modes, the guards
  /// and the state's storage must outlive the source's use.
  void retarget(const ChainModes* modes, const ModalGuards& guards, double frequency, double t0,
                const Eigen::Ref<const Eigen::VectorXd>& u0, const Eigen::Ref<const Eigen::VectorXd>& ud0);

  double t0() const override { return t0_; }
  /// d ∈ {0, 1, 2}; throws std::invalid_argument otherwise.
  double value(Eigen::Index i, double tau, int derivative = 0) const override;
  double second_derivative_bound(Eigen::Index i, double a, double b) const override;
  void sample(double tau, SegmentSample& out) const override;
  void row_jet(Eigen::Index i, double tau, double* h, double* d, double* c) const override;
  double derivative_bound(int derivative, Eigen::Index i, const SegmentSample& a,
                          const SegmentSample& b) const override;

  /// The homogeneous modal state at τ (n_r each). O(n_r).
  void state(double tau, Eigen::Ref<Eigen::VectorXd> u, Eigen::Ref<Eigen::VectorXd> ud) const;
  /// Evaluations of all modes at one time since construction (the O(n_r) unit of work).
  long evaluations() const { return evaluations_; }

 private:
  /// u, u' (and u'', u''' up to `order`) at τ into the buffers.
  void flow(double tau, int order) const;
  /// β₂a, β₃a (and β₄a if `fourth`) per mode from the buffers' state.
  void mode_bounds(bool fourth) const;

  const ChainModes* modes_ = nullptr;
  const ModalGuards* guards_ = nullptr;
  double W_ = 0.0, t0_ = 0.0, inflate_ = 1.0;
  Eigen::Index nr_ = 0;
  const double *u0_ = nullptr, *ud0_ = nullptr;
  mutable Eigen::VectorXd u_, ud_, udd_, uddd_, b2_, b3_, b4_;  // capacity, used through head(nr_)
  mutable long evaluations_ = 0;
};

/// One contact set's motion in modal form: the free chain (empty set) or the reduced chain of
/// the masses left free by the stuck stops, with every guard of that set written in its modes.
/// Built by ModalChainSimulator on first visit (see the header comment); read-only afterwards.
struct ModalContactMode {
  ContactSet stuck;                     ///< sorted rigid stop indices held
  ContactSet engaged;                   ///< sorted compliant stop indices engaged (see "Compliant stops")
  /// The chain with the engaged compliant stops' springs, dashpots and forces (null when none
  /// is engaged): the base the held stops reduce, in place of the free chain.
  std::unique_ptr<ChainModes> engaged_base;
  std::unique_ptr<ChainModes> owned;    ///< the reduced chain's modes (null for the free set)
  const ChainModes* modes = nullptr;    ///< where the state lives; null when no mass is free
  /// Per mass l: its reduced coordinate r (x_l = y_r + o_l(t)), or -1 if prescribed (x_l = o_l(t)).
  std::vector<Eigen::Index> coordinate;
  std::vector<Eigen::Index> first, last;  ///< per reduced coordinate: its masses first..last
  Eigen::VectorXd o0, oc, os;            ///< o_l(t) = o0 + oc cos Ωt + os sin Ωt (empty: all 0)
  /// The offsets' higher harmonics when a held stop moves with some: o_l(t) gains
  /// Σ_h (oxc(l, h) cos r_h t + oxs(l, h) sin r_h t), r_h = guards.rates(h) (N × H; empty
  /// otherwise, the common case, which then costs nothing).
  Eigen::MatrixXd oxc, oxs;
  /// Guards of the set (gaps of the stops neither held nor engaged, then -λ_j of the held stops,
  /// then −g_j of the engaged ones; see the header).
  ModalGuards guards;
  std::vector<int> watched;             ///< stop of each row
  Eigen::Index gap_rows = 0;
  /// Rows from here on are −g of the engaged compliant stops (their D rows are 0).
  Eigen::Index engaged_rows_from = 0;
  double build_seconds = 0.0;
  std::size_t bytes = 0;

  Eigen::Index size() const { return modes ? modes->dof() : 0; }
};

class ModalChainSimulator;

/// A segment's motion kept beyond the observer's callback (ModalSegmentView::keep): the contact
/// set's modes and the homogeneous modal state at the segment's start, O(n_r) to keep. Valid while
/// the simulator's cache holds the set (until its next run). For the analysis layer, which needs
/// the state at a segment's end only at some events, and then sometimes only a few masses.
class ModalSegmentState {
 public:
  ModalSegmentState() = default;
  ModalSegmentState(const ModalChainSimulator& sim, const ModalContactMode& mode, double t_begin,
                    Eigen::VectorXd u, Eigen::VectorXd ud)
      : sim_(&sim), mode_(&mode), t_begin_(t_begin), u_(std::move(u)), ud_(std::move(ud)) {}
  const ModalContactMode& mode() const { return *mode_; }
  /// The full state at t. O(N n_r).
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const;
  /// x and v of the given masses only. O(n_r) per mass.
  void rows(double t, const std::vector<Eigen::Index>& masses, Eigen::VectorXd& x, Eigen::VectorXd& v) const;
  /// The interior local maxima of guard `row` of the set (ModalGuards: the gap of a stop not held,
  /// or −λ of a held stop) in (from, to), from ≥ the segment's start (to may lie beyond its end:
  /// the same flow continued), by the certified search of the events on the guard's slope, armed
  /// at max(1e-13 |h'(from)|, 1e-3 × `tolerance` × the fastest rate): {value h, absolute time}.
  /// O(n_r) per evaluation.
  std::vector<Minimum> guard_local_maxima(Eigen::Index row, double from, double to, double tolerance) const;
  /// Its interior local minima, the same way (an engaged compliant stop's guard −g: the maxima of
  /// its penetration g).
  std::vector<Minimum> guard_local_minima(Eigen::Index row, double from, double to, double tolerance) const;
  /// Guard `row`'s value at t (as above, t may lie beyond the segment's end). O(n_r).
  double guard(Eigen::Index row, double t) const;

 private:
  const ModalChainSimulator* sim_ = nullptr;
  const ModalContactMode* mode_ = nullptr;
  double t_begin_ = 0.0;
  Eigen::VectorXd u_, ud_;
};

/// The modal engine's segment for observers (observers.hpp): every observer of the dense engine
/// works unchanged. A full state costs O(N n_r) (the modes' basis change), a force O(n_r).
class ModalSegmentView final : public SegmentView {
 public:
  ModalSegmentView(const ModalChainSimulator& sim, const ModalContactMode& mode, double t_begin,
                   double t_end)
      : SegmentView(t_begin, t_end), sim_(&sim), mode_(&mode) {}
  Eigen::Index dof() const override;
  const ContactSet& active() const override { return mode_->stuck; }
  /// The contact set's modal form and the simulator (valid during the observer's callback).
  const ModalContactMode& mode() const { return *mode_; }
  const ModalChainSimulator& simulator() const { return *sim_; }
  /// This segment's motion, kept (see ModalSegmentState). O(n_r).
  ModalSegmentState keep() const;
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override;
  double force(Eigen::Index a, double t) const override;
  Minimum force_minimum(Eigen::Index a) const override;
  std::vector<Minimum> force_local_minima(Eigen::Index a) const override;
  /// h = nᵀx − c written in the set's modes (h = P·u + harmonic, P = Σ_l n_l φ_l over the free
  /// masses' rows, the held masses' prescribed motion and the particular solution in the
  /// harmonic part) and searched as a ModalGuardSource. O(n_r) per evaluation.
  void plane_crossings(const Hyperplane& plane, double trigger, int& side,
                       std::vector<PlaneCrossing>& out) const override;

 private:
  const ModalChainSimulator* sim_;
  const ModalContactMode* mode_;
};

/// What the modal engine says of a stop along a general normal (Stop::Kind::normal): it runs
/// one through free flight, impacts and chatter, but does not hold one (its reductions fix
/// masses or join neighbours; see "General normals" above).
inline constexpr const char* kModalStopsOnly =
    "the modal engine runs a stop along a general normal through free flight, impacts and chatter but "
    "does not hold one (a run in which it would stick ends unsupported); the dense engine holds any "
    "(solver.engine: dense)";

/// Why the modal engine cannot run compliant stop `s` on `chain` (empty: it can). It takes a
/// compliant stop on one mass or between neighbouring masses (k_s then stays on K's band) whose
/// dashpot keeps the damping proportional, c_s = β k_s with the chain's C = αM + βK (to 1e-12
/// relative): each engaged set is then a chain again (see "Compliant stops" above).
std::string compliant_refusal(const Stop& s, const BandedChain& chain);

/// The chain with a zero forcing harmonic of every order ≥ 2 that a stop moves at and its drive
/// lacks (appended in the order the stops name them), as ImpactSystem gives its system: the
/// modes of a chain whose stops move with higher harmonics are built from it, so that each
/// order's rate and particular solution have a slot (ModalChainSimulator checks it). The chain
/// itself when nothing is missing.
BandedChain with_stop_orders(BandedChain chain, const std::vector<Stop>& stops);

/// Free flight, impacts, chatter and sticking of a proportionally damped chain with stops, in
/// modal coordinates. Stops are validated here (mass indices, r ∈ [0, 1], finite values, moving
/// stops need Ω > 0; a general normal needs N finite entries, not all zero; a compliant stop
/// compliant_refusal refuses, with its reason). Not thread-safe: one simulator per thread (they may share one const
/// ChainModes). A stop may move with higher harmonics (Stop::harmonics): its motion enters the
/// guards, the held sets' offsets and the crossing search's bounds as the drive's extra
/// harmonics do; the modes must then come from with_stop_orders(chain, stops) (InvalidInput
/// naming the stop and the order otherwise).
class ModalChainSimulator {
 public:
  ModalChainSimulator(const ChainModes& modes, std::vector<Stop> stops,
                      ModalSimulatorOptions options = {});
  /// The simulator keeps a reference to the modes: temporary ones would dangle.
  ModalChainSimulator(ChainModes&& modes, std::vector<Stop> stops, ModalSimulatorOptions options = {}) = delete;
  ~ModalChainSimulator();
  ModalChainSimulator(const ModalChainSimulator&) = delete;
  ModalChainSimulator& operator=(const ModalChainSimulator&) = delete;

  /// Throws InvalidInput for wrong sizes, non-finite values or x0 violating a stop by more than
  /// the trigger tolerance. Other trouble ends the run with a status and a message; a contact set
  /// the engine cannot reduce (see the header) ends it with RunStatus::unsupported.
  ModalRunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                      double t_end, const std::vector<Observer*>& observers = {});

  const ChainModes& modes() const { return *modes_; }
  const std::vector<Stop>& stops() const { return stops_; }
  const ModalSimulatorOptions& options() const { return options_; }
  /// Seconds spent building the free chain's stop rows Φᵀw_j (O(N) per stop), in the constructor.
  double stop_setup_seconds() const { return stop_setup_seconds_; }
  /// Sticking subsystems currently held in the cache.
  std::size_t cached_modes() const;
  /// Runs started so far: a record that points into the cache (analysis/modal_tangent.hpp) is
  /// valid only until the next run, which may drop a contact set it refers to.
  long runs_started() const { return runs_started_; }
  /// Contact sets dropped from the cache so far (mode_cache_bytes): a record made during a run
  /// that dropped one may point to a set that is gone.
  long modes_dropped() const { return modes_dropped_; }
  /// The modal form of contact set `set` (sorted stop indices), built now if not cached (for
  /// inspection and benchmarks; runs build what they visit). Throws InvalidInput naming the
  /// stops if the set cannot be reduced.
  const ModalContactMode& contact_mode(const ContactSet& set);

  // For ModalSegmentView: the current segment's start and homogeneous modal state.
  double segment_start() const { return seg_t0_; }
  Eigen::Ref<const Eigen::VectorXd> segment_u() const { return u0_.head(nr_); }
  Eigen::Ref<const Eigen::VectorXd> segment_ud() const { return ud0_.head(nr_); }
  /// The run's force trigger ε_F = trigger·F (for force minima) and gap trigger ε_g = trigger·L.
  double force_tolerance() const { return force_tolerance_; }
  double gap_tolerance() const { return gap_tolerance_; }

 private:
  struct Cache;
  class Loop;  // the engine's side of the event loop (modal_simulator.cpp)
  const ModalContactMode* mode_for(const ContactSet& set, std::string* why_not,
                                   ModalRunSummary& summary);

  const ChainModes* modes_;
  std::vector<Stop> stops_;
  ModalSimulatorOptions options_;
  double stop_setup_seconds_ = 0.0;
  long runs_started_ = 0, modes_dropped_ = 0;
  std::unique_ptr<Cache> cache_;
  double seg_t0_ = 0.0, force_tolerance_ = 1e-13, gap_tolerance_ = 1e-13;
  // The segment's homogeneous modal state: storage for the free chain's N modes, the current
  // mode's nr_ of them in use (so that changing modes allocates nothing).
  Eigen::VectorXd u0_, ud0_;
  Eigen::Index nr_ = 0;
};

}  // namespace vibro
