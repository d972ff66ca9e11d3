// Certified first crossing of a guard polynomial (guard_roots.hpp): grazing by ±1e-10, the first
// of several roots, a guard above at the start, and the remainder bound folded in.
#include "vibro/taylor/guard_roots.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

using namespace vibro::taylor;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

/// Degree-20 coefficients of (c − (τ − ½)²)·e^τ truncated at τ²⁰: the roots of c = (τ − ½)² (e^τ > 0),
/// with a realistic number of terms; the truncation (≤ 1/21! ≈ 2e-20 on [0, 1]) is far below
/// everything checked.
std::vector<double> bump(double c) {
  const double q[3] = {c - 0.25, 1.0, -1.0};
  std::vector<double> out(21, 0.0);
  double factorial = 1.0;
  std::vector<double> e(21);
  for (int k = 0; k <= 20; ++k) {
    if (k > 0) factorial *= k;
    e[k] = 1.0 / factorial;
  }
  for (int i = 0; i < 3; ++i)
    for (int k = 0; i + k <= 20; ++k) out[i + k] += q[i] * e[k];
  return out;
}

/// Bound on the error of a root computed from `c` in double: the polynomial's evaluation error
/// (2(p + 1) u Σ|c_k| τ^k, Higham 2002 §5.1) plus its coefficients' rounding (the same order),
/// over |q'| at the root.
double root_tolerance(const std::vector<double>& c, double tau, double slope) {
  double s = 0.0, power = 1.0;
  for (double ck : c) {
    s += std::abs(ck) * power;
    power *= tau;
  }
  return 4.0 * 21 * kEps * s / std::abs(slope) + 4 * kEps;
}

}  // namespace

TEST_CASE("a guard peaking 1e-10 above the trigger is found at its first root") {
  GuardRootFinder finder(20);
  const auto c = bump(1e-10);
  const auto r = finder.first_crossing(c.data(), 20, 1.0, 0.0, 0.0);
  REQUIRE(r.kind == CrossingKind::crossing);
  const double exact = 0.5 - 1e-5;  // c = (τ − ½)²
  const double slope = 2e-5 * std::exp(exact);
  INFO("root " << r.tau << ", error " << r.tau - exact << ", intervals " << r.splits);
  CHECK(std::abs(r.tau - exact) <= root_tolerance(c, exact, slope));
  CHECK(r.lower <= r.tau);
  CHECK(r.tau <= r.upper);
  CHECK(r.upper < 0.5 + 1e-5);  // the bracket isolates the first root from the second
}

TEST_CASE("a guard peaking 1e-10 below the trigger is certified clear") {
  GuardRootFinder finder(20);
  const auto c = bump(-1e-10);
  const auto r = finder.first_crossing(c.data(), 20, 1.0, 0.0, 0.0);
  INFO("intervals " << r.splits);
  CHECK(r.kind == CrossingKind::none);
  // The same with the trigger level carrying the offset: G = 0.01 − (τ − ½)² (degree 20 with
  // zero tail), ε = 0.01 ± 1e-10.
  std::vector<double> g(21, 0.0);
  g[0] = 0.01 - 0.25;
  g[1] = 1.0;
  g[2] = -1.0;
  CHECK(finder.first_crossing(g.data(), 20, 1.0, 0.01 + 1e-10, 0.0).kind == CrossingKind::none);
  const auto hit = finder.first_crossing(g.data(), 20, 1.0, 0.01 - 1e-10, 0.0);
  REQUIRE(hit.kind == CrossingKind::crossing);
  CHECK(std::abs(hit.tau - (0.5 - 1e-5)) <= root_tolerance(g, 0.5, 2e-5));
}

TEST_CASE("a remainder bound larger than the margin gives grazing, never a false answer") {
  GuardRootFinder finder(20);
  for (double c : {1e-10, -1e-10}) {
    const auto poly = bump(c);
    const auto r = finder.first_crossing(poly.data(), 20, 1.0, 0.0, 1e-9);
    INFO("peak " << c);
    REQUIRE(r.kind == CrossingKind::grazing);
    // The contact is placed where the guard comes within 1e-9 of the trigger: |τ − ½| ≤ √(1.1e-9).
    CHECK(std::abs(r.lower - 0.5) <= 4e-5);
    CHECK(r.upper - r.lower <= 1e-14);
  }
}

TEST_CASE("a guard starting within its band of the trigger still has its later crossing found") {
  // Right after an impact: the gap g starts at rounding distance of 0 and opens (g' = −0.2), then
  // returns through the trigger level ε = 5e-14 near τ = 2/3 of a step of 1.6; the remainder bound
  // (6e-14) is wider than ε, so the start cannot be told apart from the trigger level. The crossing
  // must be found (a contact at τ = 0 reported as the answer would let the caller walk over it).
  GuardRootFinder finder(20);
  std::vector<double> g(21, 0.0);
  g[0] = -2.8e-17;
  g[1] = -0.2;
  g[2] = 0.3;
  const double trigger = 5e-14;
  const auto r = finder.first_crossing(g.data(), 20, 1.6, trigger, 6e-14, 0.0, /*rounding_scales=*/true);
  REQUIRE(r.kind == CrossingKind::crossing);
  const double exact = (0.2 + std::sqrt(0.04 + 4 * 0.3 * (trigger + 2.8e-17))) / 0.6;
  CHECK(std::abs(r.tau - exact) <= 8 * kEps);
  // With a band narrower than ε the start is decided at once and the same crossing found.
  const auto narrow = finder.first_crossing(g.data(), 20, 1.6, trigger, 1e-14);
  CHECK_FALSE(narrow.start_touch);
  REQUIRE(narrow.kind == CrossingKind::crossing);
  CHECK(narrow.tau == r.tau);
  // A band that does not narrow towards the start: the first sliver is set aside, the search goes
  // on, and no answer claims the step is clear (a grazing contact past the start at worst).
  const auto wide = finder.first_crossing(g.data(), 20, 1.6, trigger, 6e-14);
  CHECK(wide.start_touch);
  CHECK(wide.kind != CrossingKind::none);
  if (wide.kind == CrossingKind::grazing) CHECK(wide.lower > 0.0);
}

