/// Tests of vibro::Simulator (framework/src/simulator.cpp): the hybrid event loop.
///
/// What is checked, and against what:
///  1. a bouncing ball (K = C = 0, force -g): impact times against the geometric series
///     t_k = Σ 2 v0 rⁱ / g, the chatter limit against 2 v0 / (g (1 - r)), the number of bounces
///     against the chatter rule, sticking forever; a ball pressed on its stop by a spring;
///  2. energy balance W_forcing - D - losses = E(end) - E(start) with composite Gauss–Legendre
///     quadratures of f·v and vᵀCv over every exact segment, the losses being the jumps of E at
///     events, each impact's loss against ½ (1 - r²) u² / (wᵀM⁻¹w); conservation through 10⁴
///     impacts with r = 1, C = 0;
///  3. the paper's system (Wagg 2004, Ω = 0.255 and 0.27, 50 periods from rest) event by event
///     against an independent fixed-step RK8 hybrid integrator (support/reference_hybrid.hpp);
///  4. grazing: trajectories engineered to come within 1e-10 of a stop (no impact) or to pass it
///     by 1e-10 (an impact, at the closed-form time), one and two degrees of freedom;
///  5. no penetration: every run is sampled densely and every gap must stay ≤ 1e-12 L;
///  6. r = 0, a symmetric clearance (mirror symmetry), a 5-DOF chain with a stop between masses,
///     a ball on a vibrating table (Newton's law on the relative velocity, flights in closed
///     form);
///  7. the Zeno guard (chatter resolution off: event cap, message, return);
///  8. contact sets built lazily, counted against the sets the events visit.
/// Measured worst errors are printed by the hidden test "[.report]":
///     ./vibro_tests_engine "[.report]"
#include "support/reference_hybrid.hpp"
#include "support/end_states.hpp"
#include "support/reference_integrator.hpp"
#include "vibro/models/chain.hpp"
#include "vibro/simulator.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::ContactSet;
using vibro::Event;
using vibro::EventKind;
using vibro::HarmonicForcing;
using vibro::ImpactSystem;
using vibro::LinearSystem;
using vibro::Observer;
using vibro::RunStatus;
using vibro::RunSummary;
using vibro::Samples;
using vibro::SegmentView;
using vibro::Simulator;
using vibro::SimulatorOptions;
using vibro::Stop;
using vibro::test::GaussLegendre;
using vibro::test::ReferenceEvent;
using vibro::test::ReferenceEventKind;
using vibro::test::ReferenceHybrid;
using vibro::test::ReferenceHybridOptions;
using vibro::test::VectorL;

constexpr double kPi = std::numbers::pi;
constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kGravity = 9.81;

/// No state may be more than this fraction of the length scale L past a stop. The engine's
/// trigger is 1e-13 L (SimulatorOptions::trigger), so 1e-12 L leaves a factor 10 for the
/// rounding of a state evaluated from the exact flow (~1e-16 of its size).
constexpr double kPenetration = 1e-12;
/// Energy balance, relative to the largest of |W|, D, losses and max E. The quadratures are
/// exact to ~1e-20 (see Audit), so what remains is the rounding of the flows (~1e-15 per
/// segment) summed over ≤ 1e4 segments: ≲ 1e-12; 1e-9 is the demand.
constexpr double kEnergyBalance = 1e-9;

// ---------------------------------------------------------------------------------------------
// Independent mechanics: written here from the definitions, not taken from the library.

VectorXd force_at(const LinearSystem& s, double t) {
  const HarmonicForcing& f = s.forcing();
  return f.constant + f.cosine * std::cos(f.frequency * t) + f.sine * std::sin(f.frequency * t);
}

double energy(const LinearSystem& s, const VectorXd& x, const VectorXd& v) {
  return 0.5 * v.dot(s.mass() * v) + 0.5 * x.dot(s.stiffness() * x);
}

/// P(t) = p + a cos(Ωt + φ) and its first derivative.
double stop_position(const Stop& s, double omega, double t) {
  return s.position + s.amplitude * std::cos(omega * t + s.phase);
}
double stop_velocity(const Stop& s, double omega, double t) {
  return -s.amplitude * omega * std::sin(omega * t + s.phase);
}

/// Gap ≤ 0 when admissible: x_i - P (upper), P - x_i (lower), x_i - x_k - P (between).
double gap(const Stop& s, double omega, double t, const VectorXd& x) {
  const double p = stop_position(s, omega, t);
  switch (s.kind) {
    case Stop::Kind::upper:
      return x(s.mass) - p;
    case Stop::Kind::lower:
      return p - x(s.mass);
    case Stop::Kind::between:
      return x(s.mass) - x(s.other) - p;
    case Stop::Kind::normal:  // general normals: none in these scenes
      break;
  }
  return 0.0;
}

/// Its rate (> 0: closing).
double gap_rate(const Stop& s, double omega, double t, const VectorXd& v) {
  const double p = stop_velocity(s, omega, t);
  switch (s.kind) {
    case Stop::Kind::upper:
      return v(s.mass) - p;
    case Stop::Kind::lower:
      return p - v(s.mass);
    case Stop::Kind::between:
      return v(s.mass) - v(s.other) - p;
    case Stop::Kind::normal:  // general normals: none in these scenes
      break;
  }
  return 0.0;
}

/// wᵀ M⁻¹ w: the inverse effective mass of a stop.
double inverse_effective_mass(const ImpactSystem& scene, const Stop& s) {
  VectorXd w = VectorXd::Zero(scene.dof());
  w(s.mass) = s.kind == Stop::Kind::lower ? -1.0 : 1.0;
  if (s.kind == Stop::Kind::between) w(s.other) = -1.0;
  return w.dot(scene.system().mass().llt().solve(w));
}

double max_gap(const ImpactSystem& scene, double t, const VectorXd& x) {
  const double omega = scene.system().forcing().frequency;
  double worst = -kInfinity;
  for (const Stop& s : scene.stops()) worst = std::max(worst, gap(s, omega, t, x));
  return worst;
}

// ---------------------------------------------------------------------------------------------
// The audit observer: quadratures, energy jumps and gaps over the exact segments.

/// One segment as seen by the audit: its mode and its states at both ends.
struct SegmentRecord {
  double t_begin = 0.0, t_end = 0.0;
  ContactSet active;
  VectorXd x_begin, v_begin, x_end, v_end;
};

/// The events reported between two segments (one pass of the event handler), with the states
/// on both sides: `before` is the end of the previous segment, `after` the start of the next.
struct EventGroup {
  double t = 0.0;
  std::vector<Event> events;
  VectorXd x_before, v_before, x_after, v_after;
  double energy_before = 0.0, energy_after = 0.0;
  bool initial = false;  ///< reported at t0, before any segment
};

/// Work of the forcing ∫ f·v dt and dissipation ∫ vᵀCv dt by composite Gauss–Legendre over each
/// segment (8 points, panels of width w with w·(2ρ) ≤ 0.5, ρ = max(|λ|, Ω) of the free system:
/// the integrands are sums of exponentials of rate ≤ 2ρ, for which the rule's error per panel is
/// ≈ (2ρw)¹⁶ (8!)⁴ / (17 (16!)³) ≈ 3e-28 of the integrand: far below 1e-13. A stuck mode is no
/// faster than the free system's ρ plus Ω in these tests). Also the largest gap over all nodes
/// and segment ends, and the energy jumps at events.
class Audit : public Observer {
 public:
  explicit Audit(const ImpactSystem& scene) : scene_(&scene), rule_(8) {
    const LinearSystem& sys = scene.system();
    const Eigen::Index n = sys.dof();
    MatrixXd A = MatrixXd::Zero(2 * n, 2 * n);
    A.topRightCorner(n, n).setIdentity();
    A.bottomLeftCorner(n, n) = -sys.mass().llt().solve(sys.stiffness());
    A.bottomRightCorner(n, n) = -sys.mass().llt().solve(sys.damping());
    const Eigen::EigenSolver<MatrixXd> eig(A, false);
    rate_ = std::max(eig.eigenvalues().cwiseAbs().maxCoeff(), sys.forcing().frequency);
  }

  void begin(const vibro::RunContext&, double t0) override { t0_ = t0; }

  void event(const Event& e) override {
    events.push_back(e);
    pending_.push_back(e);
  }

  void segment(const SegmentView& view) override {
    const LinearSystem& sys = scene_->system();
    const Eigen::Index n = sys.dof();
    SegmentRecord rec;
    rec.t_begin = view.t_begin();
    rec.t_end = view.t_end();
    rec.active = view.active();
    rec.x_begin.resize(n);
    rec.v_begin.resize(n);
    rec.x_end.resize(n);
    rec.v_end.resize(n);
    view.state(rec.t_begin, rec.x_begin, rec.v_begin);
    view.state(rec.t_end, rec.x_end, rec.v_end);
    const double e_begin = energy(sys, rec.x_begin, rec.v_begin);
    const double e_end = energy(sys, rec.x_end, rec.v_end);
    if (segments.empty()) {
      energy_start = e_begin;
      if (!pending_.empty()) {
        EventGroup g;
        g.t = t0_;
        g.events = pending_;
        g.initial = true;
        g.x_after = rec.x_begin;
        g.v_after = rec.v_begin;
        g.energy_before = g.energy_after = e_begin;
        groups.push_back(std::move(g));
      }
    } else {
      const SegmentRecord& prev = segments.back();
      EventGroup g;
      g.t = rec.t_begin;
      g.events = pending_;
      g.x_before = prev.x_end;
      g.v_before = prev.v_end;
      g.x_after = rec.x_begin;
      g.v_after = rec.v_begin;
      g.energy_before = energy(sys, prev.x_end, prev.v_end);
      g.energy_after = e_begin;
      losses += g.energy_before - g.energy_after;
      const double jump = (rec.x_begin - prev.x_end).cwiseAbs().maxCoeff();
      const bool chatter = std::any_of(pending_.begin(), pending_.end(),
                                       [](const Event& e) { return e.kind == EventKind::chatter_limit; });
      (chatter ? chatter_shift : position_jump) = std::max(chatter ? chatter_shift : position_jump, jump);
      time_gap = std::max(time_gap, std::abs(rec.t_begin - prev.t_end));
      groups.push_back(std::move(g));
    }
    pending_.clear();
    energy_end = e_end;
    energy_max = std::max({energy_max, e_begin, e_end});
    gap_max = std::max({gap_max, max_gap(*scene_, rec.t_begin, rec.x_begin),
                        max_gap(*scene_, rec.t_end, rec.x_end)});

    // Quadratures (long double sums of double integrand values).
    const double span = rec.t_end - rec.t_begin;
    if (span > 0.0) {
      const long panels = std::max(1L, static_cast<long>(std::ceil(span * 2.0 * rate_ / 0.5)));
      const MatrixXd& C = sys.damping();
      VectorXd x(n), v(n);
      const long double width = static_cast<long double>(span) / static_cast<long double>(panels);
      for (long p = 0; p < panels; ++p) {
        const long double mid = rec.t_begin + (static_cast<long double>(p) + 0.5L) * width;
        long double w_panel = 0.0L, d_panel = 0.0L;
        for (int i = 0; i < rule_.points(); ++i) {
          const auto t = static_cast<double>(mid + 0.5L * width * rule_.node(i));
          view.state(t, x, v);
          w_panel += rule_.weight(i) * static_cast<long double>(force_at(sys, t).dot(v));
          d_panel += rule_.weight(i) * static_cast<long double>(v.dot(C * v));
          gap_max = std::max(gap_max, max_gap(*scene_, t, x));
          ++nodes;
        }
        work += 0.5L * width * w_panel;
        dissipation += 0.5L * width * d_panel;
      }
    }
    segments.push_back(std::move(rec));
  }

