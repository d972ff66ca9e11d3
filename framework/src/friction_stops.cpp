// Friction and stops in one scene (friction_stops.hpp): a mode's flow and guards, the stops'
// algebra for event_resolution.hpp, and the engine side of the shared event loop (event_loop.hpp).
#include "vibro/friction_stops.hpp"

#include "event_loop.hpp"
#include "friction_tables.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace vibro {

using detail::FrictionTables;
using detail::sign_of;

namespace {

/// A mode's rows (friction_stops.hpp), written once for the engine's modes and for
/// friction_stop_mode_rows: the friction forces and the held stops' forces (F = −λ), the
/// generator, and the guard rows: [0, opening) the open stops' gaps, [opening, stop_rows) the held
/// rigid stops' −λ and the engaged compliant stops' −g (in stop order), then the friction guards.
struct ModeRows {
  Eigen::MatrixXd force, held, generator, guards;
  Eigen::Index opening = 0, stop_rows = 0;
  std::vector<int> row_stop, contact;
  std::vector<char> gap_guard, force_guard;
};

void build_mode_rows(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K,
                     const HarmonicForcing& forcing, const std::vector<Stop>& stops, const FrictionTables& tab,
                     const ContactSet& key, const ContactSet& held, const std::vector<FrictionState>& states,
                     ModeRows& out) {
  Eigen::MatrixXd accel;
  tab.mode_rows(states, out.force, accel, &out.held);
  out.generator = augmented_generator(M, C, K, forcing);
  out.generator.middleRows(tab.n, tab.n) = accel;
  const Eigen::Index n = tab.n, N = tab.N, off = tab.off;
  std::vector<Eigen::VectorXd> rows;
  auto gap_row = [&](int j) {
    const Stop& st = stops[static_cast<std::size_t>(j)];
    Eigen::VectorXd row = Eigen::VectorXd::Zero(N);
    row.head(n) = st.normal(n);
    row(off) = -st.s_cos();
    row(off + 1) = -st.s_sin();
    row(off + 2) = -st.s0();
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {  // on the forcing's slot of its order
      const Eigen::Index col = augmented_size(n, forcing_slot(forcing, st.harmonics[i].order));
      row(col) = -st.h_cos(i);
      row(col + 1) = -st.h_sin(i);
    }
    return row;
  };
  for (int j = 0; j < static_cast<int>(stops.size()); ++j)
    if (!std::binary_search(key.begin(), key.end(), j)) {
      rows.push_back(gap_row(j));
      out.row_stop.push_back(j);
    }
  out.opening = static_cast<Eigen::Index>(rows.size());
  for (int j : key) {
    if (stops[static_cast<std::size_t>(j)].is_compliant()) {
      rows.push_back(-gap_row(j));
      out.gap_guard.push_back(true);
    } else {
      const auto a = std::lower_bound(held.begin(), held.end(), j) - held.begin();
      rows.push_back(out.held.row(a).transpose());  // −λ = F
      out.gap_guard.push_back(false);
    }
    out.row_stop.push_back(j);
  }
  out.stop_rows = static_cast<Eigen::Index>(rows.size());
  const Eigen::MatrixXd friction = detail::friction_guard_rows(tab, states, out.force, &out.contact, &out.force_guard);
  out.guards.resize(out.stop_rows + friction.rows(), N);
  for (Eigen::Index i = 0; i < out.stop_rows; ++i) out.guards.row(i) = rows[static_cast<std::size_t>(i)].transpose();
  out.guards.bottomRows(friction.rows()) = friction;
}

/// The stops' part of a mode: which stops of `key` are held (rigid) and engaged (compliant).
detail::FrictionStopPart stop_part(const std::vector<Stop>& stops, const ContactSet& key) {
  detail::FrictionStopPart part;
  part.stops = &stops;
  for (int j : key) (stops[static_cast<std::size_t>(j)].is_compliant() ? part.engaged : part.held).push_back(j);
  return part;
}

}  // namespace

