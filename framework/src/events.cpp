#include "vibro/events.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace vibro {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = std::numeric_limits<double>::epsilon();

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

/// max over s ∈ [0, S] of the cubic h + d s + c s²/2 + k s³/6 (k ≥ 0): its ends and the
/// stationary points inside.
double cubic_max(double h, double d, double c, double k, double S) {
  auto p = [&](double s) { return h + s * (d + s * (0.5 * c + s * k / 6.0)); };
  double m = std::max(h, p(S));
  // p'(s) = d + c s + (k/2) s²
  auto consider = [&](double s) {
    if (s > 0.0 && s < S) m = std::max(m, p(s));
  };
  const double a2 = 0.5 * k;
  if (a2 == 0.0) {
    if (c != 0.0) consider(-d / c);
  } else {
    const double disc = c * c - 4.0 * a2 * d;
    if (disc >= 0.0) {
      const double q = -0.5 * (c + std::copysign(std::sqrt(disc), c));
      if (q != 0.0) {
        consider(q / a2);
        consider(d / q);
      }
    }
  }
  return m;
}

/// The root nearest to 0 of h + d s + c s²/2 in the open interval (lo, hi) (lo < 0 < hi or
/// one-sided); NaN if none there. The stable form of the quadratic formula.
double model_root(double h, double d, double c, double lo, double hi) {
  double best = std::numeric_limits<double>::quiet_NaN();
  auto consider = [&](double s) {
    if (s > lo && s < hi && !(std::abs(s) >= std::abs(best))) best = s;
  };
  const double disc = d * d - 2.0 * c * h;
  if (c == 0.0 || disc < 0.0) {
    if (d != 0.0) consider(-h / d);  // Newton where the model has no real root
    return best;
  }
  const double q = -0.5 * (d + std::copysign(std::sqrt(disc), d));
  if (q != 0.0) {
    consider(2.0 * q / c);
    consider(h / q);
  } else {
    consider(0.0);
  }
  return best;
}

}  // namespace

CrossingFinder::CrossingFinder(const GuardSource& source,
                               const Eigen::Ref<const Eigen::VectorXd>& triggers, double resolution) {
  retarget(source, triggers, resolution);
}

void CrossingFinder::retarget(const GuardSource& source, const Eigen::Ref<const Eigen::VectorXd>& triggers,
                              double resolution, bool rearm_leaving) {
  source_ = &source;
  rearm_ = rearm_leaving;
  triggers_ = triggers;
  resolution_ = resolution;
  started_ = false;
  subdivisions_ = 0;
  const auto rows = static_cast<std::size_t>(triggers.size());
  below_.assign(rows, Jet{-kInf, 0.0, 0.0, 0.0, false});
  leaving_.assign(rows, 0);
  if (pool_.size() < 8) pool_.resize(8);
}