  void end(double) override {
    if (!pending_.empty()) {  // events after the last segment (none expected)
      EventGroup g;
      g.t = segments.empty() ? t0_ : segments.back().t_end;
      g.events = pending_;
      groups.push_back(std::move(g));
      pending_.clear();
    }
  }

  /// (W - D - losses - (E_end - E_start)) over max(|W|, D, |losses|, max E).
  double energy_residual() const {
    const double W = static_cast<double>(work), D = static_cast<double>(dissipation);
    const double scale = std::max({std::abs(W), std::abs(D), std::abs(losses), energy_max});
    return std::abs(W - D - losses - (energy_end - energy_start)) / scale;
  }

  std::vector<Event> events;
  std::vector<SegmentRecord> segments;
  std::vector<EventGroup> groups;
  long double work = 0.0L, dissipation = 0.0L;
  double losses = 0.0;  ///< Σ (E before - E after) over event groups
  double energy_start = 0.0, energy_end = 0.0, energy_max = 0.0;
  double gap_max = -kInfinity;
  double position_jump = 0.0;  ///< largest |x(start of k+1) - x(end of k)|: positions never jump
  /// … except where a chatter is ended: the rule moves x by the skipped bounces' mean
  /// displacement (simulator.hpp, ChatterRule), O(w0³); the largest such move.
  double chatter_shift = 0.0;
  double time_gap = 0.0;       ///< largest |t_begin(k+1) - t_end(k)|: segments tile the run
  long nodes = 0;

 private:
  const ImpactSystem* scene_;
  GaussLegendre rule_;
  double rate_ = 0.0;
  double t0_ = 0.0;
  std::vector<Event> pending_;
};

/// A run with the audit and dense samples.
struct Run {
  RunSummary summary;
  Audit audit;
  double penetration = 0.0;  ///< largest gap over samples, nodes and segment ends, over L
  long sampled = 0;
  double seconds = 0.0;
  double chatter_height = 0.0;  ///< the run's option
};

Run simulate(const ImpactSystem& scene, double t0, const VectorXd& x0, const VectorXd& v0,
             double t_end, SimulatorOptions options = {}, long samples = 20000) {
  std::vector<double> times(static_cast<std::size_t>(samples));
  for (long i = 0; i < samples; ++i)
    times[static_cast<std::size_t>(i)] =
        t0 + (t_end - t0) * (static_cast<double>(i) / static_cast<double>(samples - 1));
  times.back() = t_end;
  Samples dense(times);
  Run run{RunSummary{}, Audit(scene)};
  run.chatter_height = options.chatter_height;
  Simulator sim(scene, options);
  const auto start = std::chrono::steady_clock::now();
  run.summary = sim.run(t0, x0, v0, t_end, {&run.audit, &dense});
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double worst = run.audit.gap_max;
  for (std::size_t i = 0; i < dense.t.size(); ++i)
    worst = std::max(worst, max_gap(scene, dense.t[i], dense.x.col(static_cast<Eigen::Index>(i))));
  run.penetration = worst / run.summary.length_scale;
  run.sampled = static_cast<long>(dense.t.size());
  return run;
}

/// The checks every run must pass: completed, segments tile [t0, t_end] without position jumps,
/// no penetration, the dense samples were all taken.
void check_run(const Run& r, double t_end, long samples = 20000) {
  INFO("status " << vibro::to_string(r.summary.status) << ": " << r.summary.message);
  CHECK(r.summary.status == RunStatus::completed);
  CHECK(r.summary.t == t_end);
  CHECK(r.sampled == samples);
  CHECK(r.audit.time_gap == 0.0);
  // Positions are continuous through events. A view re-derives τ = t_end - t_begin, which can
  // differ from the engine's τ by an ulp of t, so the two ends may differ by |v|·ulp(t); plus
  // the flow's own rounding (≲ 2e-12 relative for the spectral method, flow.hpp).
  CHECK(r.audit.position_jump <=
        1e-12 * r.summary.length_scale + 4.0 * kEps * t_end * r.summary.velocity_scale);
  // Where a chatter ends, x moves by the rule's correction, ~(C/G)·w0³/A²: smaller than the
  // skipped bounces' own heights, w0²/(2A) ≤ chatter_height·L, by a factor O(w0).
  CHECK(r.audit.chatter_shift <= r.chatter_height * r.summary.length_scale);
  CHECK(r.penetration <= kPenetration);
}

// ---------------------------------------------------------------------------------------------
// Scenes.

HarmonicForcing forcing1(double constant, double cosine, double omega) {
  HarmonicForcing f;
  f.constant = VectorXd::Constant(1, constant);
  f.cosine = VectorXd::Constant(1, cosine);
  f.sine = VectorXd::Zero(1);
  f.frequency = omega;
  return f;
}

LinearSystem one_mass(double m, double c, double k, HarmonicForcing f) {
  return LinearSystem(MatrixXd::Constant(1, 1, m), MatrixXd::Constant(1, 1, c),
                      MatrixXd::Constant(1, 1, k), std::move(f));
}

/// A ball under gravity above a floor at 0 with restitution r (K = C = 0).
ImpactSystem bouncing_ball(double r) {
  return ImpactSystem(one_mass(1.0, 0.0, 0.0, forcing1(-kGravity, 0.0, 0.0)),
                      {Stop::lower(0, 0.0, r)});
}

VectorXd vec(std::initializer_list<double> values) {
  VectorXd v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double x : values) v(i++) = x;
  return v;
}

double forcing_period(const ImpactSystem& scene) {
  return 2.0 * kPi / scene.system().forcing().frequency;
}

/// 3 masses, walls on both sides, a backlash stop between masses 0 and 1 and two stops on
/// single masses.
ImpactSystem three_mass_chain() {
  vibro::models::Chain c;
  c.masses = {1.0, 1.5, 0.8};
  c.springs = {1.0, 2.0};
  c.dampers = {0.05, 0.1};
  c.left_spring = 1.0;
  c.left_damper = 0.05;
  c.right_spring = 0.5;
  c.right_damper = 0.02;
  c.force_cosine = {0.6, 0.0, 0.3};
  c.frequency = 0.7;
  return ImpactSystem(
      vibro::models::build_chain(c),
      {Stop::between(0, 1, 0.15, 0.6), Stop::upper(2, 0.4, 0.8), Stop::lower(1, -0.3, 0.7)});
}

/// 5 masses, stops on the alternate masses 0, 2, 4 and one between masses 3 and 2.
ImpactSystem five_mass_chain() {
  vibro::models::Chain c;
  c.masses = {1.0, 0.8, 1.2, 1.0, 0.9};
  c.springs = {1.0, 1.5, 1.0, 2.0};
  c.dampers = {0.05, 0.05, 0.08, 0.05};
  c.left_spring = 1.0;
  c.left_damper = 0.05;
  c.right_spring = 1.0;
  c.right_damper = 0.05;
  c.force_cosine = {0.7, 0.0, 0.0, 0.0, -0.5};
  c.frequency = 0.9;
  return ImpactSystem(vibro::models::build_chain(c),
                      {Stop::lower(0, -0.4, 0.7), Stop::upper(2, 0.3, 0.6),
                       Stop::lower(4, -0.35, 0.8), Stop::between(3, 2, 0.2, 0.5)});
}

/// 10 masses, an upper and a lower stop on each (20 stops), r = 0.5.
ImpactSystem ten_mass_chain() {
  vibro::models::Chain c;
  c.masses.assign(10, 1.0);
  c.springs.assign(9, 1.0);
  c.dampers.assign(9, 0.05);
  c.left_spring = c.right_spring = 1.0;
  c.left_damper = c.right_damper = 0.05;
  c.force_cosine.assign(10, 0.0);
  c.force_cosine[0] = 0.8;
  c.force_cosine[9] = -0.6;
  c.frequency = 0.5;
  std::vector<Stop> stops;
  for (int i = 0; i < 10; ++i) {
    stops.push_back(Stop::lower(i, -0.3 - 0.02 * i, 0.5));
    stops.push_back(Stop::upper(i, 0.25 + 0.01 * i, 0.5));
  }
  return ImpactSystem(vibro::models::build_chain(c), std::move(stops));
}

// ---------------------------------------------------------------------------------------------
// 1. Bouncing ball.

struct BallResult {
  double impact_time = 0.0;   ///< worst relative error of t_k
  double impact_speed = 0.0;  ///< worst relative error of v_before = r^(k-1) v0
  double chatter_time = 0.0;  ///< relative error of the chatter limit
  long impacts = 0, predicted_impacts = 0;
};

/// Bounces predicted by the chatter rule: the k-th impact (approach speed u = r^(k-1) v0) is the
/// last if its rebound would rise (r u)² / (2 g) ≤ chatter_height · L.
long predicted_bounces(double r, double v0, double L, double chatter_height) {
  double u = v0;
  for (long k = 1; k < 10000; ++k, u *= r)
    if ((r * u) * (r * u) / (2.0 * kGravity) <= chatter_height * L) return k;
  return -1;
}

BallResult check_bouncing_ball(double r) {
  const ImpactSystem scene = bouncing_ball(r);
  const double v0 = 1.0, t_end = 5.0;
  const Run run = simulate(scene, 0.0, vec({0.0}), vec({v0}), t_end);
  check_run(run, t_end);
  BallResult out;
  const std::vector<Event>& ev = run.audit.events;
  REQUIRE(!ev.empty());
  long double t_exact = 0.0L, u = v0;
  long chatter_limits = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    const Event& e = ev[i];
    INFO("event " << i << ": " << vibro::to_string(e.kind) << " at t = " << e.t);
    CHECK(e.stop == 0);
    CHECK(e.kind != EventKind::release);
    if (e.kind == EventKind::impact) {
      t_exact += 2.0L * u / kGravity;
      ++out.impacts;
      out.impact_time =
          std::max(out.impact_time, static_cast<double>(std::fabs((e.t - t_exact) / t_exact)));
      out.impact_speed =
          std::max(out.impact_speed, static_cast<double>(std::fabs((e.v_before - u) / u)));
      const bool last = i + 1 < ev.size() && ev[i + 1].kind == EventKind::chatter_limit;
      // Newton's law, except for the impact that ends the chatter (rebound set to 0).
      CHECK(std::abs(e.v_after - (last ? 0.0 : -r * e.v_before)) <= 1e-15 * v0);
      u *= r;
    } else {
      CHECK(e.kind == EventKind::chatter_limit);
      ++chatter_limits;
      // Budd & Dux: the bounces accumulate at 2 v0 / (g (1 - r)); for constant g exactly.
      const long double t_limit = 2.0L * v0 / (kGravity * (1.0L - r));
      out.chatter_time = static_cast<double>(std::fabs((e.t - t_limit) / t_limit));
      CHECK(e.force == Approx(kGravity).epsilon(1e-12));  // λ = m g
    }
  }
  out.predicted_impacts =
      predicted_bounces(r, v0, run.summary.length_scale, SimulatorOptions{}.chatter_height);
  CHECK(chatter_limits == 1);
  CHECK(ev.back().kind == EventKind::chatter_limit);
  CHECK(out.impacts == out.predicted_impacts);
  CHECK(run.summary.stuck == ContactSet{0});
  CHECK(run.summary.releases == 0);
  CHECK(std::abs(run.summary.x(0)) <= kPenetration * run.summary.length_scale);
  CHECK(run.summary.v(0) == 0.0);
  // One segment per flight, then one held segment from the chatter impact to t_end.
  CHECK(static_cast<long>(run.audit.segments.size()) == out.impacts + 1);
  const SegmentRecord& last = run.audit.segments.back();
  CHECK(last.active == ContactSet{0});
  CHECK(last.t_begin == ev[ev.size() - 2].t);
  CHECK(last.t_end == t_end);
  // Error budget of t_k: each flight 2 u_k / g is computed from the exact flow and located to a
  // few ulps, ≲ 20 impacts accumulate ≲ 1e-14 relative: 1e-12 leaves a factor 100.
  CHECK(out.impact_time <= 1e-12);
  CHECK(out.impact_speed <= 1e-12);
  CHECK(out.chatter_time <= 1e-12);
  return out;
}

