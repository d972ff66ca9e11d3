#include "vibro/simulator.hpp"

#include "event_loop.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace vibro {
namespace {

void require_positive(double value, const char* field, bool allow_zero = false) {
  if (!std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0))
    throw InvalidInput(std::string("solver.") + field + " = " + number_text(value) + ": must be a finite number " +
                       (allow_zero ? "≥ 0" : "> 0"));
}

/// Per-run tables of the stops (allocated once per run, so that no event allocates): the normals
/// W and M⁻¹W, the Delassus matrix of all stops G = WᵀM⁻¹W (a set's G is its principal
/// submatrix), each stop's motion s(t) = s0 + sc cos Ωt + ss sin Ωt (and whether higher harmonics
/// add to it, stops.hpp), and for the second-order
/// chatter rule α_j = -w_jᵀ M⁻¹ C M⁻¹ w_j / G_jj and the pieces of its state correction,
/// M⁻¹ C M⁻¹ w_j, M⁻¹ K M⁻¹ w_j and M⁻¹ C (event_resolution.cpp, chatter_correction).
struct StopTables {
  Eigen::MatrixXd normals, minv_normals, delassus, damped_normals, stiff_normals, minv_damping;
  Eigen::VectorXd s0, sc, ss, chatter_alpha, chatter_beta;
  std::vector<char> higher;  ///< per stop: whether it moves with harmonics of order ≥ 2 too

  explicit StopTables(const ImpactSystem& scene) {
    const LinearSystem& sys = scene.system();
    const auto m = static_cast<Eigen::Index>(scene.stop_count());
    const Eigen::LLT<Eigen::MatrixXd> mass_llt(sys.mass());
    normals = scene.normals();
    // No stops: an n × 0 solve (or product) would hand Eigen's kernels a null pointer (UBSan).
    minv_normals = m > 0 ? Eigen::MatrixXd(mass_llt.solve(normals)) : Eigen::MatrixXd(sys.dof(), 0);
    const Eigen::MatrixXd g = m > 0 ? Eigen::MatrixXd(normals.transpose() * minv_normals) : Eigen::MatrixXd(0, 0);
    delassus = 0.5 * (g + g.transpose());
    s0.resize(m);
    sc.resize(m);
    ss.resize(m);
    chatter_alpha.resize(m);
    chatter_beta.resize(m);
    minv_damping = mass_llt.solve(sys.damping());
    damped_normals = m > 0 ? Eigen::MatrixXd(minv_damping * minv_normals) : Eigen::MatrixXd(sys.dof(), 0);
    stiff_normals = m > 0 ? Eigen::MatrixXd(mass_llt.solve(sys.stiffness() * minv_normals)) : Eigen::MatrixXd(sys.dof(), 0);
    for (Eigen::Index j = 0; j < m; ++j) {
      const Stop& st = scene.stops()[static_cast<std::size_t>(j)];
      s0(j) = st.s0();
      sc(j) = st.s_cos();
      ss(j) = st.s_sin();
      higher.push_back(st.has_higher_harmonics() ? 1 : 0);
      chatter_alpha(j) = -minv_normals.col(j).dot(sys.damping() * minv_normals.col(j)) / delassus(j, j);
      // β_j = (qᵀ C M⁻¹ C q − qᵀ K q) / G − (qᵀ C q / G)², q = M⁻¹ w_j (simulator.hpp, ChatterRule).
      const auto q = minv_normals.col(j);
      const double G = delassus(j, j), qcq = q.dot(sys.damping() * q);
      chatter_beta(j) = (q.dot(sys.damping() * damped_normals.col(j)) - q.dot(sys.stiffness() * q)) / G -
                        (qcq / G) * (qcq / G);
    }
  }
};

/// The dense engine's side of event resolution (event_resolution.hpp), allocation-free: the
/// stops' tables above, the sticking flow of a held set (cached ContactModes) for the
/// second-order chatter rule, and scratch sized for the run.
class DenseAlgebra final : public detail::ContactAlgebra {
 public:
  DenseAlgebra(const ImpactSystem& scene, ContactModes& modes, const StopTables& tables)
      : scene_(scene), modes_(modes), tab_(tables), omega_(scene.system().forcing().frequency) {
    const Eigen::Index n = scene.dof(), m = static_cast<Eigen::Index>(scene.stop_count());
    residual_.resize(n);
    reduced_state_.resize(augmented_size(n, scene.system().forcing()));
    q_.resize(m);
    G_.resize(m, m);
    lcp_.reserve(m);
    key_.reserve(static_cast<std::size_t>(m));
  }

