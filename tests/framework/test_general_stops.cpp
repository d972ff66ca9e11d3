// Stops along general normals (Stop::general, Stop::Kind::normal) on the dense engine: the
// shorthands against the same normal written out, a metamorphic test in rotated coordinates,
// a pitch–plunge section with a freeplay stop against an independent long-double reference,
// and the validation of normals.
#include "support/reference_general_stop.hpp"
#include "vibro/modal.hpp"
#include "vibro/simulator.hpp"
#include "vibro/stops.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using vibro::Event;
using vibro::EventKind;
using vibro::ImpactSystem;
using vibro::InvalidInput;
using vibro::LinearSystem;
using vibro::RunStatus;
using vibro::RunSummary;
using vibro::Simulator;
using vibro::SimulatorOptions;
using vibro::Stop;
using Catch::Matchers::Contains;

/// The states at given times, from the exact segments the engine reports.
class TimeSamples final : public vibro::Observer {
 public:
  TimeSamples(std::vector<double> times, Eigen::Index n) : times_(std::move(times)), x(n, times_.size()), v(n, times_.size()) {}
  void segment(const vibro::SegmentView& view) override {
    while (next_ < times_.size() && times_[next_] <= view.t_end()) {
      if (times_[next_] >= view.t_begin())
        view.state(times_[next_], x.col(static_cast<Eigen::Index>(next_)), v.col(static_cast<Eigen::Index>(next_)));
      ++next_;
    }
  }
  std::vector<double> times_;
  MatrixXd x, v;

 private:
  std::size_t next_ = 0;
};

/// The three-mass chain of the metamorphic test: a wall on the left, masses 1, 1.5, 0.8,
/// non-proportional damping, forcing on masses 0 and 2 at Ω = 0.8.
LinearSystem chain_system() {
  MatrixXd M = MatrixXd::Zero(3, 3);
  M.diagonal() << 1.0, 1.5, 0.8;
  MatrixXd K(3, 3);
  K << 3.0, -1.0, 0.0, -1.0, 2.2, -1.2, 0.0, -1.2, 1.2;
  MatrixXd C(3, 3);
  C << 0.06, -0.01, 0.0, -0.01, 0.03, -0.02, 0.0, -0.02, 0.04;
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(3, 0.8);
  f.cosine << 0.9, 0.0, 0.0;
  f.sine << 0.0, 0.0, -0.3;
  return LinearSystem(M, C, K, f);
}

/// A fixed orthogonal Q (QR of a fixed full matrix), det Q = ±1, far from any permutation.
MatrixXd rotation() {
  MatrixXd A(3, 3);
  A << 0.8, -0.3, 0.5, 0.2, 0.9, -0.4, -0.6, 0.1, 0.7;
  Eigen::HouseholderQR<MatrixXd> qr(A);
  return qr.householderQ() * MatrixXd::Identity(3, 3);
}

MatrixXd symmetric(const MatrixXd& a) { return 0.5 * (a + a.transpose()); }

struct Run {
  RunSummary summary;
  vibro::EventLog log;
};

Run run(const ImpactSystem& scene, const VectorXd& x0, const VectorXd& v0, double t_end, TimeSamples* samples,
        double length_scale) {
  SimulatorOptions o;
  o.length_scale = length_scale;  // the same tolerances in both frames (L is not rotation-invariant)
  Simulator sim(scene, o);
  Run r;
  std::vector<vibro::Observer*> obs{&r.log};
  if (samples) obs.push_back(samples);
  r.summary = sim.run(0.0, x0, v0, t_end, obs);
  return r;
}

