#pragma once
/// \file modal_tangent.hpp
/// The exact linearisation of a run of the modal chain engine (modal.hpp), matrix-free: the
/// products J·D of the tangent map J = ∂(x1, v1)/∂(x0, v0) with any directions D, at O(N n_r)
/// per segment and column and O(N) per event and column, and nothing N × N stored unless the
/// full matrix is asked for. What Newton–Krylov shooting and Arnoldi multipliers of long
/// chains need (shooting.hpp: shoot(ModalEngine&, …)).
///
/// **Between events** a tangent vector follows the homogeneous flow of the segment's contact
/// set (the particular solution and the held stops' motion do not depend on the state): on the
/// set's reduced chain δx = T δy (held masses fixed, joined masses moving as one), δy = Φ_S δu,
/// and every mode advances by its own 2 × 2 propagator — the engine's exact modal flow, written
/// once in ChainModes (advance_columns, tangent_to_modal, tangent_to_physical). A vector off the
/// constraint manifold is first projected onto it M-orthogonally, as the engine projects states.
///
/// **At an event** the saltation of linearisation.hpp, applied to vectors rather than formed:
///     δz⁺ = R_z δz + (f⁺ − R_z f⁻ − R_t) (h_z·δz) / ḣ⁻,
/// where R_z δz and R_t are directional derivatives of the engine's reset (the same rules,
/// analysis/src/mechanics.hpp, on the chain's banded form: O(N) each, by dual numbers), h_z·δz is
/// the guard's derivative (w_jᵀδx for an impact, −δλ_j for a release) and f∓ = (v, a_S) the vector
/// fields of the sets before and after. Simultaneous impacts are taken one at a time (index
/// order); their order's effect is measured on fixed test vectors (TangentMap::non_smooth).
/// A compliant stop engaging or disengaging (modal.hpp, "Compliant stops") is such a saltation
/// with the guard g_j and no reset but the held rigid stops' projection: f⁺ − f⁻ = ∓(0, M⁻¹w_j
/// c_j ġ_j) at g_j = 0 (the spring's force k_j g_j vanishes there), so the map is continuous
/// through it when c_j = 0 and jumps by (f⁺ − f⁻) w_jᵀδx / ġ_j otherwise. The sets with engaged
/// stops are flown in their own modes, as the engine flies them.
///
/// **Parameter derivatives** (parameter(): ζ = ∂z/∂p at fixed t0, t1 along a SystemDerivative dD
/// that moves Ω, the forcing (any of its harmonics) or the stops' data). None of these moves the homogeneous flow J_h of a
/// contact set (its modes depend on M, K, α, β only), so a flight from t_b to t_e, which maps z to
/// z_p(t_e) + J_h (z − z_p(t_b)) with z_p the set's periodic particular solution (the held stops'
/// motion plus the reduced chain's periodic response), gives
///     ζ ← J_h (ζ − ∂z_p(t_b)/∂p) + ∂z_p(t_e)/∂p,
/// exactly, with ∂z_p/∂p from the same per-mode harmonic response as the engine's (modal.hpp,
/// harmonic_response) in dual numbers: O(N) per flight once a set's amplitudes are known (O(N n_r)
/// per set and parameter). An event adds s_p = R_p + (f⁺ − R_z f⁻ − R_t) h_p / ḣ⁻ (linearisation.hpp),
/// h_p and R_p again by dual numbers through the same reset and guard code, seeded along dD.
/// M, C or K derivatives would move the modes themselves and are refused (InvalidInput), and so
/// are those of a compliant stop's k_s or c_s (they move its engaged sets' modes); its preload
/// F_p is a force and enters the engaged sets' particular solutions.
///
/// **Differences from the dense linearisation.** (1) A run that starts with a stop held has a
/// one-sided map at t0: here directions off the constraint manifold are projected onto it at t0
/// (the dense map lets them drift); maps that start in free flight agree to rounding
/// (tests/analysis/test_modal_tangent.cpp); the parameter derivative of a run starting held
/// likewise includes the projection of the start onto the moved manifold. (2) Parameter
/// derivatives only along Ω, the forcing and the stops' data (offsets, harmonic motion,
/// restitution, a compliant stop's preload), equal to the dense ones to rounding (≤ 7e-13 relative in the tests); mass,
/// damping and stiffness derivatives are refused (dense engine). (3) Features (options.features:
/// gap peaks, force dips with those past a release, impacts; phases always) are found by the
/// engine's certified search on the modal guards' slopes (ModalSegmentState::guard_local_maxima)
/// rather than on the dense flow's rows: the same extrema, to ≤ 4e-12 of T, L, F in the tests
/// (impact speeds and accelerations ≤ 2e-11, late in chatter sequences).
///
/// The record points into the engine's cache of contact sets: it is valid until the engine's
/// next run (apply() throws std::logic_error after that), and a run during which the cache had to
/// drop a set (ModalSimulatorOptions::mode_cache_bytes) gives no map (status unsupported, saying so).
///
/// Usage:
///     vibro::ModalEngine engine(chain, stops, options);
///     vibro::ModalTangent tangent(engine, t0, x0, v0, t0 + T);
///     Eigen::MatrixXd Jd = tangent.apply(d);          // 2N × p
///     Eigen::VectorXd dz = tangent.parameter(vibro::SystemDerivative::frequency_only());  // ∂z1/∂Ω
///     vibro::TangentMap m = tangent.map();            // end state, events, saltations …
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"

