#include "vibro/simulator.hpp"

#include "event_rate.hpp"

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

bool contains(const ContactSet& s, int j) { return std::binary_search(s.begin(), s.end(), j); }

ContactSet merge(const ContactSet& a, const ContactSet& b) {
  ContactSet out;
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

void require_positive(double value, const char* field, bool allow_zero = false) {
  if (!std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0))
    throw InvalidInput(std::string("solver.") + field + " = " + number_text(value) + ": must be a finite number " +
                       (allow_zero ? "≥ 0" : "> 0"));
}

}  // namespace

const char* to_string(RunStatus s) {
  switch (s) {
    case RunStatus::completed: return "completed";
    case RunStatus::event_cap: return "event cap reached";
    case RunStatus::numerical_failure: return "numerical failure";
    case RunStatus::unsupported: return "not supported by this engine";
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

Simulator::Simulator(const ImpactSystem& scene, SimulatorOptions options)
    : scene_(&scene), options_(options), modes_(scene, options.flow) {
  options_.validate();
}

Simulator::Scales Simulator::scales(const Eigen::VectorXd& x0, const Eigen::VectorXd& v0) const {
  const LinearSystem& sys = scene_->system();
  double omega = sys.forcing().frequency;
  if (omega == 0.0) {
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys.stiffness(), sys.mass(),
                                                                  Eigen::EigenvaluesOnly);
    omega = std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
  }
  if (!(omega > 0.0)) omega = 1.0;
  const double kmax = sys.stiffness().cwiseAbs().maxCoeff();
  const double mmax = sys.mass().cwiseAbs().maxCoeff();
  const double stiff = std::max(kmax, mmax * omega * omega);
  const HarmonicForcing& f = sys.forcing();
  const double fmax = f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() +
                      f.sine.cwiseAbs().maxCoeff();
  double L = options_.length_scale;
  if (L == 0.0) {
    L = scene_->length_scale(x0.cwiseAbs().maxCoeff());
    L = std::max({L, v0.cwiseAbs().maxCoeff() / omega, fmax / stiff});
  }
  return {L, L * omega, std::max(stiff * L, fmax), 2.0 * std::numbers::pi / omega};
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

  const Scales sc = scales(x0, v0);
  const double eps_gap = options_.trigger * sc.L;
  const double eps_force = options_.trigger * sc.F;
  const double v_chatter = options_.chatter_velocity * sc.V;
  const double h_chatter = options_.chatter_height * sc.L;
  const double v_contact = options_.contact_velocity * sc.V;
  const double dt_simultaneous = options_.simultaneity * sc.T;
  const double window = options_.event_window > 0.0 ? options_.event_window : sc.T;
  scene.check_admissible(t0, x0, eps_gap);

  RunSummary summary;
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
  const Eigen::MatrixXd minv_normals = mass_llt.solve(scene.normals());
  Eigen::VectorXd delassus_diag(stops), chatter_alpha(stops);
  Eigen::MatrixXd chatter_kick(n, stops);
  for (int j = 0; j < stops; ++j) {
    delassus_diag(j) = scene.normals().col(j).dot(minv_normals.col(j));
    chatter_alpha(j) = -minv_normals.col(j).dot(sys.damping() * minv_normals.col(j)) / delassus_diag(j);
    chatter_kick.col(j) = mass_llt.solve(sys.stiffness() * minv_normals.col(j)) / delassus_diag(j);
  }
  auto delassus_diagonal = [&](int j) { return delassus_diag(j); };  // w_jᵀ M⁻¹ w_j
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

  struct ChatterLimit {
    int stop;
    double t;
  };
  std::vector<ChatterLimit> chatter_limits;
  chatter_limits.reserve(static_cast<std::size_t>(stops));
  Eigen::VectorXd reduced_state, triggers, zr, z_full(2 * n + 3);
  std::vector<std::pair<const Functionals*, std::unique_ptr<Segment>>> segments;

  // Handles an event at time t: impacts on `impacting`, releases of `releasing`; `resting`
  // are further stops touching with zero normal speed (at the start of a run).
  auto handle = [&](const ContactSet& impacting, const ContactSet& releasing,
                    const ContactSet& resting) {
    ContactSet candidates;
    std::set_difference(stuck.begin(), stuck.end(), releasing.begin(), releasing.end(),
                        std::back_inserter(candidates));
    candidates = merge(candidates, resting);
    ContactSet chatter;
    Eigen::VectorXd g_before;
    if (!impacting.empty()) {
      g_before = scene.gap_rates(t, v);
      // Chatter candidates: stops that would hold (acceleration LCP with them stuck) and whose
      // next bounce would be too small to resolve (or too slow).
      ContactSet slow;
      for (int j : impacting) {
        const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
        if (r > 0.0 && r < 1.0) slow.push_back(j);  // r = 0 sticks at once, r = 1 never chatters
      }
      if (!slow.empty()) {
        Eigen::VectorXd hold_force;
        const ContactSet test = merge(candidates, slow);
        const ContactSet held = settle(t, x, v, test, &hold_force);
        for (int j : slow) {
          if (!contains(held, j)) continue;
          const auto a_idx = std::lower_bound(test.begin(), test.end(), j) - test.begin();
          const double accel = delassus_diagonal(j) * hold_force(a_idx);
          const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
          const double u = g_before(j);
          const double rise = (r * u) * (r * u) / (2.0 * accel);
          if (u <= v_chatter || rise <= h_chatter) chatter.push_back(j);
        }
      }
      const ContactSet all = merge(stuck, impacting);
      const ContactMode& mode = modes_.get(all);
      const auto m = static_cast<Eigen::Index>(all.size());
      Eigen::VectorXd q(m);
      for (Eigen::Index a = 0; a < m; ++a) {
        const int j = all[static_cast<std::size_t>(a)];
        const bool resting = contains(stuck, j) || contains(chatter, j);
        const double r = resting ? 0.0 : scene.stops()[static_cast<std::size_t>(j)].restitution;
        q(a) = (1.0 + r) * g_before(j);
      }
      const Eigen::VectorXd impulse = solve_lcp(mode.delassus(), q);
      v -= mode.mass_inverse_normals() * impulse;
      // Place each impacting stop's gap exactly at zero: the located root leaves it within
      // rounding (≤ ε) of the surface, and without this a long run of tiny bounces could let
      // that rounding accumulate into the stop. The correction moves x along M⁻¹w by ≤ ε.
      const Eigen::VectorXd g_now = scene.gaps(t, x);
      for (Eigen::Index a = 0; a < m; ++a) {
        const int j = all[static_cast<std::size_t>(a)];
        if (g_now(j) > 0.0) x -= mode.mass_inverse_normals().col(a) * (g_now(j) / mode.delassus()(a, a));
      }
      const Eigen::VectorXd g_after = scene.gap_rates(t, v);
      for (int j : impacting) {
        emit({t, j, EventKind::impact, g_before(j), g_after(j), 0.0});
        ++summary.impacts;
      }
      for (int j : all)
        if (g_after(j) >= -v_contact && !contains(candidates, j)) candidates.push_back(j);
      std::sort(candidates.begin(), candidates.end());
    }
    Eigen::VectorXd forces;
    ContactSet next = settle(t, x, v, candidates, &forces);
    auto force_of = [&](int j) {
      for (std::size_t a = 0; a < candidates.size(); ++a)
        if (candidates[a] == j) return forces(static_cast<Eigen::Index>(a));
      return 0.0;
    };
    // Chatter limits (ChatterRule in simulator.hpp), computed before the residual normal
    // velocity is removed below (the second-order rule's kick has a normal part the stop takes).
    chatter_limits.clear();
    for (int j : chatter) {
      if (!contains(next, j)) continue;
      const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
      const double G = delassus_diagonal(j);
      const double A = G * force_of(j);
      const double w0 = r * g_before(j);
      double t_limit = t;
      if (A > 0.0) {
        // Budd & Dux (1994): rebounds r^k w0 under a constant approach acceleration A accumulate
        // after T0 = Σ 2 r^k w0 / A = 2 w0 / (A (1 - r)).
        const double T0 = 2.0 * w0 / (A * (1.0 - r));
        t_limit = t + T0;
        if (options_.chatter_rule == ChatterRule::second_order) {
          // Next order (simulator.hpp, ChatterRule). Expansion: with A_k = A + A'(t_k - t),
          // t_k - t = (2 w0 / A)(1 - r^k)/(1 - r) and w_k = r^k w0 (1 + κ w0 (1 - r^k)/(1 - r)),
          // κ = (2/3)(A'/A² + α/A) (from u_{k+1} = w_k (1 + κ w_k)), the sum of the flights
          // τ_k = 2 w_k / A_k + (-(4/3) A'/A³ + (2/3) α/A²) w_k² is, to O(w0²),
          //   T = T0 + w0² / (1 - r)² · (-(4/3) A'/A³ + (2/3) α/A²) = T0 + T0² (α/6 - A'/(3A)),
          // using Σ r^k (1 - r^k) = r / ((1 - r)(1 - r²)) and Σ r^{2k} = 1 / (1 - r²).
          // A' = G λ_j' along the sticking flow of `next` from the post-impact state (exact).
          const ContactMode& held = modes_.get(next);
          const ContactMode::Reduced& red = held.reduced();
          reduced_state.resize(red.flow->size());
          held.reduce(t, x, v, reduced_state);
          const auto a_idx = std::lower_bound(next.begin(), next.end(), j) - next.begin();
          const double dforce = -red.watch->rows(1).row(red.gap_rows + a_idx).dot(reduced_state);
          const double A_dot = G * dforce;
          const double T = T0 + T0 * T0 * (chatter_alpha(j) / 6.0 - A_dot / (3.0 * A));
          if (std::abs(T - T0) <= 0.5 * T0) t_limit = t + T;
          // The bounces' mean displacement: ∫ δg dt = -(2/3) Σ w_k³ / A² over the tail, felt
          // through K as the momentum -K M⁻¹ w_j ∫δg dt / G (∫ δg' dt = 0, so C adds nothing).
          const double r3 = r * r * r;
          const double displacement_integral = -(2.0 / 3.0) * w0 * w0 * w0 / (A * A * (1.0 - r3));
          v -= chatter_kick.col(j) * displacement_integral;
        }
      }
      chatter_limits.push_back({j, t_limit});
    }
    // Remove the residual normal velocity of the held stops (rounding, or < v_contact).
    if (!next.empty()) {
      const ContactMode& mode = modes_.get(next);
      const Eigen::VectorXd g = scene.gap_rates(t, v);
      Eigen::VectorXd gn(static_cast<Eigen::Index>(next.size()));
      for (std::size_t a = 0; a < next.size(); ++a) gn(static_cast<Eigen::Index>(a)) = g(next[a]);
      v -= mode.mass_inverse_normals() * mode.delassus().llt().solve(gn);
    }
    for (int j : next) {
      if (contains(stuck, j)) continue;
      if (contains(chatter, j)) {
        double t_limit = t;
        for (const ChatterLimit& c : chatter_limits)
          if (c.stop == j) t_limit = c.t;
        const double u = g_before(j);
        const double r = scene.stops()[static_cast<std::size_t>(j)].restitution;
        emit({t_limit, j, EventKind::chatter_limit, r * u, 0.0, force_of(j)});
        ++summary.chatters;
      } else {
        emit({t, j, EventKind::stick, g_before.size() ? g_before(j) : 0.0, 0.0, force_of(j)});
      }
      ++summary.sticks;
    }
    const Eigen::VectorXd g_now = scene.gap_rates(t, v);
    for (int j : stuck) {
      if (contains(next, j)) continue;
      emit({t, j, EventKind::release, 0.0, g_now(j), 0.0});
      ++summary.releases;
    }
    stuck = next;
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
      handle(impacting, {}, resting);
    }

    while (true) {
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
      handle(impacting, releasing, {});
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
