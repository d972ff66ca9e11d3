/// Tests of compliant (Kelvin–Voigt) stops in the dense engine (stops.hpp, contact.hpp):
///  1. a 1-DOF soft-impact oscillator m x'' + c x' + k x = F cos Ωt with a compliant stop at
///     x = p (fixed, and moving) against a piecewise closed form written here (each piece a
///     linear 1-DOF ODE solved in long double, each switch located by bisection), and the lower
///     stop as the mirror image of the upper one;
///  2. k_s → ∞ with c_s = 0 approaches the elastic rigid stop (r = 1) at the rate k_s^(-1/2) of
///     the contact duration π √(m / k_s);
///  3. energy (kinetic, springs, and the engaged stops' ½ k_s g² + F_p g) conserved to rounding
///     without damping and forcing;
///  4. a two-stage stop: a compliant spring with a rigid stop behind it (impacts while engaged
///     against the closed form; sticking on the rigid stop with the spring engaged, its force);
///  5. bad input: the C++ API's checks and the modal engine's refusal (the tangent maps of
///     compliant stops are tested in tests/analysis/test_compliant_analysis.cpp).
#include "vibro/modal.hpp"
#include "vibro/observers.hpp"
#include "vibro/simulator.hpp"
#include "vibro/stops.hpp"
#include "vibro/system.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace {

using vibro::EventKind;
using vibro::HarmonicForcing;
using vibro::ImpactSystem;
using vibro::LinearSystem;
using vibro::Stop;
using ld = long double;

/// The exact solution of m x'' + c x' + k x = F0 + Fc cos Ωt + Fs sin Ωt (underdamped,
/// c² < 4 m k) from (t0, x0, v0), in long double.
struct Piece {
  ld m, c, k, F0, Fc, Fs, W;
  ld A = 0, B = 0, xs = 0;  // particular solution A cos Ωt + B sin Ωt + xs
  ld t0 = 0, C1 = 0, C2 = 0, sigma = 0, wd = 0;

  Piece(ld m_, ld c_, ld k_, ld F0_, ld Fc_, ld Fs_, ld W_) : m(m_), c(c_), k(k_), F0(F0_), Fc(Fc_), Fs(Fs_), W(W_) {
    const ld a = k - m * W * W, b = c * W, det = a * a + b * b;
    A = (a * Fc - b * Fs) / det;  // a A + b B = Fc, -b A + a B = Fs
    B = (b * Fc + a * Fs) / det;
    xs = F0 / k;
    sigma = c / (2 * m);
    wd = std::sqrt(k / m - sigma * sigma);
  }
  ld xp(ld t) const { return A * std::cos(W * t) + B * std::sin(W * t) + xs; }
  ld vp(ld t) const { return W * (-A * std::sin(W * t) + B * std::cos(W * t)); }
  void start(ld t, ld x, ld v) {
    t0 = t;
    C1 = x - xp(t);
    C2 = (v - vp(t) + sigma * C1) / wd;
  }
  ld x(ld t) const {
    const ld s = t - t0;
    return std::exp(-sigma * s) * (C1 * std::cos(wd * s) + C2 * std::sin(wd * s)) + xp(t);
  }
  ld v(ld t) const {
    const ld s = t - t0, e = std::exp(-sigma * s);
    return e * (-sigma * (C1 * std::cos(wd * s) + C2 * std::sin(wd * s)) +
                wd * (-C1 * std::sin(wd * s) + C2 * std::cos(wd * s))) +
           vp(t);
  }
};

/// A 1-DOF oscillator with one upper stop at p + a cos(Ωt + φ): compliant (k_s, c_s, F_p) and
/// optionally a rigid upper stop at p2 behind it (restitution r2). Integrated piece by piece in
/// closed form; switches found by sign scans at step h and bisection to 1e-17 relative.
struct Reference {
  ld m, c, k, F, W, p, a, phi, ks, cs, Fp;
  ld p2 = 1e30L, r2 = 1;
  struct Switch {
    ld t;
    int kind;  // 0 engage, 1 disengage, 2 rigid impact
  };
  std::vector<Switch> switches = {};