/// The system in the coordinates y = Qx: M' = QMQᵀ, C' = QCQᵀ, K' = QKQᵀ, every force term Q f
/// (the harmonics' too), and each stop wᵀx ≤ s as the general stop (Qw)ᵀy ≤ s, with its law.
ImpactSystem rotated(const LinearSystem& sys, const std::vector<Stop>& stops, const MatrixXd& Q) {
  vibro::HarmonicForcing f = sys.forcing();
  f.constant = Q * f.constant;
  f.cosine = Q * f.cosine;
  f.sine = Q * f.sine;
  for (vibro::ForcingHarmonic& h : f.harmonics) {
    h.cosine = Q * h.cosine;
    h.sine = Q * h.sine;
  }
  const LinearSystem turned(symmetric(Q * sys.mass() * Q.transpose()), symmetric(Q * sys.damping() * Q.transpose()),
                            symmetric(Q * sys.stiffness() * Q.transpose()), f);
  std::vector<Stop> general;
  for (const Stop& s : stops) {
    Stop g = Stop::general(Q * s.normal(sys.dof()), s.s0(), s.restitution);
    if (s.is_compliant()) g = g.compliant(s.stiffness, s.damping, s.preload);
    general.push_back(g);
  }
  return ImpactSystem(turned, general);
}

/// The largest differences between a run and its rotated twin mapped back (x = Qᵀy): event
/// times (the event sequences must agree), and the states at the sampled times and the end.
struct Differences {
  double t = 0.0, x = 0.0, v = 0.0;
};
Differences differences(const Run& a, const Run& b, const TimeSamples& sa, const TimeSamples& sb, const MatrixXd& Q) {
  Differences d;
  REQUIRE(a.log.events.size() == b.log.events.size());
  for (std::size_t e = 0; e < a.log.events.size(); ++e) {
    CHECK(a.log.events[e].kind == b.log.events[e].kind);
    CHECK(a.log.events[e].stop == b.log.events[e].stop);
    d.t = std::max(d.t, std::abs(a.log.events[e].t - b.log.events[e].t));
  }
  for (Eigen::Index c = 0; c < sa.x.cols(); ++c) {
    d.x = std::max(d.x, (Q.transpose() * sb.x.col(c) - sa.x.col(c)).cwiseAbs().maxCoeff());
    d.v = std::max(d.v, (Q.transpose() * sb.v.col(c) - sa.v.col(c)).cwiseAbs().maxCoeff());
  }
  d.x = std::max(d.x, (Q.transpose() * b.summary.x - a.summary.x).cwiseAbs().maxCoeff());
  return d;
}

}  // namespace

TEST_CASE("a general stop along ±e_i or e_i − e_k runs bit for bit as its shorthand", "[general-stops]") {
  const LinearSystem sys = chain_system();
  const ImpactSystem sparse(sys, {Stop::lower(0, -0.3, 0.6), Stop::between(1, 2, 0.2, 0.0), Stop::upper(2, 0.5, 0.8)});
  const ImpactSystem dense(sys, {Stop::general(-VectorXd::Unit(3, 0), 0.3, 0.6),
                                 Stop::general(VectorXd::Unit(3, 1) - VectorXd::Unit(3, 2), 0.2, 0.0),
                                 Stop::general(VectorXd::Unit(3, 2), 0.5, 0.8)});
  CHECK(dense.normals() == sparse.normals());
  const double T = 2.0 * std::numbers::pi / 0.8;
  const Run a = run(sparse, VectorXd::Zero(3), VectorXd::Zero(3), 30.0 * T, nullptr, 0.0);
  const Run b = run(dense, VectorXd::Zero(3), VectorXd::Zero(3), 30.0 * T, nullptr, 0.0);
  REQUIRE(a.summary.status == RunStatus::completed);
  REQUIRE(b.summary.status == RunStatus::completed);
  CHECK(a.summary.impacts > 10);
  CHECK(a.summary.sticks > 0);
  REQUIRE(a.log.events.size() == b.log.events.size());
  for (std::size_t e = 0; e < a.log.events.size(); ++e) {
    CHECK(a.log.events[e].t == b.log.events[e].t);
    CHECK(a.log.events[e].stop == b.log.events[e].stop);
    CHECK(a.log.events[e].kind == b.log.events[e].kind);
  }
  CHECK(a.summary.x == b.summary.x);
  CHECK(a.summary.v == b.summary.v);
}

