#include "vibro/taylor_simulator.hpp"

#include "engaged_system.hpp"
#include "event_loop.hpp"

#include "vibro/taylor/guard_roots.hpp"
#include "vibro/taylor/harmonic_series.hpp"
#include "vibro/taylor/horner.hpp"
#include "vibro/taylor/taylor_step.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace vibro {
namespace {

using taylor::horner_compensated;
using taylor::harmonic_series;
using taylor::harmonic_tail;

double horner(const double* a, int p, double tau) {
  double s = a[p];
  for (int k = p - 1; k >= 0; --k) s = s * tau + a[k];
  return s;
}
double horner_slope(const double* a, int p, double tau) {
  double s = p * a[p];
  for (int k = p - 1; k >= 1; --k) s = s * tau + k * a[k];
  return s;
}

/// One harmonic of a stop's motion in the canonical offset s_j(t) (stops.hpp): c cos wt + s sin wt.
struct MotionHarmonic {
  double rate, cosine, sine;
};

/// The stops' tables (per run): normals W, M⁻¹W, G = WᵀM⁻¹W, the stops' motion, and the
/// chatter rule's coefficients of the linear part (as the dense engine's, simulator.cpp).
struct TaylorTables {
  Eigen::MatrixXd normals, minv_normals, delassus, damped_normals, stiff_normals, minv_damping;
  Eigen::VectorXd s0, sc, ss, alpha, beta;
  std::vector<std::vector<MotionHarmonic>> higher;  ///< per stop: its harmonics of order ≥ 2
  std::vector<std::vector<std::pair<Eigen::Index, double>>> entries;  ///< per stop: w's nonzero (l, w_l)

  explicit TaylorTables(const ImpactSystem& scene) {
    const LinearSystem& sys = scene.system();
    const auto m = static_cast<Eigen::Index>(scene.stop_count());
    const Eigen::Index n = sys.dof();
    const Eigen::LLT<Eigen::MatrixXd> llt(sys.mass());
    normals = scene.normals();
    minv_normals = m > 0 ? Eigen::MatrixXd(llt.solve(normals)) : Eigen::MatrixXd(n, 0);
    const Eigen::MatrixXd g = m > 0 ? Eigen::MatrixXd(normals.transpose() * minv_normals) : Eigen::MatrixXd(0, 0);
    delassus = 0.5 * (g + g.transpose());
    minv_damping = llt.solve(sys.damping());
    damped_normals = m > 0 ? Eigen::MatrixXd(minv_damping * minv_normals) : Eigen::MatrixXd(n, 0);
    stiff_normals = m > 0 ? Eigen::MatrixXd(llt.solve(sys.stiffness() * minv_normals)) : Eigen::MatrixXd(n, 0);
    s0.resize(m);
    sc.resize(m);
    ss.resize(m);
    alpha.resize(m);
    beta.resize(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
      s0(j) = st.s0();
      sc(j) = st.s_cos();
      ss(j) = st.s_sin();
      entries.emplace_back();
      for (Eigen::Index l = 0; l < normals.rows(); ++l)
        if (normals(l, j) != 0.0) entries.back().emplace_back(l, normals(l, j));
      higher.emplace_back();
      for (std::size_t h = 0; h < st.harmonics.size(); ++h)
        higher.back().push_back({st.harmonics[h].rate(sys.forcing().frequency), st.h_cos(h), st.h_sin(h)});
      const auto q = minv_normals.col(j);
      const double G = delassus(j, j), qcq = q.dot(sys.damping() * q);
      alpha(j) = -qcq / G;
      beta(j) = (q.dot(sys.damping() * damped_normals.col(j)) - q.dot(sys.stiffness() * q)) / G - (qcq / G) * (qcq / G);
    }
  }
};

/// A held set's constant matrices (StepTerms): W, M⁻¹W and G⁻¹ of its stops.
struct HeldSet {
  ContactSet key;
  Eigen::MatrixXd normals, minv_normals, delassus_inverse;
  Eigen::MatrixXd stop_acceleration, probe_stop_acceleration;  // p̈'s series (k × (p + 1)): the run's, an event's
};

/// An engaged set of compliant stops (stops.hpp): the linear part and the drive with their springs,
/// dashpots, motion and preloads in force (engaged_system.hpp), for StepTerms.
struct EngagedSet {
  ContactSet key;
  Eigen::MatrixXd position, velocity;  // A_x = −M⁻¹K_E, A_v = −M⁻¹C_E
  HarmonicForcing forcing;             // f_E
  Eigen::MatrixXd drive;               // M⁻¹ times f_E's parts (drive_matrix)
};

/// M⁻¹ times the parts of a drive, by columns: the constant, cosine and sine parts, then each
/// harmonic's cosine and sine (the Taylor engine's time_series).
Eigen::MatrixXd drive_matrix(const Eigen::MatrixXd& minv, const HarmonicForcing& f) {
  Eigen::MatrixXd drive(minv.rows(), 3 + 2 * static_cast<Eigen::Index>(f.harmonics.size()));
  drive.col(0) = minv * f.constant;
  drive.col(1) = minv * f.cosine;
  drive.col(2) = minv * f.sine;
  for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
    drive.col(3 + 2 * static_cast<Eigen::Index>(h)) = minv * f.harmonics[h].cosine;
    drive.col(4 + 2 * static_cast<Eigen::Index>(h)) = minv * f.harmonics[h].sine;
  }
  return drive;
}

/// One Taylor step of a segment, kept for the observers, the event's root and the state.
struct StepRecord {
  double offset = 0.0, length = 0.0, t = 0.0;  // from the segment's start; its length; t0 + offset
  std::vector<double> z, lambda;               // 2n × (p + 1), k × (p + 1)
};

}  // namespace

