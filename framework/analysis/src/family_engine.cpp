#include "vibro/family_engine.hpp"

#include "mechanics.hpp"

#include "vibro/modal_tangent.hpp"

#include <utility>

namespace vibro {
namespace {

using Eigen::VectorXd;

using detail::lone_impact;

class DenseFamilyEngine final : public FamilyEngine {
 public:
  DenseFamilyEngine(ImpactSystem system, SystemDerivative d, const SimulatorOptions& solver)
      : FamilyEngine(std::move(d)), system_(std::move(system)), solver_(solver) {}
  Eigen::Index dof() const override { return system_.dof(); }
  std::size_t stop_count() const override { return system_.stop_count(); }
  double frequency() const override { return system_.system().forcing().frequency; }
  TangentMap linearise(double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                       const LinearisationOptions& options) override {
    return vibro::linearise(system_, solver_, t0, x0, v0, t1, options);
  }
  RunSummary run(double t0, const VectorXd& x0, const VectorXd& v0, double t1) override {
    Simulator sim(system_, solver_);  // a fresh one per run, as continuation always had
    return sim.run(t0, x0, v0, t1);
  }
  ShootingResult shoot(const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v) override {
    return vibro::shoot(system_, options, t_guess, x, v);
  }
  std::pair<VectorXd, VectorXd> impact_direction(int j) const override {
    return lone_impact(detail::Mechanics<double>(system_), j);
  }

 private:
  ImpactSystem system_;
  SimulatorOptions solver_;
};

class ModalFamilyEngine final : public FamilyEngine {
 public:
  ModalFamilyEngine(BandedChain chain, std::vector<Stop> stops, SystemDerivative d, const ModalSimulatorOptions& o)
      : FamilyEngine(std::move(d)), dof_(chain.dof()), mechanics_(with_stop_orders(chain, stops), stops),
        engine_(std::move(chain), std::move(stops), o) {
    derivative.validate(dof(), stop_count());
    if (detail::Mechanics<double>::moves_matrices(derivative))
      throw InvalidInput("continuation on the modal engine: the parameter moves the mass, damping or stiffness "
                         "matrix (hence the chain's modes); continue in Ω, the forcing or the stops' data, or use "
                         "the dense engine");
  }
  Eigen::Index dof() const override { return dof_; }
  std::size_t stop_count() const override { return engine_.stop_count(); }
  double frequency() const override { return engine_.frequency(); }
  TangentMap linearise(double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                       const LinearisationOptions& options) override {
    return vibro::linearise(engine_, t0, x0, v0, t1, options);
  }
  RunSummary run(double t0, const VectorXd& x0, const VectorXd& v0, double t1) override {
    return engine_.run(t0, x0, v0, t1);
  }
  ShootingResult shoot(const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v) override {
    return shoot_full_jacobian(engine_, options, t_guess, x, v);
  }
  std::pair<VectorXd, VectorXd> impact_direction(int j) const override { return lone_impact(mechanics_, j); }

 private:
  Eigen::Index dof_;
  detail::Mechanics<double> mechanics_;
  ModalEngine engine_;
};

/// The Taylor engine: `system` with nonlinear forces; maps from linearise(system, forces, …).
class TaylorFamilyEngine final : public FamilyEngine {
 public:
  TaylorFamilyEngine(ImpactSystem system, NonlinearForces forces, SystemDerivative d, const SimulatorOptions& solver)
      : FamilyEngine(std::move(d)), system_(std::move(system)), forces_(std::move(forces)), solver_(solver) {
    derivative.validate(dof(), stop_count());
    if (derivative.mass.size() && !derivative.mass.isZero(0.0))
      throw InvalidInput("continuation on the Taylor engine: the parameter moves the mass matrix; continue in Ω, "
                         "the forcing, C, K, the stops' data or a parameter of the forces");
  }
  Eigen::Index dof() const override { return system_.dof(); }
  std::size_t stop_count() const override { return system_.stop_count(); }
  double frequency() const override { return system_.system().forcing().frequency; }
  TangentMap linearise(double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                       const LinearisationOptions& options) override {
    return vibro::linearise(system_, forces_, solver_, t0, x0, v0, t1, options);
  }
  RunSummary run(double t0, const VectorXd& x0, const VectorXd& v0, double t1) override {
    TaylorSimulator sim(system_, forces_, solver_);
    return sim.run(t0, x0, v0, t1);
  }
  ShootingResult shoot(const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v) override {
    return vibro::shoot(system_, forces_, options, t_guess, x, v);
  }
  std::pair<VectorXd, VectorXd> impact_direction(int j) const override {
    return lone_impact(detail::Mechanics<double>(system_), j);
  }

 private:
  ImpactSystem system_;
  NonlinearForces forces_;
  SimulatorOptions solver_;
};

}  // namespace

std::unique_ptr<FamilyEngine> dense_family_engine(ImpactSystem system, SystemDerivative derivative,
                                                  const SimulatorOptions& solver) {
  return std::make_unique<DenseFamilyEngine>(std::move(system), std::move(derivative), solver);
}

std::unique_ptr<FamilyEngine> modal_family_engine(BandedChain chain, std::vector<Stop> stops,
                                                  SystemDerivative derivative, const ModalSimulatorOptions& options) {
  return std::make_unique<ModalFamilyEngine>(std::move(chain), std::move(stops), std::move(derivative), options);
}

}  // namespace vibro

namespace vibro {

std::unique_ptr<FamilyEngine> taylor_family_engine(ImpactSystem system, NonlinearForces forces,
                                                   SystemDerivative derivative, const SimulatorOptions& solver) {
  return std::make_unique<TaylorFamilyEngine>(std::move(system), std::move(forces), std::move(derivative), solver);
}

}  // namespace vibro
