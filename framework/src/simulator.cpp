#include "vibro/simulator.hpp"

#include "event_rate.hpp"
#include "event_resolution.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace vibro {
namespace {

std::string vector_text(const Eigen::VectorXd& v) {
  std::ostringstream s;
  s.precision(17);
  s << "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v(i);
  s << "]";
  return s.str();
}

void require_positive(double value, const char* field, bool allow_zero = false) {
  if (!std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0))
    throw InvalidInput(std::string("solver.") + field + " = " + number_text(value) + ": must be a finite number " +
                       (allow_zero ? "≥ 0" : "> 0"));
}

/// The dense engine's side of event resolution (event_resolution.hpp): restitution data from the
/// cached ContactModes, the sticking flow of a held set for the second-order chatter rule.
class DenseAlgebra final : public detail::ContactAlgebra {
 public:
  DenseAlgebra(const Simulator& sim, const ImpactSystem& scene, ContactModes& modes,
               const Eigen::VectorXd& delassus_diag, const Eigen::VectorXd& chatter_alpha,
               const Eigen::MatrixXd& chatter_kick, Eigen::VectorXd& reduced_state)
      : sim_(sim), scene_(scene), modes_(modes), delassus_diag_(delassus_diag),
        chatter_alpha_(chatter_alpha), chatter_kick_(chatter_kick), reduced_state_(reduced_state) {}

  double gap(int j, double t, const Eigen::VectorXd& x) const override { return scene_.gaps(t, x)(j); }
  Eigen::VectorXd gap_rates(double t, const Eigen::VectorXd& v) const override { return scene_.gap_rates(t, v); }
  ContactSet settle(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                    const ContactSet& candidates, Eigen::VectorXd* forces) override {
    return sim_.settle(t, x, v, candidates, forces);
  }
  Eigen::MatrixXd delassus(const ContactSet& set) override { return modes_.get(set).delassus(); }
  double delassus_diagonal(int j) const override { return delassus_diag_(j); }
  void apply_impulse(const ContactSet& set, const Eigen::VectorXd& impulse, Eigen::VectorXd& v) override {
    v -= modes_.get(set).mass_inverse_normals() * impulse;
  }
  void shift(const ContactSet& set, Eigen::Index a, double s, Eigen::VectorXd& z) override {
    z -= modes_.get(set).mass_inverse_normals().col(a) * s;
  }
  bool accept(const ContactSet& /*held*/, std::string* /*why*/) override { return true; }
  double chatter_alpha(int j) const override { return chatter_alpha_(j); }
  double force_slope(const ContactSet& held, int j, double t, const Eigen::VectorXd& x,
                     const Eigen::VectorXd& v) override {
    const ContactMode& mode = modes_.get(held);
    const ContactMode::Reduced& red = mode.reduced();
    reduced_state_.resize(red.flow->size());
    mode.reduce(t, x, v, reduced_state_);
    const auto a_idx = std::lower_bound(held.begin(), held.end(), j) - held.begin();
    return -red.watch->rows(1).row(red.gap_rows + a_idx).dot(reduced_state_);
  }
  void chatter_kick(int j, double s, Eigen::VectorXd& v) override { v -= chatter_kick_.col(j) * s; }

