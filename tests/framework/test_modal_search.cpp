// Tests of the certified crossing search (events.hpp) on the modal chain engine's guards
// (vibro::ModalGuardSource, modal.hpp): its bounds on |h''| and |h'''| hold along the flow, for
// gap rows and force rows (with a u' term), under- and over-damped modes, forced; and
// CrossingFinder on it finds a graze 1e-10 past the trigger level and certifies one 1e-10 short
// of it, as on the dense engine's segments.
#include "support/chains.hpp"
#include "vibro/events.hpp"
#include "vibro/modal.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <optional>
#include <vector>

namespace {

using vibro::ChainModes;
using vibro::ModalGuards;
using vibro::ModalGuardSource;

/// Two guard rows of a 6-mass chain: row 0 a gap of mass 1 (P only), row 1 a force-like row
/// with a u' term (D ≠ 0), both with the forced response's harmonic part. `offset` is added to
/// the rows' constant terms.
ModalGuards two_rows(const ChainModes& modes, const Eigen::Vector2d& offset) {
  const Eigen::Index n = modes.dof();
  ModalGuards g;
  g.P.resize(2, n);
  g.D.resize(1, n);
  g.P.row(0) = modes.phi_row(1).transpose();
  g.P.row(1) = 0.7 * modes.phi_row(3).transpose() - 0.4 * modes.phi_row(4).transpose();
  g.D.row(0) = 0.5 * modes.phi_row(2).transpose();
  const Eigen::VectorXd& c0 = modes.particular_constant();
  const Eigen::VectorXd& cc = modes.particular_cosine();
  const Eigen::VectorXd& cs = modes.particular_sine();
  const double W = modes.frequency();
  // The particular solution's part of P·q + D·q' (q' of c0 + cc cos + cs sin is W(cs cos − cc sin)).
  g.h0 = Eigen::Vector2d(g.P.row(0).dot(c0), g.P.row(1).dot(c0)) + offset;
  g.hc = Eigen::Vector2d(g.P.row(0).dot(cc), g.P.row(1).dot(cc) + W * g.D.row(0).dot(cs));
  g.hs = Eigen::Vector2d(g.P.row(0).dot(cs), g.P.row(1).dot(cs) - W * g.D.row(0).dot(cc));
  g.finish(W);
  return g;
}

/// A fixed, nonzero homogeneous state.
void start_state(Eigen::Index n, Eigen::VectorXd& u0, Eigen::VectorXd& ud0) {
  u0.resize(n);
  ud0.resize(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    u0(k) = 0.3 * std::sin(static_cast<double>(k) + 1.0);
    ud0(k) = 0.2 * std::cos(2.0 * static_cast<double>(k) + 1.0);
  }
}

/// The chains: light damping (every mode under-damped), and β = 1.5, which over-damps the modes
/// with ω > 4/3 (2σ = βω² > 2ω) and under-damps the others.
std::vector<ChainModes> chains() {
  std::vector<ChainModes> out;
  for (double beta : {0.02, 1.5}) out.emplace_back(vibro::test::uniform_chain(6, beta, 0.6, 0.8));
  return out;
}

}  // namespace

TEST_CASE("modal guard source: |h''| and |h'''| stay within B2 and B3 along the flow (gap and force rows, "
          "under- and over-damped modes)",
          "[modal][search]") {
  for (const ChainModes& modes : chains()) {
    const bool overdamped = (modes.decay().array() > modes.omega().array()).any();
    INFO("over-damped modes: " << overdamped);
    const ModalGuards g = two_rows(modes, Eigen::Vector2d::Zero());
    Eigen::VectorXd u0, ud0;
    start_state(modes.dof(), u0, ud0);
    ModalGuardSource source(modes.dof());
    source.retarget(&modes, g, modes.frequency(), 3.0, u0, ud0);
    for (double ta : {0.0, 0.7, 5.0}) {
      vibro::SegmentSample a;
      source.sample(ta, a);
      const vibro::SegmentSample& b = a;  // the bounds from a hold on [a, ∞)
      for (Eigen::Index i = 0; i < 2; ++i) {
        const double B2 = source.derivative_bound(2, i, a, b), B3 = source.derivative_bound(3, i, a, b);
        REQUIRE(std::isfinite(B2));
        REQUIRE(std::isfinite(B3));
        // The same B₂ from the times alone (minimize_row's route).
        CHECK(std::abs(source.second_derivative_bound(i, ta, ta + 1.0) - B2) <= 1e-14 * B2);
        // The sample's row i is row_jet's (two evaluation orders: rounding only; values O(1)).
        double h, d, c;
        source.row_jet(i, ta, &h, &d, &c);
        CHECK(std::abs(h - a.h(i)) <= 1e-14);
        CHECK(std::abs(d - a.d(i)) <= 1e-14);
        CHECK(std::abs(c - a.c(i)) <= 1e-14);
        // |h''(τ)| ≤ B₂ on a grid of [ta, ta + 20]; the difference quotient of h'' (a mean of
        // h''') ≤ B₃, up to h'''s rounding (1e-13 B₂ over the step).
        const double step = 1e-3;
        double worst2 = 0.0, worst3 = 0.0, prev = c;
        for (int k = 1; k <= 20000; ++k) {
          source.row_jet(i, ta + k * step, &h, &d, &c);
          worst2 = std::max(worst2, std::abs(c) / B2);
          worst3 = std::max(worst3, (std::abs(c - prev) - 1e-13 * B2) / (B3 * step));
          prev = c;
        }
        INFO("row " << i << " from τ = " << ta << ": max |h''|/B2 = " << worst2 << ", max |Δh''/Δτ|/B3 = " << worst3);
        CHECK(worst2 <= 1.0);
        CHECK(worst3 <= 1.0);
      }
    }
  }
}