TaylorSimulator::TaylorSimulator(const ImpactSystem& scene, const NonlinearForces& forces, SimulatorOptions options)
    : scene_(&scene), options_(options), tolerance_(forces.tolerance), order_(forces.order) {
  options_.validate();
  taylor::TaylorSettings{.tolerance = tolerance_, .order = order_}.validate();
  const LinearSystem& sys = scene.system();
  taylor::TaylorSystemSpec spec;
  spec.mass = sys.mass();
  spec.damping = sys.damping();
  spec.stiffness = sys.stiffness();
  spec.frequency = sys.forcing().frequency;
  spec.parameters = forces.parameters;
  spec.forces = forces.forces;
  system_ = std::make_unique<taylor::TaylorSystem>(spec);
}

TaylorSimulator::~TaylorSimulator() = default;

/// The Taylor engine's side of the event loop (event_loop.hpp) and of event resolution
/// (ContactAlgebra).
class TaylorSimulator::Loop final : public detail::ContactAlgebra, public TaylorSimulator::LoopAccess {
 public:
  Loop(TaylorSimulator& sim, const std::vector<Observer*>& observers, RunSummary& summary)
      : sim_(sim), scene_(*sim.scene_), sys_(scene_.system()), observers_(observers), summary_(summary),
        step_(*sim.system_, {.tolerance = sim.tolerance_, .order = sim.order_}),
        probe_(*sim.system_, {.tolerance = sim.tolerance_, .order = sim.order_}),
        roots_(step_.order()), p_(step_.order()), n_(sys_.dof()), tab_(scene_) {
    const auto m = static_cast<Eigen::Index>(scene_.stop_count());
    forcing_.setZero(n_, p_ + 1);
    drive_ = drive_matrix(sim.system_->inverse_mass(), sys_.forcing());  // time_series
    probe_forcing_.setZero(n_, p_ + 1);
    cos_.resize(static_cast<std::size_t>(p_) + 3);
    sin_.resize(static_cast<std::size_t>(p_) + 3);
    stop_pos_.resize(static_cast<std::size_t>(p_) + 3);
    harmonic_cos_.resize(static_cast<std::size_t>(p_) + 3);
    harmonic_sin_.resize(static_cast<std::size_t>(p_) + 3);
    // The stops' motion caps the step (motion_cap): stop j's series cut after order p leaves out
    // at most Σ_h A_h (w_h h)^{p+1} / ((p+1)! (1 − w_h h/(p+2))) (harmonic_tail), which stays
    // below ε S when E_j h^{p+1} / (p+1)! ≤ ε S / 2, E_j = Σ_h A_h w_h^{p+1}, and w_h h ≤ (p+2)/2.
    double factorial = 1.0;
    for (int k = 2; k <= p_ + 1; ++k) factorial *= k;
    for (Eigen::Index j = 0; j < m; ++j) {
      double e = 0.0;
      auto add = [&](double amplitude, double w) {
        if (amplitude == 0.0 || w == 0.0) return;
        e += amplitude * std::pow(std::abs(w), p_ + 1);
        motion_rate_ = std::max(motion_rate_, std::abs(w));
      };
      add(std::hypot(tab_.sc(j), tab_.ss(j)), frequency());
      for (const MotionHarmonic& h : tab_.higher[static_cast<std::size_t>(j)]) add(std::hypot(h.cosine, h.sine), h.rate);
      if (e > 0.0) motion_cap_ = std::min(motion_cap_, std::pow(factorial / (2.0 * e), 1.0 / (p_ + 1)));
    }
    guard_.resize(static_cast<std::size_t>(p_) + 1);
    z_.resize(2 * n_);
    rate_.resize(2 * n_);
    residual_.resize(n_);
    q_.resize(m);
    G_.resize(m, m);
    lcp_.reserve(m);
  }