TEST_CASE(
    "simulator: a bouncing ball's impacts are the geometric series sum 2 v0 r^i / g, then it "
    "sticks at the chatter limit 2 v0 / (g (1 - r)) for ever",
    "[simulator][closed-form][chatter]") {
  for (double r : {0.7, 0.5}) {
    INFO("r = " << r);
    check_bouncing_ball(r);
  }
}

TEST_CASE(
    "simulator: a ball pressed on its stop by a spring chatters into sticking, does not "
    "penetrate and stays stuck",
    "[simulator][chatter]") {
  // m x'' + c x' + k x = -g, floor at 0, equilibrium -g/k below the floor: the floor holds the
  // ball with λ = g > 0 for ever once it rests. The chatter time is not known in closed form.
  for (double c : {0.0, 0.3}) {
    INFO("c = " << c);
    const ImpactSystem scene(one_mass(1.0, c, 4.0, forcing1(-kGravity, 0.0, 0.0)),
                             {Stop::lower(0, 0.0, 0.7)});
    const double t_end = 20.0;
    const Run run = simulate(scene, 0.0, vec({0.5}), vec({0.0}), t_end);
    check_run(run, t_end);
    CHECK(run.summary.impacts > 5);
    CHECK(run.summary.chatters == 1);
    CHECK(run.summary.releases == 0);
    CHECK(run.summary.stuck == ContactSet{0});
    CHECK(std::abs(run.summary.x(0)) <= kPenetration * run.summary.length_scale);
    CHECK(std::abs(run.summary.v(0)) <= 1e-15);
    CHECK(run.audit.events.back().kind == EventKind::chatter_limit);
    CHECK(run.audit.energy_residual() <= kEnergyBalance);
  }
}

TEST_CASE(
    "simulator: a mass at rest on a stop at t0 starts stuck if the stop must push, free if "
    "not",
    "[simulator][initial]") {
  // Gravity presses the ball on the floor (λ = g): one stick at t0, nothing else, x stays 0.
  {
    const ImpactSystem scene = bouncing_ball(0.7);
    const Run run = simulate(scene, 0.0, vec({0.0}), vec({0.0}), 3.0, {}, 2000);
    check_run(run, 3.0, 2000);
    REQUIRE(run.audit.events.size() == 1);
    const Event& e = run.audit.events.front();
    CHECK(e.kind == EventKind::stick);
    CHECK(e.t == 0.0);
    CHECK(e.force == Approx(kGravity).epsilon(1e-12));
    CHECK(run.summary.stuck == ContactSet{0});
    CHECK(run.summary.x(0) == 0.0);
  }
  // A spring pulls the mass up off the floor (equilibrium +0.2 above it): the free motion
  // x = 0.2 (1 - cos 2t) returns to touch the floor with zero speed at t = π, an exact tangency
  // that is no impact: no event at all, and the final state from the closed form.
  {
    const ImpactSystem scene(one_mass(1.0, 0.0, 4.0, forcing1(0.8, 0.0, 0.0)),
                             {Stop::lower(0, 0.0, 0.7)});
    const Run run = simulate(scene, 0.0, vec({0.0}), vec({0.0}), 3.0, {}, 2000);
    check_run(run, 3.0, 2000);
    CHECK(run.audit.events.empty());
    CHECK(run.summary.x(0) == Approx(0.2 * (1.0 - std::cos(6.0))).epsilon(1e-13));
  }
}

// ---------------------------------------------------------------------------------------------
// 2. Energy balance.

struct EnergyResult {
  double residual = 0.0;     ///< energy balance, relative
  double impact_loss = 0.0;  ///< worst |jump - ½(1 - r²)u²/G| over max E, single impacts
  double gain = 0.0;         ///< largest energy gain at an event, over max E
  double penetration = 0.0;  ///< largest gap over L (samples, quadrature nodes, segment ends)
  long impacts = 0;
  double seconds = 0.0;
};

/// Checks every event group's energy jump: never a gain; a lone impact on a free system loses
/// exactly ½ (1 - r²) u² / G with G = wᵀM⁻¹w. (An impact that ends a chatter is left out: the
/// rule adds the skipped bounces' O(w0³) effect on the state to Newton's law, simulator.hpp.)
EnergyResult energy_checks(const ImpactSystem& scene, const Run& run) {
  EnergyResult out;
  out.residual = run.audit.energy_residual();
  out.penetration = run.penetration;
  out.impacts = run.summary.impacts;
  out.seconds = run.seconds;
  const double scale = run.audit.energy_max;
  const std::vector<EventGroup>& groups = run.audit.groups;
  const std::size_t offset = !groups.empty() && groups.front().initial ? 1 : 0;
  for (std::size_t k = offset; k < groups.size(); ++k) {
    const EventGroup& g = groups[k];
    out.gain = std::max(out.gain, (g.energy_after - g.energy_before) / scale);
    const bool free_before = run.audit.segments[k - offset].active.empty();  // the segment before g
    std::vector<const Event*> impacts;
    bool chatter = false;
    for (const Event& e : g.events) {
      if (e.kind == EventKind::impact) impacts.push_back(&e);
      if (e.kind == EventKind::chatter_limit) chatter = true;
    }
    if (impacts.size() != 1 || !free_before || g.events.size() > 2 || chatter) continue;
    const Event& e = *impacts.front();
    const Stop& s = scene.stops()[static_cast<std::size_t>(e.stop)];
    const double r = s.restitution;
    const double expected =
        0.5 * (1.0 - r * r) * e.v_before * e.v_before / inverse_effective_mass(scene, s);
    out.impact_loss =
        std::max(out.impact_loss, std::abs(g.energy_before - g.energy_after - expected) / scale);
  }
  return out;
}

void check_energy(const EnergyResult& e) {
  CHECK(e.residual <= kEnergyBalance);
  // An impact's loss is a difference of energies of ~1, each rounded to ~1e-16: 1e-13 is loose.
  CHECK(e.impact_loss <= 1e-13);
  CHECK(e.gain <= 1e-13);
}

EnergyResult energy_paper(double omega) {
  vibro::models::Wagg2004 p;
  p.frequency = omega;
  const ImpactSystem scene = vibro::models::wagg2004(p);
  const double t_end = 50.0 * 2.0 * kPi / omega;
  const Run run = simulate(scene, 0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end);
  check_run(run, t_end);
  return energy_checks(scene, run);
}

EnergyResult energy_three_mass() {
  const ImpactSystem scene = three_mass_chain();
  const double t_end = 50.0 * forcing_period(scene);
  const Run run = simulate(scene, 0.0, VectorXd::Zero(3), VectorXd::Zero(3), t_end);
  check_run(run, t_end);
  CHECK(run.summary.impacts > 100);
  // The backlash stop (0) is hit: the test covers a coupled stop.
  bool between_hit = false;
  for (const Event& e : run.audit.events) between_hit |= e.kind == EventKind::impact && e.stop == 0;
  CHECK(between_hit);
  return energy_checks(scene, run);
}

TEST_CASE(
    "simulator: energy balance W - D - losses = E(end) - E(start) over 50 periods of the "
    "paper's system",
    "[simulator][energy][wagg2004]") {
  for (double omega : {0.255, 0.27}) {
    INFO("Omega = " << omega);
    check_energy(energy_paper(omega));
  }
}

TEST_CASE("simulator: energy balance on a 3-DOF chain with a stop between masses",
          "[simulator][energy][chain]") {
  check_energy(energy_three_mass());
}

struct ConservationResult {
  double drift = 0.0;  ///< max |E_k - E_0| / E_0 over event groups
  long impacts = 0;
  double balance = 0.0;
};

/// The paper's geometry with r = 1, c = 0: unforced (energy conserved at every impact) or forced
/// (no losses: W = ΔE).
ConservationResult conservation(bool forced) {
  vibro::models::Wagg2004 p;
  p.c = 0.0;
  p.r = 1.0;
  if (!forced) p.A1 = 0.0;
  const ImpactSystem scene = vibro::models::wagg2004(p);
  const double t_end = forced ? 20.0 * 2.0 * kPi / p.frequency : 13500.0;
  const Run run = simulate(scene, 0.0, vec({0.0, 0.0}), vec({0.8, -0.5}), t_end, {}, 50000);
  check_run(run, t_end, 50000);
  ConservationResult out;
  out.impacts = run.summary.impacts;
  out.balance = run.audit.energy_residual();
  const double e0 = run.audit.energy_start;
  for (const EventGroup& g : run.audit.groups)
    if (!g.initial)
      out.drift = std::max(
          {out.drift, std::abs(g.energy_before - e0) / e0, std::abs(g.energy_after - e0) / e0});
  if (forced) out.drift = std::abs(run.audit.losses) / run.audit.energy_max;
  return out;
}

TEST_CASE(
    "simulator: r = 1, C = 0: energy is conserved through 10^4 impacts (unforced) and the "
    "forcing's work is the energy change (forced)",
    "[simulator][energy]") {
  const ConservationResult free = conservation(false);
  CHECK(free.impacts >= 10000);
  CHECK(free.drift <= 1e-9);
  CHECK(free.balance <= kEnergyBalance);
  const ConservationResult forced = conservation(true);
  CHECK(forced.impacts > 50);
  CHECK(forced.drift <= 1e-12);  // Σ jumps: each impact conserves E to rounding
  CHECK(forced.balance <= kEnergyBalance);
}

// ---------------------------------------------------------------------------------------------
// 3. The paper's system against the independent reference.

struct ReferenceComparison {
  bool matched = true;
  std::string mismatch;
  long impacts = 0, chatters = 0, sticks = 0, releases = 0, skipped = 0;
  double impact_time = 0.0;    ///< worst |Δt| of impacts (both sides resolve them)
  double impact_speed = 0.0;   ///< worst |Δg'| before impacts
  double chatter_time = 0.0;   ///< worst |Δt| of chatter limits against the reference sticks
  double chatter_ratio = 0.0;  ///< worst |Δt| / Δ² (Δ: the chatter interval the engine skipped)
  double release_time = 0.0;
  double stick_time = 0.0;
};

const char* name_of(ReferenceEventKind k) {
  switch (k) {
    case ReferenceEventKind::impact:
      return "impact";
    case ReferenceEventKind::stick:
      return "stick";
    case ReferenceEventKind::release:
      return "release";
  }
  return "?";
}