  ld s(ld t) const { return p + a * std::cos(W * t + phi); }
  ld sd(ld t) const { return -a * W * std::sin(W * t + phi); }
  Piece free_piece() const { return Piece(m, c, k, 0, F, 0, W); }
  Piece engaged_piece() const {
    // m x'' + (c + cs) x' + (k + ks) x = F cos + ks s(t) + cs s'(t) - Fp.
    const ld ac = a * std::cos(phi), as = a * std::sin(phi);  // s = p + ac cos Ωt - as sin Ωt
    return Piece(m, c + cs, k + ks, ks * p - Fp, F + ks * ac - cs * W * as, -ks * as - cs * W * ac, W);
  }

  /// State at t1 from (t0, x0, v0), the stop open if x0 ≤ s(t0).
  std::pair<ld, ld> run(ld t0, ld x0, ld v0, ld t1, ld h) {
    bool engaged = x0 > s(t0);
    ld t = t0, x = x0, v = v0;
    Piece piece = engaged ? engaged_piece() : free_piece();
    piece.start(t, x, v);
    while (t < t1) {
      const ld tb = std::min(t + h, t1);
      // Guards: the compliant gap g = x - s (sign per mode), the rigid gap x - p2.
      auto g = [&](ld u) { return engaged ? s(u) - piece.x(u) : piece.x(u) - s(u); };
      auto g2 = [&](ld u) { return piece.x(u) - p2; };
      const bool hit1 = g(tb) > 0, hit2 = g2(tb) > 0;
      if (!hit1 && !hit2) {
        t = tb;
        continue;
      }
      auto root = [&](auto&& fn) {
        ld lo = t, hi = tb;
        for (int i = 0; i < 200 && hi - lo > 1e-19L * std::max<ld>(1, std::abs(hi)); ++i) {
          const ld mid = 0.5L * (lo + hi);
          (fn(mid) > 0 ? hi : lo) = mid;
        }
        return hi;
      };
      const ld ta = hit1 ? root(g) : tb + 1, tr = hit2 ? root(g2) : tb + 1;
      t = std::min(ta, tr);
      x = piece.x(t);
      v = piece.v(t);
      if (tr < ta) {  // rigid impact (r2), with the compliant stop engaged or not
        v = -r2 * v;
        x = p2;
        switches.push_back({t, 2});
      } else {
        engaged = !engaged;
        switches.push_back({t, engaged ? 0 : 1});
        piece = engaged ? engaged_piece() : free_piece();
      }
      piece.start(t, x, v);
    }
    return {piece.x(t1), piece.v(t1)};
  }
};

LinearSystem one_dof(double m, double c, double k, double F, double W) {
  HarmonicForcing f = HarmonicForcing::zero(1, W);
  f.cosine(0) = F;
  return LinearSystem(Eigen::MatrixXd::Constant(1, 1, m), Eigen::MatrixXd::Constant(1, 1, c),
                      Eigen::MatrixXd::Constant(1, 1, k), f);
}

Eigen::VectorXd vec(std::initializer_list<double> v) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) out(i++) = x;
  return out;
}

std::vector<vibro::Event> switches_of(const std::vector<vibro::Event>& events) {
  std::vector<vibro::Event> out;
  for (const vibro::Event& e : events)
    if (e.kind == EventKind::engage || e.kind == EventKind::disengage || e.kind == EventKind::impact)
      out.push_back(e);
  return out;
}