 private:
  const Simulator& sim_;
  const ImpactSystem& scene_;
  ContactModes& modes_;
  const Eigen::VectorXd &delassus_diag_, &chatter_alpha_;
  const Eigen::MatrixXd& chatter_kick_;
  Eigen::VectorXd& reduced_state_;
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
    : scene_(&scene), options_(options), modes_(scene, options.flow) {
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
  const LinearSystem& sys = scene_->system();
  const double omega = sys.forcing().frequency;
  const auto m = static_cast<Eigen::Index>(candidates.size());
  // q = free gap acceleration Wᵀ M⁻¹ (f - C v - K x) - s''(t).
  const Eigen::VectorXd acc = sys.acceleration(t, x, v);
  Eigen::VectorXd q(m);
  Eigen::MatrixXd G(m, m);
  const Eigen::MatrixXd& W = scene_->normals();
  const Eigen::LLT<Eigen::MatrixXd> llt(sys.mass());
  Eigen::MatrixXd Wc(W.rows(), m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const int j = candidates[static_cast<std::size_t>(a)];
    const Stop& st = scene_->stops()[static_cast<std::size_t>(j)];
    const double s_dd = -omega * omega * (st.s_cos() * std::cos(omega * t) + st.s_sin() * std::sin(omega * t));
    q(a) = W.col(j).dot(acc) - s_dd;
    Wc.col(a) = W.col(j);
  }
  G = Wc.transpose() * llt.solve(Wc);
  const Eigen::VectorXd lambda = solve_lcp(G, q);
  ContactSet held;
  for (Eigen::Index a = 0; a < m; ++a)
    if (lambda(a) > 0.0) held.push_back(candidates[static_cast<std::size_t>(a)]);
  if (forces) *forces = lambda;
  return held;
}

RunSummary Simulator::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                          double t_end, const std::vector<Observer*>& observers) {
  const ImpactSystem& scene = *scene_;
  const LinearSystem& sys = scene.system();
  const Eigen::Index n = sys.dof();
  const int stops = static_cast<int>(scene.stop_count());
  if (x0.size() != n || v0.size() != n)
    throw InvalidInput("initial state: x has " + std::to_string(x0.size()) + " and v has " +
                       std::to_string(v0.size()) + " entries, expected " + std::to_string(n));
  if (!x0.allFinite() || !v0.allFinite())
    throw InvalidInput("initial state: x = " + vector_text(x0) + ", v = " + vector_text(v0) + " is not finite");
  if (!std::isfinite(t0) || !std::isfinite(t_end) || t_end < t0)
    throw InvalidInput("time span: [" + number_text(t0) + ", " + number_text(t_end) + "] must be finite with t_end ≥ t0");

  const HarmonicForcing& f = sys.forcing();
  const double omega = scale_frequency(), kmax = sys.stiffness().cwiseAbs().maxCoeff();
  const double mmax = sys.mass().cwiseAbs().maxCoeff();
  const double fmax = f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff();
  const detail::RunScales sc = detail::run_scales(options_, omega, kmax, mmax, fmax, scene.stops(), x0, v0);
  SimulatorOptions automatic = options_;
  automatic.length_scale = 0.0;
  std::vector<std::string> warnings;
  detail::check_resolution(sc, detail::run_scales(automatic, omega, kmax, mmax, fmax, scene.stops(), x0, v0),
                           options_, t0, t_end, warnings);
  {
    // The exact flow carries the forcing as a unit oscillator (z = [x; v; cos; sin; 1]), so its
    // rounding is relative to max(1, fmax/k) in the scene's length unit: measured 12 ε fmax/k
    // relative (one mass, k = 1, F = 1e6 … 1e15: 3.6e-9 … 0.67; tests/framework/test_resolution.cpp).
    const double stiff = std::max(kmax, mmax * omega * omega);
    const double deflection = stiff > 0.0 ? fmax / stiff : 0.0;
    const double relative = 12.0 * std::numeric_limits<double>::epsilon() * deflection;
    const std::string why = "the forcing's static deflection fmax/k = " + number_text(deflection) +
                            " (in the scene's length unit) costs the exact flow about 12 ε × " + number_text(deflection) +
                            " = " + number_text(relative) + " relative rounding";
    const std::string hint = "; scale lengths (stops, initial state) and forces by one factor so that the "
                             "deflection is of order 1 (the motion scales exactly)";
    if (relative > 1e-6) throw InvalidInput(why + " (1e-6 at most)" + hint);
    if (relative > options_.trigger) warnings.push_back(why + ", above the trigger " + number_text(options_.trigger) + hint);
  }
  const double eps_gap = sc.eps_gap, eps_force = sc.eps_force, v_contact = sc.rules.v_contact;
  const double dt_simultaneous = sc.dt_simultaneous, window = sc.window;
  scene.check_admissible(t0, x0, eps_gap);

  RunSummary summary;
  summary.warnings = std::move(warnings);
  summary.length_scale = sc.L;
  summary.velocity_scale = sc.V;
  summary.force_scale = sc.F;
  summary.time_scale = sc.T;
  const RunContext context{n, scene.stop_count(), sys.forcing().frequency};
  for (Observer* o : observers) o->begin(context, t0);

  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  ContactSet stuck;
  detail::EventRate rate(options_.max_events, window);
  const Eigen::LLT<Eigen::MatrixXd> mass_llt(sys.mass());
  // Per stop, once per run: M⁻¹ w_j, G_jj = w_jᵀ M⁻¹ w_j, and for the second-order chatter rule
  // α_j = -w_jᵀ M⁻¹ C M⁻¹ w_j / G_jj and the direction M⁻¹ K M⁻¹ w_j / G_jj of its state kick.
  // No stops: an n × 0 solve would hand Eigen's kernels a null pointer (UBSan).
  const Eigen::MatrixXd minv_normals = stops > 0 ? Eigen::MatrixXd(mass_llt.solve(scene.normals())) : Eigen::MatrixXd(n, 0);
  Eigen::VectorXd delassus_diag(stops), chatter_alpha(stops);
  Eigen::MatrixXd chatter_kick(n, stops);
  for (int j = 0; j < stops; ++j) {
    delassus_diag(j) = scene.normals().col(j).dot(minv_normals.col(j));
    chatter_alpha(j) = -minv_normals.col(j).dot(sys.damping() * minv_normals.col(j)) / delassus_diag(j);
    chatter_kick.col(j) = mass_llt.solve(sys.stiffness() * minv_normals.col(j)) / delassus_diag(j);
  }
  auto emit = [&](const Event& e) {
    for (Observer* o : observers) o->event(e);
  };
  auto finish = [&](RunStatus status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    summary.t = t;
    summary.x = x;
    summary.v = v;
    summary.stuck = stuck;
    summary.contact_sets_built = modes_.built();
    summary.sticking_flows_built = modes_.reduced_built();
    for (Observer* o : observers) o->end(t);
    return summary;
  };

  Eigen::VectorXd reduced_state, triggers, zr, z_full(2 * n + 3);
  std::vector<std::pair<const Functionals*, std::unique_ptr<Segment>>> segments;

  // Events are resolved by the rules shared with the modal engine (event_resolution.hpp).
  DenseAlgebra algebra(*this, scene, modes_, delassus_diag, chatter_alpha, chatter_kick, reduced_state);
  const detail::EventRules& rules = sc.rules;
  const std::function<void(const Event&)> emit_event = emit;
  auto resolve = [&](const ContactSet& impacting, const ContactSet& releasing, const ContactSet& resting) {
    std::string unused;
    detail::resolve_event(algebra, scene.stops(), rules, t, x, v, stuck, impacting, releasing, resting,
                          emit_event, summary, &unused);
  };

  try {
    // Initial contacts: stops touched at t0 (within ε) that are approached or resting.
    {
      const Eigen::VectorXd g = scene.gaps(t, x), gd = scene.gap_rates(t, v);
      ContactSet impacting, resting;
      for (int j = 0; j < stops; ++j) {
        if (g(j) < -eps_gap) continue;
        if (gd(j) > v_contact) impacting.push_back(j);
        else if (gd(j) >= -v_contact) resting.push_back(j);
      }
      resolve(impacting, {}, resting);
    }

    // Stiff or heavily damped: the certified search steps by 1/ρ (ρ the flow's spectral radius).
    if (const double steps = sc.T * modes_.get(stuck).reduced().flow->spectral_radius();
        steps > detail::kStiffStepsPerPeriod)
      summary.warnings.push_back(detail::stiff_warning(steps, (t_end - t0) / sc.T));
    auto interrupted = [&] { return options_.interrupt && options_.interrupt->load(std::memory_order_relaxed); };
    auto report = [&](double reached) {
      if (options_.reached) options_.reached->store(reached, std::memory_order_relaxed);
    };
    while (true) {
      report(t);
      if (interrupted()) return finish(RunStatus::interrupted, "interrupted at t = " + number_text(t));
      const ContactMode& mode = modes_.get(stuck);
      const ContactMode::Reduced& red = mode.reduced();
      // One Segment per contact mode, reused: re-targeting it allocates nothing.
      Segment* slot = nullptr;
      for (auto& [functionals, seg] : segments)
        if (functionals == red.watch.get()) slot = seg.get();
      reduced_state.resize(red.flow->size());
      mode.reduce(t, x, v, reduced_state);
      if (!slot) {
        segments.emplace_back(red.watch.get(), std::make_unique<Segment>(*red.watch, t, reduced_state));
        slot = segments.back().second.get();
      } else {
        slot->reset(t, reduced_state);
      }
      const Segment& segment = *slot;
      const Eigen::Index rows = red.watch->count();
      triggers.resize(rows);
      for (Eigen::Index i = 0; i < rows; ++i) {
        triggers(i) = i < red.gap_rows ? eps_gap : eps_force;
        // A guard that starts inside its tolerance band while moving away (just after an impact
        // or a release) is only re-armed above where it starts, so rounding cannot re-fire it.
        const double h0 = segment.value(i, 0.0);
        if (h0 > 0.0 && segment.value(i, 0.0, 1) <= 0.0) triggers(i) += h0;
      }
      const double resolution =
          8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), sc.T);
      CrossingFinder finder(segment, triggers, resolution);
      const double step = 1.0 / std::max(red.flow->spectral_radius(), 1e-300);
      const double span = t_end - t;
      std::optional<Crossing> hit;
      for (double a = 0.0; a < span && !hit;) {
        if (interrupted()) return finish(RunStatus::interrupted, "interrupted at t = " + number_text(t));
        report(t + a);
        const double b = std::min(a + step, span);
        if (rows > 0) hit = finder.first(a, b);
        a = b;
      }
      const double tau = hit ? hit->tau : span;
      const double t_next = hit ? t + tau : t_end;
      ++summary.segments;
      if (!observers.empty()) {
        const DenseSegmentView view(mode, segment, t, t_next, eps_force);
        for (Observer* o : observers) o->segment(view);
      }
      zr.resize(red.flow->size());
      segment.state(tau, zr);
      z_full.noalias() = red.to_full * zr;
      x = z_full.head(n);
      v = z_full.segment(n, n);
      t = t_next;
      if (!x.allFinite() || !v.allFinite())
        return finish(RunStatus::numerical_failure,
                      "non-finite state at t = " + number_text(t) + " in contact set of " +
                          std::to_string(stuck.size()) + " stops");
      if (!hit) break;

      // Which guards fire together (within the simultaneity window).
      ContactSet impacting, releasing;
      for (Eigen::Index i = 0; i < rows; ++i) {
        const double h = segment.value(i, tau), hd = segment.value(i, tau, 1);
        const bool fired = i == hit->row ||
                           (hd > 0.0 && h >= -std::max(triggers(i), hd * dt_simultaneous));
        if (!fired) continue;
        (i < red.gap_rows ? impacting : releasing).push_back(red.watched[static_cast<std::size_t>(i)]);
      }
      std::sort(impacting.begin(), impacting.end());
      std::sort(releasing.begin(), releasing.end());
      resolve(impacting, releasing, {});
      if (rate.exceeded(t)) {
        const int j = !impacting.empty() ? impacting.front() : releasing.front();
        return finish(RunStatus::event_cap,
                      "event cap: more than " + std::to_string(options_.max_events) +
                          " events within " + number_text(window) + " time units, at t = " + number_text(t) +
                          ", stop " + std::to_string(j) + " (" +
                          scene.stops()[static_cast<std::size_t>(j)].name + "), x = " + vector_text(x) +
                          ", v = " + vector_text(v) +
                          " (Zeno behaviour the chatter rule did not resolve: raise "
                          "solver.chatter_velocity or solver.max_events)");
      }
    }
  } catch (const std::runtime_error& e) {
    return finish(RunStatus::numerical_failure, std::string(e.what()) + " (at t = " + number_text(t) + ")");
  }
  return finish(RunStatus::completed, "");
}

}  // namespace vibro