std::optional<Crossing> CrossingFinder::first(double a, double b) {
  if (!source_) throw std::logic_error("CrossingFinder::first: no guard source (call retarget)");
  const Eigen::Index rows = triggers_.size();
  if (rows == 0) return std::nullopt;
  if (!started_) {
    started_ = true;
    search_start_ = a;
    const SegmentSample& A = pool_[0];
    source_->sample(a, pool_[0]);
    for (Eigen::Index i = 0; i < rows; ++i) {
      if (rearm_ && A.h(i) > 0.0 && A.d(i) <= 0.0) triggers_(i) += A.h(i);
      // A guard on its surface (within ε) and moving away does not bracket a root from there:
      // the root finder could return the surface just left. Moving away: h' < 0, or h' > 0 by
      // no more than rounding while h'' < 0 turns it back below ε (its quadratic model peaks
      // at h + h'²/(2|h''|) < ε) — a slip that starts where μ_s = μ_k has u' = 0 up to rounding
      // and u'' carrying it on, and a root bracketed from there would be the model's second
      // zero 2h'/|h''| after the start: a slip ended as soon as it began, for ever.
      const double h = A.h(i), d = A.d(i), c = A.c(i);
      leaving_[static_cast<std::size_t>(i)] =
          h >= -triggers_(i) && (d < 0.0 || (d > 0.0 && c < 0.0 && h + d * d / (-2.0 * c) < triggers_(i)));
    }
  } else if (pool_[1].tau == a && pool_[1].h.size() == rows) {
    std::swap(pool_[0], pool_[1]);
  } else {
    source_->sample(a, pool_[0]);
  }
  Crossing hit{};
  if (pool_[0].tau == search_start_) {
    // A guard leaving its surface at the start with h'' > 0 (a bounce) returns near
    // τ_p = -2h'/h'' (its quadratic model): search [a, τ_p (1 + 1e-3)] first, so that a short
    // bounce is located from a point just past it without sampling the whole step.
    double predicted = kInf;
    for (Eigen::Index i = 0; i < rows; ++i)
      if (leaving_[static_cast<std::size_t>(i)] && pool_[0].c(i) > 0.0)
        predicted = std::min(predicted, a - 2.0 * pool_[0].d(i) / pool_[0].c(i) * (1.0 + 1e-3));
    if (predicted > a && predicted < b) {
      source_->sample(predicted, pool_[1]);
      if (search(0, 1, 2, &hit)) return hit;
      std::swap(pool_[0], pool_[1]);
    }
  }
  source_->sample(b, pool_[1]);
  if (search(0, 1, 2, &hit)) return hit;
  return std::nullopt;
}