/// Runs the 1-DOF soft-impact oscillator in the dense engine and in the reference; checks the
/// switch times one to one and the final state.
void check_against_reference(Reference ref, double t_end, double tol) {
  std::vector<Stop> stops{Stop::upper(0, static_cast<double>(ref.p), 1.0)
                              .moving(static_cast<double>(ref.a), static_cast<double>(ref.phi))
                              .compliant(static_cast<double>(ref.ks), static_cast<double>(ref.cs),
                                         static_cast<double>(ref.Fp))};
  if (ref.p2 < 1e29L) stops.push_back(Stop::upper(0, static_cast<double>(ref.p2), static_cast<double>(ref.r2)));
  const ImpactSystem scene(one_dof(static_cast<double>(ref.m), static_cast<double>(ref.c), static_cast<double>(ref.k),
                                   static_cast<double>(ref.F), static_cast<double>(ref.W)),
                           stops);
  vibro::Simulator sim(scene);
  vibro::EventLog log;
  const vibro::RunSummary r = sim.run(0.0, vec({0.0}), vec({0.0}), t_end, {&log});
  REQUIRE(r.status == vibro::RunStatus::completed);
  const auto [x_ref, v_ref] = ref.run(0, 0, 0, t_end, 0.01L);
  const std::vector<vibro::Event> got = switches_of(log.events);
  INFO("switches: engine " << got.size() << ", reference " << ref.switches.size());
  REQUIRE(got.size() == ref.switches.size());
  REQUIRE(got.size() >= 8);
  double worst_t = 0.0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const int kind = got[i].kind == EventKind::engage ? 0 : got[i].kind == EventKind::disengage ? 1 : 2;
    CHECK(kind == ref.switches[i].kind);
    worst_t = std::max(worst_t, std::abs(got[i].t - static_cast<double>(ref.switches[i].t)));
  }
  const double dx = std::abs(r.x(0) - static_cast<double>(x_ref)), dv = std::abs(r.v(0) - static_cast<double>(v_ref));
  WARN("switch times: worst error " << worst_t << "; final state errors " << dx << ", " << dv);
  CHECK(worst_t < tol);
  CHECK(dx < tol);
  CHECK(dv < tol);
}

}  // namespace

// --- 1. The soft-impact oscillator against its piecewise closed form ----------------------------

// Tolerance 1e-9: each switch is located at a root of the gap to a few ulps of t (events.hpp)
// and each piece's flow is exact to ~1e-15 relative; over ~40 switches in 8 forcing periods
// the errors measured are ≤ 1.2e-14 (printed), so 1e-9 leaves four orders for platforms while
// any error in the engaged flow's K, C or f terms (O(1e-2) or more) fails it.
TEST_CASE("a compliant stop follows the soft-impact oscillator's piecewise closed form", "[compliant]") {
  Reference ref{1.0L, 0.1L, 1.0L, 1.0L, 0.8L, 0.5L, 0.0L, 0.0L, 20.0L, 0.3L, 0.0L};
  SECTION("fixed stop, spring and dashpot") { check_against_reference(ref, 60.0, 1e-9); }
  SECTION("fixed stop with a preload") {
    ref.Fp = 0.2L;
    check_against_reference(ref, 60.0, 1e-9);
  }
  SECTION("moving stop: the spring and dashpot follow s(t) and s'(t)") {
    ref.a = 0.1L;
    ref.phi = 0.7L;
    check_against_reference(ref, 60.0, 1e-9);
  }
}

TEST_CASE("a lower compliant stop is the mirror image of an upper one", "[compliant]") {
  // x → -x maps the upper stop at p with forcing F onto the lower stop at -p with forcing -F.
  auto run = [](bool upper) {
    const double sign = upper ? 1.0 : -1.0;
    const Stop base = upper ? Stop::upper(0, 0.5, 1.0) : Stop::lower(0, -0.5, 1.0);
    const double phase = upper ? 0.7 : 0.7 + std::numbers::pi;  // the lower stop moves as −(upper stop)
    const ImpactSystem scene(one_dof(1.0, 0.1, 1.0, sign * 1.0, 0.8), {base.moving(0.1, phase).compliant(20.0, 0.3, 0.2)});
    vibro::Simulator sim(scene);
    vibro::EventLog log;
    const vibro::RunSummary r = sim.run(0.0, vec({0.0}), vec({0.0}), 40.0, {&log});
    REQUIRE(r.status == vibro::RunStatus::completed);
    return std::make_pair(r, log.events);
  };
  const auto [up, up_events] = run(true);
  const auto [low, low_events] = run(false);
  REQUIRE(up_events.size() == low_events.size());
  REQUIRE(up_events.size() >= 8);
  for (std::size_t i = 0; i < up_events.size(); ++i) {
    CHECK(up_events[i].kind == low_events[i].kind);
    CHECK(std::abs(up_events[i].t - low_events[i].t) < 1e-12);
    CHECK(std::abs(up_events[i].force - low_events[i].force) < 1e-12);
  }
  CHECK(std::abs(up.x(0) + low.x(0)) < 1e-12);
  CHECK(std::abs(up.v(0) + low.v(0)) < 1e-12);
}

