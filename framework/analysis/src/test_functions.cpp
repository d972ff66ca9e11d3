/// \file test_functions.cpp
/// The scalars whose zeros are continuation's smooth bifurcations: the multipliers' products for
/// period doubling and Neimark–Sacker, the nearest approach to a stop for grazing and the least
/// contact force for rising (the maths in test_functions.hpp).
#include "test_functions.hpp"

#include "event_signature.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <vector>

namespace vibro::detail {

double doubling_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i) p *= 1.0 + f.values(i);
  return p.real();
}
double torus_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  std::complex<double> p = 1.0;
  for (Index i = 0; i < d; ++i)
    for (Index j = i + 1; j < d; ++j) p *= f.values(i) * f.values(j) - 1.0;
  return p.real();
}
double branch_point_test(const FloquetMultipliers& f) {
  const Index d = f.values.size() - f.structural_zeros;
  double nearest = std::numeric_limits<double>::quiet_NaN(), sign = 1.0;
  for (Index i = 0; i < d; ++i) {
    const std::complex<double> mu = f.values(i);
    if (std::abs(mu.imag()) > 1e-12 * std::abs(mu)) continue;  // a pair: |μ − 1|² > 0
    double g = mu.real() - 1.0;
    if (std::isnan(nearest)) {
      nearest = g;
      continue;
    }
    if (std::abs(g) < std::abs(nearest)) std::swap(g, nearest);  // g: the one left out, its sign counts
    if (g < 0.0) sign = -sign;
  }
  return sign * nearest;
}
bool has_unit_pair(const FloquetMultipliers& f, double tol) {
  const Index d = f.values.size() - f.structural_zeros;
  for (Index i = 0; i < d; ++i)
    if (std::abs(f.values(i).imag()) > tol && std::abs(std::abs(f.values(i)) - 1.0) < tol) return true;
  return false;
}

double grazing_function(const Node& n, std::size_t stops, std::size_t j, int fewer, int more) {
  const int count = n.b.signature.impacts[j];
  bool compliant = false;  // stop j engages somewhere on this orbit (a compliant stop)
  for (const Event& e : n.e.map.events)
    if (e.stop == static_cast<int>(j) && (e.kind == EventKind::engage || e.kind == EventKind::disengage)) compliant = true;
  if (compliant && (count == fewer || count == more)) {
    // The gap peaks of the free flights (≤ 0) on the side with fewer engagements, the least
    // penetration peak (> 0) of an engaged phase on the other: both → 0 at the grazing.
    const bool free_side = count == fewer;
    double best = free_side ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
    for (const GapPeak& g : n.e.map.gap_peaks)
      if (g.stop == static_cast<int>(j) && (g.value > 0.0) != free_side)
        best = free_side ? std::max(best, g.value) : std::min(best, g.value);
    return std::isfinite(best) ? best : kNaN;
  }
  if (count == fewer) {
    double best = -std::numeric_limits<double>::infinity();
    for (const GapPeak& g : n.e.map.gap_peaks)
      if (g.stop == static_cast<int>(j)) best = std::max(best, g.value);
    return std::isfinite(best) ? best : kNaN;
  }
  if (count == more) {
    const std::vector<StopEvents> ev = per_stop(n.e.map, stops);
    double best = std::numeric_limits<double>::infinity();
    for (const ImpactRecord& r : ev[j].free_impacts)
      if (r.acceleration < 0.0) best = std::min(best, r.speed * r.speed / (2.0 * -r.acceleration));
    return std::isfinite(best) ? best : kNaN;
  }
  return kNaN;
}

/// Rising of stop j: the least interior minimum of its contact force with `fewer` phases, the
/// least force the held flow continued past a release would need with more.
double rising_function(const Node& n, std::size_t j, int fewer) {
  const int count = n.b.signature.phases[j];
  double best = std::numeric_limits<double>::infinity();
  for (const ForceDip& d : n.e.map.force_dips)
    if (d.stop == static_cast<int>(j) && d.past_release == (count != fewer)) best = std::min(best, d.value);
  return std::isfinite(best) ? best : kNaN;
}

double arrival_function(const Node& n, std::size_t j, int fewer) {
  const bool sticking_side = n.b.signature.phases[j] == fewer;
  double best = sticking_side ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  for (const ForceDip& d : n.e.map.force_dips)
    if (d.stop == static_cast<int>(j) && d.past_release == sticking_side)
      best = sticking_side ? std::max(best, d.value) : std::min(best, d.value);
  return std::isfinite(best) ? best : kNaN;
}

bool frictional(const Node& n, std::size_t j) {
  for (const Event& e : n.e.map.events)
    if (e.stop == static_cast<int>(j) && (e.kind == EventKind::friction_stick || e.kind == EventKind::friction_slip ||
                                          e.kind == EventKind::friction_reversal))
      return true;
  return false;
}

}  // namespace vibro::detail
