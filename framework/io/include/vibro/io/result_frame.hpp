#pragma once
/// \file result_frame.hpp
/// The frame a base-excited scene's results are written in (`record.frame`, docs/scenes.md).
/// The engines compute in the frame `base.frame` chooses (base_motion.hpp); a result asked for
/// in the other frame is mapped state by state at its own time t:
///
///     absolute from relative:  x = y + ι x_b(t),   v = v_y + ι x_b'(t),
///     relative from absolute:  y = x − ι x_b(t),   v_y = v − ι x_b'(t),
///
/// with x_b the base displacement of the scene (or of the sweep point, diagram value or branch
/// point the state belongs to: its Ω and amplitudes). A scene without a base, or one whose
/// results are in the frame it computes in, maps nothing: the states are written as computed,
/// bit for bit. Event times, gaps and gap rates are the same in both frames.
///
/// Usage:
///     const ResultFrame frame = ResultFrame::of(scene);
///     frame.to_result(t, x, v);   // before writing a state computed at time t
///     frame.to_scene(t, x, v);    // a written state back to the engine's frame (resume)
#include "vibro/base_motion.hpp"

#include <Eigen/Dense>

#include <memory>

namespace vibro::io {

struct Scene;

class ResultFrame {
 public:
  ResultFrame() = default;  ///< maps nothing
  /// The map from the frame `scene` computes in to the frame its results are written in.
  static ResultFrame of(const Scene& scene);
  bool identity() const { return sign_ == 0.0; }
  /// A state computed at time t, mapped to the result's frame (in place).
  void to_result(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const;
  /// The inverse: a written state back to the frame the scene computes in.
  void to_scene(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const;

 private:
  void shift(double sign, double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const;
  std::shared_ptr<const BaseExcitation> base_;
  double frequency_ = 0.0;
  double sign_ = 0.0;  ///< +1: ι x_b added (results absolute, computed relative); −1: subtracted; 0: none
};

}  // namespace vibro::io