// Metamorphic: in coordinates y = Q x (Q orthogonal) the system is M' = QMQᵀ, C' = QCQᵀ,
// K' = QKQᵀ, f' = Q f, and a stop wᵀx ≤ s becomes (Q w)ᵀ y ≤ s, a general stop. The motion mapped
// back, Qᵀ y(t), must be x(t): impacts, chatter, sticking and releases alike. The two runs differ
// only by rounding (the rotated matrices are rounded, the flows are computed from different
// eigen-decompositions, the event searches see different rounding), which a non-chaotic orbit
// keeps at the level of the event location, 1e-13·L (SimulatorOptions::trigger); 1e-12·L
// leaves a factor 10 for the accumulation over the run.
TEST_CASE("a chain in rotated coordinates moves as the chain itself (metamorphic)", "[general-stops]") {
  const LinearSystem sys = chain_system();
  const std::vector<Stop> stops{Stop::lower(0, -0.3, 0.6), Stop::between(1, 2, 0.2, 0.0)};
  const ImpactSystem plain(sys, stops);
  const MatrixXd Q = rotation();
  REQUIRE((Q * Q.transpose() - MatrixXd::Identity(3, 3)).norm() < 1e-15);
  const ImpactSystem turned = rotated(sys, stops, Q);

  const double T = 2.0 * std::numbers::pi / 0.8;
  const double periods = 100.0;
  std::vector<double> times;
  for (int i = 1; i <= 100 * 50; ++i) times.push_back(T * i / 50.0);
  const VectorXd x0 = (VectorXd(3) << 0.1, -0.05, 0.0).finished();
  const VectorXd v0 = (VectorXd(3) << 0.0, 0.2, -0.1).finished();
  const double L = 0.3;
  TimeSamples sa(times, 3), sb(times, 3);
  const Run a = run(plain, x0, v0, periods * T, &sa, L);
  const Run b = run(turned, Q * x0, Q * v0, periods * T, &sb, L);
  REQUIRE(a.summary.status == RunStatus::completed);
  REQUIRE(b.summary.status == RunStatus::completed);
  // The orbit the test claims to cover: impacts on both stops, and sticking.
  CHECK(a.summary.impacts > 20);
  CHECK(a.summary.sticks + a.summary.chatters > 0);
  CHECK(a.summary.releases > 0);
  bool hit[2] = {false, false};
  for (const Event& e : a.log.events)
    if (e.kind == EventKind::impact) hit[e.stop] = true;
  CHECK(hit[0]);
  CHECK(hit[1]);

  const auto [dt, dx, dv] = differences(a, b, sa, sb, Q);
  WARN("metamorphic: " << a.log.events.size() << " events (" << a.summary.impacts << " impacts, " << a.summary.sticks
                       << " sticks, " << a.summary.chatters << " chatter limits, " << a.summary.releases
                       << " releases), max |Δt| = " << dt << " (T = " << T
                       << "), max |Δx|/L = " << dx / L << ", max |Δv|/(LΩ) = " << dv / (L * 0.8));
  CHECK(dx <= 1e-12 * L);
  CHECK(dv <= 1e-12 * L * 0.8);
  CHECK(dt <= 1e-12 * T);
}