  double gap(int j, double t, const Eigen::VectorXd& x) const override {
    const auto [c, s] = phase(t);
    const double g = tab_.normals.col(j).dot(x) - (tab_.s0(j) + tab_.sc(j) * c + tab_.ss(j) * s);
    return tab_.higher[static_cast<std::size_t>(j)] ? g - higher(j, t, 0) : g;
  }
  void gap_rates(double t, const Eigen::VectorXd& v, Eigen::Ref<Eigen::VectorXd> out) const override {
    const auto [c, s] = phase(t);
    for (Eigen::Index j = 0; j < out.size(); ++j) {
      out(j) = tab_.normals.col(j).dot(v) - omega_ * (-tab_.sc(j) * s + tab_.ss(j) * c);
      if (tab_.higher[static_cast<std::size_t>(j)]) out(j) -= higher(static_cast<int>(j), t, 1);
    }
  }
  /// The engaged compliant stops whose forces act alongside (nullptr or empty: none); the
  /// held rigid stops' algebra then runs on the mode with them (contact.hpp).
  void set_engaged(const ContactSet* engaged) { engaged_ = engaged; }
  /// The acceleration LCP of contact.hpp: q = free gap acceleration Wᵀ M⁻¹ (f - C v - K x
  /// - Σ_engaged w N) - s''(t), N = k g + c g' + F_p of each engaged compliant stop.
  void settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, const ContactSet& candidates,
              ContactSet& held, Eigen::Ref<Eigen::VectorXd> forces) override {
    held.clear();
    if (candidates.empty()) return;
    const LinearSystem& sys = scene_.system();
    const HarmonicForcing& f = sys.forcing();
    const auto [c, s] = phase(t);
    residual_.noalias() = -sys.damping() * v;
    residual_.noalias() -= sys.stiffness() * x;
    residual_ += f.constant + f.cosine * c + f.sine * s;
    for (const ForcingHarmonic& h : f.harmonics) {
      const double w = h.rate(f.frequency);
      residual_ += h.cosine * std::cos(w * t) + h.sine * std::sin(w * t);
    }
    if (engaged_)
      for (int j : *engaged_) residual_ -= tab_.normals.col(j) * compliant_force(j, t, x, v);
    const auto k = static_cast<Eigen::Index>(candidates.size());
    auto q = q_.head(k);
    auto G = G_.topLeftCorner(k, k);
    delassus(candidates, G);
    for (Eigen::Index a = 0; a < k; ++a) {
      const int j = candidates[static_cast<std::size_t>(a)];
      const double s_dd = -omega_ * omega_ * (tab_.sc(j) * c + tab_.ss(j) * s);
      q(a) = tab_.minv_normals.col(j).dot(residual_) - s_dd;
      if (tab_.higher[static_cast<std::size_t>(j)]) q(a) -= higher(j, t, 2);
    }
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
    for (std::size_t a = 0; a < set.size(); ++a)
      v -= tab_.minv_normals.col(set[a]) * impulse(static_cast<Eigen::Index>(a));
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) const override {
    z -= tab_.minv_normals.col(set[static_cast<std::size_t>(a)]) * s;
  }
  bool accept(const ContactSet& /*held*/, std::string* /*why*/) override { return true; }
  double chatter_alpha(int j) const override { return tab_.chatter_alpha(j); }
  void force_rates(const ContactSet& held, int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                   double* slope, double* curvature) override {
    const ContactMode& mode = modes_.get(mode_key(held));
    const ContactMode::Reduced& red = mode.reduced();
    auto z = reduced_state_.head(red.flow->size());
    mode.reduce(t, x, v, z);
    const auto a_idx = std::lower_bound(held.begin(), held.end(), j) - held.begin();
    *slope = -red.watch->rows(1).row(red.gap_rows + a_idx).dot(z);
    *curvature = -red.watch->rows(2).row(red.gap_rows + a_idx).dot(z);
  }
  double chatter_beta(int j) const override { return tab_.chatter_beta(j); }
  double normal_dot(int j, const Eigen::VectorXd& y) const override { return tab_.normals.col(j).dot(y); }
  void damped_normal(int j, Eigen::VectorXd& d) override { d = tab_.damped_normals.col(j); }
  void damped_response(int j, const Eigen::VectorXd& d, Eigen::VectorXd& e) override {
    e.noalias() = tab_.minv_damping * d;
    e -= tab_.stiff_normals.col(j);
  }

  /// N = k g + c g' + F_p of compliant stop j at (t, x, v) (stops.hpp).
  double compliant_force(int j, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) const {
    const Stop& st = scene_.stops()[static_cast<std::size_t>(j)];
    const auto [c, s] = phase(t);
    double rate = tab_.normals.col(j).dot(v) - omega_ * (-tab_.sc(j) * s + tab_.ss(j) * c);
    if (tab_.higher[static_cast<std::size_t>(j)]) rate -= higher(j, t, 1);
    return st.stiffness * gap(j, t, x) + st.damping * rate + st.preload;
  }
  /// The mode of the held rigid stops `held` with the engaged compliant ones (sorted union).
  const ContactSet& mode_key(const ContactSet& held) {
    if (!engaged_ || engaged_->empty()) return held;
    key_.clear();
    std::set_union(held.begin(), held.end(), engaged_->begin(), engaged_->end(), std::back_inserter(key_));
    return key_;
  }

 private:
  /// The higher harmonics' part of stop j's s, s' or s'' (stops.hpp).
  double higher(int j, double t, int derivative) const {
    return stop_higher_motion(scene_.stops()[static_cast<std::size_t>(j)], omega_, t, derivative);
  }
  /// (cos Ωt, sin Ωt), kept for the last t (an event asks for them several times).
  std::pair<double, double> phase(double t) const {
    if (!(t == phase_t_)) {
      phase_t_ = t;
      phase_ = {std::cos(omega_ * t), std::sin(omega_ * t)};
    }
    return phase_;
  }

  const ImpactSystem& scene_;
  ContactModes& modes_;
  const StopTables& tab_;
  double omega_;
  mutable double phase_t_ = std::numeric_limits<double>::quiet_NaN();
  mutable std::pair<double, double> phase_;
  Eigen::VectorXd residual_, reduced_state_, q_;
  Eigen::MatrixXd G_;
  LcpWorkspace lcp_;
  const ContactSet* engaged_ = nullptr;
  ContactSet key_;
};

