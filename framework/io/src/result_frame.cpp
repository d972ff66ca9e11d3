#include "vibro/io/result_frame.hpp"

#include "vibro/io/scene.hpp"

namespace vibro::io {

ResultFrame ResultFrame::of(const Scene& scene) {
  ResultFrame f;
  if (!scene.base || scene.record.frame == scene.base->frame) return f;
  f.base_ = std::make_shared<const BaseExcitation>(*scene.base);
  f.frequency_ = scene.forcing().frequency;
  f.sign_ = scene.record.frame == BaseFrame::absolute ? 1.0 : -1.0;
  return f;
}

void ResultFrame::shift(double sign, double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  if (sign == 0.0) return;
  const double xb = base_->position(frequency_, t), vb = base_->velocity(frequency_, t);
  x += (sign * xb) * base_->influence;
  v += (sign * vb) * base_->influence;
}

void ResultFrame::to_result(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  shift(sign_, t, x, v);
}

void ResultFrame::to_scene(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const {
  shift(-sign_, t, x, v);
}

}  // namespace vibro::io
