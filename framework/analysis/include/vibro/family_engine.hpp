#pragma once
/// \file family_engine.hpp
/// The engine at one value p of a parameter, as continuation (continuation.hpp) drives it: the
/// exact map over [t0, t1] with its Jacobian, its derivative ∂z1/∂p along dD/dp and the features
/// the test functions need (linearisation.hpp); plain runs; Newton shooting (shooting.hpp).
///
/// One implementation per engine (engine.hpp): the Taylor engine's is taylor_family_engine below.
///  * dense: an ImpactSystem and the SimulatorOptions — linearise(ImpactSystem, …), Simulator,
///    shoot(ImpactSystem, …). Any M, C, K and any parameter.
///  * modal: a ModalEngine on a proportionally damped chain — linearise(ModalEngine&, …) with the
///    full J (ModalTangent::fill_jacobian: 2N products per map, O(N²) memory) and
///    shoot_full_jacobian, so continuation does the same dense linear algebra (LU on the bordered
///    (2N + 1)² system, eigenvalues of the reduced map) on either engine's maps and takes the same
///    steps up to their rounding. Parameters along Ω, the forcing and the stops' data only: a
///    dD/dp that moves M, C or K would move the modes (modal_tangent.hpp) and is refused when the
///    engine is made (InvalidInput).
///    Cost per corrector iteration: one run, 2N tangent columns through it and an O(N³) LU —
///    fine up to a couple of thousand masses. Beyond, a matrix-free bordered corrector
///    (Newton–Krylov on [J − I, ∂P/∂p; tᵀ], as shoot(ModalEngine&, …, KrylovOptions) does for
///    J − I, with Arnoldi multipliers) is the next step; it is not built yet.
///
/// A family maps p to such an engine (it throws InvalidInput where p gives no valid system:
/// continuation takes that as "no orbit there"). Not running_locate.hpp's EngineFamily, which gives
/// plain engines (engine.hpp) to the running method of locating bifurcations.
///
/// Usage:
///     vibro::ContinuationFamily fam = [&](double omega) {
///       vibro::BandedChain c = chain;  c.forcing.frequency = omega;
///       return vibro::modal_family_engine(std::move(c), stops, vibro::SystemDerivative::frequency_only(), {});
///     };
///     vibro::ContinuationResult r = vibro::continue_orbits(fam, 0.5, t, x, v, options);
#include "vibro/engine.hpp"
#include "vibro/linearisation.hpp"
#include "vibro/parameter.hpp"
#include "vibro/shooting.hpp"

#include <functional>
#include <memory>
#include <utility>
#include <vector>

namespace vibro {

class FamilyEngine {
 public:
  explicit FamilyEngine(SystemDerivative d) : derivative(std::move(d)) {}
  virtual ~FamilyEngine() = default;
  FamilyEngine(const FamilyEngine&) = delete;
  FamilyEngine& operator=(const FamilyEngine&) = delete;

  virtual Eigen::Index dof() const = 0;
  virtual std::size_t stop_count() const = 0;
  virtual double frequency() const = 0;  ///< Ω at this p
  /// The map over [t0, t1] (linearisation.hpp); throws InvalidInput as the engine's run does.
  virtual TangentMap linearise(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1,
                               const LinearisationOptions& options) = 0;
  /// A plain run from (t0, x0, v0) to t1.
  virtual RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t1) = 0;
  /// Newton shooting with the full Jacobian (options.solver: the dense engine's; the modal engine
  /// has its own settings).
  virtual ShootingResult shoot(const ShootingOptions& options, double t_guess, const Eigen::VectorXd& x,
                               const Eigen::VectorXd& v) = 0;

  /// Stop j's normal w (its gap is g = wᵀx − s_j(t)) and the velocity jump of a lone impact on it
  /// per unit approach speed, −(1 + r_j) M⁻¹w / (wᵀM⁻¹w): what an impact born at a grazing adds
  /// to the orbit, to first order in its speed (continuation's grazing corners). For a compliant
  /// stop the jump is empty: its engagement has no impulse (the corner step does not apply).
  virtual std::pair<Eigen::VectorXd, Eigen::VectorXd> impact_direction(int j) const = 0;
  /// dD/dp at this p (parameter.hpp). Continuation along a line in a plane of two parameters
  /// (follow_curve) replaces it by the line's combination.
  SystemDerivative derivative;
};

using ContinuationFamily = std::function<std::unique_ptr<FamilyEngine>(double p)>;

/// The dense engine on `system` with `solver`.
std::unique_ptr<FamilyEngine> dense_family_engine(ImpactSystem system, SystemDerivative derivative,
                                                  const SimulatorOptions& solver);

/// The Taylor engine (taylor_simulator.hpp) on `system` with the nonlinear `forces`: maps from
/// linearise(system, forces, …) (linearisation.hpp), whose parameter column follows Ω, the
/// drive, C, K, the stops' data and the forces' named parameters (SystemDerivative::
/// force_parameters). Orbits with impacts in free flight only (a held stop fails the map).
/// Throws InvalidInput for a derivative that moves M (or has the wrong size).
std::unique_ptr<FamilyEngine> taylor_family_engine(ImpactSystem system, NonlinearForces forces,
                                                   SystemDerivative derivative, const SimulatorOptions& solver);

/// The modal engine on `chain` and `stops`. Throws InvalidInput for a derivative that moves M, C or
/// K (or has the wrong size), and as ModalEngine's constructor does.
std::unique_ptr<FamilyEngine> modal_family_engine(BandedChain chain, std::vector<Stop> stops,
                                                  SystemDerivative derivative, const ModalSimulatorOptions& options);

}  // namespace vibro