/// What the event loop keeps per contact mode visited, so that returning to a mode allocates
/// nothing: its segment (re-targeted at each visit), its crossing finder and trigger levels.
struct ModeSlot {
  const Functionals* watch = nullptr;
  std::unique_ptr<Segment> segment;
  CrossingFinder finder;
  Eigen::VectorXd triggers;
};

}  // namespace

const char* to_string(RunStatus s) {
  switch (s) {
    case RunStatus::completed: return "completed";
    case RunStatus::event_cap: return "event cap reached";
    case RunStatus::numerical_failure: return "numerical failure";
    case RunStatus::unsupported: return "not supported by this engine";
    case RunStatus::interrupted: return "interrupted";
  }
  return "?";
}

const char* to_string(ChatterRule rule) {
  switch (rule) {
    case ChatterRule::first_order: return "first_order";
    case ChatterRule::second_order: return "second_order";
    case ChatterRule::third_order: return "third_order";
  }
  return "?";
}

void SimulatorOptions::validate() const {
  require_positive(trigger, "trigger");
  require_positive(simultaneity, "simultaneity", true);
  require_positive(chatter_velocity, "chatter_velocity", true);
  require_positive(chatter_height, "chatter_height", true);
  require_positive(contact_velocity, "contact_velocity", true);
  require_positive(event_window, "event_window", true);
  require_positive(length_scale, "length_scale", true);
  if (max_events < 1)
    throw InvalidInput("solver.max_events = " + std::to_string(max_events) + ": must be ≥ 1");
  if (trigger >= 1e-3)
    throw InvalidInput("solver.trigger = " + number_text(trigger) +
                       ": must be < 1e-3 (it is the allowed penetration relative to the length scale)");
}

double run_length_scale(const SimulatorOptions& options, double omega, double kmax, double mmax, double fmax,
                        const std::vector<Stop>& stops, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0) {
  return detail::run_scales(options, omega, kmax, mmax, fmax, stops, x0, v0).L;
}

Simulator::Simulator(const ImpactSystem& scene, SimulatorOptions options)
    : scene_(&scene), options_(options), modes_(scene, options.flow, options.interrupt) {
  options_.validate();
}

double Simulator::scale_frequency() const {
  const LinearSystem& sys = scene_->system();
  if (sys.forcing().frequency != 0.0) return sys.forcing().frequency;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys.stiffness(), sys.mass(), Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
}

