#pragma once
// Private to vibro_io: one simulation of a scene, the transient (not recorded) then the recorded
// periods with the observers the scene asks for. run.kind: simulate is one of them; every point
// of a sweep is one (kinds/simulate.cpp, kinds/sweep.cpp, mpi_sweep.cpp).
#include "vibro/io/results.hpp"

#include <Eigen/Dense>

#include <atomic>

namespace vibro::io::detail {

struct StartState {
  double t;
  Eigen::VectorXd x, v;
};

/// Recording::for_scene, looking at `interrupt` (if given) every 2²⁰ sample times while it lays
/// them out (tens of millions take a second or more): raising it throws vibro::Interrupted
/// (bounded_wait.hpp) within milliseconds. Defined in results.cpp.
Recording recording_for(const Scene& scene, double t_start, const std::atomic<bool>* interrupt);

/// Transient (unrecorded) then recorded periods of one scene from `start`. The engine polls the
/// interrupt flag (the scene's solver.interrupt, else SIGINT and SIGTERM) at every event and
/// search step, and stores the time it reached in `reached` (if given) for a progress line.
Recording simulate(const Scene& base, const StartState& start, std::atomic<double>* reached = nullptr);

}  // namespace vibro::io::detail