/// Matches the engine's events one to one with the reference's. The engine ends a chatter at
/// the impact whose rebound would rise less than chatter_height·L, logging a chatter_limit at the
/// Budd–Dux accumulation time; the reference keeps integrating the bounces down to ~1e-7 and
/// then sticks (its t_limit adds the remaining tail). So: each engine impact must be the next
/// reference event (same stop, kind); after an engine impact followed by a chatter_limit, the
/// reference's further impacts on that stop up to its stick are skipped, and the chatter_limit
/// is compared with that stick's t_limit.
/// Impacts slower than `min_speed` are matched but left out of the worst impact error (used to
/// measure the reference against itself only where the engine is measured against it).
ReferenceComparison compare_events(const std::vector<Event>& lib,
                                   const std::vector<ReferenceEvent>& ref, double min_speed = 0.0) {
  ReferenceComparison c;
  std::vector<bool> used(ref.size(), false);
  std::size_t k = 0;
  auto fail = [&](std::size_t i, const std::string& why) {
    c.matched = false;
    char buf[400];
    const Event& e = lib[i];
    std::snprintf(buf, sizeof buf, "engine event %zu (%s, stop %d, t = %.15g): %s", i,
                  vibro::to_string(e.kind), e.stop, e.t, why.c_str());
    c.mismatch = buf;
  };
  for (std::size_t i = 0; i < lib.size(); ++i) {
    const Event& e = lib[i];
    if (e.kind == EventKind::chatter_limit) {
      std::size_t m = k;
      while (m < ref.size() &&
             (used[m] || ref[m].kind != ReferenceEventKind::stick || ref[m].stop != e.stop))
        ++m;
      if (m == ref.size()) {
        fail(i, "the reference never sticks on this stop");
        return c;
      }
      for (std::size_t q = k; q < m; ++q)
        if (!used[q] && ref[q].stop == e.stop && ref[q].kind == ReferenceEventKind::impact) {
          used[q] = true;
          ++c.skipped;
        }
      used[m] = true;
      const double dt = std::abs(e.t - static_cast<double>(ref[m].t_limit));
      const double delta = e.t - lib[i - 1].t;  // the interval the engine jumped over
      c.chatter_time = std::max(c.chatter_time, dt);
      if (delta > 0.0) c.chatter_ratio = std::max(c.chatter_ratio, dt / (delta * delta));
      ++c.chatters;
      continue;
    }
    while (k < ref.size() && used[k]) ++k;
    if (k == ref.size()) {
      fail(i, "the reference has no more events");
      return c;
    }
    const ReferenceEvent& r = ref[k];
    const bool same_kind = (e.kind == EventKind::impact && r.kind == ReferenceEventKind::impact) ||
                           (e.kind == EventKind::stick && r.kind == ReferenceEventKind::stick) ||
                           (e.kind == EventKind::release && r.kind == ReferenceEventKind::release);
    if (!same_kind || e.stop != r.stop) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "the reference has %s on stop %d at t = %.15Lg",
                    name_of(r.kind), r.stop, r.t);
      fail(i, buf);
      return c;
    }
    used[k] = true;
    const double dt = std::abs(e.t - static_cast<double>(r.t));
    switch (e.kind) {
      case EventKind::impact:
        ++c.impacts;
        if (e.v_before < min_speed) break;
        c.impact_time = std::max(c.impact_time, dt);
        c.impact_speed =
            std::max(c.impact_speed, std::abs(e.v_before - static_cast<double>(r.v_before)));
        break;
      case EventKind::stick:
        ++c.sticks;
        c.stick_time = std::max(c.stick_time, dt);
        break;
      case EventKind::release:
        ++c.releases;
        c.release_time = std::max(c.release_time, dt);
        break;
      case EventKind::chatter_limit:
      case EventKind::engage:  // compliant stops and friction: none in these scenes
      case EventKind::disengage:
      case EventKind::friction_stick:
      case EventKind::friction_slip:
      case EventKind::friction_reversal:
        break;
    }
  }
  for (std::size_t q = k; q < ref.size(); ++q)
    if (!used[q]) {
      c.matched = false;
      char buf[200];
      std::snprintf(buf, sizeof buf, "the reference has an extra %s on stop %d at t = %.15Lg",
                    name_of(ref[q].kind), ref[q].stop, ref[q].t);
      c.mismatch = buf;
      break;
    }
  return c;
}

/// Rebounds slower than this stick in the reference: the bounce heights (r u)²/2a ~ 1e-14 are
/// still ~1e6 ulps of a position ~0.3 in long double, and the Budd–Dux tail it adds,
/// Δ_ref = 2 r u / (a (1 - r)) ≲ 1e-5, has an error O(Δ_ref² |a'/a|) ≲ 1e-10. Resolving the
/// bounces further (1e-9) was measured to be worse: heights ~1e-18 are noisy in long double.
constexpr long double kReferenceStickVelocity = 1e-7L;

struct PaperComparison {
  ReferenceComparison engine;  ///< engine against the reference at h·ρ = 0.05
  ReferenceComparison
      reference;  ///< the reference at h·ρ = 0.05 against itself at 0.025 (own error)
  long reference_events = 0;
  double seconds = 0.0;
};

/// The reference's own events converted to engine events, to compare it with itself.
std::vector<Event> as_engine_events(const std::vector<ReferenceEvent>& ref) {
  std::vector<Event> out;
  for (const ReferenceEvent& r : ref) {
    Event e;
    e.t = static_cast<double>(r.t);
    e.stop = r.stop;
    e.kind = r.kind == ReferenceEventKind::impact  ? EventKind::impact
             : r.kind == ReferenceEventKind::stick ? EventKind::stick
                                                   : EventKind::release;
    e.v_before = static_cast<double>(r.v_before);
    e.v_after = static_cast<double>(r.v_after);
    out.push_back(e);
  }
  return out;
}

PaperComparison paper_against_reference(double omega) {
  vibro::models::Wagg2004 p;
  p.frequency = omega;
  const ImpactSystem scene = vibro::models::wagg2004(p);
  const double t_end = 50.0 * 2.0 * kPi / omega;
  const Run run = simulate(scene, 0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end);
  check_run(run, t_end);
  PaperComparison out;
  const auto start = std::chrono::steady_clock::now();
  ReferenceHybridOptions fine;
  fine.step_rate = 0.05L;
  fine.stick_velocity = kReferenceStickVelocity;
  ReferenceHybrid ref(scene, fine);
  ref.run(0.0L, VectorL::Zero(2), VectorL::Zero(2), static_cast<long double>(t_end));
  ReferenceHybridOptions finer = fine;
  finer.step_rate = 0.025L;
  ReferenceHybrid ref_finer(scene, finer);
  ref_finer.run(0.0L, VectorL::Zero(2), VectorL::Zero(2), static_cast<long double>(t_end));
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.reference_events = static_cast<long>(ref.events.size());
  out.engine = compare_events(run.audit.events, ref.events);
  // The engine resolves bounces down to (r u)²/2a = chatter_height·L, u ≳ 1e-5 here; the
  // reference's own slower chatter bounces are not compared with anything.
  out.reference = compare_events(as_engine_events(ref.events), ref_finer.events, 5e-6);
  return out;
}

void check_paper(const PaperComparison& c) {
  INFO(c.engine.mismatch);
  REQUIRE(c.engine.matched);
  INFO(c.reference.mismatch);
  REQUIRE(c.reference.matched);
  CHECK(c.engine.impacts > 1000);
  CHECK(c.engine.chatters > 50);
  CHECK(c.engine.releases > 50);
  // The reference's own error, from halving its step (h·ρ = 0.05 → 0.025; its local error
  // ∝ h⁹): it must be ≤ 1/10 of the tolerances below for them to measure the engine. (At
  // h·ρ = 0.1 the slowest compared impacts still move by 1.5e-10: 0.05 is the coarsest step
  // that is safely converged.)
  CHECK(c.reference.impact_time <= 1e-10);
  CHECK(c.reference.release_time <= 1e-11);
  // Impact times. An impact at approach speed u has a time sensitivity δg/u to an error δg in
  // the gap; the slowest impacts both sides resolve have u ≈ 1e-5 (the engine resolves bounces
  // rising more than chatter_height·L = 3e-10), and after ~3e3 events δg ≈ 1e-15: δt ≲ 1e-10.
  // The bound is 1e-9; the aim is ≤ 1e-8.
  CHECK(c.engine.impact_time <= 1e-9);
  CHECK(c.engine.impact_speed <= 1e-10);
  // Releases are force crossings with slopes ~0.1 and forces exact to ~1e-15: 1e-10.
  CHECK(c.engine.release_time <= 1e-10);
  // The chatter limit is the Budd–Dux extrapolation over the interval Δ ≲ 1e-3 the engine
  // skips, assuming the approach acceleration a constant; the true a drifts by a'Δ, which moves
  // the accumulation point by O(Δ² |a'|/a). |a'/a| ≲ 1 here (the forces vary at the rates 0.26
  // to 1.6 and a is not small where the chatter ends), so |Δt| ≤ Δ² bounds it (measured ratio in
  // the report). A wrong law (e.g. a missing factor r or 1 - r) would be off by O(Δ).
  CHECK(c.engine.chatter_ratio <= 1.0);
  CHECK(c.engine.chatter_time <= 2e-7);
}

TEST_CASE(
    "simulator: the paper's system at Omega = 0.255 matches an independent RK8 hybrid "
    "reference event by event over 50 periods",
    "[simulator][reference][wagg2004]") {
  check_paper(paper_against_reference(0.255));
}

TEST_CASE(
    "simulator: the paper's system at Omega = 0.27 (after rising) matches the RK8 hybrid "
    "reference event by event over 50 periods",
    "[simulator][reference][wagg2004]") {
  check_paper(paper_against_reference(0.27));
}

/// Chatter-limit errors against the reference (10 periods of the paper at Ω = 0.255) for
/// chatter_height = 1e-9 and 1e-10.
std::pair<double, double> chatter_convergence() {
  vibro::models::Wagg2004 p;
  const ImpactSystem scene = vibro::models::wagg2004(p);
  const double t_end = 10.0 * 2.0 * kPi / p.frequency;
  ReferenceHybridOptions o;
  o.stick_velocity = kReferenceStickVelocity;
  ReferenceHybrid ref(scene, o);
  ref.run(0.0L, VectorL::Zero(2), VectorL::Zero(2), static_cast<long double>(t_end));
  double errors[2] = {0.0, 0.0};
  int i = 0;
  for (double h : {1e-9, 1e-10}) {
    SimulatorOptions options;
    options.chatter_height = h;
    options.chatter_rule = vibro::ChatterRule::first_order;  // the Budd–Dux rule's O(Δ²) is tested here
    const Run run = simulate(scene, 0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, options);
    check_run(run, t_end);
    const ReferenceComparison c = compare_events(run.audit.events, ref.events);
    INFO(c.mismatch);
    REQUIRE(c.matched);
    REQUIRE(c.chatters > 5);
    errors[i++] = c.chatter_time;
  }
  return {errors[0], errors[1]};
}

TEST_CASE(
    "simulator: the chatter limit converges to the reference like the chatter height "
    "(Budd-Dux error O(Delta^2))",
    "[simulator][reference][chatter]") {
  // Δ² ∝ u² ∝ chatter_height, so lowering it from 1e-9 to 1e-10 must shrink the chatter-limit
  // error about tenfold (measured in the report); below ~1e-11 both sides' rounding of bounces
  // slower than ~1e-6 takes over. A factor 4 is required.
  const auto [coarse, fine] = chatter_convergence();
  CHECK(fine <= coarse / 4.0);
}

// ---------------------------------------------------------------------------------------------
// 4. Grazing.