TEST_CASE("modal guard source: CrossingFinder finds a peak 1e-10 past the trigger and certifies one 1e-10 short "
          "of it (gap and force rows)",
          "[modal][search][grazing]") {
  // From τ = 5 on, when the over-damped modes' transient has gone, up to τ = 20.
  const double lo = 5.0, span = 20.0, eps = 1e-13;
  for (const ChainModes& modes : chains()) {
    const bool overdamped = (modes.decay().array() > modes.omega().array()).any();
    Eigen::VectorXd u0, ud0;
    start_state(modes.dof(), u0, ud0);
    for (Eigen::Index row = 0; row < 2; ++row) {
      // The row's highest point in [lo, span], found independently of the search: a grid of step
      // 1e-3, then Newton on h' = 0 from its best point (inside, so h' = 0 there).
      const ModalGuards plain = two_rows(modes, Eigen::Vector2d::Zero());
      ModalGuardSource source(modes.dof());
      source.retarget(&modes, plain, modes.frequency(), 0.0, u0, ud0);
      double best = -std::numeric_limits<double>::infinity(), at = 0.0;
      for (int k = 0; k <= 15000; ++k) {
        const double h = source.value(row, lo + k * 1e-3);
        if (h > best) {
          best = h;
          at = lo + k * 1e-3;
        }
      }
      INFO("over-damped modes: " << overdamped << ", row " << row << ": highest at τ = " << at);
      REQUIRE(at > lo);
      REQUIRE(at < span);
      double h = 0.0, d = 0.0, c = 0.0;
      for (int it = 0; it < 30; ++it) {
        source.row_jet(row, at, &h, &d, &c);
        const double next = at - d / c;
        if (next == at) break;
        at = next;
      }
      source.row_jet(row, at, &h, &d, &c);
      REQUIRE(c < 0.0);
      const double peak = h, tau_peak = at, curvature = -c;
      // minimize_row on the modal source (the certified minimum of one row) finds the same peak.
      const vibro::Minimum m = vibro::minimize_row(source, row, lo, span, 1e-15, -1.0);
      CHECK(std::abs(-m.value - peak) <= 1e-14);

      for (double delta : {1e-10, -1e-10}) {
        INFO("peak " << delta << " past the row's zero");
        // Shift the row so that its highest point is at δ; the other row far below its trigger.
        Eigen::Vector2d offset(-1e3, -1e3);
        offset(row) = delta - peak;
        const ModalGuards g = two_rows(modes, offset);
        ModalGuardSource shifted(modes.dof());
        shifted.retarget(&modes, g, modes.frequency(), 0.0, u0, ud0);
        const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * span;
        vibro::CrossingFinder finder(shifted, Eigen::Vector2d::Constant(eps), resolution);
        std::optional<vibro::Crossing> hit;
        const double step = 1.0 / modes.omega().maxCoeff();
        for (double a = lo; a < span && !hit;) {
          const double b = std::min(a + step, span);
          hit = finder.first(a, b);
          a = b;
        }
        if (delta < 0.0) {
          CHECK(!hit.has_value());
          continue;
        }
        REQUIRE(hit.has_value());
        CHECK(hit->row == row);
        // The first root of h = 0: s = √(2δ/|h''|) before the peak, to the quadratic model's
        // accuracy (the cubic term moves it by ~ s² |h'''|/|h''| ≲ 1e-9 here).
        const double s = std::sqrt(2.0 * delta / curvature);
        CHECK(std::abs(hit->tau - (tau_peak - s)) <= 1e-3 * s);
        CHECK(std::abs(shifted.value(row, hit->tau)) <= 1e-14);
      }
    }
  }
}