// --- 2. The rigid limit ---------------------------------------------------------------------------

// Unforced, undamped: x'' + x = 0 from x = 0, v = 1 hits the stop at x = 1/2 at t = π/6. The
// rigid elastic stop reverses the velocity there; the compliant one holds the mass for the
// contact time π/√(k + k_s) (→ π √(m/k_s)) and releases it with the same speed (no damping), so
// the motion afterwards lags by that time: the state error at a time after the contact is
// O(k_s^(-1/2)) (observed order 1/2 per decade of k_s).
TEST_CASE("a stiff compliant stop without damping approaches the elastic rigid stop at rate k_s^-1/2",
          "[compliant]") {
  const double t_end = std::numbers::pi / 6.0 + 1.0;  // after the contact, before the next one
  auto final_state = [&](const Stop& stop) {
    const ImpactSystem scene(one_dof(1.0, 0.0, 1.0, 0.0, 0.0), {stop});
    vibro::Simulator sim(scene);
    const vibro::RunSummary r = sim.run(0.0, vec({0.0}), vec({1.0}), t_end);
    REQUIRE(r.status == vibro::RunStatus::completed);
    return Eigen::Vector2d(r.x(0), r.v(0));
  };
  const Eigen::Vector2d rigid = final_state(Stop::upper(0, 0.5, 1.0));
  std::vector<double> errors;
  for (double ks : {1e2, 1e3, 1e4, 1e5, 1e6}) {
    errors.push_back((final_state(Stop::upper(0, 0.5, 1.0).compliant(ks, 0.0)) - rigid).norm());
    WARN("k_s = " << ks << ": |state − rigid| = " << errors.back());
  }
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double order = std::log10(errors[i - 1] / errors[i]);
    WARN("observed order per decade of k_s: " << order);
    // Expected 1/2; the next term is O(1/k_s) relative, ≤ 1e-2 from k_s = 1e2, so ±0.05.
    CHECK(order > 0.45);
    CHECK(order < 0.55);
  }
}

// --- 3. Energy ------------------------------------------------------------------------------------