FrictionStopModeRows friction_stop_mode_rows(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C,
                                             const Eigen::MatrixXd& K, const HarmonicForcing& forcing,
                                             const std::vector<Stop>& stops,
                                             const std::vector<FrictionContact>& contacts, const ContactSet& key,
                                             const std::vector<FrictionState>& states) {
  const detail::FrictionStopPart part = stop_part(stops, key);
  const FrictionTables tab(M, C, K, forcing, contacts, &part);
  ModeRows rows;
  build_mode_rows(M, C, K, forcing, stops, tab, key, part.held, states, rows);
  FrictionStopModeRows out;
  out.held = part.held;
  out.generator = std::move(rows.generator);
  out.guards = std::move(rows.guards);
  out.opening_rows = rows.opening;
  out.stop_rows = rows.stop_rows;
  out.force = std::move(rows.force);
  out.held_force = std::move(rows.held);
  out.relative = tab.u_rows;
  out.held_rates = tab.uc_rows;
  out.locked = tab.locked;
  if (out.locked.empty()) out.locked.assign(contacts.size(), 0);
  return out;
}

/// A mode's exact flow and guards (friction_stops.hpp; the rows of build_mode_rows).
class FrictionStopSimulator::Mode {
 public:
  Mode(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts, const ContactSet& key,
       const std::vector<FrictionState>& states, FlowOptions options)
      : key_(key) {
    const LinearSystem& sys = scene.system();
    const detail::FrictionStopPart part = stop_part(scene.stops(), key);
    held_ = part.held;
    tab_ = std::make_unique<FrictionTables>(sys, contacts, &part);
    ModeRows rows;
    build_mode_rows(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing(), scene.stops(), *tab_, key, held_, states,
                    rows);
    force_rows_ = std::move(rows.force);
    held_rows_ = std::move(rows.held);
    generator_ = std::move(rows.generator);
    flow_ = std::make_unique<LinearFlow>(generator_, tab_->n, sys.forcing().frequency, options);
    opening_rows_ = rows.opening;
    stop_rows_ = rows.stop_rows;
    row_stop_ = std::move(rows.row_stop);
    contact_ = std::move(rows.contact);
    gap_guard_ = std::move(rows.gap_guard);
    force_guard_ = std::move(rows.force_guard);
    guards_ = std::make_unique<Functionals>(*flow_, std::move(rows.guards));
  }

  const ContactSet& key() const { return key_; }
  const LinearFlow& flow() const { return *flow_; }
  const Functionals& guards() const { return *guards_; }
  const FrictionTables& tables() const { return *tab_; }
  const Eigen::MatrixXd& generator() const { return generator_; }
  const Eigen::MatrixXd& force_rows() const { return force_rows_; }
  const Eigen::MatrixXd& held_rows() const { return held_rows_; }
  const ContactSet& held() const { return held_; }
  Eigen::Index opening_rows() const { return opening_rows_; }
  Eigen::Index stop_rows() const { return stop_rows_; }
  const std::vector<int>& row_stop() const { return row_stop_; }
  int contact_of(Eigen::Index row) const { return contact_[static_cast<std::size_t>(row - stop_rows_)]; }
  /// Trigger levels: ε_gap on gap rows, ε_F on the held stops' forces and friction force rows,
  /// ε_v on the slip velocities.
  Eigen::VectorXd triggers(double eps_gap, double eps_f, double eps_v) const {
    Eigen::VectorXd t(guards_->count());
    for (Eigen::Index i = 0; i < t.size(); ++i) {
      if (i < opening_rows_) t(i) = eps_gap;
      else if (i < stop_rows_) t(i) = gap_guard_[static_cast<std::size_t>(i - opening_rows_)] ? eps_gap : eps_f;
      else t(i) = force_guard_[static_cast<std::size_t>(i - stop_rows_)] ? eps_f : eps_v;
    }
    return t;
  }
  /// The mode's segment and finder, re-targeted at each visit.
  Segment& segment(double t0, const Eigen::VectorXd& z0) const {
    if (segment_) segment_->reset(t0, z0);
    else segment_ = std::make_unique<Segment>(*guards_, t0, z0);
    return *segment_;
  }
  CrossingFinder& finder() const { return finder_; }