struct GrazingResult {
  double time_error = 0.0;   ///< worst |t - t*| over the impact cases
  double relative = 0.0;     ///< worst |t - t*| / t*
  double allowed = 0.0;      ///< the tolerance at that case
  double worst_ratio = 0.0;  ///< worst |t - t*| / tolerance
  long missed = 0, spurious = 0;
  double state_error = 0.0;  ///< worst final-state error of the no-impact runs (relative)
};

/// x(t) = R cos(ω t - φ) from the (double) initial state, in long double.
struct Harmonic1 {
  long double omega, R, phi;
  Harmonic1(double w, double x0, double v0)
      : omega(w),
        R(std::hypot(static_cast<long double>(x0), static_cast<long double>(v0) / w)),
        phi(std::atan2(static_cast<long double>(v0) / w, static_cast<long double>(x0))) {}
  long double x(long double t) const { return R * std::cos(omega * t - phi); }
  long double v(long double t) const { return -R * omega * std::sin(omega * t - phi); }
};

/// One undamped mass (ω = 1.3) whose turning point x = R is at t_peak, in the middle of the free
/// flight [0, 2 t_peak]; an upper stop at R + δ (δ = +1e-10: passes 1e-10 short, no impact) or
/// R - δ (δ = -1e-10: passes 1e-10 beyond, one impact where R cos(ωt - φ) = stop). With
/// mirror = true the same with x → -x and a lower stop (the trough).
void grazing_one(double t_peak, double delta, bool mirror, GrazingResult& out) {
  const double w = 1.3, A = 1.0;
  const double sign = mirror ? -1.0 : 1.0;
  const VectorXd x0 = vec({sign * A * std::cos(-w * t_peak)});
  const VectorXd v0 = vec({-sign * A * w * std::sin(-w * t_peak)});
  // The unmirrored motion, from the rounded initial state.
  const Harmonic1 exact(w, sign * x0(0), sign * v0(0));
  const double p = static_cast<double>(exact.R + delta);
  const ImpactSystem scene(one_mass(1.0, 0.0, w * w, HarmonicForcing::zero(1)),
                           {mirror ? Stop::lower(0, -p, 1.0) : Stop::upper(0, p, 1.0)});
  const double t_end = 2.0 * t_peak;
  const Run run = simulate(scene, 0.0, x0, v0, t_end, {}, 4000);
  check_run(run, t_end, 4000);
  // The peak of R cos(ωt - φ) nearest t_peak, and the crossing before it.
  const long double period = 2.0L * std::numbers::pi_v<long double> / exact.omega;
  long double t_max = exact.phi / exact.omega;
  t_max += period * std::round((t_peak - t_max) / period);
  const long double t_cross =
      t_max - std::acos(static_cast<long double>(p) / exact.R) / exact.omega;
  INFO("t_peak = " << t_peak << ", delta = " << delta << (mirror ? ", mirrored" : ""));
  if (delta > 0.0) {
    if (run.summary.impacts != 0) ++out.spurious;
    CHECK(run.summary.impacts == 0);
    const double err =
        std::max(std::abs(sign * run.summary.x(0) - static_cast<double>(exact.x(t_end))),
                 std::abs(sign * run.summary.v(0) - static_cast<double>(exact.v(t_end))) / w);
    out.state_error = std::max(out.state_error, err / A);
    return;
  }
  if (run.summary.impacts != 1) ++out.missed;
  REQUIRE(run.summary.impacts == 1);
  const Event& e = run.audit.events.front();
  CHECK(e.kind == EventKind::impact);
  // The root of x(t) = p is ill-conditioned near a turning point: an error ε·A in evaluating x
  // moves it by ε·A / |x'(t*)|, with |x'(t*)| = A ω sin(acos(p/R)) ≈ 1.4e-5 here, i.e. ~1e-11 —
  // more than the 1e-12 relative the issue asks for a peak at t ~ 3. So the tolerance is that
  // conditioning (with 8 ulps for the flow and the root) plus 1e-12 of the flight time.
  const double slope = std::abs(static_cast<double>(exact.v(t_cross)));
  const double tol = 8.0 * kEps * A / slope + 1e-12 * static_cast<double>(t_cross);
  const double err = std::abs(e.t - static_cast<double>(t_cross));
  const double e_time = e.t;
  CHECK(err <= tol);
  CHECK(e.v_before == Approx(slope).epsilon(1e-4));
  out.time_error = std::max(out.time_error, err);
  out.relative = std::max(out.relative, err / e_time);
  if (err / tol > out.worst_ratio) {
    out.worst_ratio = err / tol;
    out.allowed = tol;
  }
}

/// Two masses (M = I, K = [[2, -1], [-1, 1]]): x_0(t) = Σ_k a_k cos(ω_k t) + b_k sin(ω_k t), a sum
/// of the two modes ω² = (3 ∓ √5)/2 with shapes (1, 2 - ω²). Modal amplitudes 1 and 0.35 peak
/// together at t_peak; a stop on x_0 at max ± 1e-10.
void grazing_two(double t_peak, double delta, GrazingResult& out) {
  using LD = long double;
  const LD s5 = std::sqrt(5.0L);
  const LD lam[2] = {(3.0L - s5) / 2.0L, (3.0L + s5) / 2.0L};
  const LD om[2] = {std::sqrt(lam[0]), std::sqrt(lam[1])};
  const LD shape[2] = {2.0L - lam[0], 2.0L - lam[1]};  // second component of the mode shapes
  const LD amp[2] = {1.0L, 0.35L};
  VectorXd x0(2), v0(2);
  for (int i = 0; i < 2; ++i) {
    LD x = 0.0L, v = 0.0L;
    for (int k = 0; k < 2; ++k) {
      const LD comp = i == 0 ? 1.0L : shape[k];
      x += comp * amp[k] * std::cos(-om[k] * t_peak);
      v += -comp * amp[k] * om[k] * std::sin(-om[k] * t_peak);
    }
    x0(i) = static_cast<double>(x);
    v0(i) = static_cast<double>(v);
  }
  // Exact modal coefficients from the rounded initial state (modes are orthogonal, M = I).
  LD a[2], b[2];
  for (int k = 0; k < 2; ++k) {
    const LD norm = 1.0L + shape[k] * shape[k];
    a[k] = (x0(0) + shape[k] * x0(1)) / norm;
    b[k] = (v0(0) + shape[k] * v0(1)) / norm / om[k];
  }
  auto x_first = [&](LD t, int d) {
    LD sum = 0.0L;
    for (int k = 0; k < 2; ++k) {
      const LD c = std::cos(om[k] * t), s = std::sin(om[k] * t), w = om[k];
      switch (d) {
        case 0:
          sum += a[k] * c + b[k] * s;
          break;
        case 1:
          sum += w * (-a[k] * s + b[k] * c);
          break;
        default:
          sum += -w * w * (a[k] * c + b[k] * s);
          break;
      }
    }
    return sum;
  };
  LD t_max = t_peak;
  for (int it = 0; it < 50; ++it) t_max -= x_first(t_max, 1) / x_first(t_max, 2);
  const LD peak = x_first(t_max, 0);
  const double p = static_cast<double>(peak + delta);
  vibro::models::Chain c;
  c.masses = {1.0, 1.0};
  c.springs = {1.0};
  c.left_spring = 1.0;
  const ImpactSystem scene(vibro::models::build_chain(c), {Stop::upper(0, p, 1.0)});
  const double t_end = 2.0 * t_peak;
  const Run run = simulate(scene, 0.0, x0, v0, t_end, {}, 4000);
  check_run(run, t_end, 4000);
  INFO("2-DOF, t_peak = " << t_peak << ", delta = " << delta);
  if (delta > 0.0) {
    if (run.summary.impacts != 0) ++out.spurious;
    CHECK(run.summary.impacts == 0);
    out.state_error = std::max(out.state_error,
                               std::abs(run.summary.x(0) - static_cast<double>(x_first(t_end, 0))));
    return;
  }
  if (run.summary.impacts != 1) ++out.missed;
  REQUIRE(run.summary.impacts == 1);
  // The crossing before the peak: Newton from the parabola's estimate, bracketed.
  LD lo = t_max - 0.5L, hi = t_max;
  LD t = t_max - std::sqrt(2.0L * std::fabs(delta) / -x_first(t_max, 2));
  for (int it = 0; it < 100; ++it) {
    const LD f = x_first(t, 0) - p;
    (f > 0.0L ? hi : lo) = t;
    LD next = t - f / x_first(t, 1);
    if (!(next > lo && next < hi)) next = 0.5L * (lo + hi);
    if (std::fabs(next - t) < 1e-19L) break;
    t = next;
  }
  const double slope = static_cast<double>(x_first(t, 1));
  const double tol = 8.0 * kEps * std::abs(p) / slope + 1e-12 * static_cast<double>(t);
  const double err = std::abs(run.audit.events.front().t - static_cast<double>(t));
  const double e_time = run.audit.events.front().t;
  CHECK(err <= tol);
  out.time_error = std::max(out.time_error, err);
  out.relative = std::max(out.relative, err / e_time);
  if (err / tol > out.worst_ratio) {
    out.worst_ratio = err / tol;
    out.allowed = tol;
  }
}

/// Peak times: inside and at the ends of the engine's search chunks (length 1/ρ = 1/1.3 for the
/// 1-DOF case), early and late in the run.
const std::vector<double>& peak_times() {
  static const std::vector<double> t = {0.5,       1.0 / 1.3, 1.0, 2.0 / 1.3, 2.2,
                                        3.0 / 1.3, 3.0,       4.0, 4.6};
  return t;
}

GrazingResult grazing_all() {
  GrazingResult out;
  for (double tp : peak_times())
    for (double delta : {1e-10, -1e-10})
      for (bool mirror : {false, true}) grazing_one(tp, delta, mirror, out);
  for (double tp : {3.0, 4.5, 6.25})
    for (double delta : {1e-10, -1e-10}) grazing_two(tp, delta, out);
  return out;
}

TEST_CASE(
    "simulator: grazing within 1e-10 of a stop is no impact, passing it by 1e-10 is an impact "
    "at the closed-form time (1 and 2 DOF, turning point mid-flight)",
    "[simulator][grazing][closed-form]") {
  const GrazingResult r = grazing_all();
  CHECK(r.missed == 0);
  CHECK(r.spurious == 0);
  CHECK(r.worst_ratio <= 1.0);
  // No impact: the flow is exact to rounding over ≤ 10 time units.
  CHECK(r.state_error <= 1e-13);
}

// ---------------------------------------------------------------------------------------------
// 6. r = 0, symmetric clearance, 5-DOF chain, moving stop.

struct PlasticResult {
  long impacts = 0, held = 0, separated = 0;
  double rebound = 0.0;  ///< worst |g'⁺| after an impact
  double energy = 0.0;
};

PlasticResult plastic_impacts() {
  // m = k = 1, light damping, F = 0.8 cos 0.6t, floor at -0.5 with r = 0: each impact kills the
  // normal velocity; the mass then sticks if the floor must push (free gap acceleration > 0 at
  // rest on it) and leaves at once otherwise.
  const ImpactSystem scene(one_mass(1.0, 0.02, 1.0, forcing1(0.0, 0.8, 0.6)),
                           {Stop::lower(0, -0.5, 0.0)});
  const double t_end = 20.0 * forcing_period(scene);
  const Run run = simulate(scene, 0.0, vec({0.0}), vec({0.0}), t_end);
  check_run(run, t_end);
  PlasticResult out;
  out.energy = run.audit.energy_residual();
  for (const EventGroup& g : run.audit.groups) {
    const Event* impact = nullptr;
    bool stuck = false;
    for (const Event& e : g.events) {
      if (e.kind == EventKind::impact) impact = &e;
      if (e.kind == EventKind::stick || e.kind == EventKind::chatter_limit) {
        stuck = true;
        CHECK(e.t == g.t);  // r = 0: the "accumulation point" is the impact itself
      }
    }
    if (impact == nullptr) continue;
    ++out.impacts;
    out.rebound = std::max(out.rebound, std::abs(impact->v_after));
    // Free gap acceleration at rest on the floor: -(f - c·0 - k x)/m with x = -0.5.
    const double q = -(force_at(scene.system(), g.t)(0) - 1.0 * g.x_after(0));
    INFO("impact at t = " << g.t << ", free gap acceleration " << q);
    CHECK(stuck == (q > 0.0));
    (stuck ? out.held : out.separated) += 1;
  }
  return out;
}

