#pragma once
// Private to vibro_analysis: what both tangent recorders (linearisation.cpp for the dense engine,
// modal_tangent.cpp for the modal one) read off the events at one instant, written once.
//  * classify: which stops impacted, were caught by the chatter rule, were released;
//  * record_of: the SaltationRecord's description of the transition;
//  * PhaseBook: the held phases (HeldPhase) as stops enter and leave the held set;
//  * impact_sequence: simultaneous impacts taken one at a time (index order or reversed), each
//    with its own reset rule and the velocities before and after it; the last step lands in the
//    engine's post-event velocity. Each recorder turns the steps into its own saltation form.
#include "mechanics.hpp"
#include "vibro/linearisation.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace vibro::detail {

struct Transition {
  ContactSet impacting, caught, released;
  ContactSet switched;  ///< compliant stops engaging or disengaging (stops.hpp)
};

inline Transition classify(const std::vector<Event>& events) {
  Transition out;
  for (const Event& e : events) {
    if (e.kind == EventKind::impact) out.impacting.push_back(e.stop);
    if (e.kind == EventKind::chatter_limit) out.caught.push_back(e.stop);
    if (e.kind == EventKind::release) out.released.push_back(e.stop);
    if (e.kind == EventKind::engage || e.kind == EventKind::disengage) out.switched.push_back(e.stop);
  }
  for (ContactSet* s : {&out.impacting, &out.caught, &out.released, &out.switched}) {
    std::sort(s->begin(), s->end());
    s->erase(std::unique(s->begin(), s->end()), s->end());
  }
  return out;
}

inline SaltationRecord record_of(double t, const ContactSet& held_before, const Transition& tr,
                                 const ContactSet& held_after) {
  SaltationRecord r;
  r.t = t;
  r.held_before = held_before;
  r.impacting = tr.impacting;
  r.caught = tr.caught;
  r.released = tr.released;
  r.held_after = held_after;
  return r;
}

class PhaseBook {
 public:
  PhaseBook(std::vector<HeldPhase>& phases, std::size_t stops) : phases_(phases), open_(stops, -1) {}

  void open(int j, double t) {
    open_[static_cast<std::size_t>(j)] = static_cast<long>(phases_.size());
    phases_.push_back({j, t, t, false});
  }
  /// At t the held set goes from `before` to `after`: a stop that leaves it was released
  /// (closed), one that enters it starts a phase.
  void change(double t, const ContactSet& before, const ContactSet& after) {
    for (int j : before)
      if (!Mechanics<double>::contains(after, j) && open_[static_cast<std::size_t>(j)] >= 0) {
        HeldPhase& p = phases_[static_cast<std::size_t>(open_[static_cast<std::size_t>(j)])];
        p.t_end = t;
        p.closed = true;  // a stop leaves the held set only by a release (of its own or an impulse's)
        open_[static_cast<std::size_t>(j)] = -1;
      }
    for (int j : after)
      if (!Mechanics<double>::contains(before, j)) open(j, t);
  }
  /// The run ends at t: phases still open end there (not closed).
  void end(double t) {
    for (long idx : open_)
      if (idx >= 0) phases_[static_cast<std::size_t>(idx)].t_end = t;
  }

 private:
  std::vector<HeldPhase>& phases_;
  std::vector<long> open_;
};

/// The features' rule for a gap peak found at s into a flight of length τ, value g, the gap being
/// g_start at the flight's start and `size` its largest magnitude at the start, middle and end:
/// a flight that starts on the stop (a release) starts with the gap rate zero up to rounding, and
/// a sign change of that rounding in its first instants is not a maximum of the flight: the gap
/// there has not moved from its start by more than rounding of the flight's own size. (Such a
/// "peak", ~1e-16 at ~4e-8 into a flight of 6.7 in the paper's system, posed as a grazing: the
/// largest gap peak is the grazing test function.)
inline bool flight_start_artifact(double s, double tau, double g, double g_start, double size) {
  return s <= 1e-6 * tau && std::abs(g - g_start) <= 1e-9 * size;
}

struct SequenceStep {
  ResetRule rule;
  int stop = -1;
  Eigen::VectorXd x_before, v_before, v_after;  // x: the chatter rule moves it (mechanics.hpp)
};

inline std::vector<SequenceStep> impact_sequence(const Mechanics<double>& mech, const ContactSet& held_before,
                                                 const Transition& tr, const ContactSet& held_after,
                                                 const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                                 const Eigen::VectorXd& vp, double t, ChatterRule chatter,
                                                 bool reverse) {
  ContactSet order = tr.impacting;
  if (reverse) std::reverse(order.begin(), order.end());
  ContactSet held = held_before;
  Eigen::VectorXd pos = x, vel = v;
  std::vector<SequenceStep> out;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const int j = order[i];
    const ContactSet one{j};
    const ContactSet caught_j = Mechanics<double>::contains(tr.caught, j) ? one : ContactSet{};
    ContactSet next = Mechanics<double>::contains(held_after, j) ? set_union(held, one) : held;
    const bool last = i + 1 == order.size();
    if (last) next = held_after;
    SequenceStep step;
    step.rule = {held, one, caught_j, impulse_set(mech, held, one, caught_j, vel, t), next, chatter};
    step.stop = j;
    step.x_before = pos;
    step.v_before = vel;
    if (last) {
      step.v_after = vp;
    } else {
      const Eigen::VectorXd after = mech.reset(step.rule, pos, vel, t);
      pos = after.head(x.size());
      step.v_after = after.tail(x.size());
    }
    held = next;
    vel = step.v_after;
    out.push_back(std::move(step));
  }
  return out;
}

}  // namespace vibro::detail
