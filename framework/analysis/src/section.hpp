#pragma once
/// \file section.hpp
/// Where a periodic orbit may be cut by its stroboscopic section (private to the analysis layer):
/// not at an event, nor while a stop is held. The map over kT from a section at an impact time is
/// discontinuous in the state (a state just before the impact and one just after lie on either
/// side of it), and on a held stop the state is not free; so shooting puts its section, and
/// continuation moves its section as the events drift with the parameter, into the middle of the
/// longest stretch of the orbit free of both.
#include "vibro/linearisation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace vibro::detail {

/// The times an orbit over [t0, t1] may not be cut at: its events (points) and held phases.
inline std::vector<std::pair<double, double>> busy_intervals(const TangentMap& m) {
  std::vector<std::pair<double, double>> busy;
  for (const Event& e : m.events) busy.push_back({e.t, e.t});
  for (const HeldPhase& h : m.phases) busy.push_back({h.t_start, h.t_end});
  if (m.starts_held) busy.push_back({m.t0, m.t0});
  std::sort(busy.begin(), busy.end());
  return busy;
}

/// The distance from the section (t0, and t1 ≡ t0 one orbit later) to the nearest event or
/// held phase of the orbit m over [t0, t1]; 0 if one covers it.
inline double section_clearance(const TangentMap& m) {
  double d = std::numeric_limits<double>::infinity();
  for (const auto& [a, b] : busy_intervals(m))
    for (double t : {m.t0, m.t1}) d = std::min(d, (t >= a && t <= b) ? 0.0 : std::min(std::abs(t - a), std::abs(t - b)));
  return d;
}

/// The middle of the longest stretch of [t0, t1] free of events and held phases, the orbit taken
/// as closed (the stretch after the last event continues into the one before the first), as a
/// time in [t0, t1); and that stretch's half length. {t0, (t1 − t0)/2} for an orbit without events.
inline std::pair<double, double> free_section(const TangentMap& m) {
  const double span = m.t1 - m.t0;
  const auto busy = busy_intervals(m);
  if (busy.empty()) return {m.t0 + 0.5 * span, 0.5 * span};
  double best_len = -1.0, best_mid = m.t0, cursor = std::max(m.t0, busy.front().second);
  auto consider = [&](double a, double b) {
    if (b - a > best_len) best_len = b - a, best_mid = 0.5 * (a + b);
  };
  for (const auto& [a, b] : busy) {
    if (a > cursor) consider(cursor, a);
    cursor = std::max(cursor, b);
  }
  // The stretch from the last busy time round to the first one, one orbit later.
  consider(cursor, busy.front().first + span);
  if (best_mid >= m.t1) best_mid -= span;
  return {std::clamp(best_mid, m.t0, m.t1), 0.5 * best_len};
}

}  // namespace vibro::detail
