#include "vibro/taylor/guard_roots.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace vibro::taylor {

namespace {

constexpr int kMaxDepth = 80;
constexpr double kUnit = std::numeric_limits<double>::epsilon() / 2;

/// q(x) and q'(x) for q = Σ c_k x^k − trigger (Horner).
void evaluate(const double* c, int degree, double trigger, double x, double& value, double& slope) {
  double v = c[degree], d = 0.0;
  for (int k = degree - 1; k >= 0; --k) {
    d = d * x + v;
    v = v * x + c[k];
  }
  value = v - trigger;
  slope = d;
}

}  // namespace

GuardRootFinder::GuardRootFinder(int max_degree) : max_degree_(max_degree) {
  if (max_degree < 1) throw std::invalid_argument("GuardRootFinder: max_degree must be at least 1");
  const std::size_t entries = kMaxDepth + 4;
  stack_.resize(entries * (max_degree + 1));
  lo_.resize(entries);
  hi_.resize(entries);
  depth_.resize(entries);
  work_.resize(max_degree + 1);
  absolute_.resize(max_degree + 1);
  ratios_.resize(static_cast<std::size_t>(max_degree) + 1);
}

const double* GuardRootFinder::bernstein_ratios(int degree) {
  std::vector<double>& table = ratios_[static_cast<std::size_t>(degree)];
  if (table.empty()) {  // once per degree (the first call that needs it)
    const auto width = static_cast<std::size_t>(degree) + 1;
    table.assign(width * width, 0.0);
    for (int i = 0; i <= degree; ++i) {
      double ratio = 1.0;  // k = 0 first
      for (int k = 0; k <= i; ++k) {
        table[static_cast<std::size_t>(i) * width + k] = ratio;
        if (k < degree) ratio *= static_cast<double>(i - k) / static_cast<double>(degree - k);
      }
    }
  }
  return table.data();
}

double GuardRootFinder::refine(const double* c, int degree, double trigger, double a, double b) {
  double fa, fb, slope;
  evaluate(c, degree, trigger, a, fa, slope);
  evaluate(c, degree, trigger, b, fb, slope);
  if (fa == 0.0) return a;
  if (fb == 0.0) return b;
  const double orientation = fa < 0.0 ? 1.0 : -1.0;  // q·orientation rises through the root
  double x = 0.5 * (a + b), best = x, best_value = std::numeric_limits<double>::infinity();
  double width_before = b - a;
  for (int iteration = 0; iteration < 200; ++iteration) {
    double f;
    evaluate(c, degree, trigger, x, f, slope);
    if (std::abs(f) < best_value) {
      best_value = std::abs(f);
      best = x;
    }
    if (f == 0.0) return x;
    if (f * orientation < 0.0) a = x;
    else b = x;
    const double width = b - a;
    if (width <= 2.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(a), std::abs(b)) ||
        width <= std::numeric_limits<double>::denorm_min())
      break;
    const double newton = x - f / slope;
    const bool inside = std::isfinite(newton) && newton > a && newton < b;
    // Converged: a Newton correction within a unit of x's last place (quadratic convergence
    // from one side shrinks the bracket only by its bisections, ~50 of them from a whole step).
    if (inside && std::abs(newton - x) <= std::numeric_limits<double>::epsilon() * std::abs(x)) {
      evaluate(c, degree, trigger, newton, f, slope);
      return std::abs(f) < best_value ? newton : best;
    }
    // Newton while it stays in the bracket and the bracket at least halves every two steps.
    if (inside && width <= 0.5 * width_before) {
      x = newton;
      width_before = width;
    } else if (inside && iteration % 2 == 0) {
      x = newton;
    } else {
      x = a + 0.5 * width;
      width_before = width;
    }
    if (x <= a || x >= b) break;
  }
  return best;
}