ContactSet Simulator::settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                             const ContactSet& candidates, Eigen::VectorXd* forces) const {
  if (candidates.empty()) {
    if (forces) forces->resize(0);
    return {};
  }
  const StopTables tables(*scene_);
  DenseAlgebra algebra(*scene_, const_cast<ContactModes&>(modes_), tables);  // settle reads no mode
  ContactSet held;
  held.reserve(candidates.size());
  Eigen::VectorXd lambda(static_cast<Eigen::Index>(candidates.size()));
  algebra.settle(t, x, v, candidates, held, lambda);
  if (forces) *forces = lambda;
  return held;
}

/// The dense engine's side of the event loop (event_loop.hpp): exact flows of the contact modes
/// (ContactModes, flow.hpp), one Segment and CrossingFinder per mode visited, the stops' algebra
/// of DenseAlgebra.
class Simulator::Loop {
 public:
  Loop(Simulator& sim, const std::vector<Observer*>& observers, RunSummary& summary, double t_end)
      : sim_(sim), scene_(*sim.scene_), sys_(scene_.system()), observers_(observers), summary_(summary),
        t_end_(t_end) {}

  Eigen::Index dof() const { return sys_.dof(); }
  const std::vector<Stop>& stops() const { return scene_.stops(); }
  double frequency() const { return sys_.forcing().frequency; }
  detail::ScaleInputs scale_inputs() {
    const HarmonicForcing& f = sys_.forcing();
    in_ = {sim_.scale_frequency(), sys_.stiffness().cwiseAbs().maxCoeff(), sys_.mass().cwiseAbs().maxCoeff(),
           f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff()};
    for (const ForcingHarmonic& h : f.harmonics) in_.fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
    return in_;
  }
  void check_scene(const detail::RunScales& /*sc*/, std::vector<std::string>& warnings) const {
    // The exact flow carries the forcing as a unit oscillator (z = [x; v; cos; sin; 1]), so its
    // rounding is relative to max(1, fmax/k) in the scene's length unit: measured 12 ε fmax/k
    // relative (one mass, k = 1, F = 1e6 … 1e15: 3.6e-9 … 0.67; tests/framework/test_resolution.cpp).
    const SimulatorOptions& options = sim_.options_;
    const double stiff = std::max(in_.kmax, in_.mmax * in_.omega * in_.omega);
    const double deflection = stiff > 0.0 ? in_.fmax / stiff : 0.0;
    const double relative = 12.0 * std::numeric_limits<double>::epsilon() * deflection;
    if (relative > std::min(options.trigger, 1e-6)) {  // the message only where used (~2 µs a run)
      const std::string why = "the forcing's static deflection fmax/k = " + number_text(deflection) +
                              " (in the scene's length unit) costs the exact flow about 12 ε × " +
                              number_text(deflection) + " = " + number_text(relative) + " relative rounding";
      const std::string hint = "; scale lengths (stops, initial state) and forces by one factor so that the "
                               "deflection is of order 1 (the motion scales exactly)";
      if (relative > 1e-6) throw InvalidInput(why + " (1e-6 at most)" + hint);
      if (relative > options.trigger)
        warnings.push_back(why + ", above the trigger " + number_text(options.trigger) + hint);
    }
  }
  void start(const detail::RunScales& sc, detail::RunState& st) {
    const Eigen::Index n = sys_.dof();
    sim_.guard_evaluations_ = 0;
    eps_gap_ = sc.eps_gap;
    eps_force_ = sc.eps_force;
    rules_ = sc.rules;
    resolution_ = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end_), sc.T);
    // Scratch sized once: the largest reduced state is the full one (augmented_size).
    const Eigen::Index N = augmented_size(n, sys_.forcing());
    for (Eigen::VectorXd* z : {&reduced_state_, &zr_, &z_full_}) z->resize(N);
    view_scratch_.resize(2 * N);
    tables_ = std::make_unique<StopTables>(scene_);
    algebra_ = std::make_unique<DenseAlgebra>(scene_, sim_.modes_, *tables_);
    work_.reserve(static_cast<Eigen::Index>(scene_.stop_count()), n);
    emit_ = [this](const Event& e) {
      for (Observer* o : observers_) o->event(e);
    };
    // Impact sets are visited sets too (RunSummary::contact_sets_built): their restitution data.
    visit_ = [this](const ContactSet& set) { sim_.modes_.get(set); };
    // Compliant stops (stops.hpp): those penetrated at t0 start engaged (CompliantStopLaw).
    compliant_ = has_compliant(scene_.stops());
    engaged_.clear();
    if (compliant_) {
      const auto m = static_cast<std::size_t>(scene_.stop_count());
      for (ContactSet* set : {&engaged_, &key_, &rigid_impacts_, &rigid_releases_}) set->reserve(m);
      rates_.resize(static_cast<Eigen::Index>(m));
      const Eigen::VectorXd g = scene_.gaps(st.t, st.x);
      for (std::size_t j = 0; j < m; ++j)
        if (scene_.stops()[j].is_compliant() && CompliantStopLaw::engaged_at_start(g(static_cast<Eigen::Index>(j))))
          engaged_.push_back(static_cast<int>(j));
      algebra_->set_engaged(&engaged_);
    }
  }
  void initial_guards(const detail::RunState& st, Eigen::VectorXd& g, Eigen::VectorXd& gd) const {
    g = scene_.gaps(st.t, st.x);
    gd = scene_.gap_rates(st.t, st.v);
  }
  /// Events are resolved by the rules shared with the modal engine (event_resolution.hpp); every
  /// contact set has a dense mode.
  bool resolve(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, const ContactSet& resting,
               std::string* /*why*/) {
    std::string unused;
    detail::resolve_event(*algebra_, scene_.stops(), rules_, st.t, st.x, st.v, st.stuck, impacts, releases, resting,
                          emit_, summary_, &unused, work_, visit_);
    return true;
  }
  /// Compliant stops' switches (engage, disengage: the state unchanged, the mode changes) come
  /// first, then the rigid stops' impacts and releases, resolved with the new engaged set's
  /// forces acting; held rigid stops are settled again after a switch (a preload or dashpot
  /// that sets in may pull a held stop open).
  bool event(detail::RunState& st, const ContactSet& impacts, const ContactSet& releases, std::string* why) {
    if (!compliant_) return resolve(st, impacts, releases, {}, why);
    const bool switched = detail::compliant_switches(*algebra_, scene_.stops(), st.t, st.x, st.v, impacts, releases,
                                                     engaged_, rigid_impacts_, rigid_releases_, rates_, emit_);
    if (rigid_impacts_.empty() && rigid_releases_.empty() && !(switched && !st.stuck.empty())) return true;
    return resolve(st, rigid_impacts_, rigid_releases_, {}, why);
  }
  /// The current mode's key: the held rigid stops and the engaged compliant ones (contact.hpp).
  const ContactSet& mode_key(const detail::RunState& st) {
    if (engaged_.empty()) return st.stuck;
    key_.clear();
    std::set_union(st.stuck.begin(), st.stuck.end(), engaged_.begin(), engaged_.end(), std::back_inserter(key_));
    return key_;
  }
  double stiffness(const detail::RunState& st, double T) {
    return T * sim_.modes_.get(mode_key(st)).reduced().flow->spectral_radius();
  }

  detail::SegmentPlan begin_segment(const detail::RunState& st, double t_end) {
    mode_ = &sim_.modes_.get(mode_key(st));
    const ContactMode::Reduced& red = mode_->reduced();
    // One segment and finder per contact mode, reused: re-targeting them allocates nothing.
    ModeSlot* slot = nullptr;
    for (const auto& s : slots_)
      if (s->watch == red.watch.get()) slot = s.get();
    const Eigen::Index size = red.flow->size();
    auto z0 = reduced_state_.head(size);
    mode_->reduce(st.t, st.x, st.v, z0);
    if (!slot) {
      slots_.push_back(std::make_unique<ModeSlot>());
      slot = slots_.back().get();
      slot->watch = red.watch.get();
      slot->segment = std::make_unique<Segment>(*red.watch, st.t, z0);
    } else {
      slot->segment->reset(st.t, z0);
    }
    slot_ = slot;
    rows_ = red.watch->count();
    Eigen::VectorXd& base = slot->triggers;
    base.resize(rows_);
    for (Eigen::Index i = 0; i < rows_; ++i)  // gaps (and engaged compliant stops' -g) against ε·L
      base(i) = i < red.gap_rows || i >= red.engaged_rows_from ? eps_gap_ : eps_force_;
    // A guard that starts inside its tolerance band while moving away (just after an impact or
    // a release) is only re-armed above where it starts, so rounding cannot re-fire it.
    slot->finder.retarget(*slot->segment, base, resolution_, true);
    guards_before_ = slot->segment->guard_evaluations();
    points_before_ = slot->segment->evaluations();
    // The closed-form exponential of a nearly defective flow holds up to its horizon
    // (flow.hpp): a longer free flight is continued as a new segment from there.
    return {1.0 / std::max(red.flow->spectral_radius(), 1e-300), std::min(t_end - st.t, red.flow->horizon())};
  }
  bool search(double a, double b, Crossing* hit) {
    if (rows_ == 0) return false;
    const std::optional<Crossing> c = slot_->finder.first(a, b);
    if (c) *hit = *c;
    return c.has_value();
  }
  void end_search() {
    const Segment& segment = *slot_->segment;
    summary_.guard_evaluations += segment.guard_evaluations() - guards_before_;
    summary_.evaluation_points += segment.evaluations() - points_before_;
    sim_.guard_evaluations_ = summary_.guard_evaluations;
  }
  void report(double t, double t_next, const std::vector<Observer*>& observers) {
    const DenseSegmentView view(*mode_, *slot_->segment, t, t_next, eps_force_, &view_scratch_);
    for (Observer* o : observers) o->segment(view);
  }
  bool advance(detail::RunState& st, const Crossing* hit, double /*tau*/, double t_next) {
    const Segment& segment = *slot_->segment;
    const Eigen::Index n = sys_.dof();
    auto z = zr_.head(mode_->reduced().flow->size());
    // The state at t_next exactly as the observers' view gives it (at t_next - t, which may
    // differ from tau by an ulp of t): the analysis layer's saltation matrices combine the
    // view's pre-event state with the engine's post-event one, and a state an ulp of t
    // apart (|ż|·ulp(t), ~1e-12 at t ~ 1e4) biases, e.g., a conservative system's Lyapunov sum
    // (test_lyapunov.cpp). The crossing's own exponentials are reused where the two times agree.
    const double elapsed = t_next - st.t;
    if (hit && elapsed == hit->tau) segment.state(slot_->finder.crossing_sample(), z);
    else segment.state(elapsed, z);
    mode_->expand(z, z_full_);
    st.x = z_full_.head(n);
    st.v = z_full_.segment(n, n);
    return st.x.allFinite() && st.v.allFinite();
  }
  detail::FiredGuards fired() const {
    const SegmentSample& at = slot_->finder.crossing_sample();
    const ContactMode::Reduced& red = mode_->reduced();
    return {at.h, at.d, slot_->finder.triggers(), red.gap_rows, red.watched};
  }
  bool stop_requested(std::string* /*why*/) const { return false; }
  void state(const detail::RunState& st, bool /*physical*/, Eigen::VectorXd& x, Eigen::VectorXd& v) const {
    x = st.x;
    v = st.v;
  }
  void finish(RunSummary& summary) const {
    summary.contact_sets_built = sim_.modes_.built();
    summary.sticking_flows_built = sim_.modes_.reduced_built();
  }

 private:
  Simulator& sim_;
  const ImpactSystem& scene_;
  const LinearSystem& sys_;
  const std::vector<Observer*>& observers_;
  RunSummary& summary_;
  double t_end_;
  detail::ScaleInputs in_;
  double eps_gap_ = 0.0, eps_force_ = 0.0, resolution_ = 0.0;
  detail::EventRules rules_;
  Eigen::VectorXd reduced_state_, zr_, z_full_, view_scratch_;
  std::vector<std::unique_ptr<ModeSlot>> slots_;
  std::unique_ptr<StopTables> tables_;
  std::unique_ptr<DenseAlgebra> algebra_;
  detail::EventWorkspace work_;
  std::function<void(const Event&)> emit_;
  std::function<void(const ContactSet&)> visit_;
  const ContactMode* mode_ = nullptr;
  ModeSlot* slot_ = nullptr;
  bool compliant_ = false;                            // the scene has compliant stops
  ContactSet engaged_, key_, rigid_impacts_, rigid_releases_;  // engaged compliant stops; scratch
  Eigen::VectorXd rates_;
  Eigen::Index rows_ = 0;
  long guards_before_ = 0, points_before_ = 0;
};

RunSummary Simulator::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                          double t_end, const std::vector<Observer*>& observers) {
  RunSummary summary;
  Loop loop(*this, observers, summary, t_end);
  detail::run_event_loop(loop, options_, t0, x0, v0, t_end, observers, summary);
  return summary;
}

}  // namespace vibro