 private:
  ContactSet key_, held_;
  std::unique_ptr<FrictionTables> tab_;
  Eigen::MatrixXd force_rows_, held_rows_, generator_;
  std::unique_ptr<LinearFlow> flow_;
  std::unique_ptr<Functionals> guards_;
  Eigen::Index opening_rows_ = 0, stop_rows_ = 0;
  std::vector<int> row_stop_, contact_;
  std::vector<char> gap_guard_, force_guard_;
  mutable std::unique_ptr<Segment> segment_;
  mutable CrossingFinder finder_;
};

namespace {

/// A segment for the observers: states from the mode's exact flow, the held rigid stops' forces.
class FrictionStopView final : public SegmentView {
 public:
  FrictionStopView(const FrictionStopSimulator::Mode& mode, const Segment& segment, double t_begin, double t_end)
      : SegmentView(t_begin, t_end), mode_(&mode), segment_(&segment), z_(segment.initial_state().size()) {}
  Eigen::Index dof() const override { return mode_->tables().n; }
  const ContactSet& active() const override { return mode_->held(); }
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override {
    const Eigen::Index n = dof();
    segment_->state_unstored(t - segment_->t0(), z_);
    x = z_.head(n);
    v = z_.segment(n, n);
  }
  double force(Eigen::Index a, double t) const override {
    segment_->state_unstored(t - segment_->t0(), z_);
    return -mode_->held_rows().row(a).dot(z_);
  }
  Minimum force_minimum(Eigen::Index) const override {
    throw std::logic_error("friction with stops: the segments' certified force minima are not computed");
  }
  std::vector<Minimum> force_local_minima(Eigen::Index) const override { return {}; }

 private:
  const FrictionStopSimulator::Mode* mode_;
  const Segment* segment_;
  mutable Eigen::VectorXd z_;
};

}  // namespace

/// The engine side of event_loop.hpp, and the stops' algebra of event_resolution.hpp (one
/// object: the algebra's settle and force rates read the current friction states and modes).
class FrictionStopSimulator::Loop final : public detail::ContactAlgebra {
 public:
  Loop(FrictionStopSimulator& sim, const std::vector<Observer*>& observers,
       const std::vector<FrictionStopObserver*>& mode_observers, RunSummary& summary, double t_end)
      : sim_(sim), scene_(*sim.scene_), sys_(scene_.system()), stops_(scene_.stops()), observers_(observers),
        mode_observers_(mode_observers), summary_(summary), t_end_(t_end), omega_(sys_.forcing().frequency) {
    const Eigen::Index n = sys_.dof();
    const auto m = static_cast<Eigen::Index>(stops_.size());
    const Eigen::LLT<Eigen::MatrixXd> llt(sys_.mass());
    normals_ = scene_.normals();
    minv_ = llt.solve(Eigen::MatrixXd::Identity(n, n));
    minv_normals_ = minv_ * normals_;
    delassus_ = normals_.transpose() * minv_normals_;
    delassus_ = 0.5 * (delassus_ + delassus_.transpose());
    // The chatter rule's coefficients of the free system, as simulator.cpp's StopTables computes
    // them (its tables are private to the dense engine; the formulas are the same).
    minv_damping_ = minv_ * sys_.damping();
    damped_normals_ = minv_damping_ * minv_normals_;
    stiff_normals_ = minv_ * sys_.stiffness() * minv_normals_;
    alpha_.resize(m);
    beta_.resize(m);
    for (Eigen::Index j = 0; j < m; ++j) {
      const auto q = minv_normals_.col(j);
      const double G = delassus_(j, j), qcq = q.dot(sys_.damping() * q);
      alpha_(j) = -qcq / G;
      beta_(j) = (q.dot(sys_.damping() * damped_normals_.col(j)) - q.dot(sys_.stiffness() * q)) / G - (qcq / G) * (qcq / G);
    }
    lcp_.reserve(m);
  }