void CrossingFinder::note_below(const SegmentSample& s) {
  for (Eigen::Index i = 0; i < s.h.size(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (s.h(i) > 0.0) continue;
    if (s.tau >= below_[k].tau)
      below_[k] = {s.tau, s.h(i), s.d(i), s.c(i), s.tau == search_start_ && leaving_[k] != 0};
  }
}

bool CrossingFinder::certified(Eigen::Index i, const SegmentSample& a, const SegmentSample& b) const {
  const double L = b.tau - a.tau, eps = triggers_(i);
  const double B2 = source_->derivative_bound(2, i, a, b);
  if (upper_bound(a.h(i), a.d(i), b.h(i), b.d(i), B2, L) <= eps) return true;
  // The cubic model of each half, with the exact curvature at its end (events.hpp).
  const double B3 = source_->derivative_bound(3, i, a, b);
  const double half = 0.5 * L;
  return cubic_max(a.h(i), a.d(i), a.c(i), B3, half) <= eps && cubic_max(b.h(i), -b.d(i), b.c(i), B3, half) <= eps;
}

double CrossingFinder::split_point(const SegmentSample& a, const SegmentSample& b) const {
  // The first guard not certified on [a, b] chooses: at the start of the search, the lowest
  // point of a guard leaving its surface (h' < 0 < h'': the apex of a bounce, however short);
  // the predicted maximum of one whose slope changes sign inside, if not within L/16 of an end
  // (so that no sequence of thin slices can form); else the middle. Either way both parts are
  // shorter than [a, b], and only the first split of a search can be thinner than L/16.
  const double L = b.tau - a.tau;
  for (Eigen::Index i = 0; i < a.h.size(); ++i) {
    if (certified(i, a, b)) continue;
    if (a.tau == search_start_ && leaving_[static_cast<std::size_t>(i)] && a.c(i) > 0.0) {
      const double s = -a.d(i) / a.c(i);
      if (s > 1e-9 * L && s < 0.5 * L) return a.tau + s;
    } else if (a.d(i) > 0.0 && b.d(i) < 0.0) {
      const double s = L * a.d(i) / (a.d(i) - b.d(i));
      if (s > L / 16.0 && s < L - L / 16.0) return a.tau + s;
    }
    break;
  }
  return a.tau + 0.5 * L;
}

bool CrossingFinder::search(std::size_t ia, std::size_t ib, std::size_t free, Crossing* out) {
  // Room for this level's sample (deep splitting only; kept for later segments). References into
  // the pool are taken after this and not used across the recursive calls below.
  if (free >= pool_.size()) pool_.resize(2 * free);
  note_below(pool_[ia]);
  const Eigen::Index rows = triggers_.size();
  // Past the trigger at the left end: only at the start of the search (every later left end was
  // a certified right end); the event is the last crossing of 0 before it.
  {
    double best = kInf;
    Eigen::Index row = -1;
    for (Eigen::Index i = 0; i < rows; ++i)
      if (pool_[ia].h(i) > triggers_(i)) {
        const double r = from_last_below(i, pool_[ia].tau);
        if (r < best) {
          best = r;
          row = i;
        }
      }
    if (row >= 0) {
      source_->sample(best, pool_[free]);
      hit_ = free;
      *out = {best, row};
      return true;
    }
  }
  const SegmentSample& A = pool_[ia];
  const SegmentSample& B = pool_[ib];
  const double L = B.tau - A.tau;
  bool all_certified = true;
  for (Eigen::Index i = 0; i < rows && all_certified; ++i) all_certified = certified(i, A, B);
  if (all_certified) {
    note_below(B);
    return false;
  }
  // Guards above their trigger at B: each has a root after the last point seen ≤ 0.
  double best = kInf;
  Eigen::Index best_row = -1;
  bool bracketed = true;
  for (Eigen::Index i = 0; i < rows; ++i) {
    if (!(B.h(i) > triggers_(i))) continue;
    const Jet& lo = below_[static_cast<std::size_t>(i)];
    double r = B.tau;  // not ≤ 0 since the segment began (re-armed above its start): placed at B
    if (std::isfinite(lo.tau)) r = root(i, lo, {B.tau, B.h(i), B.d(i), B.c(i)});
    else bracketed = false;
    if (r < best) {
      best = r;
      best_row = i;
    }
  }
  if (L <= resolution_) {
    if (best_row < 0) {  // below time resolution and never seen above ε
      note_below(B);
      return false;
    }
    source_->sample(best, pool_[free]);
    hit_ = free;
    *out = {best, best_row};
    return true;
  }
  if (best_row >= 0 && bracketed) {
    SegmentSample& R = pool_[free];
    source_->sample(best, R);
    bool ok = best <= A.tau;  // a root before A: [its bracket, A] is already certified
    if (!ok) {
      ok = true;
      for (Eigen::Index i = 0; i < rows && ok; ++i) ok = certified(i, pool_[ia], R);
    }
    if (ok) {
      hit_ = free;
      *out = {best, best_row};
      return true;
    }
  }
  if (++subdivisions_ > 2000000)
    throw std::runtime_error("event search: subdivision budget exhausted near t = " +
                             std::to_string(source_->t0() + A.tau) +
                             " (a guard stays within rounding of zero over a long interval)");
  const double m = split_point(pool_[ia], pool_[ib]);
  source_->sample(m, pool_[free]);
  if (search(ia, free, free + 1, out)) return true;
  return search(free, ib, free + 1, out);
}

double CrossingFinder::root(Eigen::Index row, Jet lo, Jet hi) const {
  // Invariant h(lo) ≤ 0 < h(hi). Each step goes to the root of the local quadratic model
  // h + h' s + h'' s²/2 at the end nearer the root (Newton where the model has none), and
  // halves when that leaves the bracket or when two steps have not halved it.
  const double t0 = source_->t0();
  double last = kInf;
  bool bisect = false;
  Jet best{kInf, kInf, 0.0, 0.0};
  for (int it = 0; it < 200; ++it) {
    const double width = hi.tau - lo.tau;
    const double ulp = kEps * std::max({std::abs(t0 + lo.tau), std::abs(t0 + hi.tau), 1e-300});
    if (width <= 2.0 * ulp) break;
    // The local quadratic model's root from each end; the shorter step is the better model.
    // Halve instead when the last step did not at least halve |h|.
    const double s_hi = model_root(hi.h, hi.d, hi.c, -width, 0.0);
    const double s_lo = lo.leaving ? std::numeric_limits<double>::quiet_NaN()
                                   : model_root(lo.h, lo.d, lo.c, 0.0, width);
    double x = std::numeric_limits<double>::quiet_NaN();
    if (std::isfinite(s_hi) && !(std::abs(s_lo) < std::abs(s_hi))) x = hi.tau + s_hi;
    else if (std::isfinite(s_lo)) x = lo.tau + s_lo;
    if (!(x > lo.tau && x < hi.tau) || bisect) x = 0.5 * (lo.tau + hi.tau);
    Jet j{x, 0.0, 0.0, 0.0};
    source_->row_jet(row, x, &j.h, &j.d, &j.c);
    if (j.h == 0.0) return x;
    const bool progress = std::abs(j.h) <= 0.5 * last;
    last = std::abs(j.h);
    if (std::abs(j.h) < std::abs(best.h)) best = j;
    (j.h > 0.0 ? hi : lo) = j;
    // Converged: the Newton correction from x is within an ulp of t. (Where rounding in h
    // exceeds that, the bracket is closed to 2 ulps instead: stopping at the rounding level
    // would leave the root anywhere in a band of width rounding/|h'|, and an ill-conditioned
    // sequence of tiny bounces carries that choice into later events.)
    if (std::abs(j.h) <= 2.0 * kEps * std::max(std::abs(t0 + x), 1e-300) * std::abs(j.d)) return best.tau;
    bisect = !progress && !bisect;
  }
  // Return the end closer to the surface.
  return std::abs(lo.h) <= std::abs(hi.h) ? lo.tau : hi.tau;
}

double CrossingFinder::refine_root(Eigen::Index row, double a, double b) const {
  Jet lo{a, 0.0, 0.0, 0.0}, hi{b, 0.0, 0.0, 0.0};
  source_->row_jet(row, a, &lo.h, &lo.d, &lo.c);
  if (lo.h > 0.0) return a;
  source_->row_jet(row, b, &hi.h, &hi.d, &hi.c);
  return root(row, lo, hi);
}

double CrossingFinder::from_last_below(Eigen::Index row, double above) const {
  // h(above) > 0: the event is the last crossing of h = 0 before it. If no evaluated point had
  // h ≤ 0, a certified minimum over [search start, above] tells whether h dipped below 0 (then
  // bracket the root from that minimum) or only touched the surface within ε (then the event
  // is the closest approach, where h' = 0).
  double below = below_[static_cast<std::size_t>(row)].tau;
  if (!(below <= above)) {
    const Minimum m = minimize_row(*source_, row, search_start_, above, 1e-3 * triggers_(row));
    if (m.value > 0.0) return m.tau;
    below = m.tau;
  }
  return refine_root(row, below, above);
}

Minimum minimize_row(const GuardSource& source, Eigen::Index row, double a, double b,
                     double tolerance, double sign) {
  struct Interval {
    double a, b, ha, da, hb, db;
  };
  auto h = [&](double tau) { return sign * source.value(row, tau); };
  auto dh = [&](double tau) { return sign * source.value(row, tau, 1); };
  const double ha0 = h(a), hb0 = h(b);
  Minimum best = ha0 <= hb0 ? Minimum{ha0, a} : Minimum{hb0, b};
  std::vector<Interval> stack{{a, b, ha0, dh(a), hb0, dh(b)}};
  long budget = 100000;
  while (!stack.empty() && --budget > 0) {
    const Interval iv = stack.back();
    stack.pop_back();
    const double L = iv.b - iv.a;
    const double B = source.second_derivative_bound(row, iv.a, iv.b);
    if (lower_bound(iv.ha, iv.da, iv.hb, iv.db, B, L) >= best.value - tolerance) continue;
    if (iv.da < 0.0 && iv.db > 0.0) {
      // A stationary point bracketed by slopes of opposite sign: regula falsi on h'.
      double lo = iv.a, hi = iv.b, dlo = iv.da, dhi = iv.db;
      for (int it = 0; it < 100; ++it) {
        if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() *
                           std::max(1.0, std::abs(source.t0() + hi)))
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
    if (L <= 16.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(source.t0() + iv.b)))
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