TEST_CASE(
    "simulator: r = 0 impacts are plastic: the mass sticks where the stop must push and "
    "separates at once where it need not",
    "[simulator][plastic]") {
  const PlasticResult r = plastic_impacts();
  CHECK(r.impacts > 10);
  CHECK(r.held > 0);
  CHECK(r.rebound <= 1e-15);
  CHECK(r.energy <= kEnergyBalance);
}

struct MirrorResult {
  double time = 0.0;  ///< worst |Δt| between mirrored events
  long events = 0;
  double energy = 0.0;
};

MirrorResult symmetric_clearance() {
  // One forced mass between stops at ±0.5: the run with forcing -F from -x0 is the mirror image
  // of the run with F from x0, upper stop ↔ lower stop, at the same times.
  auto scene_for = [](double amplitude) {
    return ImpactSystem(one_mass(1.0, 0.05, 1.0, forcing1(0.0, amplitude, 0.8)),
                        {Stop::upper(0, 0.5, 0.8), Stop::lower(0, -0.5, 0.8)});
  };
  const ImpactSystem plus = scene_for(1.0), minus = scene_for(-1.0);
  const double t_end = 30.0 * forcing_period(plus);
  const Run a = simulate(plus, 0.0, vec({0.1}), vec({0.0}), t_end);
  const Run b = simulate(minus, 0.0, vec({-0.1}), vec({0.0}), t_end);
  check_run(a, t_end);
  check_run(b, t_end);
  MirrorResult out;
  out.energy = std::max(a.audit.energy_residual(), b.audit.energy_residual());
  REQUIRE(a.audit.events.size() == b.audit.events.size());
  out.events = static_cast<long>(a.audit.events.size());
  long upper = 0, lower = 0;
  for (std::size_t i = 0; i < a.audit.events.size(); ++i) {
    const Event& e = a.audit.events[i];
    const Event& f = b.audit.events[i];
    INFO("event " << i << " at t = " << e.t);
    CHECK(e.kind == f.kind);
    CHECK(e.stop == 1 - f.stop);
    if (e.kind == EventKind::impact) (e.stop == 0 ? upper : lower) += 1;
    out.time = std::max(out.time, std::abs(e.t - f.t));
  }
  CHECK(upper > 10);
  CHECK(lower > 10);
  return out;
}

TEST_CASE(
    "simulator: a forced mass in a symmetric clearance: the mirrored run has the mirrored "
    "events at the same times",
    "[simulator][symmetry]") {
  const MirrorResult r = symmetric_clearance();
  // The two runs do the same operations up to signs, so they agree to rounding (a few ulps per
  // event, accumulated over ~100 events of a damped, non-chaotic orbit).
  CHECK(r.time <= 1e-12);
  CHECK(r.energy <= kEnergyBalance);
}

EnergyResult five_mass() {
  const ImpactSystem scene = five_mass_chain();
  const double t_end = 20.0 * forcing_period(scene);
  const Run run = simulate(scene, 0.0, VectorXd::Zero(5), VectorXd::Zero(5), t_end);
  check_run(run, t_end);
  CHECK(run.summary.impacts > 50);
  std::set<int> hit;
  for (const Event& e : run.audit.events)
    if (e.kind == EventKind::impact) hit.insert(e.stop);
  CHECK(hit.size() == 4);  // every stop, the one between masses included
  return energy_checks(scene, run);
}

TEST_CASE(
    "simulator: a 5-DOF chain with stops on alternate masses and one between masses runs "
    "20 periods without penetration, with the energy balanced",
    "[simulator][chain][energy]") {
  check_energy(five_mass());
}

struct TableResult {
  long impacts = 0, flights = 0;
  double newton = 0.0;         ///< worst |g'⁺ + r g'⁻| over V
  double relative_rate = 0.0;  ///< worst |logged g'⁻ - (P' - v) from the state| over V
  double flight_time = 0.0;    ///< worst |t_impact - closed-form landing time|
};

TableResult vibrating_table() {
  // A ball (K = 0, force -g) on a table moving as a cos Ωt, a Ω² = 1.6 g > g so it is thrown.
  const double a = 0.01, omega = std::sqrt(1.6 * kGravity / a), r = 0.5;
  const ImpactSystem scene(one_mass(1.0, 0.0, 0.0, forcing1(-kGravity, 0.0, omega)),
                           {Stop::lower(0, 0.0, r).moving(a, 0.0)});
  const Stop& s = scene.stops().front();
  const double t_end = 15.0 * 2.0 * kPi / omega;
  const Run run = simulate(scene, 0.0, vec({a}), vec({0.0}), t_end);
  check_run(run, t_end);
  const double V = a * omega;
  TableResult out;
  out.impacts = run.summary.impacts;
  for (std::size_t k = 0; k < run.audit.groups.size(); ++k) {
    const EventGroup& g = run.audit.groups[k];
    for (const Event& e : g.events) {
      if (e.kind != EventKind::impact) continue;
      // The logged rates are the relative normal velocity P'(t) - v (lower stop).
      const double before = gap_rate(s, omega, g.t, g.v_before);
      const double after = gap_rate(s, omega, g.t, g.v_after);
      out.relative_rate = std::max(
          {out.relative_rate, std::abs(e.v_before - before) / V, std::abs(e.v_after - after) / V});
      const bool ends_chatter = std::any_of(g.events.begin(), g.events.end(), [](const Event& x) {
        return x.kind == EventKind::chatter_limit;
      });
      out.newton =
          std::max(out.newton, std::abs(e.v_after + (ends_chatter ? 0.0 : r) * e.v_before) / V);
    }
  }
  // Each free flight that ends in an impact lands where x0 + v0 τ - g τ²/2 = a cos Ω(t0 + τ),
  // from the engine's own take-off state: bracket the first landing, bisect in long double.
  const std::size_t offset = !run.audit.groups.empty() && run.audit.groups.front().initial ? 1 : 0;
  for (std::size_t k = 0; k + 1 < run.audit.segments.size(); ++k) {
    const SegmentRecord& seg = run.audit.segments[k];
    if (!seg.active.empty()) continue;
    const EventGroup& next = run.audit.groups[k + offset];  // the events ending this flight
    if (std::none_of(next.events.begin(), next.events.end(),
                     [](const Event& e) { return e.kind == EventKind::impact; }))
      continue;
    using LD = long double;
    const LD t0 = seg.t_begin, x0 = seg.x_begin(0), v0 = seg.v_begin(0);
    auto h = [&](LD tau) {  // gap P - x
      return a * std::cos(omega * (t0 + tau)) - (x0 + v0 * tau - 0.5L * kGravity * tau * tau);
    };
    // Scan geometrically from 1e-9 (chatter flights are as short as ~1e-6), then in steps of
    // 1e-3/Ω: the first point with h ≤ 0 marks the take-off, the next with h > 0 the landing.
    const LD step = 1e-3L / omega;
    LD lo = 0.0L, hi = 0.0L;
    bool airborne = false;
    for (LD tau = 1e-9L; tau < 10.0L; tau = std::min(1.2L * tau, tau + step)) {
      if (h(tau) <= 0.0L) {
        airborne = true;
        lo = tau;
      } else if (airborne) {
        hi = tau;
        break;
      }
    }
    REQUIRE(hi > 0.0L);
    for (int it = 0; it < 200 && hi - lo > 1e-18L; ++it) {
      const LD mid = 0.5L * (lo + hi);
      (h(mid) > 0.0L ? hi : lo) = mid;
    }
    ++out.flights;
    out.flight_time = std::max(out.flight_time, std::abs(seg.t_end - static_cast<double>(t0 + hi)));
  }
  return out;
}

TEST_CASE(
    "simulator: a ball on a vibrating table: impacts obey Newton's law on the relative "
    "velocity and every flight lands at its closed-form time",
    "[simulator][moving-stop][closed-form]") {
  const TableResult r = vibrating_table();
  CHECK(r.impacts > 20);
  CHECK(r.flights > 10);
  CHECK(r.newton <= 1e-14);
  CHECK(r.relative_rate <= 1e-14);
  // Landing times from the engine's own take-off states: flight ≲ 0.1 time units, exact flows,
  // roots to a few ulps; the landing speeds here are ≳ 1e-3 V, so 1e-12 covers the conditioning.
  CHECK(r.flight_time <= 1e-12);
}

// ---------------------------------------------------------------------------------------------
// 7. Zeno guard.

struct ZenoResult {
  RunSummary summary;
  double seconds = 0.0;
  double penetration = 0.0;
  long events = 0;
};

/// The bouncing ball with every chatter resolution off (chatter_height = chatter_velocity = 0)
/// and no resting-contact shortcut (contact_velocity = 0): infinitely many impacts before
/// t* = 2 v0 / (g (1 - r)), which only the event cap can stop. max_events = 20000 keeps the test
/// short (the default 1e5 behaves the same, ~5x slower).
ZenoResult zeno(double r, double contact_velocity, long max_events) {
  const ImpactSystem scene = bouncing_ball(r);
  SimulatorOptions options;
  options.chatter_height = 0.0;
  options.chatter_velocity = 0.0;
  options.contact_velocity = contact_velocity;
  options.max_events = max_events;
  const Run run = simulate(scene, 0.0, vec({0.0}), vec({1.0}), 10.0, options, 2000);
  return {run.summary, run.seconds, run.penetration, static_cast<long>(run.audit.events.size())};
}

TEST_CASE(
    "simulator: Zeno guard: without chatter resolution a bouncing ball ends with the event "
    "cap and a message naming the time and the stop",
    "[simulator][zeno]") {
  const ZenoResult z = zeno(0.7, 0.0, 20000);
  CHECK(z.summary.status == RunStatus::event_cap);
  CHECK(z.events == 20001);
  const std::string& m = z.summary.message;
  INFO(m);
  CHECK(m.find("event cap") != std::string::npos);
  CHECK(m.find("t = ") != std::string::npos);
  CHECK(m.find("stops[0] (lower x0)") != std::string::npos);
  CHECK(m.find(std::to_string(20000)) != std::string::npos);
  // The run stops where it reached the cap, and the message gives that time.
  char t_text[64];
  std::snprintf(t_text, sizeof t_text, "t = %.17g", z.summary.t);
  CHECK(m.find(t_text) != std::string::npos);
  CHECK(z.summary.t < 10.0);
  CHECK(z.summary.t > 2.0 / (kGravity * 0.3) * 0.999);
  // It returns: 2e4 events take ~3 s on a loaded 2-core machine; a hang would not.
  CHECK(z.seconds < 30.0);
}

