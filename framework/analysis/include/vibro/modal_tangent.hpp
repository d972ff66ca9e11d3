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
///
/// **Differences from the dense linearisation.** (1) A run that starts with a stop held has a
/// one-sided map at t0: here directions off the constraint manifold are projected onto it at t0
/// (the dense map lets them drift); maps that start in free flight agree to rounding
/// (tests/analysis/test_modal_tangent.cpp). (2) No parameter derivatives and no features (gap
/// peaks, force dips): continuation stays on the dense engine; asking for them throws.
///
/// The record points into the engine's cache of contact sets: it is valid until the engine's
/// next run (apply() throws std::logic_error after that), and a run during which the cache had to
/// drop a set (ModalSimulatorOptions::mode_cache_bytes) gives no map (status unsupported, saying so).
///
/// Usage:
///     vibro::ModalEngine engine(chain, stops, options);
///     vibro::ModalTangent tangent(engine, t0, x0, v0, t0 + T);
///     Eigen::MatrixXd Jd = tangent.apply(d);          // 2N × p
///     vibro::TangentMap m = tangent.map();            // end state, events, saltations …
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"

#include <memory>
#include <vector>

namespace vibro {

class ModalTangent {
 public:
  /// Runs `engine` from (t0, x0, v0) to t1 and records the tangent map. Throws InvalidInput as
  /// the engine's run does (sizes, an inadmissible start). If the run does not complete, map()
  /// says so in its summary and apply() throws std::logic_error.
  /// `modal_events` false takes every event through physical coordinates (the general path; for
  /// tests of the free-flight fast path, see below).
  ModalTangent(ModalEngine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
               bool modal_events = true);
  ~ModalTangent();
  ModalTangent(const ModalTangent&) = delete;
  ModalTangent& operator=(const ModalTangent&) = delete;

  /// The run: summary, start and end states, rates, events, saltation records, held phases,
  /// least guard rate, free dimension, non-smoothness. jacobian, products, reduced are empty.
  const TangentMap& map() const { return map_; }
  Eigen::Index size() const { return 2 * n_; }

  /// J·D for D of 2N rows (unscaled x, v).
  Eigen::MatrixXd apply(const Eigen::MatrixXd& directions) const;
  /// The same map in the free chain's modal coordinates (δu; δu') = Φ̃⁻¹ (δx; δv), Φ̃ = diag(Φ, Φ):
  /// Φ̃⁻¹ J Φ̃ D. Free flights and free-flight impacts cost O(N) per column there; the basis
  /// changes (O(N²) per column) are paid only around events with stops held, where the engine
  /// pays them too. The form for Krylov methods on long chains (same eigenvalues as J).
  Eigen::MatrixXd apply_modal(const Eigen::MatrixXd& directions) const;
  Eigen::MatrixXd modal_coordinates(const Eigen::MatrixXd& physical) const;  ///< Φ̃⁻¹ D
  Eigen::MatrixXd physical_coordinates(const Eigen::MatrixXd& modal) const;  ///< Φ̃ D

  /// J itself (2N products) with its reduced map and lift (linearisation.hpp, structural
  /// zeros): O(N²) memory. For chains of up to a few thousand masses.
  void fill_jacobian(TangentMap& out) const;

  struct Record;  ///< what the run left (defined in modal_tangent.cpp only)

 private:
  /// The whole record on D, in physical or modal coordinates; checks D's size.
  Eigen::MatrixXd through(const Eigen::MatrixXd& directions, bool modal) const;
  /// Ops [from, to) of the record applied to D in place; D's columns in modal coordinates on the
  /// way in / out where asked.
  void apply_range(std::size_t from, std::size_t to, Eigen::MatrixXd& D, bool modal_in, bool modal_out) const;

  const ModalChainSimulator* sim_;
  long run_ = 0;
  Eigen::Index n_ = 0;
  TangentMap map_;
  std::unique_ptr<Record> record_;
};

/// linearise() on the modal engine: the map over [t0, t1] with J (options.jacobian, directions
/// empty) or the products J·directions. Throws InvalidInput for a parameter derivative or
/// features (dense engine only) and for directions of the wrong size.
TangentMap linearise(ModalEngine& engine, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                     double t1, const LinearisationOptions& options = {});

}  // namespace vibro
