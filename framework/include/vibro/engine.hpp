#pragma once
/// \file engine.hpp
/// One interface over the two event-driven engines, for what does not care which runs: periodic
/// orbits found by running (running_orbit.hpp), bifurcations located by running
/// (running_locate.hpp), the runner.
///
/// * DenseEngine: the general Simulator (simulator.hpp) on an ImpactSystem it owns.
/// * ModalEngine: the modal chain engine (modal.hpp) on a proportionally damped chain it owns.
///
/// Both report through the same RunSummary and observers, so a result does not depend on the
/// engine beyond rounding (tests/framework/test_modal.cpp, tests/io/test_locate.cpp).
///
/// Usage:
///     std::unique_ptr<vibro::Engine> e = std::make_unique<vibro::ModalEngine>(chain, stops, options);
///     vibro::RunningOrbit orbit = vibro::run_to_periodic_orbit(*e, orbit_options, 0.0, x0, v0);
#include "vibro/modal.hpp"
#include "vibro/simulator.hpp"

#include <memory>
#include <vector>

namespace vibro {

class Engine {
 public:
  virtual ~Engine() = default;
  /// As Simulator::run: from (t0, x0, v0) to t_end, reporting to `observers`.
  virtual RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                         double t_end, const std::vector<Observer*>& observers = {}) = 0;
  /// The forcing frequency Ω.
  virtual double frequency() const = 0;
  virtual std::size_t stop_count() const = 0;
};

/// The dense Simulator on its own copy of the system.
class DenseEngine final : public Engine {
 public:
  DenseEngine(ImpactSystem system, const SimulatorOptions& options)
      : system_(std::make_unique<ImpactSystem>(std::move(system))), sim_(*system_, options) {}
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {}) override {
    return sim_.run(t0, x0, v0, t_end, observers);
  }
  double frequency() const override { return system_->system().forcing().frequency; }
  std::size_t stop_count() const override { return system_->stop_count(); }
  Simulator& simulator() { return sim_; }

 private:
  std::unique_ptr<ImpactSystem> system_;  // stable address for sim_
  Simulator sim_;
};

/// The modal chain engine on its own modes (set up in the constructor, O(N²) with LAPACK), built
/// from with_stop_orders(chain, stops) (a slot for every order a stop moves at).
class ModalEngine final : public Engine {
 public:
  ModalEngine(BandedChain chain, std::vector<Stop> stops, const ModalSimulatorOptions& options)
      : modes_(std::make_unique<ChainModes>(with_stop_orders(std::move(chain), stops))),
        sim_(*modes_, std::move(stops), options) {}
  RunSummary run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                 const std::vector<Observer*>& observers = {}) override {
    return sim_.run(t0, x0, v0, t_end, observers);  // the RunSummary part of the ModalRunSummary
  }
  double frequency() const override { return modes_->frequency(); }
  std::size_t stop_count() const override { return sim_.stops().size(); }
  ModalChainSimulator& simulator() { return sim_; }

 private:
  std::unique_ptr<ChainModes> modes_;  // stable address for sim_
  ModalChainSimulator sim_;
};

/// The scene solver settings that the modal engine shares (flow_method and max_condition are the
/// dense flow's and have no modal counterpart).
ModalSimulatorOptions modal_options(const SimulatorOptions& options);

}  // namespace vibro
