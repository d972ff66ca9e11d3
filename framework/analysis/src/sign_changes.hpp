#pragma once
// Private to vibro_analysis: the certified scan for the interior local extrema of a quantity
// along a segment's exact flow (the features of the tangent maps: gap peaks, force dips), shared
// by the dense engine's recorder (linearisation.cpp) and the friction-with-stops one
// (friction_stops_tangent.cpp).
#include "vibro/bounded_wait.hpp"
#include "vibro/flow.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

namespace vibro::detail {

/// Upper bound of h over [a, b] from its ends, its end slopes and B ≥ |h''| (Taylor, as in
/// events.hpp), and the matching lower bound.
inline double upper_bound(double ha, double da, double hb, double db, double B, double L) {
  const double chord = std::max(ha, hb) + B * L * L / 8.0;
  const double from_a = std::max(ha, ha + da * L + 0.5 * B * L * L);
  const double from_b = std::max(hb, hb - db * L + 0.5 * B * L * L);
  return std::min({chord, from_a, from_b});
}
inline double lower_bound(double ha, double da, double hb, double db, double B, double L) {
  return -upper_bound(-ha, -da, -hb, -db, B, L);
}

/// The points of (a, b) where sign·(row `slope` of the segment) changes from > 0 to ≤ 0: the
/// interior local maxima (sign = +1) or minima (sign = −1) of the quantity whose derivative the
/// row is. Certified with the row's second-derivative bound: an interval is passed over only
/// when the Taylor bounds show no such change in it, and a root is accepted when the row is
/// monotone around it; intervals shorter than `resolution` are not split further. A scan can
/// take seconds on a large system (each value is O(N)): it looks at `stop` every 1024 intervals
/// and throws Interrupted once it is raised (the engine's event loop ends the run there).
class SignChanges {
 public:
  SignChanges(const Segment& segment, Eigen::Index slope, double sign, double resolution, const std::atomic<bool>* stop)
      : seg_(segment), row_(slope), sign_(sign), resolution_(resolution), stop_(stop) {}

  std::vector<double> in(double a, double b) {
    out_.clear();
    if (b > a) scan(a, b, h(a), dh(a), h(b), dh(b), 0);
    return out_;
  }

 private:
  double h(double tau) const { return sign_ * seg_.value(row_, tau); }
  double dh(double tau) const { return sign_ * seg_.value(row_, tau, 1); }

  void scan(double a, double b, double ha, double da, double hb, double db, int depth) {
    if (stop_ && (++intervals_ & 1023) == 0 && stop_->load(std::memory_order_relaxed)) throw Interrupted();
    const double L = b - a;
    if (L <= resolution_ || depth > 60) {
      if (ha > 0.0 && hb <= 0.0) out_.push_back(refine(a, b));
      return;
    }
    const double B = seg_.second_derivative_bound(row_, a, b);
    if (ha > 0.0 && hb <= 0.0 && std::max(da, db) + B * L < 0.0) {  // monotone: exactly one
      out_.push_back(refine(a, b));
      return;
    }
    if (ha > 0.0 && hb > 0.0 && lower_bound(ha, da, hb, db, B, L) > 0.0) return;
    if (ha <= 0.0 && hb <= 0.0 && upper_bound(ha, da, hb, db, B, L) <= 0.0) return;
    if (ha <= 0.0 && hb > 0.0 && std::min(da, db) - B * L > 0.0) return;  // monotone rise
    const double m = 0.5 * (a + b);
    const double hm = h(m), dm = dh(m);
    scan(a, m, ha, da, hm, dm, depth + 1);
    scan(m, b, hm, dm, hb, db, depth + 1);
  }

  /// h(a) > 0 ≥ h(b): safeguarded Newton / bisection to a few ulps.
  double refine(double a, double b) const {
    for (int it = 0; it < 200; ++it) {
      const double ulp = 4.0 * std::numeric_limits<double>::epsilon() *
                         std::max({std::abs(seg_.t0() + a), std::abs(seg_.t0() + b), 1e-300});
      if (b - a <= ulp) break;
      const double hb = h(b), db = dh(b);
      double x = db < 0.0 ? b - hb / db : 0.5 * (a + b);
      if (!(x > a && x < b) || it % 3 == 2) x = 0.5 * (a + b);
      if (h(x) > 0.0) a = x;
      else b = x;
    }
    return 0.5 * (a + b);
  }

  const Segment& seg_;
  Eigen::Index row_;
  double sign_, resolution_;
  const std::atomic<bool>* stop_;
  unsigned long intervals_ = 0;
  std::vector<double> out_;
};

}  // namespace vibro::detail
