#pragma once
// An observer that reads every segment's states at both ends and in the middle, as the analysis
// layer does (linearisation.cpp): for tests that a run does not depend on what observes it.
#include "vibro/observers.hpp"

#include <Eigen/Dense>

namespace vibro::test {

class EndStates final : public vibro::Observer {
 public:
  void segment(const vibro::SegmentView& view) override {
    Eigen::VectorXd x(view.dof()), v(view.dof());
    view.state(view.t_begin(), x, v);
    view.state(view.t_end(), x, v);
    view.state(0.5 * (view.t_begin() + view.t_end()), x, v);
  }
};

}  // namespace vibro::test