TEST_CASE(
    "simulator: Zeno run: the bounces accumulate at 2 v0 / (g (1 - r)) without the ball "
    "sinking into the stop",
    "[simulator][zeno]") {
  // Regression: after the 55th impact (rebound 3.0e-9) the next segment started a hair past the
  // floor (rounding) while moving away; the re-armed guard then located each return where the
  // gap reached ε, not 0, so each bounce sank another ε (x = -9.8e-8 after 1e5 events) and the
  // ball bounced on for ever at √(2 g ε / (1 - r²)). Fixed by placing impacting gaps exactly at
  // zero after each impact (simulator.cpp).
  const ZenoResult z = zeno(0.7, 0.0, 20000);
  CHECK(z.penetration <= kPenetration);
  CHECK(z.summary.t <= 2.0 / (kGravity * 0.3) + 1e-9);
}

TEST_CASE(
    "simulator: with chatter resolution off, resting contact (contact_velocity) ends a "
    "bouncing ball's geometric bounces in sticking",
    "[simulator][zeno]") {
  // Rebounds faster than contact_velocity·V = 1e-11·9.81 are resolved one by one (the geometric
  // series to ~1e-10), then the ball rests: completed, stuck, no penetration.
  const ZenoResult z = zeno(0.5, SimulatorOptions{}.contact_velocity, 5000);
  INFO(z.summary.message);
  CHECK(z.summary.status == RunStatus::completed);
  CHECK(z.summary.stuck == ContactSet{0});
  CHECK(z.penetration <= kPenetration);
}

TEST_CASE(
    "simulator: with chatter resolution off, resting contact ends the bounces in sticking "
    "also for r = 0.7",
    "[simulator][zeno]") {
  // Regression: the ratchet above used to start at rebounds ~3e-9, before the rebound fell below
  // contact_velocity·V ≈ 1e-10, so the run ended in the event cap with the ball sunk into the
  // stop instead of resting on it.
  const ZenoResult z = zeno(0.7, SimulatorOptions{}.contact_velocity, 5000);
  INFO(z.summary.message);
  CHECK(z.summary.status == RunStatus::completed);
  CHECK(z.penetration <= kPenetration);
}

// ---------------------------------------------------------------------------------------------
// 8. Lazy contact sets.

struct LazyResult {
  std::size_t built = 0, visited = 0, held_sets = 0;
  std::size_t singletons_only = 0;  ///< sets visited only as the {j} of a chatter check
  bool segments_agree = true;
  long events = 0;
};

LazyResult lazy_sets() {
  const ImpactSystem scene = ten_mass_chain();
  const double t_end = 20.0 * forcing_period(scene);
  const Run run = simulate(scene, 0.0, VectorXd::Zero(10), VectorXd::Zero(10), t_end);
  check_run(run, t_end);
  // Replay the events: the held set S changes by sticks/chatter limits (+) and releases (-); an
  // impact group I needs the restitution data of S ∪ I; every held set is a mode; a chatter
  // check reads the single stop's Delassus entry, so {j} of a chatter limit is built too. The
  // replayed S must be the mode of the segment that follows each group.
  LazyResult out;
  std::set<ContactSet> visited, held, singletons;
  ContactSet S;
  auto add = [](ContactSet s, int j) {
    if (!std::binary_search(s.begin(), s.end(), j))
      s.insert(std::upper_bound(s.begin(), s.end(), j), j);
    return s;
  };
  const std::vector<EventGroup>& groups = run.audit.groups;
  const std::vector<SegmentRecord>& segments = run.audit.segments;
  const std::size_t offset = !groups.empty() && groups.front().initial ? 1 : 0;
  if (offset == 0) {
    visited.insert(S);
    held.insert(S);
    if (segments.front().active != S) out.segments_agree = false;
  }
  for (std::size_t k = 0; k < groups.size(); ++k) {
    const EventGroup& g = groups[k];
    ContactSet impact_set = S;
    bool any_impact = false;
    for (const Event& e : g.events)
      if (e.kind == EventKind::impact) {
        impact_set = add(impact_set, e.stop);
        any_impact = true;
      }
    if (any_impact) visited.insert(impact_set);
    for (const Event& e : g.events) {
      if (e.kind == EventKind::stick || e.kind == EventKind::chatter_limit) S = add(S, e.stop);
      if (e.kind == EventKind::release) S.erase(std::remove(S.begin(), S.end(), e.stop), S.end());
      if (e.kind == EventKind::chatter_limit) singletons.insert(ContactSet{e.stop});
    }
    visited.insert(S);
    held.insert(S);
    const std::size_t next = k + 1 - offset;  // the segment after group k
    if (next < segments.size() && segments[next].active != S) out.segments_agree = false;
  }
  for (const ContactSet& j : singletons) out.singletons_only += visited.insert(j).second ? 1 : 0;
  out.built = run.summary.contact_sets_built;
  out.visited = visited.size();
  out.held_sets = held.size();
  out.events = static_cast<long>(run.audit.events.size());
  CHECK(run.summary.sticking_flows_built == held.size());
  return out;
}

TEST_CASE(
    "simulator: contact sets are built lazily: a 10-mass chain with 20 stops builds only the "
    "sets its events visit",
    "[simulator][lazy]") {
  const LazyResult r = lazy_sets();
  CHECK(r.events > 100);
  CHECK(r.held_sets > 1);       // sticking happened: several modes were integrated
  CHECK(r.segments_agree);      // the events describe the contact set of every segment
  CHECK(r.built == r.visited);  // one set per distinct set visited, none ahead of need
  CHECK(r.built < 1000);        // ≪ 2^20 possible sets
}

TEST_CASE(
    "simulator: a chatter check while another stop is held builds no set the run does not "
    "visit",
    "[simulator][lazy]") {
  // Two uncoupled balls under gravity: ball 0 rests on its floor from t0 (held set {0}), ball 1
  // bounces on its floor and chatters into sticking. The sets visited are {0} (held), {0, 1}
  // (impact sets and, after the chatter, held). Regression: the chatter check once read the
  // Delassus entry of the impacting stop alone through modes_.get({1}), building the never
  // visited set {1}.
  HarmonicForcing f;
  f.constant = VectorXd::Constant(2, -kGravity);
  f.cosine = f.sine = VectorXd::Zero(2);
  const ImpactSystem scene(
      LinearSystem(MatrixXd::Identity(2, 2), MatrixXd::Zero(2, 2), MatrixXd::Zero(2, 2), f),
      {Stop::lower(0, 0.0, 0.7), Stop::lower(1, 0.0, 0.7)});
  const Run run = simulate(scene, 0.0, vec({0.0, 0.0}), vec({0.0, 1.0}), 2.0, {}, 2000);
  check_run(run, 2.0, 2000);
  CHECK(run.summary.chatters == 1);
  CHECK(run.summary.stuck == (ContactSet{0, 1}));
  CHECK(run.summary.sticking_flows_built == 2);
  CHECK(run.summary.contact_sets_built == 2);
}

TEST_CASE(
    "simulator: an impact that leaves a held stop separating releases it at that instant (no "
    "cascade of impacts)",
    "[simulator][contact]") {
  // An 8-mass chain with a stop between masses 6 and 7 and one below mass 7. At t ≈ 2.5437 the
  // stop between them is held when mass 7 hits its lower stop; the impulse law (r = 0 for the
  // held stop) gives the held stop no impulse, since keeping it shut would take a pull: it opens
  // with a normal rate of about -0.17. Before issue 13's stop 21 it stayed in the held set and
  // the residual-velocity step pulled it shut, which sent mass 7 back into its stop: a dozen
  // impacts at one instant, each r × the last, that amplified rounding ~1e4-fold (the dense and
  // modal engines then disagreed by 1e-8, tests/framework/test_modal.cpp). Required: every impact
  // followed by another of the same stop within 1e-9 T (a chatter flight here lasts ≥ 1e-4 T) is
  // absent, and the held stop's release is logged at the impact's own time.
  vibro::models::Chain c;
  c.masses.assign(8, 1.0);
  c.springs.assign(7, 1.0);
  c.dampers.assign(7, 0.03);
  c.left_spring = 1.0;
  c.left_damper = 0.03;
  c.right_spring = 2.0;
  c.right_damper = 0.06;
  c.force_cosine.assign(8, 0.0);
  c.force_sine.assign(8, 0.0);
  c.force_cosine[0] = 0.8;
  c.force_sine[7] = -0.5;
  c.frequency = 0.5;
  const ImpactSystem scene(vibro::models::build_chain(c),
                           {Stop::upper(0, 0.3, 0.0), Stop::lower(7, -0.2, 0.4), Stop::between(6, 7, 0.05, 0.3)});
  const double T = 2.0 * std::numbers::pi / c.frequency;
  Simulator sim(scene);
  vibro::EventLog log;
  const auto s = sim.run(0.0, VectorXd::Zero(8), VectorXd::Zero(8), 5.0 * T, {&log});
  REQUIRE(s.status == vibro::RunStatus::completed);
  long repeats = 0, opened = 0;
  for (std::size_t e = 0; e < log.events.size(); ++e) {
    const Event& a = log.events[e];
    if (a.kind != EventKind::impact) continue;
    for (std::size_t f = e + 1; f < log.events.size() && log.events[f].t - a.t <= 1e-9 * T; ++f) {
      const Event& b = log.events[f];
      if (b.kind == EventKind::impact && b.stop == a.stop) ++repeats;
      if (b.kind == EventKind::release && b.stop == 2 && a.stop == 1 && b.t == a.t) ++opened;
    }
  }
  CHECK(repeats == 0);
  CHECK(opened >= 1);
}

namespace {

/// Raises an interrupt flag at the n-th event (as a signal handler would, mid-run).
class InterruptAt final : public Observer {
 public:
  InterruptAt(std::atomic<bool>& flag, int n) : flag_(flag), n_(n) {}
  void event(const Event& e) override {
    if (++seen_ == n_) flag_.store(true);
    last_t = e.t;
  }
  int seen() const { return seen_; }
  double last_t = 0.0;

 private:
  std::atomic<bool>& flag_;
  int n_, seen_ = 0;
};

}  // namespace

TEST_CASE(
    "simulator: at a coarse chatter threshold the rule moves positions only where a chatter ends, "
    "by less than the threshold",
    "[simulator][chatter]") {
  // The second- and third-order rules add the skipped bounces' mean displacement to x (through
  // the damping: simulator.hpp, ChatterRule); the paper's system is damped, so every chatter limit
  // moves x a little, and nothing else may. check_run bounds the ordinary position jumps by
  // rounding and the chatter ones by chatter_height·L; here they must also be there at all.
  SimulatorOptions o;
  o.chatter_height = 1e-6;
  const ImpactSystem scene = vibro::models::wagg2004();
  const double T = 2.0 * kPi / vibro::models::Wagg2004{}.frequency;
  const Run run = simulate(scene, 0.0, VectorXd::Zero(2), VectorXd::Zero(2), 20.0 * T, o, 2000);
  check_run(run, 20.0 * T, 2000);
  CHECK(run.summary.chatters > 10);
  CHECK(run.audit.chatter_shift > 0.0);
}