TEST_CASE("the first of several roots is the one returned, on a scaled interval") {
  GuardRootFinder finder(20);
  // q(τ) = (τ − 0.02)(τ − 0.05)(τ − 0.08) on [0, 0.1]: below at 0, rises through 0.02 first.
  std::vector<double> c(21, 0.0);
  const double r1 = 0.02, r2 = 0.05, r3 = 0.08;
  c[0] = -r1 * r2 * r3;
  c[1] = r1 * r2 + r1 * r3 + r2 * r3;
  c[2] = -(r1 + r2 + r3);
  c[3] = 1.0;
  const auto r = finder.first_crossing(c.data(), 20, 0.1, 0.0, 0.0);
  REQUIRE(r.kind == CrossingKind::crossing);
  CHECK(std::abs(r.tau - r1) <= 8 * kEps * r1);
  // Above at the start: reported as such.
  const auto above = finder.first_crossing(c.data(), 20, 0.1, -1e-3, 0.0);
  CHECK(above.kind == CrossingKind::at_start);
  // Only the first root inside the interval counts: on [0, 0.03] still 0.02; on [0, 0.015] none.
  CHECK(finder.first_crossing(c.data(), 20, 0.03, 0.0, 0.0).tau == Approx(r1).epsilon(1e-15));
  CHECK(finder.first_crossing(c.data(), 20, 0.015, 0.0, 0.0).kind == CrossingKind::none);
}

TEST_CASE("refine reaches the root to rounding from a bracket") {
  // q = τ² − 2 on [1, 2]: √2.
  const double c[3] = {-2.0, 0.0, 1.0};
  CHECK(std::abs(GuardRootFinder::refine(c, 2, 0.0, 1.0, 2.0) - std::sqrt(2.0)) <= 2 * kEps * std::sqrt(2.0));
  // The reverse orientation (q falling through the root) too.
  const double d[3] = {2.0, 0.0, -1.0};
  CHECK(std::abs(GuardRootFinder::refine(d, 2, 0.0, 1.0, 2.0) - std::sqrt(2.0)) <= 2 * kEps * std::sqrt(2.0));
}

// The degree-reduced exclusion (a `none` from the polynomial truncated to a lower degree, the
// dropped terms bounded by Σ|a_k|) must never clear a guard that reaches its trigger: random
// degree-27 guards with coefficients decaying like 0.45^k (a Taylor step's at a coarse tolerance)
// whose maximum over the step lies anywhere from 0.3 below the trigger to above it. Every `none`
// is checked against the guard's maximum on 4001 points (its largest value plus the sampling gap's
// curvature bound stays below the trigger: at an interior maximum q' = 0, so q there exceeds the
// nearest sample by at most ½ max|q''| (gap/2)², and the ends are samples), every crossing's root
// against the polynomial's value.
// The reduced test must answer some of the cases the cheap Σ|a_k| test cannot.
TEST_CASE("the degree-reduced exclusion never clears a guard that reaches its trigger") {
  GuardRootFinder finder(27);
  std::uint64_t state = 12345;
  auto uniform = [&state] {  // xorshift64*: reproducible, no library generator's variation
    state ^= state >> 12;
    state ^= state << 25;
    state ^= state >> 27;
    return static_cast<double>((state * 2685821657736338717ULL) >> 11) * 0x1p-53;
  };
  int none = 0, beyond_sum = 0, crossings = 0;
  std::vector<double> c(28);
  for (int trial = 0; trial < 3000; ++trial) {
    double decay = 1.0;
    for (int k = 1; k <= 27; ++k, decay *= 0.45) c[k] = (2.0 * uniform() - 1.0) * decay;
    c[0] = 0.0;
    double peak = -std::numeric_limits<double>::infinity(), curvature = 0.0;
    for (int k = 2; k <= 27; ++k) curvature += k * (k - 1) * std::abs(c[k]);
    for (int i = 0; i <= 4000; ++i) {
      const double tau = i / 4000.0;
      double v = c[27];
      for (int k = 26; k >= 0; --k) v = v * tau + c[k];
      peak = std::max(peak, v);
    }
    c[0] = -peak + 0.3 * uniform() - 0.25;  // the maximum from 0.25 below the trigger to 0.05 above
    const double remainder = 1e-12;
    double absolute = std::abs(c[0]);
    for (int k = 1; k <= 27; ++k) absolute += std::abs(c[k]);
    const GuardCrossing r = finder.first_crossing(c.data(), 27, 1.0, 0.0, remainder);
    const double top = c[0] + peak;  // the sampled maximum
    if (r.kind == CrossingKind::none) {
      ++none;
      if (c[0] + (absolute - std::abs(c[0])) >= -remainder) ++beyond_sum;  // where the Σ|a_k| test could not answer
      INFO("trial " << trial << ": sampled maximum " << top);
      CHECK(top + 0.5 * curvature * std::pow(0.5 / 4000.0, 2) < 0.0);
    } else if (r.kind == CrossingKind::crossing) {
      ++crossings;
      double v = c[27];
      for (int k = 26; k >= 0; --k) v = v * r.tau + c[k];
      CHECK(std::abs(v) <= 1e-12);
    }
  }
  INFO(none << " none (" << beyond_sum << " beyond the sum test), " << crossings << " crossings");
  CHECK(beyond_sum > 100);
  CHECK(crossings > 100);
}