#include <atomic>
#include <memory>
#include <vector>

namespace vibro {

class ModalTangent {
 public:
  /// Runs `engine` from (t0, x0, v0) to t1 and records the tangent map. Throws InvalidInput as
  /// the engine's run does (sizes, an inadmissible start). Compliant stops' engagements and
  /// disengagements are switches of the vector field with their saltation matrices, as on the
  /// dense map (linearisation.hpp). If the run does not complete, map()
  /// says so in its summary and apply() throws std::logic_error.
  /// `modal_events` false takes every event through physical coordinates (the general path; for
  /// tests of the free-flight fast path, see below).
  ModalTangent(ModalEngine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
               bool modal_events = true);
  /// The same, with the features options.features asks for (gap peaks, force dips, within
  /// options.past_release_window, impacts: TangentMap; phases are always recorded); the other
  /// options are for linearise() and ignored here.
  ModalTangent(ModalEngine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
               const LinearisationOptions& options, bool modal_events = true);
  ~ModalTangent();
  ModalTangent(const ModalTangent&) = delete;
  ModalTangent& operator=(const ModalTangent&) = delete;

  /// The run: summary, start and end states, rates, events, saltation records, held phases,
  /// least guard rate, free dimension, non-smoothness. jacobian, products, reduced are empty.
  const TangentMap& map() const { return map_; }
  Eigen::Index size() const { return 2 * n_; }

  /// J·D for D of 2N rows (unscaled x, v). The engine's interrupt flag is looked at between the
  /// record's ops, as in fill_jacobian(): throws Interrupted once it is raised.
  Eigen::MatrixXd apply(const Eigen::MatrixXd& directions) const;
  /// ∂(x1, v1)/∂p at fixed t0, t1 along dD (TangentMap::parameter of linearisation.hpp), exactly,
  /// for a dD that leaves the chain's homogeneous dynamics alone: Ω, the forcing, every stop's
  /// offset, harmonic motion and restitution. Throws InvalidInput for a dD of the wrong size or
  /// one that moves M, C or K (the dense engine has those). Costs one more column's pass of the
  /// record plus, per contact set of the run, its particular solution's derivative (O(N n_r)).
  /// One record serves any number of parameters.
  Eigen::VectorXd parameter(const SystemDerivative& derivative) const;
  /// The same map in the free chain's modal coordinates (δu; δu') = Φ̃⁻¹ (δx; δv), Φ̃ = diag(Φ, Φ):
  /// Φ̃⁻¹ J Φ̃ D. Free flights and free-flight impacts cost O(N) per column there; the basis
  /// changes (O(N²) per column) are paid only around events with stops held, where the engine
  /// pays them too. The form for Krylov methods on long chains (same eigenvalues as J).
  Eigen::MatrixXd apply_modal(const Eigen::MatrixXd& directions) const;
  Eigen::MatrixXd modal_coordinates(const Eigen::MatrixXd& physical) const;  ///< Φ̃⁻¹ D
  Eigen::MatrixXd physical_coordinates(const Eigen::MatrixXd& modal) const;  ///< Φ̃ D

  /// J itself (2N products) with its reduced map and lift (linearisation.hpp, structural
  /// zeros): O(N²) memory. For chains of up to a few thousand masses, where it takes seconds to
  /// minutes (O(N³) at each event with stops held): the columns go through the record in blocks
  /// of 64 to 127 (one pass for 2N < 128; each column's products are the same whichever block
  /// holds it), and between blocks and between the record's ops the engine's interrupt flag
  /// (SimulatorOptions::interrupt) is looked at. Throws Interrupted once it is raised; `out`
  /// then has no J (linearise reports the map as interrupted).
  void fill_jacobian(TangentMap& out) const;

  struct Record;       ///< what the run left (defined in modal_tangent.cpp only)
  struct Sensitivity;  ///< a parameter column's data (likewise)

 private:
  /// The whole record on D, in physical or modal coordinates; checks D's size. With `stop`, as
  /// apply_range.
  Eigen::MatrixXd through(const Eigen::MatrixXd& directions, bool modal, const std::atomic<bool>* stop = nullptr) const;
  /// Ops [from, to) of the record applied to D in place; D's columns in modal coordinates on the
  /// way in / out where asked. With `p`, column p->column is a parameter sensitivity ζ and also
  /// gets the affine terms of each flight and event.
  /// With `stop`, throws Interrupted before an op once *stop is raised.
  void apply_range(std::size_t from, std::size_t to, Eigen::MatrixXd& D, bool modal_in, bool modal_out,
                   Sensitivity* p = nullptr, const std::atomic<bool>* stop = nullptr) const;

  const ModalChainSimulator* sim_;
  long run_ = 0;
  Eigen::Index n_ = 0;
  TangentMap map_;
  std::unique_ptr<Record> record_;
};

/// linearise() on the modal engine: the map over [t0, t1] with J (options.jacobian, directions
/// empty) or the products J·directions, and ∂z1/∂p for options.parameter (see parameter()).
/// With options.features, the features of linearisation.hpp (gap peaks, force dips, impacts).
/// Throws InvalidInput for a parameter derivative that moves M, C or K or has the wrong size and
/// for directions of the wrong size. The engine's interrupt flag raised while J is formed
/// (fill_jacobian) ends the map as the dense engine's does: status interrupted, no J.
TangentMap linearise(ModalEngine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                     double t1, const LinearisationOptions& options = {});

}  // namespace vibro