// The three features together, in both frames: a compliant stop with a dashpot (its engage and
// disengage switches), a rigid stop, and a drive with a 2nd and a 3rd harmonic; rotated, the
// stops are general normals (the compliant one too) and the harmonics' amplitudes turn with f.
// The tolerance is the one above, for the same reason; velocities are measured against the
// fastest motion of the scene, L·ω_s with ω_s = √(k_s / m_min) ≈ 7.1 the engaged spring's
// frequency (8.8 Ω): while it is engaged the motion oscillates at ω_s, so a rounding-level
// difference δx of the state comes with δv ≈ ω_s·δx, not Ω·δx.
TEST_CASE("a compliant stop, a rigid stop and a three-harmonic drive in rotated coordinates (metamorphic)",
          "[general-stops][compliant][harmonics]") {
  LinearSystem base = chain_system();
  vibro::HarmonicForcing f = base.forcing();
  f.harmonics.push_back({2, (VectorXd(3) << 0.0, 0.4, 0.0).finished(), (VectorXd(3) << 0.1, 0.0, 0.0).finished()});
  f.harmonics.push_back({3, (VectorXd(3) << 0.0, 0.0, 0.25).finished(), VectorXd::Zero(3)});
  const LinearSystem sys(base.mass(), base.damping(), base.stiffness(), f);
  const std::vector<Stop> stops{Stop::lower(0, -0.3, 0.6), Stop::upper(2, 0.25, 1.0).compliant(40.0, 0.3, 0.05)};
  const ImpactSystem plain(sys, stops);
  const MatrixXd Q = rotation();
  const ImpactSystem turned = rotated(sys, stops, Q);

  const double T = 2.0 * std::numbers::pi / 0.8;
  const double periods = 60.0;
  std::vector<double> times;
  for (int i = 1; i <= 60 * 40; ++i) times.push_back(T * i / 40.0);
  const VectorXd x0 = (VectorXd(3) << 0.1, -0.05, 0.0).finished();
  const VectorXd v0 = (VectorXd(3) << 0.0, 0.2, -0.1).finished();
  const double L = 0.3;
  TimeSamples sa(times, 3), sb(times, 3);
  const Run a = run(plain, x0, v0, periods * T, &sa, L);
  const Run b = run(turned, Q * x0, Q * v0, periods * T, &sb, L);
  REQUIRE(a.summary.status == RunStatus::completed);
  REQUIRE(b.summary.status == RunStatus::completed);
  int impacts = 0, engages = 0;
  for (const Event& e : a.log.events) {
    impacts += e.kind == EventKind::impact;
    engages += e.kind == EventKind::engage;
  }
  CHECK(impacts > 10);  // the orbit covers both laws
  CHECK(engages > 10);

  const auto [dt, dx, dv] = differences(a, b, sa, sb, Q);
  WARN("metamorphic, compliant + rigid + 3 harmonics: " << a.log.events.size() << " events (" << impacts
                                                         << " impacts, " << engages << " engagements), max |Δt| = " << dt
                                                         << ", max |Δx|/L = " << dx / L << ", max |Δv|/(LΩ) = "
                                                         << dv / (L * 0.8) << ", max |Δv|/(Lω_s) = "
                                                         << dv / (L * std::sqrt(40.0 / 0.8)));
  const double omega_s = std::sqrt(40.0 / 0.8);
  CHECK(dx <= 1e-12 * L);
  CHECK(dv <= 1e-12 * L * omega_s);
  CHECK(dt <= 1e-12 * T);
}