GuardCrossing GuardRootFinder::first_crossing(const double* c, int degree, double h, double trigger,
                                              double remainder, double truncation, bool rounding_scales) {
  if (degree < 0 || degree > max_degree_)
    throw std::invalid_argument("GuardRootFinder: degree " + std::to_string(degree) + " beyond the scratch's " +
                                std::to_string(max_degree_));
  GuardCrossing result;
  const int width = degree + 1;
  // q in the scaled variable s = τ/h: a_k = q_k h^k, then its Bernstein coefficients on [0, 1].
  // With rounding_scales also |c_k| h^k (the guard's own coefficients, the trigger not
  // subtracted): the rounding bound over [0, s h] is rounding · Σ |c_k| (s h)^k / Σ |c_k| h^k.
  double* root = &stack_[0];
  double* a = absolute_.data();
  double scale = 0.0, power = 1.0, absolute_sum = 0.0;
  root[0] = c[0] - trigger;
  scale = std::abs(root[0]);
  if (rounding_scales) absolute_sum = (a[0] = std::abs(c[0]));
  power *= h;
  for (int k = 1; k <= degree; ++k, power *= h) {
    root[k] = c[k] * power;
    scale += std::abs(root[k]);
    if (rounding_scales) absolute_sum += (a[k] = std::abs(c[k]) * power);
  }
  if (!std::isfinite(scale) || !(remainder >= 0.0) || !(truncation >= 0.0))
    throw std::invalid_argument("GuardRootFinder: coefficients, step or remainder not finite");
  const double q0 = root[0];
  const double rounding = remainder;
  remainder += truncation;  // over the whole step
  const auto band = [&](int depth) { return remainder + 2.0 * (2 * degree + depth + 4) * kUnit * scale; };
  // Over [lo, hi] ⊂ [0, 1] (in s = τ/h): the tail's bound at s = hi, (hi)^{degree+1} of the whole,
  // and with rounding_scales the rounding's at s = hi.
  const auto interval_band = [&](int depth, double hi) {
    if (hi >= 1.0 || (truncation == 0.0 && !rounding_scales)) return band(depth);
    double scaled = truncation;
    for (int k = 0; k <= degree && scaled > 0.0; ++k) scaled *= hi;
    double round = rounding;
    if (rounding_scales && absolute_sum > 0.0) {
      double sum = 0.0;
      for (int k = degree; k >= 0; --k) sum = sum * hi + absolute_[static_cast<std::size_t>(k)];
      round = rounding * std::min(1.0, sum / absolute_sum);
    }
    return round + scaled + 2.0 * (2 * degree + depth + 4) * kUnit * scale;
  };
  // Already above at τ = 0: against the band there (the tail is 0 at τ = 0; with rounding_scales
  // the rounding is c_0's share), so that a guard above its trigger at the start is never set
  // aside as a start touch below.
  if (q0 > (rounding_scales ? interval_band(0, 0.0) : band(0))) {
    result.kind = CrossingKind::at_start;
    return result;
  }
  // Every Bernstein coefficient is at most a_0 + Σ_{k≥1} |a_k| (the ratios below lie in [0, 1]):
  // with that (and the rounding of both sums) below −band, the root interval alone would be
  // examined and discarded, so the answer is `none` without the conversion.
  if (q0 + (scale - std::abs(q0)) + 2.0 * (3 * degree + 4) * kUnit * scale < -band(0)) {
    result.splits = 1;
    return result;
  }
  // The same at a lower degree m: q = Q_m + T with Q_m = Σ_{k≤m} a_k s^k and |T(s)| ≤
  // Σ_{k>m} |a_k| on [0, 1]. Every Bernstein coefficient of Q_m (degree m) plus that tail, plus
  // twice the conversion's rounding allowance, below −band: `none`, certified as above, for an
  // O(m²) conversion instead of O(p²). m is the lowest degree whose tail is at most an eighth of
  // the margin at τ = 0; where the guard rises too close to the band for that, the full search
  // below decides.
  if (q0 < -band(0)) {
    const double target = 0.125 * (-q0 - band(0));
    double tail = 0.0;
    int m = degree;
    while (m > 1 && tail + std::abs(root[m]) <= target) tail += std::abs(root[m--]);
    if (m < degree - 1) {
      const double* ratios = bernstein_ratios(m);
      double largest = -std::numeric_limits<double>::infinity();
      for (int i = 0; i <= m; ++i) {
        const double* ratio = ratios + static_cast<std::size_t>(i) * (m + 1);
        double b = 0.0;
        for (int k = 0; k <= i; ++k) b += ratio[k] * root[k];
        largest = std::max(largest, b);
      }
      if (largest + tail + 2.0 * (2 * degree + 4) * kUnit * scale < -band(0)) {
        result.splits = 1;
        return result;
      }
    }
  }
  // b_i = Σ_{k≤i} C(i,k)/C(p,k) a_k, from the top down so that root[] can be overwritten; the
  // ratios C(i,k)/C(p,k) tabulated once per degree.
  const double* ratios = bernstein_ratios(degree);
  for (int i = degree; i >= 1; --i) {
    const double* ratio = ratios + static_cast<std::size_t>(i) * width;
    double s = 0.0;
    for (int k = 0; k <= i; ++k) s += ratio[k] * root[k];
    root[i] = s;
  }
  int top = 0;
  lo_[0] = 0.0;
  hi_[0] = 1.0;
  depth_[0] = 0;
  while (top >= 0) {
    double* b = &stack_[static_cast<std::size_t>(top) * width];
    const double lo = lo_[top], hi = hi_[top];
    const int depth = depth_[top];
    --top;
    ++result.splits;
    const double tol = interval_band(depth, hi);
    double largest = b[0];
    int changes = 0, last_sign = 0;
    for (int i = 0; i <= degree; ++i) {
      largest = std::max(largest, b[i]);
      const int sign = b[i] > 0.0 ? 1 : (b[i] < 0.0 ? -1 : 0);
      if (sign != 0) {
        if (last_sign != 0 && sign != last_sign) ++changes;
        last_sign = sign;
      }
    }
    if (largest < -tol) continue;  // q + R < 0 here: no event
    if (changes == 1 && b[0] < -tol && b[degree] > tol) {
      // Exactly one root of q in [lo, hi] (Descartes in the Bernstein basis), rising.
      result.kind = CrossingKind::crossing;
      result.lower = lo * h;
      result.upper = hi * h;
      result.tau = refine(c, degree, trigger, result.lower, result.upper);
      double value, slope;
      evaluate(c, degree, trigger, result.tau, value, slope);
      result.uncertainty = slope != 0.0 ? remainder / std::abs(slope) : std::numeric_limits<double>::infinity();
      return result;
    }
    const double tau_lo = lo * h, tau_hi = hi * h;
    if (depth >= kMaxDepth ||
        tau_hi - tau_lo <= 4.0 * std::numeric_limits<double>::epsilon() * std::max(tau_hi, std::abs(h) * 1e-300)) {
      if (lo == 0.0) {
        // The guard starts within the band of its trigger level (right after its own event, when
        // the band is wider than the trigger): the step's first sliver cannot be decided, but the
        // rest of the step must still be searched — returning here would let a caller that takes
        // a contact at τ = 0 as the event just resolved walk over a later crossing.
        result.start_touch = true;
        continue;
      }
      result.kind = CrossingKind::grazing;
      result.tau = tau_lo;
      result.lower = tau_lo;
      result.upper = tau_hi;
      return result;
    }
    // de Casteljau at s = 1/2 (Farouki & Rajan 1988): after r rounds of midpoint averaging,
    // work[i] is the triangle's entry (r, i); the left half's coefficient r is entry (r, 0),
    // the right half's coefficient degree − r is entry (r, degree − r). The right half goes
    // where b was (b copied to work first), the left half above it, to be examined next.
    double* right = &stack_[static_cast<std::size_t>(top + 1) * width];
    double* left = &stack_[static_cast<std::size_t>(top + 2) * width];
    double* work = work_.data();
    std::copy(b, b + width, work);
    left[0] = work[0];
    right[degree] = work[degree];
    for (int r = 1; r <= degree; ++r) {
      for (int i = 0; i <= degree - r; ++i) work[i] = 0.5 * (work[i] + work[i + 1]);
      left[r] = work[0];
      right[degree - r] = work[degree - r];
    }
    ++top;
    lo_[top] = 0.5 * (lo + hi);
    hi_[top] = hi;
    depth_[top] = depth + 1;
    ++top;
    lo_[top] = lo;
    hi_[top] = 0.5 * (lo + hi);
    depth_[top] = depth + 1;
  }
  return result;
}

}  // namespace vibro::taylor