TEST_CASE("simulator: a run's result does not depend on what observes it, bit for bit", "[simulator][observers]") {
  // Observers read states through the segment's view; none of it may feed back into the engine.
  // Until issue 13's stop 21 the view's states at a segment's ends went through the cache of
  // exponentials the event search takes its series from (storing τ = 0 there evicted a point
  // the engine's end state could have started its series from), so the same run observed at
  // the segments' ends ended rounded differently.
  const ImpactSystem scene = vibro::models::wagg2004();
  const double t_end = 50.0 * 2.0 * kPi / vibro::models::Wagg2004{}.frequency;
  Simulator bare(scene);
  const RunSummary a = bare.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end);
  std::vector<double> times;
  for (int i = 0; i <= 4000; ++i) times.push_back(t_end * i / 4000.0);
  Samples samples(times);
  vibro::EventLog log;
  vibro::test::EndStates ends;
  Simulator watched(scene);
  const RunSummary b = watched.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, {&samples, &log, &ends});
  REQUIRE(a.status == RunStatus::completed);
  REQUIRE(b.status == RunStatus::completed);
  CHECK(b.impacts == a.impacts);
  CHECK(b.sticks == a.sticks);
  CHECK(b.x == a.x);
  CHECK(b.v == a.v);
}

TEST_CASE("simulator: an interrupt flag ends the run at the next event with status interrupted",
          "[simulator][interrupt]") {
  vibro::models::Wagg2004 p;
  const ImpactSystem scene = vibro::models::wagg2004(p);
  std::atomic<bool> flag{false};
  SimulatorOptions o;
  o.interrupt = &flag;
  Simulator sim(scene, o);
  const double t_end = 50.0 * 2.0 * kPi / p.frequency;
  // Raised before the run: nothing is simulated.
  flag.store(true);
  const RunSummary none = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end);
  CHECK(none.status == RunStatus::interrupted);
  CHECK(none.t == 0.0);
  CHECK(none.segments == 0);
  // Raised at the 10th event: the run stops there, at the state that event left, far from t_end.
  flag.store(false);
  InterruptAt at(flag, 10);
  const RunSummary cut = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, {&at});
  CHECK(cut.status == RunStatus::interrupted);
  CHECK(at.seen() >= 10);
  CHECK(at.seen() <= 12);  // a resolution emits the events of one instant together
  CHECK(cut.t == at.last_t);
  CHECK(cut.t < t_end);
  CHECK(std::string(vibro::to_string(cut.status)) == "interrupted");
  // Without a flag the same run completes.
  Simulator plain(scene);
  CHECK(plain.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end).status == RunStatus::completed);
}

namespace {

/// For every segment of a run: states() at times that hold both ends (the start twice, the end
/// between two interior runs) against state() at each time, bit for bit, through the default
/// SegmentView::states (state() per time); and state() at the requested times by the rule
/// Samples follows (a time in [t_begin, t_end] is taken by the first segment holding it).
class StatesProbe : public Observer {
 public:
  explicit StatesProbe(std::vector<double> times) : times_(std::move(times)) {}
  void segment(const SegmentView& view) override {
    const double a = view.t_begin(), b = view.t_end(), span = b - a;
    const std::vector<double> ts{a, a, a + 0.25 * span, a + 0.5 * span, b, a + 0.75 * span, a + 0.9 * span, b};
    const auto count = static_cast<Eigen::Index>(ts.size());
    const Eigen::Index n = view.dof();
    MatrixXd x(n, count), v(n, count), x_each(n, count), v_each(n, count);
    view.states(ts.data(), count, x, v);
    view.SegmentView::states(ts.data(), count, x_each, v_each);
    mismatches += ((x.array() != x_each.array()) || (v.array() != v_each.array())).count();
    ++segments;
    for (; next_ < times_.size() && times_[next_] <= b; ++next_) {
      const double ts_k = times_[next_];
      if (ts_k < a) continue;
      if (ts_k == a || ts_k == b) ++at_ends;
      VectorXd xk(n), vk(n);
      view.state(ts_k, xk, vk);
      t.push_back(ts_k);
      this->x.push_back(xk);
      this->v.push_back(vk);
    }
  }
  long mismatches = 0, segments = 0, at_ends = 0;
  std::vector<double> t;
  std::vector<VectorXd> x, v;

 private:
  std::vector<double> times_;
  std::size_t next_ = 0;
};

/// Samples over [t0, t_end] at a grid reaching past both ends plus every event time of the run
/// (segment ends, where the engine's own arithmetic is used), against StatesProbe.
void check_samples_against_state(const ImpactSystem& scene, const VectorXd& x0, const VectorXd& v0, double t_end) {
  vibro::EventLog log;
  Simulator(scene).run(0.0, x0, v0, t_end, {&log});
  REQUIRE(log.events.size() >= 5);
  std::vector<double> times;
  for (int i = 0; i <= 400; ++i) times.push_back(-0.5 + (t_end + 1.0) * i / 400.0);
  for (const Event& e : log.events) times.push_back(e.t);
  std::sort(times.begin(), times.end());
  Samples samples(times);
  StatesProbe probe(times);
  Simulator(scene).run(0.0, x0, v0, t_end, {&samples, &probe});
  CHECK(probe.segments > 5);
  CHECK(probe.mismatches == 0);
  // Some requested times fall on segment ends. Not all of them need to: what an observer asks of
  // a segment can change the engine's rounding (state() at the ends goes through the segment's
  // cache of exponentials, which the event search also uses), so the observed run need not
  // repeat the first run's events bit for bit.
  CHECK(probe.at_ends >= 5);
  REQUIRE(samples.t == probe.t);
  REQUIRE(samples.x.cols() == static_cast<Eigen::Index>(probe.t.size()));
  long differ = 0;
  for (std::size_t k = 0; k < probe.t.size(); ++k) {
    const auto col = static_cast<Eigen::Index>(k);
    differ += ((samples.x.col(col).array() != probe.x[k].array()) ||
               (samples.v.col(col).array() != probe.v[k].array())).count();
  }
  CHECK(differ == 0);
}

}  // namespace

TEST_CASE("simulator: a view's states at many times, and Samples, are its state() at each time bit for bit",
          "[simulator][observers]") {
  // DenseSegmentView::states evaluates the times inside a segment in one batched call and the
  // ends by the engine's arithmetic, as state() does; Samples hands it each segment's run of
  // times. Exact equality with state() per time, on flights in closed form and sticking (a
  // bouncing ball that chatters to rest) and on the spectral flows of the paper's system. Fails
  // if an end goes through the batched path (rounded in another order), a run of times is
  // split or shifted, or Samples misplaces a column or a time.
  INFO("bouncing ball");
  check_samples_against_state(bouncing_ball(0.8), vec({1.0}), vec({0.0}), 3.0);
  INFO("wagg2004");
  vibro::models::Wagg2004 p;
  check_samples_against_state(vibro::models::wagg2004(p), VectorXd::Zero(2), VectorXd::Zero(2),
                              20.0 * 2.0 * kPi / p.frequency);
}

// ---------------------------------------------------------------------------------------------
// Report.

TEST_CASE("simulator accuracy report", "[.report]") {
  std::printf(
      "\n1. bouncing ball (relative errors)          t_k        u_k        chatter   impacts "
      "(predicted)\n");
  for (double r : {0.7, 0.5}) {
    const BallResult b = check_bouncing_ball(r);
    std::printf("   r = %.1f                               %9.2e  %9.2e  %9.2e   %ld (%ld)\n", r,
                b.impact_time, b.impact_speed, b.chatter_time, b.impacts, b.predicted_impacts);
  }
  std::printf(
      "\n2. energy balance           residual   impact loss  gain      impacts  seconds  max gap/L\n");
  for (double omega : {0.255, 0.27}) {
    const EnergyResult e = energy_paper(omega);
    std::printf("   paper, Omega = %.3f     %9.2e  %9.2e  %9.2e  %6ld  %6.2f  %9.2e\n", omega,
                e.residual, e.impact_loss, e.gain, e.impacts, e.seconds, e.penetration);
  }
  {
    const EnergyResult e = energy_three_mass();
    std::printf("   3-DOF chain               %9.2e  %9.2e  %9.2e  %6ld  %6.2f  %9.2e\n", e.residual,
                e.impact_loss, e.gain, e.impacts, e.seconds, e.penetration);
    const EnergyResult f = five_mass();
    std::printf("   5-DOF chain               %9.2e  %9.2e  %9.2e  %6ld  %6.2f  %9.2e\n", f.residual,
                f.impact_loss, f.gain, f.impacts, f.seconds, f.penetration);
  }
  for (bool forced : {false, true}) {
    const ConservationResult c = conservation(forced);
    std::printf("   r = 1, C = 0, %s: |dE|/E0 %9.2e, balance %9.2e, %ld impacts\n",
                forced ? "forced  " : "unforced", c.drift, c.balance, c.impacts);
  }
  std::printf("\n3. paper vs RK8 hybrid reference (absolute times)\n");
  for (double omega : {0.255, 0.27}) {
    const PaperComparison p = paper_against_reference(omega);
    const ReferenceComparison& c = p.engine;
    std::printf(
        "   Omega = %.3f: matched %d  impacts %ld (skipped %ld)  dt %9.2e  dv %9.2e | chatter %ld  "
        "dt %9.2e  dt/D^2 %9.2e | releases %ld  dt %9.2e | reference %.2f s, %ld events\n",
        omega, c.matched, c.impacts, c.skipped, c.impact_time, c.impact_speed, c.chatters,
        c.chatter_time, c.chatter_ratio, c.releases, c.release_time, p.seconds, p.reference_events);
    std::printf("      reference h vs h/2: impacts dt %9.2e, releases dt %9.2e, chatter dt %9.2e\n",
                p.reference.impact_time, p.reference.release_time, p.reference.stick_time);
  }
  {
    const auto [coarse, fine] = chatter_convergence();
    std::printf("   chatter limit error, chatter_height 1e-9: %9.2e, 1e-10: %9.2e (10 periods)\n",
                coarse, fine);
  }
  {
    const GrazingResult g = grazing_all();
    std::printf(
        "\n4. grazing: worst |dt| %9.2e (relative %9.2e; tolerance there %9.2e, worst ratio %.2f), "
        "missed %ld, "
        "spurious %ld, state error %9.2e\n",
        g.time_error, g.relative, g.allowed, g.worst_ratio, g.missed, g.spurious, g.state_error);
  }
  {
    const PlasticResult p = plastic_impacts();
    std::printf("\n6. r = 0: %ld impacts (%ld held, %ld separated), rebound %9.2e, energy %9.2e\n",
                p.impacts, p.held, p.separated, p.rebound, p.energy);
    const MirrorResult m = symmetric_clearance();
    std::printf("   symmetric clearance: %ld events, mirrored |dt| %9.2e, energy %9.2e\n", m.events,
                m.time, m.energy);
    const TableResult t = vibrating_table();
    std::printf(
        "   vibrating table: %ld impacts, Newton %9.2e V, relative rate %9.2e V, %ld flights |dt| "
        "%9.2e\n",
        t.impacts, t.newton, t.relative_rate, t.flights, t.flight_time);
  }
  {
    const ZenoResult z = zeno(0.7, 0.0, 20000);
    std::printf("\n7. Zeno: %s after %.2f s, %ld events, t = %.10g, penetration %9.2e L\n   %s\n",
                vibro::to_string(z.summary.status), z.seconds, z.events, z.summary.t, z.penetration,
                z.summary.message.c_str());
    const ZenoResult d = zeno(0.7, 0.0, SimulatorOptions{}.max_events);
    std::printf("   default cap: %s after %.2f s, t = %.10g, penetration %9.2e L\n",
                vibro::to_string(d.summary.status), d.seconds, d.summary.t, d.penetration);
  }
  {
    const LazyResult l = lazy_sets();
    std::printf(
        "\n8. lazy sets: built %zu, visited %zu (of which %zu only as a chatter check's {j}), held "
        "sets %zu, %ld events\n",
        l.built, l.visited, l.singletons_only, l.held_sets, l.events);
  }
  SUCCEED();
}

}  // namespace