// Two masses (M = diag(1, 2), wall springs and a link), an upper compliant stop with a preload on
// mass 0 and a lower compliant stop on mass 1; no damping, no forcing. The energy
// ½vᵀMv + ½xᵀKx + Σ_engaged (½ k_s g² + F_p g) is a potential system's and stays constant: its
// drift, measured ~1e-15 relative over 60 time units, is held to 1e-12 (a wrong sign of any
// term of the engaged flow changes it by O(1)).
TEST_CASE("compliant stops without damping or forcing conserve energy to rounding", "[compliant]") {
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(2, 2), K(2, 2);
  M.diagonal() << 1.0, 2.0;
  K << 3.0, -1.0, -1.0, 2.0;
  const LinearSystem sys(M, Eigen::MatrixXd::Zero(2, 2), K, HarmonicForcing::zero(2));
  const std::vector<Stop> stops{Stop::upper(0, 0.4, 1.0).compliant(50.0, 0.0, 0.5),
                                Stop::lower(1, -0.3, 1.0).compliant(30.0, 0.0, 0.0)};
  const ImpactSystem scene(sys, stops);
  auto energy = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
    double e = 0.5 * v.dot(M * v) + 0.5 * x.dot(K * x);
    const Eigen::VectorXd g = scene.gaps(0.0, x);
    for (std::size_t j = 0; j < stops.size(); ++j) {
      const double gj = g(static_cast<Eigen::Index>(j));
      if (gj > 0.0) e += 0.5 * stops[j].stiffness * gj * gj + stops[j].preload * gj;
    }
    return e;
  };
  std::vector<double> times;
  for (int i = 1; i <= 600; ++i) times.push_back(0.1 * i);
  vibro::Samples samples(times);
  vibro::EventLog log;
  vibro::Simulator sim(scene);
  const Eigen::VectorXd x0 = vec({0.0, 0.0}), v0 = vec({1.5, -1.2});
  const vibro::RunSummary r = sim.run(0.0, x0, v0, 60.0, {&samples, &log});
  REQUIRE(r.status == vibro::RunStatus::completed);
  long engages = 0;
  for (const vibro::Event& e : log.events) engages += e.kind == EventKind::engage ? 1 : 0;
  REQUIRE(engages >= 10);
  const double e0 = energy(x0, v0);
  double drift = 0.0;
  for (Eigen::Index i = 0; i < samples.x.cols(); ++i)
    drift = std::max(drift, std::abs(energy(samples.x.col(i), samples.v.col(i)) - e0) / e0);
  WARN("energy drift (relative) over " << engages << " engagements: " << drift);
  CHECK(drift < 1e-12);
}

// --- 4. Two-stage stop ----------------------------------------------------------------------------

TEST_CASE("a two-stage stop: a compliant spring, then a rigid stop behind it", "[compliant]") {
  SECTION("impacts on the rigid stop while the spring is engaged, against the closed form") {
    // Unforced, undamped except the spring's dashpot; the rigid stop at 0.45 with r = 0.8 takes
    // impacts until the motion no longer reaches it. Tolerance as in section 1.
    Reference ref{1.0L, 0.0L, 1.0L, 0.0L, 0.0L, 0.3L, 0.0L, 0.0L, 10.0L, 0.05L, 0.0L};
    ref.p2 = 0.45L;
    ref.r2 = 0.8L;
    const ImpactSystem scene(one_dof(1.0, 0.0, 1.0, 0.0, 0.0),
                             {Stop::upper(0, 0.3, 1.0).compliant(10.0, 0.05), Stop::upper(0, 0.45, 0.8)});
    vibro::Simulator sim(scene);
    vibro::EventLog log;
    const vibro::RunSummary r = sim.run(0.0, vec({0.0}), vec({2.0}), 40.0, {&log});
    REQUIRE(r.status == vibro::RunStatus::completed);
    const auto [x_ref, v_ref] = ref.run(0, 0, 2, 40, 0.01L);
    const std::vector<vibro::Event> got = switches_of(log.events);
    REQUIRE(got.size() == ref.switches.size());
    int impacts = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      const int kind = got[i].kind == EventKind::engage ? 0 : got[i].kind == EventKind::disengage ? 1 : 2;
      CHECK(kind == ref.switches[i].kind);
      CHECK(std::abs(got[i].t - static_cast<double>(ref.switches[i].t)) < 1e-9);
      if (kind == 2) {
        ++impacts;
        CHECK(got[i].stop == 1);
      }
    }
    CHECK(impacts >= 2);
    CHECK(std::abs(r.x(0) - static_cast<double>(x_ref)) < 1e-9);
    CHECK(std::abs(r.v(0) - static_cast<double>(v_ref)) < 1e-9);
  }
  SECTION("held by the rigid stop with the spring engaged: the contact force counts the spring") {
    // A constant push F0 = 3 drives the mass through the spring (k_s = 4, preload 0.25, from
    // 0.2) onto the rigid stop at 0.5 (r = 0): it sticks there with λ = F0 − k·0.5 − k_s·0.3 −
    // F_p = 3 − 0.5 − 1.2 − 0.25 = 1.05 and stays.
    HarmonicForcing f = HarmonicForcing::zero(1, 0.0);
    f.constant(0) = 3.0;
    const LinearSystem sys(Eigen::MatrixXd::Constant(1, 1, 1.0), Eigen::MatrixXd::Constant(1, 1, 0.2),
                           Eigen::MatrixXd::Constant(1, 1, 1.0), f);
    const ImpactSystem scene(sys, {Stop::upper(0, 0.2, 1.0).compliant(4.0, 0.1, 0.25), Stop::upper(0, 0.5, 0.0)});
    vibro::Simulator sim(scene);
    vibro::EventLog log;
    const vibro::RunSummary r = sim.run(0.0, vec({0.0}), vec({0.0}), 20.0, {&log});
    REQUIRE(r.status == vibro::RunStatus::completed);
    REQUIRE(log.events.size() >= 3);
    CHECK(log.events[0].kind == EventKind::engage);
    bool stuck = false;
    for (const vibro::Event& e : log.events)
      if (e.kind == EventKind::stick && e.stop == 1) {
        stuck = true;
        CHECK(std::abs(e.force - 1.05) < 1e-12);
      }
    CHECK(stuck);
    CHECK(r.stuck == vibro::ContactSet{1});
    CHECK(std::abs(r.x(0) - 0.5) < 1e-12);
  }
}

