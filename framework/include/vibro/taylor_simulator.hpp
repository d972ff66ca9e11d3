#pragma once
/// \file taylor_simulator.hpp
/// The Taylor-series engine: an ImpactSystem (linear M, C, K, harmonic drive, rigid and compliant
/// stops) with
/// nonlinear forces F(x, v, t) added to its equations,
///
///     M x'' + C x' + K x = f(t) + F(x, v, t),
///
/// run through the same hybrid event loop and the same event resolution as the dense engine
/// (event_loop.hpp, event_resolution.hpp: Newton impacts through the LCP, the chatter rule,
/// sticking, release at a contact force's sign change).
///
/// Between events the motion of the current contact mode is advanced by Taylor steps
/// (vibro/taylor/taylor_step.hpp: automatic differentiation of the forces, order and step from
/// the coefficients' decay, Jorba & Zou 2005). The drive f(t) and the stops' motion p(t) enter as
/// time series known in closed form. With a set of rigid stops held, the acceleration is the
/// constrained one a = M⁻¹(F − Wλ), Wᵀa = p̈(t) (taylor_step.hpp, StepTerms): the constant
/// matrices W, M⁻¹W, (WᵀM⁻¹W)⁻¹ of each held set are built on its first visit, and the contact
/// forces λ come out of every step as series too. An engaged compliant stop (stops.hpp) adds its
/// spring and dashpot along its normal to K and C and its motion and preload to the drive
/// (engaged_system.hpp): each engaged set's A_x, A_v and drive are built on its first
/// visit and replace the system's in the steps (StepTerms), so an engaged set is the same
/// Taylor system with other linear terms, held rigid stops (a two-stage stop) on top of it.
///
/// Events: each step's guards — the gap wᵀx − p(t) of every stop neither held nor engaged, −λ of
/// every held one, −(wᵀx − p(t)) of every engaged compliant one — are polynomials in the step time (their coefficients from the state's and λ's), with
/// the step's remainder bound; the first rise above the trigger is isolated by guard_roots.hpp
/// (certified: Bernstein sign changes with the remainder folded in), and the event's time is
/// the guard's root at zero refined to rounding, as the dense engine places it. A compliant
/// stop's engage and disengage change the engaged set only (compliant_switches, shared with
/// the dense engine), the state is continuous.
///
/// Accuracy: the series is truncated at ~ε of the state's scale per step (TaylorSettings), and
/// the state is evaluated by compensated Horner, so a linear scene run here agrees with the exact
/// dense engine to ~1e-13 of its scales (tests/taylor/test_taylor_engine.cpp).
///
/// Limits: the chatter rule's local coefficients (α_j, β_j and the state correction of
/// event_resolution.hpp) are those of the linear part M, C, K: a nonlinear force's Jacobian at
/// the contact does not enter them (the accumulation point is then located to the order the
/// rule is exact for the linear part; first_order is unaffected).
///
/// Layering: the engine lives in vibro_core (it needs the core's private event loop and event
/// resolution), and vibro_core links vibro_taylor, which depends on Eigen only, so there is no
/// cycle.
///
/// Usage:
///     vibro::NonlinearForces f;
///     f.parameters = {{"beta", 0.5}};
///     f.forces = {"-beta*x0^3"};                      // one entry per coordinate ("" for none)
///     vibro::TaylorSimulator sim(system, f, options);  // throws ExpressionError, InvalidInput
///     vibro::RunSummary s = sim.run(0.0, x0, v0, 100.0, {&samples});
#include "vibro/engine.hpp"
#include "vibro/simulator.hpp"
#include "vibro/taylor/taylor_system.hpp"

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace vibro {

/// The nonlinear forces of a scene: F_i as expressions (vibro/taylor/expression.hpp) in x0…,
/// v0…, t, Omega and the named parameters.
struct NonlinearForces {
  std::vector<std::pair<std::string, double>> parameters;
  std::vector<std::string> forces;  ///< n entries ("" for none) or empty
  /// The series' tolerance (TaylorSettings::tolerance; default: the unit roundoff).
  double tolerance = std::numeric_limits<double>::epsilon();
  /// The series' order (TaylorSettings::order; default 0: from the tolerance).
  int order = 0;
};

class TaylorSimulator {
 public:
  /// Compiles the forces (throws taylor::ExpressionError / std::invalid_argument) and validates
  /// the options. The scene must outlive the simulator.
  TaylorSimulator(const ImpactSystem& scene, const NonlinearForces& forces, SimulatorOptions options = {});
  /// The simulator keeps a reference to its scene: a temporary one would dangle.
  TaylorSimulator(ImpactSystem&& scene, const NonlinearForces& forces, SimulatorOptions options = {}) = delete;
  ~TaylorSimulator();
  TaylorSimulator(const TaylorSimulator&) = delete;
  TaylorSimulator& operator=(const TaylorSimulator&) = delete;

  /// As Simulator::run.
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {});
  /// Taylor steps taken by the last run.
  long steps() const { return steps_; }
  const taylor::TaylorSystem& system() const { return *system_; }

  /// What a run's segment view reads of the running loop (private to the engine).
  class LoopAccess {
   public:
    virtual ~LoopAccess() = default;
    virtual Eigen::Index dof() const = 0;
    virtual const ContactSet& active() const = 0;
    virtual void state_at(double elapsed, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const = 0;
    virtual double force_at(Eigen::Index a, double elapsed) const = 0;
    virtual void force_minima(Eigen::Index a, double span, double t_begin, std::vector<Minimum>& out) const = 0;
  };

 private:
  class Loop;
  const ImpactSystem* scene_;
  SimulatorOptions options_;
  double tolerance_;
  int order_;
  std::unique_ptr<taylor::TaylorSystem> system_;
  long steps_ = 0;
};

/// The Taylor engine behind engine.hpp's interface, on its own copy of the system.
class TaylorEngine final : public Engine {
 public:
  TaylorEngine(ImpactSystem system, const NonlinearForces& forces, const SimulatorOptions& options)
      : system_(std::make_unique<ImpactSystem>(std::move(system))), sim_(*system_, forces, options) {}
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {}) override {
    return sim_.run(t0, x0, v0, t_end, observers);
  }
  double frequency() const override { return system_->system().forcing().frequency; }
  std::size_t stop_count() const override { return system_->stop_count(); }
  TaylorSimulator& simulator() { return sim_; }

 private:
  std::unique_ptr<ImpactSystem> system_;  // stable address for sim_
  TaylorSimulator sim_;
};

}  // namespace vibro
