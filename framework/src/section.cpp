// Poincaré sections on a hyperplane in the positions (section.hpp): the Section observer and the
// alternating certified search of a passive guard's crossings within one segment.
#include "vibro/section.hpp"

#include "vibro/events.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

namespace vibro {

const char* to_string(Section::Direction direction) {
  switch (direction) {
    case Section::Direction::up: return "up";
    case Section::Direction::down: return "down";
    case Section::Direction::both: return "both";
  }
  return "?";
}

void SegmentView::plane_crossings(const Hyperplane&, double, int&, std::vector<PlaneCrossing>&) const {
  throw InvalidInput("section: this engine does not locate crossings of a hyperplane (the dense and the modal "
                     "engine do)");
}

void locate_plane_crossings(const GuardSource& source, double t_begin, double span, double step, double trigger,
                            int& side, std::vector<PlaneCrossing>& out) {
  // Rows h (row 0) and −h (row 1), one armed at a time (the other's trigger is +∞): below the
  // hyperplane the search waits for h to rise above ε, above it for −h; after each crossing it
  // starts again just past the root with the other row armed (as the force minima of
  // DenseSegmentView::force_local_minima step from extremum to extremum).
  if (!(span > 0.0)) return;
  const double inf = std::numeric_limits<double>::infinity();
  const double resolution =
      8.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(t_begin + span));
  step = step > 0.0 && std::isfinite(step) ? step : span;
  CrossingFinder finder;
  Eigen::Vector2d triggers;
  double from = 0.0;
  for (long count = 0; from < span; ++count) {
    if (count > 10000000)
      throw std::runtime_error("section: more than 10^7 crossings of the hyperplane in one segment near t = " +
                               number_text(t_begin + from));
    triggers << (side < 0 ? trigger : inf), (side < 0 ? inf : trigger);
    finder.retarget(source, triggers, resolution);
    std::optional<Crossing> hit;
    for (double a = from; a < span && !hit;) {
      const double b = std::min(a + step, span);
      hit = finder.first(a, b);
      a = b;
    }
    if (!hit) break;
    side = -side;
    out.push_back({t_begin + hit->tau, side});
    from = std::max(hit->tau, from) + resolution;
  }
}

Section::Section(Hyperplane plane, Direction direction) : plane_(std::move(plane)), direction_(direction) {
  if (plane_.normal.size() == 0) throw InvalidInput("section: the normal is empty");
  if (!plane_.normal.allFinite()) throw InvalidInput("section: the normal has a value that is not finite");
  if (plane_.normal.norm() == 0.0) throw InvalidInput("section: the normal is zero");
  if (!std::isfinite(plane_.value)) throw InvalidInput("section: the value is not finite");
}

void Section::begin(const RunContext& run, double t0) {
  if (plane_.normal.size() != run.dof)
    throw InvalidInput("section: the normal has " + std::to_string(plane_.normal.size()) +
                       " entries, the system " + std::to_string(run.dof) + " coordinates");
  omega_ = run.frequency;
  // The stops' trigger along n (a unit normal: the gaps' own level). Without one from the
  // engine, the same relative level of the hyperplane's offset.
  const double scale = run.gap_trigger > 0.0 ? run.gap_trigger : 1e-13 * std::max(1.0, std::abs(plane_.value));
  trigger_ = scale * plane_.normal.norm();
  if (t0 != last_end_) side_ = 0;  // a run continuing the last one keeps its side
}

void Section::segment(const SegmentView& view) {
  if (side_ == 0) {
    Eigen::VectorXd xs(view.dof()), vs(view.dof());
    view.state(view.t_begin(), xs, vs);
    side_ = plane_.at(xs) > 0.0 ? 1 : -1;
  }
  found_.clear();
  view.plane_crossings(plane_, trigger_, side_, found_);
  for (const PlaneCrossing& c : found_) {
    if ((direction_ == Direction::up && c.direction < 0) || (direction_ == Direction::down && c.direction > 0))
      continue;
    Eigen::VectorXd xs(view.dof()), vs(view.dof());
    view.state(c.t, xs, vs);
    t.push_back(c.t);
    double theta = omega_ > 0.0 ? std::fmod(omega_ * c.t, 2.0 * std::numbers::pi) : 0.0;
    if (theta < 0.0) theta += 2.0 * std::numbers::pi;
    phase.push_back(theta);
    crossing.push_back(c.direction);
    x.push_back(std::move(xs));
    v.push_back(std::move(vs));
  }
}

}  // namespace vibro