  // ---- the engine interface of event_loop.hpp ----
  Eigen::Index dof() const { return sys_.dof(); }
  const std::vector<Stop>& stops() const { return stops_; }
  double frequency() const { return omega_; }
  detail::ScaleInputs scale_inputs() const {
    const HarmonicForcing& f = sys_.forcing();
    detail::ScaleInputs in;
    in.omega = omega_;
    if (in.omega == 0.0) {
      Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys_.stiffness(), sys_.mass(), Eigen::EigenvaluesOnly);
      in.omega = std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
    }
    in.kmax = sys_.stiffness().cwiseAbs().maxCoeff();
    in.mmax = sys_.mass().cwiseAbs().maxCoeff();
    in.fmax = f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff();
    for (const ForcingHarmonic& h : f.harmonics) in.fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
    for (const FrictionContact& c : sim_.contacts_) in.fmax += c.static_coefficient * c.normal_load;
    return in;
  }
  void check_scene(const detail::RunScales& /*sc*/, std::vector<std::string>& /*warnings*/) const {}
  void start(const detail::RunScales& sc, detail::RunState& st) {
    eps_gap_ = sc.eps_gap;
    eps_f_ = sc.eps_force;
    eps_v_ = sim_.options_.trigger * sc.V;
    eps_a_ = sim_.options_.trigger * sc.V * (2.0 * std::numbers::pi / sc.T);
    rules_ = sc.rules;
    resolution_ = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end_), sc.T);
    work_.reserve(static_cast<Eigen::Index>(stops_.size()), sys_.dof());
    emit_ = [this](const Event& e) {
      for (Observer* o : observers_) o->event(e);
    };
    engaged_.clear();
    const Eigen::VectorXd g = scene_.gaps(st.t, st.x);
    for (std::size_t j = 0; j < stops_.size(); ++j)
      if (stops_[j].is_compliant() && CompliantStopLaw::engaged_at_start(g(static_cast<Eigen::Index>(j))))
        engaged_.push_back(static_cast<int>(j));
    // The frictional contacts at the start (friction.hpp): those at u = 0 decided by the
    // resolution, the others slipping with u.
    states_.assign(sim_.contacts_.size(), FrictionState::slip_positive);
    const Eigen::VectorXd z = detail::augmented_state(sys_, st.t, st.x, st.v);
    const FrictionTables& tab = mode(st.stuck).tables();
    const Eigen::VectorXd u = tab.u_rows * z;
    std::vector<char> candidate(states_.size());
    for (std::size_t j = 0; j < states_.size(); ++j) {
      candidate[j] = std::abs(u(static_cast<Eigen::Index>(j))) <= eps_v_;
      if (!candidate[j]) states_[j] = u(static_cast<Eigen::Index>(j)) > 0.0 ? FrictionState::slip_positive
                                                                            : FrictionState::slip_negative;
    }
    const std::vector<FrictionState> before = states_;
    if (!detail::resolve_states(mode(st.stuck).tables(), z, states_, -1, eps_v_, eps_f_, eps_a_))
      throw std::runtime_error("friction: no consistent stick/slip state at the start");
    emit_friction(st, before, z, &candidate);
  }
  void initial_guards(const detail::RunState& st, Eigen::VectorXd& g, Eigen::VectorXd& gd) const {
    g = scene_.gaps(st.t, st.x);
    gd = scene_.gap_rates(st.t, st.v);
  }
  bool resolve(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, const ContactSet& resting,
               std::string* why) {
    return resolve_all(st, impacts, releases, resting, -1, why);
  }
  /// Compliant switches first (the mode changes, the state does not: as the dense engine's
  /// Simulator::Loop::event), then the rigid stops' impacts and releases and the friction
  /// switch, resolved together (resolve_all).
  bool event(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, std::string* why) {
    FrictionStopSwitch sw;
    if (!mode_observers_.empty()) {
      sw.t = st.t;
      sw.guard_row = crossing_row_;
      sw.guards_fired = static_cast<int>(impacts.size() + releases.size()) + (crossing_row_ >= mode_->stop_rows() ? 1 : 0);
      sw.key_before = mode_->key();
      sw.before = states_;
      sw.z_before = detail::augmented_state(sys_, st.t, st.x, st.v);
    }
    if (!event_resolved(st, impacts, releases, why)) return false;
    if (!mode_observers_.empty()) {
      std::set_union(st.stuck.begin(), st.stuck.end(), engaged_.begin(), engaged_.end(), std::back_inserter(sw.key_after));
      sw.held_by_stops = held_by_stops_;
      sw.after = states_;
      sw.z_after = detail::augmented_state(sys_, st.t, st.x, st.v);
      for (FrictionStopObserver* o : mode_observers_) o->mode_switch(sw);
    }
    return true;
  }
  bool event_resolved(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, std::string* why) {
    ContactSet rigid_impacts, rigid_releases;
    Eigen::VectorXd rates(static_cast<Eigen::Index>(stops_.size()));
    detail::compliant_switches(*this, stops_, st.t, st.x, st.v, impacts, releases, engaged_, rigid_impacts,
                               rigid_releases, rates, emit_);
    const int fired = crossing_row_ >= mode_->stop_rows() ? mode_->contact_of(crossing_row_) : -1;
    return resolve_all(st, rigid_impacts, rigid_releases, {}, fired, why);
  }
  double stiffness(const detail::RunState& st, double T) { return T * mode(st.stuck).flow().spectral_radius(); }
  detail::SegmentPlan begin_segment(const detail::RunState& st, double t_end) {
    mode_ = &mode(st.stuck);
    const Eigen::VectorXd z = mode_->flow().augment(st.t, st.x, st.v);
    segment_ = &mode_->segment(st.t, z);
    mode_->finder().retarget(*segment_, mode_->triggers(eps_gap_, eps_f_, eps_v_), resolution_, true);
    crossing_row_ = -1;
    return {1.0 / std::max(mode_->flow().spectral_radius(), 1e-300), std::min(t_end - st.t, mode_->flow().horizon())};
  }
  bool search(double a, double b, Crossing* hit) {
    if (mode_->guards().count() == 0) return false;
    const std::optional<Crossing> c = mode_->finder().first(a, b);
    if (c) {
      *hit = *c;
      crossing_row_ = c->row;
    }
    return c.has_value();
  }
  void end_search() {}
  void report(double t, double t_next, const std::vector<Observer*>& observers) {
    const FrictionStopView view(*mode_, *segment_, t, t_next);
    for (Observer* o : observers) o->segment(view);
  }
  bool advance(detail::RunState& st, const Crossing* hit, double /*tau*/, double t_next) {
    const Eigen::Index n = sys_.dof();
    Eigen::VectorXd z(segment_->initial_state().size());
    const double elapsed = t_next - st.t;
    if (hit && elapsed == hit->tau) segment_->state(mode_->finder().crossing_sample(), z);
    else segment_->state(elapsed, z);
    for (FrictionStopObserver* o : mode_observers_)
      o->mode_segment(st.t, t_next, mode_->key(), states_, segment_->initial_state());
    st.x = z.head(n);
    st.v = z.segment(n, n);
    return st.x.allFinite() && st.v.allFinite();
  }
  /// The stops' rows at the crossing (the friction rows follow them and are not the frame's:
  /// a friction crossing reaches event() with its row remembered by search()).
  detail::FiredGuards fired() {
    const SegmentSample& at = mode_->finder().crossing_sample();
    const Eigen::Index k = mode_->stop_rows();
    h_ = at.h.head(k);
    d_ = at.d.head(k);
    trig_ = mode_->finder().triggers().head(k);
    return {h_, d_, trig_, mode_->opening_rows(), mode_->row_stop()};
  }
  bool stop_requested(std::string* /*why*/) const { return false; }
  void state(const detail::RunState& st, bool /*physical*/, Eigen::VectorXd& x, Eigen::VectorXd& v) const {
    x = st.x;
    v = st.v;
  }
  void finish(RunSummary& summary) const {
    summary.contact_sets_built = sim_.modes_.size();
    summary.sticking_flows_built = sim_.modes_.size();
    sim_.states_ = states_;
  }

  // ---- the stops' algebra (event_resolution.hpp) ----
  double gap(int j, double t, const Eigen::VectorXd& x) const override {
    return scene_.stops()[static_cast<std::size_t>(j)].normal(sys_.dof()).dot(x) - stop_position(j, t);
  }
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override {
    out = scene_.gap_rates(t, v);
  }
  /// The acceleration LCP with the frictional contacts in their current states: q = the gap
  /// accelerations of the mode without held stops, G = the stops' Delassus matrix reduced by
  /// the stuck contacts' constraints (friction_stops.hpp).
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override {
    held.clear();
    if (candidates.empty()) return;
    const Eigen::VectorXd z = detail::augmented_state(sys_, t, x, v);
    const FrictionTables& tab = mode({}).tables();  // the engaged compliant stops, no held stop
    const auto k = static_cast<Eigen::Index>(candidates.size());
    Eigen::MatrixXd Nc(sys_.dof(), k);
    for (Eigen::Index a = 0; a < k; ++a) Nc.col(a) = normals_.col(candidates[static_cast<std::size_t>(a)]);
    // Stuck contacts whose tangents the candidates' normals span are no constraint here: the
    // stops take the load (FrictionTables::locked), and such a contact exerts no force.
    std::vector<Eigen::Index> stuck;
    Eigen::VectorXd r = tab.r_rows * z;
    for (std::size_t j = 0; j < states_.size(); ++j) {
      const auto J = static_cast<Eigen::Index>(j);
      if (states_[j] != FrictionState::stuck) r -= tab.W.col(J) * (tab.limit_kinetic(J) * sign_of(states_[j]));
      else if (!FrictionTables::in_span(Nc, tab.W.col(J))) stuck.push_back(J);
    }
    Eigen::VectorXd accel = minv_ * r;
    Eigen::MatrixXd G = Nc.transpose() * minv_ * Nc;
    if (!stuck.empty()) {
      const auto ks = static_cast<Eigen::Index>(stuck.size());
      Eigen::MatrixXd Ws(sys_.dof(), ks);
      Eigen::VectorXd s2(ks);
      for (Eigen::Index a = 0; a < ks; ++a) {
        Ws.col(a) = tab.W.col(stuck[static_cast<std::size_t>(a)]);
        s2(a) = tab.s2_rows.row(stuck[static_cast<std::size_t>(a)]).dot(z);
      }
      const Eigen::MatrixXd MWs = minv_ * Ws;
      const Eigen::LDLT<Eigen::MatrixXd> Gs(Ws.transpose() * MWs);
      accel += MWs * Gs.solve(s2 - Ws.transpose() * accel);
      const Eigen::MatrixXd B = Nc.transpose() * MWs;
      G -= B * Gs.solve(B.transpose());
      G = 0.5 * (G + G.transpose());
    }
    Eigen::VectorXd q(k);
    const double c = std::cos(omega_ * t), s = std::sin(omega_ * t);
    for (Eigen::Index a = 0; a < k; ++a) {
      const Stop& st = stops_[static_cast<std::size_t>(candidates[static_cast<std::size_t>(a)])];
      q(a) = Nc.col(a).dot(accel) + omega_ * omega_ * (st.s_cos() * c + st.s_sin() * s);  // − p''
      if (st.has_higher_harmonics()) q(a) -= stop_higher_motion(st, omega_, t, 2);
    }
    solve_lcp(G, q, forces, lcp_);
    for (Eigen::Index a = 0; a < k; ++a)
      if (forces(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
  }
  void delassus(const ContactSet& set, Eigen::Ref<Eigen::MatrixXd> G) const override {
    for (std::size_t a = 0; a < set.size(); ++a)
      for (std::size_t b = 0; b < set.size(); ++b)
        G(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = delassus_(set[a], set[b]);
  }
  double delassus_diagonal(int j) const override { return delassus_(j, j); }
  void apply_impulse(const ContactSet& set, const Eigen::Ref<const Eigen::VectorXd>& impulse,
                     Eigen::VectorXd& v) const override {
    for (std::size_t a = 0; a < set.size(); ++a) v -= minv_normals_.col(set[a]) * impulse(static_cast<Eigen::Index>(a));
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override {
    z -= minv_normals_.col(set[static_cast<std::size_t>(a)]) * s;
  }
  bool accept(const ContactSet& /*held*/, std::string* /*why*/) override { return true; }
  double chatter_alpha(int j) const override { return alpha_(j); }
  double chatter_beta(int j) const override { return beta_(j); }
  /// λ' and λ'' of stop j along the exact flow of the mode with `held` (and the current friction
  /// states) from (t, x, v).
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override {
    const Mode& md = mode(held);
    const Eigen::VectorXd z = detail::augmented_state(sys_, t, x, v);
    const auto a = std::lower_bound(md.held().begin(), md.held().end(), j) - md.held().begin();
    const Eigen::VectorXd Az = md.generator() * z;
    *slope = -md.held_rows().row(a).dot(Az);
    *curvature = -md.held_rows().row(a).dot(md.generator() * Az);
  }
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return normals_.col(j).dot(y); }
  void damped_normal(int j, Eigen::VectorXd& d) override { d = damped_normals_.col(j); }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override {
    e.noalias() = minv_damping_ * d;
    e -= stiff_normals_.col(j);
  }

 private:
  double stop_position(int j, double t) const {
    const Stop& st = stops_[static_cast<std::size_t>(j)];
    const double p = st.s0() + st.s_cos() * std::cos(omega_ * t) + st.s_sin() * std::sin(omega_ * t);
    return st.has_higher_harmonics() ? p + stop_higher_motion(st, omega_, t, 0) : p;
  }
  /// The mode of the held rigid stops `held` with the engaged compliant stops and the current
  /// friction states, built on first use.
  const Mode& mode(const ContactSet& held) {
    ContactSet key;
    std::set_union(held.begin(), held.end(), engaged_.begin(), engaged_.end(), std::back_inserter(key));
    auto it = sim_.modes_.find({key, states_});
    if (it == sim_.modes_.end())
      it = sim_.modes_
               .emplace(std::make_pair(key, states_),
                        std::make_unique<Mode>(scene_, sim_.contacts_, key, states_, sim_.options_.flow))
               .first;
    return *it->second;
  }

  /// An event's resolution (friction_stops.hpp): the stops by resolve_event with the friction
  /// states as they are; the frictional contacts again, with the held stops as constraints;
  /// the stops settled again with the new friction states, until the held set stays.
  bool resolve_all(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases,
                   const ContactSet& resting, int fired, std::string* why) {
    const std::vector<FrictionState> before = states_;
    if (!impacts.empty() || !releases.empty() || !resting.empty() || !st.stuck.empty()) {
      if (!detail::resolve_event(*this, stops_, rules_, st.t, st.x, st.v, st.stuck, impacts, releases, resting, emit_,
                                 summary_, why, work_))
        return false;
    }
    held_by_stops_ = st.stuck;
    Eigen::VectorXd z = detail::augmented_state(sys_, st.t, st.x, st.v);
    {  // An impulse may have moved a relative velocity off zero: that contact slips with it.
      const Eigen::VectorXd u = mode(st.stuck).tables().u_rows * z;
      for (std::size_t j = 0; j < states_.size(); ++j) {
        const double uj = u(static_cast<Eigen::Index>(j));
        if (std::abs(uj) > eps_v_) states_[j] = uj > 0.0 ? FrictionState::slip_positive : FrictionState::slip_negative;
      }
    }
    for (std::size_t round = 0;; ++round) {
      if (!detail::resolve_states(mode(st.stuck).tables(), z, states_, round == 0 ? fired : -1, eps_v_, eps_f_, eps_a_))
        throw std::runtime_error("friction with stops: no consistent stick/slip state at t = " + number_text(st.t));
      if (st.stuck.empty()) break;
      ContactSet next;
      Eigen::VectorXd forces(static_cast<Eigen::Index>(st.stuck.size()));
      settle(st.t, st.x, st.v, st.stuck, next, forces);
      if (next == st.stuck) break;
      if (round > stops_.size())
        throw std::runtime_error("friction with stops: the held stops and the frictional contacts found no consistent "
                                 "state at t = " + number_text(st.t));
      const Eigen::VectorXd rates = scene_.gap_rates(st.t, st.v);
      for (int j : st.stuck)
        if (!std::binary_search(next.begin(), next.end(), j)) {
          emit_({st.t, j, EventKind::release, 0.0, rates(j), 0.0});
          ++summary_.releases;
        }
      st.stuck = next;
    }
    detail::settle_relative_velocities(mode(st.stuck).tables(), before, states_, z);
    st.v = z.segment(sys_.dof(), sys_.dof());
    emit_friction(st, before, z, nullptr);
    return true;
  }

  /// Friction events (friction.hpp's kinds) for the contacts whose state changed (at the start:
  /// every candidate).
  void emit_friction(const detail::RunState& st, const std::vector<FrictionState>& before, const Eigen::VectorXd& z,
                     const std::vector<char>* initial) {
    const Mode& md = mode(st.stuck);
    const Eigen::VectorXd force = md.force_rows() * z;
    const Eigen::VectorXd u = md.tables().u_rows * z;
    for (std::size_t j = 0; j < states_.size(); ++j) {
      FrictionEventKind kind;
      if (initial) {
        if (!(*initial)[j]) continue;
        kind = states_[j] == FrictionState::stuck ? FrictionEventKind::stick : FrictionEventKind::slip;
      } else if (states_[j] == before[j]) {
        continue;
      } else if (states_[j] == FrictionState::stuck) {
        kind = FrictionEventKind::stick;
      } else if (before[j] == FrictionState::stuck) {
        kind = FrictionEventKind::slip;
      } else {
        kind = FrictionEventKind::reversal;
      }
      const auto J = static_cast<Eigen::Index>(j);
      EventKind out = EventKind::friction_stick;
      if (kind == FrictionEventKind::stick) {
        ++sim_.sticks_;
        ++summary_.sticks;
      } else {
        out = kind == FrictionEventKind::slip ? EventKind::friction_slip : EventKind::friction_reversal;
        ++(kind == FrictionEventKind::slip ? sim_.slips_ : sim_.reversals_);
        ++summary_.releases;
      }
      emit_({st.t, static_cast<int>(j), out, u(J), u(J), force(J)});
    }
  }

  FrictionStopSimulator& sim_;
  const ImpactSystem& scene_;
  const LinearSystem& sys_;
  const std::vector<Stop>& stops_;
  const std::vector<Observer*>& observers_;
  const std::vector<FrictionStopObserver*>& mode_observers_;
  RunSummary& summary_;
  double t_end_, omega_;
  Eigen::MatrixXd normals_, minv_, minv_normals_, delassus_, minv_damping_, damped_normals_, stiff_normals_;
  Eigen::VectorXd alpha_, beta_, h_, d_, trig_;
  LcpWorkspace lcp_;
  double eps_gap_ = 0.0, eps_f_ = 0.0, eps_v_ = 0.0, eps_a_ = 0.0, resolution_ = 0.0;
  detail::EventRules rules_;
  detail::EventWorkspace work_;
  std::function<void(const Event&)> emit_;
  ContactSet engaged_, held_by_stops_;
  std::vector<FrictionState> states_;
  const Mode* mode_ = nullptr;
  Segment* segment_ = nullptr;
  Eigen::Index crossing_row_ = -1;
};

FrictionStopSimulator::FrictionStopSimulator(const ImpactSystem& scene, std::vector<FrictionContact> contacts,
                                             SimulatorOptions options)
    : scene_(&scene), contacts_(validated_friction(std::move(contacts), scene.dof())), options_(options) {
  options_.validate();
}

FrictionStopSimulator::~FrictionStopSimulator() = default;

RunSummary FrictionStopSimulator::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                                      const std::vector<Observer*>& observers,
                                      const std::vector<FrictionStopObserver*>& mode_observers) {
  sticks_ = slips_ = reversals_ = 0;
  RunSummary summary;
  Loop loop(*this, observers, mode_observers, summary, t_end);
  detail::run_event_loop(loop, options_, t0, x0, v0, t_end, observers, summary);
  return summary;
}

}  // namespace vibro