  // ---- the frame's engine interface (event_loop.hpp) ----
  Eigen::Index dof() const override { return n_; }
  const std::vector<Stop>& stops() const { return scene_.stops(); }
  double frequency() const { return sys_.forcing().frequency; }
  detail::ScaleInputs scale_inputs() const {
    const HarmonicForcing& f = sys_.forcing();
    double omega = f.frequency;
    if (omega == 0.0) {
      Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys_.stiffness(), sys_.mass(), Eigen::EigenvaluesOnly);
      omega = std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
    }
    detail::ScaleInputs in{omega, sys_.stiffness().cwiseAbs().maxCoeff(), sys_.mass().cwiseAbs().maxCoeff(),
                           f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff()};
    for (const ForcingHarmonic& h : f.harmonics) in.fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
    return in;
  }
  void check_scene(const detail::RunScales& /*sc*/, std::vector<std::string>& /*warnings*/) const {}
  void start(const detail::RunScales& sc, detail::RunState& st) {
    eps_gap_ = sc.eps_gap;
    eps_force_ = sc.eps_force;
    rules_ = sc.rules;
    scale_T_ = sc.T;
    sim_.steps_ = 0;
    work_.reserve(static_cast<Eigen::Index>(scene_.stop_count()), n_);
    emit_ = [this](const Event& e) {
      for (Observer* o : observers_) o->event(e);
    };
    // Compliant stops (stops.hpp): those penetrated at t0 start engaged (CompliantStopLaw), as
    // on the dense engine.
    compliant_ = has_compliant(scene_.stops());
    engaged_.clear();
    engaged_set_ = nullptr;
    if (compliant_) {
      const auto m = static_cast<std::size_t>(scene_.stop_count());
      for (ContactSet* set : {&engaged_, &rigid_impacts_, &rigid_releases_}) set->reserve(m);
      rates_.resize(static_cast<Eigen::Index>(m));
      const Eigen::VectorXd g = scene_.gaps(st.t, st.x);
      for (std::size_t j = 0; j < m; ++j)
        if (scene_.stops()[j].is_compliant() && CompliantStopLaw::engaged_at_start(g(static_cast<Eigen::Index>(j))))
          engaged_.push_back(static_cast<int>(j));
      if (!engaged_.empty()) engaged_set_ = &engaged_set(engaged_);
    }
    // The initial state's forces must be finite (an expression may be singular there).
    z_ << st.x, st.v;
    rate_at(st.t, z_, rate_);
  }
  void initial_guards(const detail::RunState& st, Eigen::VectorXd& g, Eigen::VectorXd& gd) const {
    g = scene_.gaps(st.t, st.x);
    gd = scene_.gap_rates(st.t, st.v);
  }
  bool resolve(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, const ContactSet& resting,
               std::string* /*why*/) {
    std::string unused;
    detail::resolve_event(*this, scene_.stops(), rules_, st.t, st.x, st.v, st.stuck, impacts, releases, resting, emit_,
                          summary_, &unused, work_);
    return true;
  }
  /// Compliant stops' switches first (the state unchanged, the engaged set changes:
  /// compliant_switches, as the dense engine), then the rigid stops' impacts and releases with
  /// the new engaged set's forces acting; held rigid stops are settled again after a switch.
  bool event(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, std::string* why) {
    if (!compliant_) return resolve(st, impacts, releases, {}, why);
    const bool switched = detail::compliant_switches(*this, scene_.stops(), st.t, st.x, st.v, impacts, releases,
                                                     engaged_, rigid_impacts_, rigid_releases_, rates_, emit_);
    if (switched) engaged_set_ = engaged_.empty() ? nullptr : &engaged_set(engaged_);
    if (rigid_impacts_.empty() && rigid_releases_.empty() && !(switched && !st.stuck.empty())) return true;
    return resolve(st, rigid_impacts_, rigid_releases_, {}, why);
  }
  double stiffness(const detail::RunState& /*st*/, double /*T*/) const { return 0.0; }

  detail::SegmentPlan begin_segment(const detail::RunState& st, double t_end) {
    held_ = st.stuck.empty() ? nullptr : &held_set(st.stuck);
    seg_t_ = st.t;
    cursor_ = 0.0;
    used_ = 0;
    z_ << st.x, st.v;
    // Rows: the gap of every stop neither held nor engaged, then −λ of every held one, then −g
    // of every engaged compliant one (the dense engine's order, contact.hpp).
    row_stop_.clear();
    for (int j = 0; j < static_cast<int>(scene_.stop_count()); ++j)
      if (!std::binary_search(st.stuck.begin(), st.stuck.end(), j) &&
          !std::binary_search(engaged_.begin(), engaged_.end(), j))
        row_stop_.push_back(j);
    opening_rows_ = static_cast<Eigen::Index>(row_stop_.size());
    for (int j : st.stuck) row_stop_.push_back(j);
    engaged_rows_from_ = static_cast<Eigen::Index>(row_stop_.size());
    for (int j : engaged_) row_stop_.push_back(j);
    const auto rows = static_cast<Eigen::Index>(row_stop_.size());
    triggers_.resize(rows);
    for (Eigen::Index i = 0; i < rows; ++i) triggers_(i) = is_gap_row(i) ? eps_gap_ : eps_force_;
    armed_ = false;
    h_.resize(rows);
    d_.resize(rows);
    step_.set_terms(terms(&forcing_, held_, held_ ? &held_->stop_acceleration : nullptr));
    const double reach = t_end - st.t;
    reach_ = reach;
    return {std::max(scale_T_, 1e-300), reach};
  }

  bool search(double /*a*/, double b, Crossing* hit) {
    while (cursor_ < b) {
      StepRecord& r = next_record();
      r.offset = cursor_;
      r.t = seg_t_ + cursor_;
      time_series(r.t, forcing_, held_ ? &held_->stop_acceleration : nullptr, held_);
      const taylor::StepStatus status = step_.expand(r.t, z_);
      if (status != taylor::StepStatus::ok) throw std::runtime_error("Taylor step: " + step_.trouble());
      ++sim_.steps_;
      // The step runs its full length past the search window's end b (the windows only pace the
      // loop's progress report and interruption), cut at the segment's reach alone.
      double length = std::min({step_.step_size(), motion_cap(), reach_ - cursor_});
      const std::size_t width = static_cast<std::size_t>(p_) + 1;
      r.z.resize(static_cast<std::size_t>(2 * n_) * width);
      for (Eigen::Index i = 0; i < 2 * n_; ++i)
        std::copy_n(step_.state_coefficients(static_cast<int>(i)), width, r.z.begin() + static_cast<std::ptrdiff_t>(i) * static_cast<std::ptrdiff_t>(width));
      const std::size_t k = held_ ? held_->key.size() : 0;
      r.lambda.resize(k * width);
      for (std::size_t a = 0; a < k; ++a)
        std::copy_n(step_.force_coefficients(static_cast<int>(a)), width, r.lambda.begin() + static_cast<std::ptrdiff_t>(a * width));
      if (!armed_) arm(r);
      // Every row's first certified rise above its trigger in [0, length]. A grazing (a touch of
      // the trigger level within the remainder band) ends the step before it, and the next step,
      // expanded there, decides it with its own band. A grazing at the step's start (within
      // kStartFraction of the length, or one that would not move the time) cannot be cut at: no
      // progress. The band shrinks with the length (the tail as h^{p+1}, the rounding towards
      // the start's share), so the step is halved and searched again, at most kHalvings times;
      // a guard still undecided at its start then is a numerical failure, named, never a loop
      // and never a step taken over it. So every step either advances the time by at least
      // kStartFraction · 2^-kHalvings of its own size or ends the run with a decision.
      constexpr double kStartFraction = 0x1p-20;
      constexpr int kHalvings = 30;
      double first = std::numeric_limits<double>::infinity(), cut = length;
      Eigen::Index first_row = -1, stalled_row = -1;
      for (int halving = 0;; ++halving) {
        first = std::numeric_limits<double>::infinity();
        cut = length;
        first_row = stalled_row = -1;
        for (Eigen::Index i = 0; i < triggers_.size(); ++i) {
          guard_coefficients(r, i, guard_.data());
          double rounding = 0.0, truncation = 0.0;
          step_.remainder_parts(guard_.data(), length, &rounding, &truncation);
          if (is_gap_row(i)) truncation += motion_tail(row_stop_[static_cast<std::size_t>(i)], std::min(length, step_.step_size()));
          const taylor::GuardCrossing c = roots_.first_crossing(guard_.data(), p_, length, triggers_(i), rounding,
                                                                truncation, /*rounding_scales=*/true);
          if (c.kind == taylor::CrossingKind::crossing || c.kind == taylor::CrossingKind::at_start) {
            if (c.tau < first) {
              first = c.tau;
              first_row = i;
            }
          } else if (c.kind == taylor::CrossingKind::grazing) {
            if (c.lower <= kStartFraction * length || !(r.t + c.lower > r.t)) {
              if (stalled_row < 0) stalled_row = i;
            } else {
              cut = std::min(cut, c.lower);
            }
          }
        }
        // A crossing before every undecided start is an answer; otherwise halve.
        if (stalled_row < 0 || (first_row >= 0 && first == 0.0)) break;
        if (halving == kHalvings || !(r.t + 0.5 * length > r.t)) {
          const int j = row_stop_[static_cast<std::size_t>(stalled_row)];
          std::string why = "Taylor engine: the ";
          why += is_gap_row(stalled_row) ? "gap" : "contact force";
          why += " guard of stop '";
          why += scene_.stops()[static_cast<std::size_t>(j)].name;
          why += "' stays within its remainder band of the trigger level at the step's start at t = ";
          why += number_text(r.t);
          why += " with the step cut to ";
          why += number_text(length);
          why += ": the search cannot decide it";
          throw std::runtime_error(why);
        }
        length *= 0.5;
      }
      if (first_row >= 0 && first <= cut) {
        locate(first_row, first);
        hit->tau = records_[hit_record_].offset + hit_tau_;
        hit->row = first_row;
        return true;
      }
      length = cut;
      const double next = cursor_ + length;
      r.length = next - cursor_;
      for (Eigen::Index i = 0; i < 2 * n_; ++i) z_(i) = horner_compensated(coefficients(r, i), p_, r.length);
      cursor_ = next;
    }
    return false;
  }
  void end_search() {}
  void report(double t, double t_next, const std::vector<Observer*>& observers);
  bool advance(detail::RunState& st, const Crossing* hit, double /*tau*/, double t_next) {
    if (used_ == 0) return true;  // a segment of zero length (t_next = st.t): no step was taken
    const double elapsed = t_next - st.t;
    std::size_t r = hit_record_;
    double tau = hit_tau_;
    if (!(hit && elapsed == hit->tau)) locate_time(elapsed, &r, &tau);
    if (hit) {
      at_record_ = r;
      at_tau_ = tau;
    }
    for (Eigen::Index i = 0; i < n_; ++i) {
      st.x(i) = horner_compensated(coefficients(records_[r], i), p_, tau);
      st.v(i) = horner_compensated(coefficients(records_[r], n_ + i), p_, tau);
    }
    return st.x.allFinite() && st.v.allFinite();
  }
  detail::FiredGuards fired() {
    const StepRecord& r = records_[at_record_];
    for (Eigen::Index i = 0; i < triggers_.size(); ++i) {
      guard_coefficients(r, i, guard_.data());
      h_(i) = horner(guard_.data(), p_, at_tau_);
      d_(i) = horner_slope(guard_.data(), p_, at_tau_);
    }
    return {h_, d_, triggers_, opening_rows_, row_stop_};
  }
  bool stop_requested(std::string* /*why*/) const { return false; }
  void state(const detail::RunState& st, bool /*physical*/, Eigen::VectorXd& x, Eigen::VectorXd& v) const {
    x = st.x;
    v = st.v;
  }
  void finish(RunSummary& summary) const { summary.sticking_flows_built = sets_.size(); }

  // ---- ContactAlgebra (event_resolution.hpp) ----
  double gap(int j, double t, const Eigen::VectorXd& x) const override {
    const double g = tab_.normals.col(j).dot(x) - (tab_.s0(j) + tab_.sc(j) * std::cos(frequency() * t) +
                                                   tab_.ss(j) * std::sin(frequency() * t));
    return g - higher_motion(j, t, 0);
  }
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override {
    const double w = frequency(), c = std::cos(w * t), s = std::sin(w * t);
    for (Eigen::Index j = 0; j < out.size(); ++j)
      out(j) = tab_.normals.col(j).dot(v) - w * (-tab_.sc(j) * s + tab_.ss(j) * c) - higher_motion(static_cast<int>(j), t, 1);
  }
  /// The acceleration LCP (contact.hpp) with the free acceleration of the nonlinear system.
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override {
    held.clear();
    if (candidates.empty()) return;
    z_probe_.resize(2 * n_);
    z_probe_ << x, v;
    rate_at(t, z_probe_, rate_);
    const auto k = static_cast<Eigen::Index>(candidates.size());
    auto q = q_.head(k);
    auto G = G_.topLeftCorner(k, k);
    delassus(candidates, G);
    const double w = frequency(), c = std::cos(w * t), s = std::sin(w * t);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = candidates[static_cast<std::size_t>(a)];
      q(a) = tab_.normals.col(j).dot(rate_.tail(n_)) + w * w * (tab_.sc(j) * c + tab_.ss(j) * s) - higher_motion(j, t, 2);
    }
    // q = Wᵀ a_free − p̈ is the free gap acceleration; the LCP wants it as the dense engine's
    // Wᵀ M⁻¹ (f − C v − K x) − s'' (the same quantity).
    solve_lcp(G, q, forces, lcp_);
    for (Eigen::Index a = 0; a < k; ++a)
      if (forces(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
  }
  void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const override {
    for (std::size_t a = 0; a < set.size(); ++a)
      for (std::size_t b = 0; b < set.size(); ++b)
        G(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = tab_.delassus(set[a], set[b]);
  }
  double delassus_diagonal(int j) const override { return tab_.delassus(j, j); }
  void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                     Eigen::VectorXd& v) const override {
    for (std::size_t a = 0; a < set.size(); ++a) v -= tab_.minv_normals.col(set[a]) * impulse(static_cast<Eigen::Index>(a));
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override {
    z -= tab_.minv_normals.col(set[static_cast<std::size_t>(a)]) * s;
  }
  bool accept(const ContactSet& /*held*/, std::string* /*why*/) override { return true; }
  double chatter_alpha(int j) const override { return tab_.alpha(j); }
  double chatter_beta(int j) const override { return tab_.beta(j); }
  /// λ_j' and λ_j'' along the held flow from (t, x, v): the first coefficients of a step's λ.
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override {
    HeldSet& set = held_set(held);
    time_series(t, probe_forcing_, &set.probe_stop_acceleration, &set);
    probe_.set_terms(terms(&probe_forcing_, &set, &set.probe_stop_acceleration));
    z_probe_.resize(2 * n_);
    z_probe_ << x, v;
    if (probe_.expand(t, z_probe_) != taylor::StepStatus::ok) throw std::runtime_error("Taylor step: " + probe_.trouble());
    const auto a = static_cast<int>(std::lower_bound(held.begin(), held.end(), j) - held.begin());
    *slope = probe_.force_coefficients(a)[1];
    *curvature = 2.0 * probe_.force_coefficients(a)[2];
  }
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return tab_.normals.col(j).dot(y); }
  void damped_normal(int j, Eigen::VectorXd& d) override { d = tab_.damped_normals.col(j); }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override {
    e.noalias() = tab_.minv_damping * d;
    e -= tab_.stiff_normals.col(j);
  }

  // ---- for the segment view (LoopAccess) ----
  void state_at(double elapsed, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override {
    if (used_ == 0) {  // a segment of zero length: its start
      x = z_.head(n_);
      v = z_.tail(n_);
      return;
    }
    std::size_t r = 0;
    double tau = 0.0;
    locate_time(elapsed, &r, &tau);
    for (Eigen::Index i = 0; i < n_; ++i) {
      x(i) = horner_compensated(coefficients(records_[r], i), p_, tau);
      v(i) = horner_compensated(coefficients(records_[r], n_ + i), p_, tau);
    }
  }
  double force_at(Eigen::Index a, double elapsed) const override {
    if (used_ == 0) return 0.0;  // a segment of zero length has no step (and no force series)
    std::size_t r = 0;
    double tau = 0.0;
    locate_time(elapsed, &r, &tau);
    return horner_compensated(records_[r].lambda.data() + static_cast<std::size_t>(a) * (static_cast<std::size_t>(p_) + 1), p_, tau);
  }
  /// Interior minima of λ_a over [0, span] of the segment: the roots of λ_a' rising through zero,
  /// step by step, by the certified root search (guard_roots.hpp) with the polynomial's rounding
  /// as its bound, alternating with the maxima (−λ_a' rising) so that it moves from extremum to
  /// extremum.
  void force_minima(Eigen::Index a, double span, double t_begin, std::vector<Minimum>& out) const override {
    const std::size_t width = static_cast<std::size_t>(p_) + 1;
    std::vector<double> d(width), shifted(width);
    taylor::GuardRootFinder finder(p_);
    for (std::size_t r = 0; r < used_; ++r) {
      const StepRecord& rec = records_[r];
      const double end = std::min(r + 1 < used_ ? records_[r + 1].offset : span, span) - rec.offset;
      if (!(end > 0.0)) break;
      const double* lam = rec.lambda.data() + static_cast<std::size_t>(a) * width;
      for (int k = 0; k + 1 <= p_; ++k) d[static_cast<std::size_t>(k)] = (k + 1) * lam[k + 1];
      d[static_cast<std::size_t>(p_)] = 0.0;
      double lo = 0.0;
      double sign = horner(d.data(), p_, 0.0) > 0.0 ? -1.0 : 1.0;  // a maximum first where λ' > 0
      for (int guard = 0; guard < 4 * p_ && lo < end; ++guard) {
        // shifted(s) = sign · λ'(lo + s), by repeated synthetic division (Taylor shift)
        for (std::size_t k = 0; k < width; ++k) shifted[k] = sign * d[k];
        for (int i = 0; i < p_; ++i)
          for (int k = p_ - 1; k >= i; --k) shifted[static_cast<std::size_t>(k)] += lo * shifted[static_cast<std::size_t>(k) + 1];
        double abs_sum = 0.0, power = 1.0;
        for (std::size_t k = 0; k < width; ++k, power *= end - lo) abs_sum += std::abs(shifted[k]) * power;
        const double delta = 8.0 * (p_ + 1) * std::numeric_limits<double>::epsilon() * abs_sum;
        const taylor::GuardCrossing c = finder.first_crossing(shifted.data(), p_, end - lo, 0.0, delta);
        if (c.kind == taylor::CrossingKind::none) break;
        const double at = lo + (c.kind == taylor::CrossingKind::crossing ? c.tau : c.upper);
        if (c.kind == taylor::CrossingKind::crossing && sign > 0.0)
          out.push_back({horner_compensated(lam, p_, at), t_begin + rec.offset + at});
        if (c.kind == taylor::CrossingKind::crossing) sign = -sign;
        lo = std::max(at, lo) + 4.0 * std::numeric_limits<double>::epsilon() * std::max(end, 1.0);
      }
    }
  }
  const double* coefficients(const StepRecord& r, Eigen::Index i) const {
    return r.z.data() + static_cast<std::size_t>(i) * (static_cast<std::size_t>(p_) + 1);
  }
  int order() const { return p_; }
  Eigen::Index dof_count() const { return n_; }
  /// The record holding segment time `elapsed` (the last one whose offset is ≤ it) and τ in it.
  void locate_time(double elapsed, std::size_t* r, double* tau) const {
    std::size_t i = 0;
    while (i + 1 < used_ && records_[i + 1].offset <= elapsed) ++i;
    *r = i;
    *tau = elapsed - records_[i].offset;
  }
  const StepRecord& record(std::size_t i) const { return records_[i]; }
  std::size_t records() const { return used_; }
  const ContactSet& active() const override { return held_ ? held_->key : empty_; }

 private:
  StepRecord& next_record() {
    if (used_ == records_.size()) records_.emplace_back();
    return records_[used_++];
  }
  /// The drive's acceleration series M⁻¹ f(t0 + τ) and, for a held set, its stops' p̈ series.
  void time_series(double t0, Eigen::MatrixXd& acceleration, Eigen::MatrixXd* stop_acc, const HeldSet* held) {
    // Columns of the drive (drive_matrix): M⁻¹ times the constant, cosine and sine parts, then
    // each harmonic's two; with compliant stops engaged, theirs (EngagedSet).
    const HarmonicForcing& f = engaged_set_ ? engaged_set_->forcing : sys_.forcing();
    const Eigen::MatrixXd& drive = engaged_set_ ? engaged_set_->drive : drive_;
    const Eigen::Index n = n_;
    double* out = acceleration.data();  // n × (p + 1), column-major
    const double* constant = drive.col(0).data();
    auto add_harmonic = [&](double rate, Eigen::Index column, bool first) {
      harmonic_series(rate, t0, p_, cos_.data(), sin_.data());
      const double* cosine = drive.col(column).data();
      const double* sine = drive.col(column + 1).data();
      const double* cs = cos_.data();
      const double* sn = sin_.data();
      // Coordinate by coordinate (each entry is its own closed form: the order of the loops does
      // not change a bit), the orders innermost, contiguous for one coordinate.
      for (Eigen::Index i = 0; i < n; ++i) {
        const double a = cosine[i], b = sine[i];
        double* row = out + i;
        if (first) {  // order 0 with the constant part, then the entries written (not added to)
          row[0] = constant[i] + (a * cs[0] + b * sn[0]);
          for (int k = 1; k <= p_; ++k) row[static_cast<Eigen::Index>(k) * n] = a * cs[k] + b * sn[k];
        } else {
          for (int k = 0; k <= p_; ++k) {
            double& e = row[static_cast<Eigen::Index>(k) * n];
            e = e + (a * cs[k] + b * sn[k]);
          }
        }
      }
    };
    add_harmonic(f.frequency, 1, true);
    for (std::size_t h = 0; h < f.harmonics.size(); ++h)
      add_harmonic(f.harmonics[h].rate(f.frequency), 3 + 2 * static_cast<Eigen::Index>(h), false);
    if (!held || !stop_acc) return;
    for (std::size_t a = 0; a < held->key.size(); ++a) {
      const int j = held->key[a];
      motion_series(j, t0, p_ + 2, stop_pos_.data());
      for (int k = 0; k <= p_; ++k)
        (*stop_acc)(static_cast<Eigen::Index>(a), k) =
            static_cast<double>((k + 1) * (k + 2)) * stop_pos_[static_cast<std::size_t>(k) + 2];
    }
  }
  /// Stop j's position s_j(t0 + τ)'s series to `order` (≤ p + 2) in out: s0, the first harmonic
  /// and every higher one, each in closed form (harmonic_series).
  void motion_series(int j, double t0, int order, double* out) {
    const bool moving = tab_.sc(j) != 0.0 || tab_.ss(j) != 0.0;  // a fixed stop's position is s0 alone
    if (moving) harmonic_series(frequency(), t0, order, cos_.data(), sin_.data());
    for (int k = 0; k <= order; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      const double s0 = k == 0 ? tab_.s0(j) : 0.0;
      out[k] = moving ? s0 + tab_.sc(j) * cos_[kk] + tab_.ss(j) * sin_[kk] : s0;
    }
    for (const MotionHarmonic& h : tab_.higher[static_cast<std::size_t>(j)]) {
      harmonic_series(h.rate, t0, order, harmonic_cos_.data(), harmonic_sin_.data());
      for (int k = 0; k <= order; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        out[k] += h.cosine * harmonic_cos_[kk] + h.sine * harmonic_sin_[kk];
      }
    }
  }
  /// The higher harmonics' part of stop j's s_j, s_j' or s_j'' at t (stops.hpp; 0 without them).
  double higher_motion(int j, double t, int derivative) const {
    if (tab_.higher[static_cast<std::size_t>(j)].empty()) return 0.0;
    return stop_higher_motion(scene_.stops()[static_cast<std::size_t>(j)], frequency(), t, derivative);
  }
  /// The bound on what stop j's motion series, cut after order p, leaves out over [0, h].
  double motion_tail(int j, double h) const {
    double tail = harmonic_tail(std::hypot(tab_.sc(j), tab_.ss(j)), frequency(), h, p_);
    for (const MotionHarmonic& m : tab_.higher[static_cast<std::size_t>(j)])
      tail += harmonic_tail(std::hypot(m.cosine, m.sine), m.rate, h, p_);
    return tail;
  }
  /// The longest step over which every stop's motion series stays within ε S of the motion
  /// (the constructor's rule; S = max(1, ‖z‖∞) as the step's own scale): infinity for fixed stops.
  double motion_cap() const {
    if (!std::isfinite(motion_cap_)) return motion_cap_;
    const double scale = std::max(1.0, z_.cwiseAbs().maxCoeff());
    return std::min(motion_cap_ * std::pow(sim_.tolerance_ * scale, 1.0 / (p_ + 1)), 0.5 * (p_ + 2) / motion_rate_);
  }
  /// z'(t) of the free system (the drive and the nonlinear forces at (t, z)).
  void rate_at(double t, const Eigen::VectorXd& z, Eigen::VectorXd& out) {
    time_series(t, probe_forcing_, nullptr, nullptr);
    probe_.set_terms(terms(&probe_forcing_, nullptr, nullptr));
    const taylor::StepStatus s = probe_.rate(t, z, out);
    if (s == taylor::StepStatus::domain_error) throw InvalidInput("the forces at t = " + number_text(t) + ": " + probe_.trouble());
    if (s != taylor::StepStatus::ok)
      throw InvalidInput("the forces are not finite at t = " + number_text(t) + " (state " + detail::vector_text(z) + ")");
  }
  HeldSet& held_set(const ContactSet& key) {
    for (const auto& h : sets_)
      if (h->key == key) return *h;
    auto h = std::make_unique<HeldSet>();
    h->key = key;
    const auto k = static_cast<Eigen::Index>(key.size());
    h->normals.resize(n_, k);
    h->minv_normals.resize(n_, k);
    Eigen::MatrixXd G(k, k);
    for (Eigen::Index a = 0; a < k; ++a) {
      h->normals.col(a) = tab_.normals.col(key[static_cast<std::size_t>(a)]);
      h->minv_normals.col(a) = tab_.minv_normals.col(key[static_cast<std::size_t>(a)]);
      for (Eigen::Index b = 0; b < k; ++b) G(a, b) = tab_.delassus(key[static_cast<std::size_t>(a)], key[static_cast<std::size_t>(b)]);
    }
    h->delassus_inverse = G.llt().solve(Eigen::MatrixXd::Identity(k, k));
    h->stop_acceleration.setZero(k, p_ + 1);
    h->probe_stop_acceleration.setZero(k, p_ + 1);
    sets_.push_back(std::move(h));
    return *sets_.back();
  }
  /// The StepTerms of the current mode: the drive's series `acceleration`, a held set (with its
  /// p̈ series `stop_acceleration`) and the engaged compliant stops' linear part.
  taylor::StepTerms terms(const Eigen::MatrixXd* acceleration, const HeldSet* held,
                          const Eigen::MatrixXd* stop_acceleration) const {
    taylor::StepTerms out{acceleration};
    if (held) {
      out.normals = &held->normals;
      out.minv_normals = &held->minv_normals;
      out.delassus_inverse = &held->delassus_inverse;
      out.stop_acceleration = stop_acceleration;
    }
    if (engaged_set_) {
      out.position_matrix = &engaged_set_->position;
      out.velocity_matrix = &engaged_set_->velocity;
    }
    return out;
  }
  EngagedSet& engaged_set(const ContactSet& key) {
    for (const auto& e : engaged_sets_)
      if (e->key == key) return *e;
    auto e = std::make_unique<EngagedSet>();
    e->key = key;
    detail::EngagedSystem sys = detail::engaged_system(scene_, key);
    const Eigen::MatrixXd& minv = sim_.system_->inverse_mass();
    e->position = -minv * sys.stiffness;  // as taylor_system.cpp's A_x, A_v
    e->velocity = -minv * sys.damping;
    e->drive = drive_matrix(minv, sys.forcing);
    e->forcing = std::move(sys.forcing);
    engaged_sets_.push_back(std::move(e));
    return *engaged_sets_.back();
  }
  /// Whether row i watches a gap (an open stop's g, an engaged compliant stop's −g), not a force.
  bool is_gap_row(Eigen::Index i) const { return i < opening_rows_ || i >= engaged_rows_from_; }
  /// Row i's guard series over record r: a gap wᵀx − p(t), −λ of a held stop, or −(wᵀx − p(t))
  /// of an engaged compliant one.
  void guard_coefficients(const StepRecord& r, Eigen::Index i, double* g) {
    const int j = row_stop_[static_cast<std::size_t>(i)];
    if (!is_gap_row(i)) {
      const auto a = static_cast<std::size_t>(i - opening_rows_);
      for (int k = 0; k <= p_; ++k) g[k] = -r.lambda[a * (static_cast<std::size_t>(p_) + 1) + static_cast<std::size_t>(k)];
      return;
    }
    motion_series(j, r.t, p_, stop_pos_.data());
    // wᵀx's series over the normal's nonzero entries (in the order of the coordinates), then p(t)'s.
    std::fill(g, g + p_ + 1, 0.0);
    for (const auto& [l, w] : tab_.entries[static_cast<std::size_t>(j)]) {
      const double* x = coefficients(r, l);
      for (int k = 0; k <= p_; ++k) g[k] += w * x[k];
    }
    for (int k = 0; k <= p_; ++k) g[k] -= stop_pos_[static_cast<std::size_t>(k)];
    if (i >= engaged_rows_from_)
      for (int k = 0; k <= p_; ++k) g[k] = -g[k];
  }
  /// At the segment's first step: a row starting inside its band (0 < h ≤ ε) and moving away is
  /// re-armed at ε + h(0), as the dense engine's finder does (events.hpp), so that rounding
  /// cannot re-fire a guard just left.
  void arm(const StepRecord& r) {
    armed_ = true;
    for (Eigen::Index i = 0; i < triggers_.size(); ++i) {
      guard_coefficients(r, i, guard_.data());
      if (guard_[0] > 0.0 && guard_[1] <= 0.0) triggers_(i) += guard_[0];
    }
  }
  /// The event of row i found at τ* in the last record (its certified rise above the trigger):
  /// its time is the guard's root at zero just before τ*, as the dense engine places it. The
  /// last point before τ* where the guard is below zero is looked for back from τ* (64 points a
  /// step, through the segment's earlier steps if need be), and the root between it and the next
  /// point refined to rounding (guard_roots.hpp, safeguarded Newton).
  void locate(Eigen::Index i, double tau_star) {
    constexpr int kPoints = 64;
    for (std::size_t r = used_; r-- > 0;) {
      guard_coefficients(records_[r], i, guard_.data());
      const double end = r == used_ - 1 ? tau_star : records_[r].length;
      double above = end;
      for (int k = 1; k <= kPoints; ++k) {
        const double a = end * (1.0 - static_cast<double>(k) / kPoints);
        const double g = horner(guard_.data(), p_, a);
        if (g < 0.0) {
          const double gb = horner(guard_.data(), p_, above);
          hit_record_ = r;
          hit_tau_ = gb == 0.0 ? above : (gb > 0.0 ? taylor::GuardRootFinder::refine(guard_.data(), p_, 0.0, a, above) : above);
          return;
        }
        above = a;
      }
    }
    hit_record_ = used_ - 1;  // above zero since the segment's start: the trigger's crossing
    hit_tau_ = tau_star;
  }

  TaylorSimulator& sim_;
  const ImpactSystem& scene_;
  const LinearSystem& sys_;
  const std::vector<Observer*>& observers_;
  RunSummary& summary_;
  taylor::TaylorStep step_, probe_;
  taylor::GuardRootFinder roots_;
  int p_;
  Eigen::Index n_;
  TaylorTables tab_;
  double eps_gap_ = 0.0, eps_force_ = 0.0, scale_T_ = 1.0;
  detail::EventRules rules_;
  detail::EventWorkspace work_;
  std::function<void(const Event&)> emit_;
  std::vector<std::unique_ptr<HeldSet>> sets_;
  HeldSet* held_ = nullptr;
  bool compliant_ = false;  // the scene has compliant stops
  ContactSet engaged_, rigid_impacts_, rigid_releases_;  // engaged compliant stops; scratch
  std::vector<std::unique_ptr<EngagedSet>> engaged_sets_;
  const EngagedSet* engaged_set_ = nullptr;  // engaged_'s (none engaged: nullptr)
  Eigen::VectorXd rates_;
  ContactSet empty_;
  Eigen::MatrixXd forcing_, probe_forcing_, drive_;
  std::vector<double> cos_, sin_, stop_pos_, guard_, harmonic_cos_, harmonic_sin_;
  double motion_cap_ = std::numeric_limits<double>::infinity(), motion_rate_ = 0.0;
  Eigen::VectorXd z_, z_probe_, rate_, residual_, q_, h_, d_, triggers_;
  Eigen::MatrixXd G_;
  LcpWorkspace lcp_;
  std::vector<int> row_stop_;
  Eigen::Index opening_rows_ = 0, engaged_rows_from_ = 0;
  bool armed_ = false;
  double seg_t_ = 0.0, cursor_ = 0.0, reach_ = 0.0, hit_tau_ = 0.0, at_tau_ = 0.0;
  std::vector<StepRecord> records_;
  std::size_t used_ = 0, hit_record_ = 0, at_record_ = 0;
};

namespace {

/// A segment of the Taylor engine as observers see it: the steps' polynomials (dense output).
class TaylorSegmentView final : public SegmentView {
 public:
  TaylorSegmentView(const TaylorSimulator::LoopAccess& loop, double t_begin, double t_end)
      : SegmentView(t_begin, t_end), loop_(loop) {}
  Eigen::Index dof() const override { return loop_.dof(); }
  const ContactSet& active() const override { return loop_.active(); }
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override {
    loop_.state_at(t - t_begin(), x, v);
  }
  double force(Eigen::Index a, double t) const override { return loop_.force_at(a, t - t_begin()); }
  Minimum force_minimum(Eigen::Index a) const override {
    Minimum best{force(a, t_begin()), t_begin()};
    if (const double e = force(a, t_end()); e < best.value) best = {e, t_end()};
    for (const Minimum& m : force_local_minima(a))
      if (m.value < best.value) best = m;
    return best;
  }
  std::vector<Minimum> force_local_minima(Eigen::Index a) const override {
    std::vector<Minimum> out;
    loop_.force_minima(a, t_end() - t_begin(), t_begin(), out);
    return out;
  }

 private:
  const TaylorSimulator::LoopAccess& loop_;
};

}  // namespace

void TaylorSimulator::Loop::report(double t, double t_next, const std::vector<Observer*>& observers) {
  const TaylorSegmentView view(*this, t, t_next);
  for (Observer* o : observers) o->segment(view);
}

RunSummary TaylorSimulator::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                                const std::vector<Observer*>& observers) {
  RunSummary summary;
  Loop loop(*this, observers, summary);
  detail::run_event_loop(loop, options_, t0, x0, v0, t_end, observers, summary);
  return summary;
}

}  // namespace vibro
