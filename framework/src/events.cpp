#include "vibro/events.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro {
namespace {

/// Upper bound of h over [a, b] from end values, end slopes and B ≥ |h''| (see events.hpp).
double upper_bound(double ha, double da, double hb, double db, double B, double L) {
  const double chord = std::max(ha, hb) + B * L * L / 8.0;
  const double from_a = std::max(ha, ha + da * L + 0.5 * B * L * L);
  const double from_b = std::max(hb, hb - db * L + 0.5 * B * L * L);
  return std::min({chord, from_a, from_b});
}

double lower_bound(double ha, double da, double hb, double db, double B, double L) {
  return -upper_bound(-ha, -da, -hb, -db, B, L);
}

}  // namespace

CrossingFinder::CrossingFinder(const Segment& segment,
                               const Eigen::Ref<const Eigen::VectorXd>& triggers, double resolution)
    : segment_(&segment), triggers_(triggers), resolution_(resolution) {}

std::optional<Crossing> CrossingFinder::first(double a, double b) {
  std::optional<Crossing> best;
  for (Eigen::Index i = 0; i < triggers_.size(); ++i) {
    const double limit = best ? best->tau : b;
    if (limit <= a) break;
    last_below_ = -std::numeric_limits<double>::infinity();
    search_start_ = a;
    const auto [ha, da] = segment_->value_and_slope(i, a);
    const auto [hb, db] = segment_->value_and_slope(i, limit);
    if (auto tau = search(i, a, limit, ha, da, hb, db)) {
      if (!best || *tau < best->tau) best = Crossing{*tau, i};
    }
  }
  return best;
}

std::optional<double> CrossingFinder::search(Eigen::Index row, double a, double b, double ha,
                                             double da, double hb, double db) {
  const double eps = triggers_(row);
  if (ha <= 0.0) last_below_ = std::max(last_below_, a);
  if (ha > eps) return from_last_below(row, a);  // already past the trigger at the start (caller's state is on it)
  if (hb > eps) {
    // An event inside [a, b]: locate a root of h = 0, then make sure no earlier rise above ε
    // hides in [a, root] (h may cross 0 more than once in a wide interval).
    if (ha > 0.0) {
      // The start touches the surface within ε (e.g. just after an impact); the event sought is
      // a later rise, so split until it is bracketed from below.
      if (b - a <= resolution_) return from_last_below(row, b);
      const double m = 0.5 * (a + b);
      const auto [hm, dm] = segment_->value_and_slope(row, m);
      if (auto left = search(row, a, m, ha, da, hm, dm)) return left;
      return search(row, m, b, hm, dm, hb, db);
    }
    const double r = refine_root(row, a, b);
    if (r <= a) return a;
    const auto [hr_raw, dr] = segment_->value_and_slope(row, r);
    const double hr = std::min(hr_raw, eps);
    if (auto earlier = search(row, a, r, ha, da, hr, dr)) return earlier;
    return r;
  }
  const double L = b - a;
  const double B = segment_->second_derivative_bound(row, a, b);
  if (upper_bound(ha, da, hb, db, B, L) <= eps || L <= resolution_) {
    // Certified (or below time resolution and never seen above ε).
    if (hb <= 0.0) last_below_ = std::max(last_below_, b);
    return std::nullopt;
  }
  if (++subdivisions_ > 2000000)
    throw std::runtime_error("event search: subdivision budget exhausted near t = " +
                             std::to_string(segment_->t0() + a) +
                             " (a guard stays within rounding of zero over a long interval)");
  const double m = 0.5 * (a + b);
  const auto [hm, dm] = segment_->value_and_slope(row, m);
  if (auto left = search(row, a, m, ha, da, hm, dm)) return left;
  return search(row, m, b, hm, dm, hb, db);
}

