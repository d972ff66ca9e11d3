/// \file event_signature.cpp
/// An orbit's events per stop, with the impacts of chatter sequences told apart from the free
/// ones (event_signature.hpp), and the orbit's event signature built from them: per stop, the
/// free impacts, the chatter sequences and the contact phases per orbit.
#include "event_signature.hpp"

#include <algorithm>
#include <sstream>
#include <string>

namespace vibro {
namespace detail {

std::vector<StopEvents> per_stop(const TangentMap& m, std::size_t stops) {
  struct Item {
    double t;
    EventKind kind;
    std::size_t impact;  ///< index into m.impacts (impacts only)
  };
  std::vector<std::vector<Item>> items(stops);
  std::vector<int> engaged(stops, 0);
  std::size_t next_impact = 0;
  for (const Event& e : m.events) {
    const auto j = static_cast<std::size_t>(e.stop);
    const bool impact = e.kind == EventKind::impact;
    const std::size_t index = impact && next_impact < m.impacts.size() ? next_impact++ : m.impacts.size();
    if (j >= stops || (impact && index == m.impacts.size())) continue;
    if (e.kind == EventKind::engage || e.kind == EventKind::disengage) {  // a compliant stop
      if (e.kind == EventKind::engage) ++engaged[j];
      continue;
    }
    items[j].push_back({e.t, e.kind, index});
  }
  const double span = m.t1 - m.t0;
  std::vector<StopEvents> out(stops);
  for (std::size_t j = 0; j < stops; ++j) {
    out[j].engagements = engaged[j];
    std::vector<Item>& it = items[j];
    // Rotate so that the events start just after the last closing event, one orbit earlier.
    std::size_t last_close = it.size();
    for (std::size_t i = 0; i < it.size(); ++i)
      if (it[i].kind != EventKind::impact) last_close = i;
    if (last_close < it.size()) {
      for (std::size_t i = last_close + 1; i < it.size(); ++i) it[i].t -= span;
      std::rotate(it.begin(), it.begin() + static_cast<std::ptrdiff_t>(last_close + 1), it.end());
    }
    double opened = it.empty() ? m.t0 : it.back().t - span;  // the closing event before the first
    std::vector<const Item*> run;
    for (const Item& e : it) {
      if (e.kind == EventKind::impact) {
        run.push_back(&e);
        continue;
      }
      std::size_t first_caught = run.size();  // stick, release: every impact of the run is free
      if (e.kind == EventKind::chatter_limit && !run.empty()) {
        double longest = -1.0, before = opened;
        for (std::size_t i = 0; i < run.size(); ++i) {
          if (run[i]->t - before > longest) longest = run[i]->t - before, first_caught = i;
          before = run[i]->t;
        }
      }
      for (std::size_t i = 0; i < first_caught; ++i) out[j].free_impacts.push_back(m.impacts[run[i]->impact]);
      run.clear();
      opened = e.t;
      if (e.kind == EventKind::chatter_limit) ++out[j].chatters;
      if (e.kind != EventKind::release) ++out[j].phases;
    }
    for (const Item* e : run) out[j].free_impacts.push_back(m.impacts[e->impact]);  // no closing event at all
  }
  return out;
}

}  // namespace detail

std::string Signature::text() const {
  std::ostringstream s;
  s << "k=" << k;
  for (std::size_t j = 0; j < impacts.size(); ++j)
    s << " s" << j << ":i" << impacts[j] << "c" << chatters[j] << "h" << phases[j];
  return s.str();
}

Signature orbit_signature(const TangentMap& m, int k, std::size_t stops) {
  Signature s;
  s.k = k;
  const std::vector<detail::StopEvents> ev = detail::per_stop(m, stops);
  for (const detail::StopEvents& e : ev) {
    s.impacts.push_back(static_cast<int>(e.free_impacts.size()) + e.engagements);
    s.chatters.push_back(e.chatters);
    s.phases.push_back(e.phases);
  }
  return s;
}

}  // namespace vibro