// --- 5. Bad input -----------------------------------------------------------------------------------

TEST_CASE("compliant stops: bad parameters and unsupported uses are refused clearly", "[compliant]") {
  const LinearSystem sys = one_dof(1.0, 0.1, 1.0, 1.0, 0.8);
  auto refused = [&](const Stop& stop, const std::string& what) {
    CHECK_THROWS_WITH(ImpactSystem(sys, {stop}), Catch::Contains(what));
  };
  const Stop base = Stop::upper(0, 0.5, 1.0);
  refused(base.compliant(0.0, 0.0), "stiffness is 0");
  refused(base.compliant(-1.0, 0.0), "stiffness is -1");
  refused(base.compliant(std::nan(""), 0.0), "stiffness is nan");
  refused(base.compliant(1.0, -0.5), "damping is -0.5");
  refused(base.compliant(1.0, std::numeric_limits<double>::infinity()), "damping is inf");
  refused(base.compliant(1.0, 0.0, -1.0), "preload is -1");
  // A compliant and a rigid stop on one side of one mass are a two-stage stop, not a duplicate.
  CHECK_NOTHROW(ImpactSystem(sys, {base.compliant(1.0, 0.0), Stop::upper(0, 0.7, 0.5)}));
  // A compliant stop may start penetrated (engaged); a rigid one may not.
  const ImpactSystem scene(sys, {base.compliant(10.0, 0.0)});
  vibro::Simulator sim(scene);
  vibro::EventLog log;
  const vibro::RunSummary r = sim.run(0.0, vec({0.6}), vec({0.0}), 5.0, {&log});
  CHECK(r.status == vibro::RunStatus::completed);
  REQUIRE(!log.events.empty());
  CHECK(log.events[0].kind == EventKind::disengage);  // it starts engaged at g = 0.1

  // The modal chain engine takes a compliant stop whose dashpot keeps the damping proportional
  // (this undamped chain: c_s = β k_s = 0) and refuses another, naming the dense engine.
  const vibro::ChainModes modes(
      vibro::BandedChain::from_links({1, 1, 1}, {1, 1}, {}, 1.0, 0.0, 1.0, 0.0, HarmonicForcing::zero(3, 1.0)));
  CHECK_NOTHROW(vibro::ModalChainSimulator(modes, {base.compliant(10.0, 0.0)}));
  CHECK_THROWS_WITH(vibro::ModalChainSimulator(modes, {base.compliant(10.0, 0.3)}),
                    Catch::Contains("dense engine"));
}