// A pitch–plunge aerofoil section (plunge h, pitch α about the elastic axis): mass m, static
// moment S = m x_α b, inertia I_α, springs k_h, k_α, small viscous damping, a harmonic lift and
// moment, and a freeplay stop at a point a distance l aft: h + l α ≤ p (a general normal
// [1, l] with a coupled mass matrix, so the impulse M⁻¹n moves both h and α).
TEST_CASE("a pitch–plunge section with a freeplay stop at the tip matches a long-double reference", "[general-stops]") {
  MatrixXd M(2, 2), C(2, 2), K(2, 2);
  M << 1.0, 0.25, 0.25, 0.5;  // m, S; S, I_α
  K << 1.0, 0.0, 0.0, 2.5;    // k_h, k_α
  C << 0.02, 0.0, 0.0, 0.03;
  vibro::HarmonicForcing f = vibro::HarmonicForcing::zero(2, 1.1);
  f.cosine << 0.35, 0.1;
  const LinearSystem sys(M, C, K, f);
  const double l = 0.6, p = 0.2, r = 0.75;
  const VectorXd n = (VectorXd(2) << 1.0, l).finished();
  const ImpactSystem scene(sys, {Stop::general(n, p, r)});
  const double T = 2.0 * std::numbers::pi / 1.1, t_end = 25.0 * T;

  Simulator sim(scene);
  vibro::EventLog log;
  const RunSummary s = sim.run(0.0, VectorXd::Zero(2), VectorXd::Zero(2), t_end, {&log});
  REQUIRE(s.status == RunStatus::completed);
  REQUIRE(s.sticks == 0);
  REQUIRE(s.chatters == 0);

  vibro::test::ReferenceGeneralStop ref(sys, n, p, r);
  ref.run(0.0L, vibro::test::VectorL::Zero(2), vibro::test::VectorL::Zero(2), static_cast<long double>(t_end));
  // The reference's own error: the same run with half the step.
  vibro::test::ReferenceGeneralStop fine(sys, n, p, r, vibro::test::ReferenceIntegrator::default_step_rate / 2);
  fine.run(0.0L, vibro::test::VectorL::Zero(2), vibro::test::VectorL::Zero(2), static_cast<long double>(t_end));
  REQUIRE(fine.impacts.size() == ref.impacts.size());
  long double ref_dt = 0.0L;
  for (std::size_t i = 0; i < ref.impacts.size(); ++i) ref_dt = std::max(ref_dt, std::fabs(fine.impacts[i].t - ref.impacts[i].t));
  const double ref_dx = static_cast<double>((fine.x - ref.x).cwiseAbs().maxCoeff());
  std::vector<Event> impacts;
  for (const Event& e : log.events)
    if (e.kind == EventKind::impact) impacts.push_back(e);
  CHECK(impacts.size() >= 20);
  REQUIRE(impacts.size() == ref.impacts.size());
  double dt = 0.0, du = 0.0, dt_first = 0.0;
  for (std::size_t i = 0; i < impacts.size(); ++i) {
    dt = std::max(dt, std::abs(impacts[i].t - static_cast<double>(ref.impacts[i].t)));
    if (i < 10) dt_first = std::max(dt_first, std::abs(impacts[i].t - static_cast<double>(ref.impacts[i].t)));
    du = std::max(du, std::abs(impacts[i].v_before - static_cast<double>(ref.impacts[i].u_before)));
  }
  const double dx = (s.x - ref.x.cast<double>()).cwiseAbs().maxCoeff();
  const double dv = (s.v - ref.v.cast<double>()).cwiseAbs().maxCoeff();
  WARN("pitch-plunge: " << impacts.size() << " impacts, max |Δt| = " << dt << " (first ten: " << dt_first << "), max |Δu| = " << du
                        << ", |Δx| = " << dx << ", |Δv| = " << dv << "; reference at half the step: max |Δt| = "
                        << static_cast<double>(ref_dt) << ", |Δx| = " << ref_dx);
  // Measured: the first impacts agree to ~1e-15 (the rounding of t), then the difference
  // grows by the orbit's sensitivity, by ~1.3 per impact with alternating sign (the reference
  // at half its step shows the same growth from its own ~1e-15 start), to ~3e-11 at the 29th.
  // So: 1e-13·T over the first ten impacts (the event location's 1e-13·L, times a rate of
  // order one), 1e-10·T over the run (room for the growth, while a wrong impact law would move
  // the orbit by O(1)).
  CHECK(static_cast<double>(ref_dt) <= 1e-10 * T);
  CHECK(dt_first <= 1e-13 * T);
  CHECK(dt <= 1e-10 * T);
  CHECK(du <= 1e-10);
  CHECK(dx <= 1e-10);
  CHECK(dv <= 1e-10);
  // Newton's law along n in the metric of M: the rebound nᵀv⁺ = −r nᵀv⁻.
  for (const Event& e : impacts) CHECK(std::abs(e.v_after + r * e.v_before) <= 1e-12 * std::abs(e.v_before));
}