double CrossingFinder::from_last_below(Eigen::Index row, double above) const {
  // h(above) > 0: the event is the last crossing of h = 0 before it. If no evaluated point had
  // h ≤ 0, a certified minimum over [search start, above] tells whether h dipped below 0 (then
  // bracket the root from that minimum) or only touched the surface within ε (then the event
  // is the closest approach, where h' = 0).
  double below = last_below_;
  if (!(below <= above)) {
    const Minimum m = minimize_row(*segment_, row, search_start_, above, 1e-3 * triggers_(row));
    if (m.value > 0.0) return m.tau;
    below = m.tau;
  }
  return refine_root(row, below, above);
}

double CrossingFinder::refine_root(Eigen::Index row, double a, double b) const {
  // Invariant h(a) ≤ 0 < h(b). Newton from the better end, bisection when it leaves [a, b] or
  // fails to halve the bracket.
  double ha = segment_->value(row, a);
  if (ha > 0.0) return a;
  for (int it = 0; it < 200; ++it) {
    const double width = b - a;
    const double ulp = std::numeric_limits<double>::epsilon() *
                       std::max({std::abs(segment_->t0() + a), std::abs(segment_->t0() + b), 1e-300});
    if (width <= 2.0 * ulp) break;
    const auto [hb, db] = segment_->value_and_slope(row, b);
    double x = (db > 0.0) ? b - hb / db : 0.5 * (a + b);
    if (!(x > a && x < b) || it % 3 == 2) x = 0.5 * (a + b);
    const double hx = segment_->value(row, x);
    if (hx > 0.0) {
      b = x;
    } else {
      a = x;
      ha = hx;
      if (hx == 0.0) return x;
    }
  }
  // Return the end closer to the surface.
  return std::abs(segment_->value(row, a)) <= std::abs(segment_->value(row, b)) ? a : b;
}

Minimum minimize_row(const Segment& segment, Eigen::Index row, double a, double b,
                     double tolerance, double sign) {
  struct Interval {
    double a, b, ha, da, hb, db;
  };
  auto h = [&](double tau) { return sign * segment.value(row, tau); };
  auto dh = [&](double tau) { return sign * segment.value(row, tau, 1); };
  const double ha0 = h(a), hb0 = h(b);
  Minimum best = ha0 <= hb0 ? Minimum{ha0, a} : Minimum{hb0, b};
  std::vector<Interval> stack{{a, b, ha0, dh(a), hb0, dh(b)}};
  long budget = 100000;
  while (!stack.empty() && --budget > 0) {
    const Interval iv = stack.back();
    stack.pop_back();
    const double L = iv.b - iv.a;
    const double B = segment.second_derivative_bound(row, iv.a, iv.b);
    if (lower_bound(iv.ha, iv.da, iv.hb, iv.db, B, L) >= best.value - tolerance) continue;
    if (iv.da < 0.0 && iv.db > 0.0) {
      // A stationary point bracketed by slopes of opposite sign: regula falsi on h'.
      double lo = iv.a, hi = iv.b, dlo = iv.da, dhi = iv.db;
      for (int it = 0; it < 100; ++it) {
        if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() *
                           std::max(1.0, std::abs(segment.t0() + hi)))
          break;
        double x = lo - dlo * (hi - lo) / (dhi - dlo);
        if (!(x > lo && x < hi) || it % 3 == 2) x = 0.5 * (lo + hi);
        const double dx = dh(x);
        if (dx > 0.0) {
          hi = x;
          dhi = dx;
        } else {
          lo = x;
          dlo = dx;
        }
      }
      const double x = 0.5 * (lo + hi);
      const double hx = h(x);
      if (hx < best.value) best = {hx, x};
    }
    if (L <= 16.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(segment.t0() + iv.b)))
      continue;
    const double m = 0.5 * (iv.a + iv.b);
    const double hm = h(m), dm = dh(m);
    if (hm < best.value) best = {hm, m};
    stack.push_back({m, iv.b, hm, dm, iv.hb, iv.db});
    stack.push_back({iv.a, m, iv.ha, iv.da, hm, dm});
  }
  return best;
}

}  // namespace vibro