TEST_CASE("general normals are validated and named", "[general-stops]") {
  const LinearSystem sys = chain_system();
  auto error = [&](std::vector<Stop> stops) {
    try {
      const ImpactSystem s(sys, std::move(stops));
    } catch (const InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  CHECK_THAT(error({Stop::general(VectorXd::Ones(2), 0.1, 0.5)}),
             Contains("stops[0] (normal 1·x0 + 1·x1): normal has 2 entries: expected one per degree of freedom, 3"));
  CHECK_THAT(error({Stop::upper(0, 0.1, 0.5), Stop::general(VectorXd::Zero(3), 0.1, 0.5)}),
             Contains("stops[1] (normal): normal is zero"));
  VectorXd bad = VectorXd::Ones(3);
  bad(2) = std::nan("");
  CHECK_THAT(error({Stop::general(bad, 0.1, 0.5)}), Contains("normal[2] is nan: must be finite"));
  bad(2) = INFINITY;
  CHECK_THAT(error({Stop::general(bad, 0.1, 0.5)}), Contains("normal[2] is inf: must be finite"));
  // The same constraint twice: parallel normals, same side, whatever the scale.
  const VectorXd w = (VectorXd(3) << 1.0, -2.0, 0.5).finished();
  CHECK_THAT(error({Stop::general(w, 0.1, 0.5), Stop::general(3.0 * w, 0.3, 0.5)}),
             Contains("stops[1] (normal 3·x0 - 6·x1 + 1.5·x2): duplicates stops[0]"));
  CHECK_THAT(error({Stop::upper(1, 0.1, 0.5), Stop::general(2.0 * VectorXd::Unit(3, 1), 0.3, 0.5)}),
             Contains("duplicates stops[0] (upper x1)"));
  // Opposing normals: wᵀx ≤ 0.1 and −2wᵀx ≤ 0.1 (wᵀx ≥ −0.05) leave room; ≤ −0.3 does not.
  CHECK(error({Stop::general(w, 0.1, 0.5), Stop::general(-2.0 * w, 0.1, 0.5)}) == "accepted");
  CHECK_THAT(error({Stop::general(w, 0.1, 0.5), Stop::general(-2.0 * w, -0.3, 0.5)}),
             Contains("leave no room between them"));
  // The clearance includes the motion of moving stops (along the unit normal).
  CHECK_THAT(error({Stop::general(w, 0.1, 0.5), Stop::general(-2.0 * w, 0.1, 0.5).moving(0.4, 0.0)}),
             Contains("leave no room between them"));
  CHECK_THAT(error({Stop::lower(0, -0.1, 0.5), Stop::general(VectorXd::Unit(3, 0), -0.2, 0.5)}),
             Contains("stops[0] (lower x0) and stops[1] (normal 1·x0) leave no room"));
  // Non-parallel normals never conflict; gaps and admissibility use nᵀx.
  const ImpactSystem ok(sys, {Stop::general(w, 0.1, 0.5), Stop::upper(0, 0.2, 0.5)});
  const VectorXd x = (VectorXd(3) << 0.1, 0.2, 0.3).finished();
  CHECK(ok.gaps(0.0, x)(0) == w.dot(x) - 0.1);
  CHECK(vibro::stop_gap(ok.stops()[0], 0.8, 0.0, x) == w.dot(x) - 0.1);
  CHECK_THROWS_WITH(ok.check_admissible(0.0, -0.5 * VectorXd::Unit(3, 1), 1e-12),
                    Contains("initial state violates stops[0] (normal 1·x0 - 2·x1 + 0.5·x2) by 0.9"));
}

