#include "vibro/friction.hpp"

#include "friction_tables.hpp"
#include "vibro/events.hpp"
#include "vibro/flow.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace vibro {

FrictionContact FrictionContact::on_surface(Eigen::Index mass, double load, double mu_s, double mu_k,
                                            double amplitude, double phase) {
  FrictionContact c;
  c.kind = Kind::surface;
  c.mass = mass;
  c.normal_load = load;
  c.static_coefficient = mu_s;
  c.kinetic_coefficient = mu_k;
  c.amplitude = amplitude;
  c.phase = phase;
  return c;
}

FrictionContact FrictionContact::between(Eigen::Index mass, Eigen::Index other, double load, double mu_s,
                                         double mu_k) {
  FrictionContact c = on_surface(mass, load, mu_s, mu_k);
  c.kind = Kind::between;
  c.other = other;
  return c;
}

Eigen::VectorXd FrictionContact::tangent(Eigen::Index n) const {
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  w(mass) = 1.0;
  if (kind == Kind::between) w(other) = -1.0;
  return w;
}

const char* to_string(FrictionEventKind kind) {
  switch (kind) {
    case FrictionEventKind::stick: return "stick";
    case FrictionEventKind::slip: return "slip";
    case FrictionEventKind::reversal: return "reversal";
  }
  return "?";
}

std::vector<FrictionContact> validated_friction(std::vector<FrictionContact> contacts, Eigen::Index n) {
  for (std::size_t j = 0; j < contacts.size(); ++j) {
    FrictionContact& c = contacts[j];
    const std::string at = "friction[" + std::to_string(j) + "]";
    auto index_ok = [n](Eigen::Index i) { return i >= 0 && i < n; };
    if (!index_ok(c.mass))
      throw InvalidInput(at + ": mass index " + std::to_string(c.mass) + " is out of range [0, " +
                         std::to_string(n - 1) + "]");
    if (c.kind == FrictionContact::Kind::between) {
      if (!index_ok(c.other))
        throw InvalidInput(at + ": between index " + std::to_string(c.other) + " is out of range [0, " +
                           std::to_string(n - 1) + "]");
      if (c.other == c.mass) throw InvalidInput(at + ": between needs two different masses");
      if (c.amplitude != 0.0)
        throw InvalidInput(at + ": a contact between two masses has no surface motion (amplitude must be 0)");
    }
    const std::pair<const char*, double> values[] = {{"normal_load", c.normal_load},
                                                      {"static", c.static_coefficient},
                                                      {"kinetic", c.kinetic_coefficient},
                                                      {"surface.amplitude", c.amplitude},
                                                      {"surface.phase", c.phase}};
    for (const auto& [key, value] : values)
      if (!std::isfinite(value)) throw InvalidInput(at + ": " + key + " = " + number_text(value) + " is not finite");
    if (c.normal_load < 0.0)
      throw InvalidInput(at + ": normal_load = " + number_text(c.normal_load) + " must be ≥ 0");
    if (c.kinetic_coefficient < 0.0)
      throw InvalidInput(at + ": kinetic = " + number_text(c.kinetic_coefficient) + " must be ≥ 0");
    if (c.static_coefficient < c.kinetic_coefficient)
      throw InvalidInput(at + ": static = " + number_text(c.static_coefficient) + " is below kinetic = " +
                         number_text(c.kinetic_coefficient) + " (μ_s ≥ μ_k is required)");
    if (c.name.empty())
      c.name = c.kind == FrictionContact::Kind::between
                   ? "between x" + std::to_string(c.mass) + "-x" + std::to_string(c.other)
                   : "mass x" + std::to_string(c.mass);
  }
  return contacts;
}

namespace {

using detail::sign_of;
using Tables = detail::FrictionTables;

}  // namespace

/// A mode's exact flow (its generator is the free one with the slipping forces in f and the
/// stuck contacts' constraint rows, friction.hpp) and its guards.
class FrictionSimulator::Mode {
 public:
  Mode(const LinearSystem& sys, const Tables& tab, const std::vector<FrictionState>& states, FlowOptions options)
      : states_(states) {
    Eigen::MatrixXd A = mode_generator(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing(), tab, states, force_rows_);
    flow_ = std::make_unique<LinearFlow>(std::move(A), tab.n, sys.forcing().frequency, options);
    guards_ = std::make_unique<Functionals>(*flow_, mode_guards(tab, states, force_rows_, &contact_, &force_guard_));
  }

  /// The mode's generator: the free one with the accelerations of the mode (friction.hpp).
  static Eigen::MatrixXd mode_generator(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K,
                                        const HarmonicForcing& f, const Tables& tab,
                                        const std::vector<FrictionState>& states, Eigen::MatrixXd& force_rows) {
    Eigen::MatrixXd accel;
    tab.mode_rows(states, force_rows, accel);
    Eigen::MatrixXd A = augmented_generator(M, C, K, f);
    A.middleRows(tab.n, tab.n) = accel;
    return A;
  }
  /// Guards: −σ u_j while slipping; ±F_j − μ_s N while stuck (per contact, in order).
  static Eigen::MatrixXd mode_guards(const Tables& tab, const std::vector<FrictionState>& states,
                                     const Eigen::MatrixXd& force_rows, std::vector<int>* contact,
                                     std::vector<char>* force_guard) {
    std::vector<Eigen::VectorXd> rows;
    for (std::size_t j = 0; j < states.size(); ++j) {
      const auto J = static_cast<Eigen::Index>(j);
      if (states[j] != FrictionState::stuck) {
        rows.emplace_back(-sign_of(states[j]) * tab.u_rows.row(J).transpose());
        if (contact) contact->push_back(static_cast<int>(j));
        if (force_guard) force_guard->push_back(false);
      } else {
        for (double sign : {1.0, -1.0}) {
          Eigen::VectorXd row = sign * force_rows.row(J).transpose();
          row(tab.off + 2) -= tab.limit_static(J);
          rows.push_back(row);
          if (contact) contact->push_back(static_cast<int>(j));
          if (force_guard) force_guard->push_back(true);
        }
      }
    }
    Eigen::MatrixXd guard_rows(static_cast<Eigen::Index>(rows.size()), tab.N);
    for (std::size_t i = 0; i < rows.size(); ++i) guard_rows.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
    return guard_rows;
  }

  const LinearFlow& flow() const { return *flow_; }
  const Functionals& guards() const { return *guards_; }
  /// The mode's segment, re-targeted to (t0, z0): one per mode, reused (no allocation per event).
  Segment& segment(double t0, const Eigen::VectorXd& z0) const {
    if (segment_) segment_->reset(t0, z0);
    else segment_.emplace(*guards_, t0, z0);
    return *segment_;
  }
  /// The guards' triggers: eps_f on force guards, eps_v on velocity guards (kept while they hold).
  const Eigen::VectorXd& triggers(double eps_f, double eps_v) const {
    if (eps_f != trigger_f_ || eps_v != trigger_v_ || triggers_.size() != guards_->count()) {
      triggers_.resize(guards_->count());
      for (Eigen::Index i = 0; i < triggers_.size(); ++i) triggers_(i) = force_guard(i) ? eps_f : eps_v;
      trigger_f_ = eps_f;
      trigger_v_ = eps_v;
    }
    return triggers_;
  }
  const Eigen::MatrixXd& force_rows() const { return force_rows_; }
  int contact_of(Eigen::Index row) const { return contact_[static_cast<std::size_t>(row)]; }
  bool force_guard(Eigen::Index row) const { return force_guard_[static_cast<std::size_t>(row)]; }

 private:
  std::vector<FrictionState> states_;
  std::unique_ptr<LinearFlow> flow_;
  std::unique_ptr<Functionals> guards_;
  Eigen::MatrixXd force_rows_;
  std::vector<int> contact_;
  std::vector<char> force_guard_;
  mutable std::optional<Segment> segment_;
  mutable Eigen::VectorXd triggers_;
  mutable double trigger_f_ = -1.0, trigger_v_ = -1.0;
};

namespace {

/// A friction segment for the usual observers: full states from the exact flow; no stops.
class FrictionSegmentView final : public SegmentView {
 public:
  FrictionSegmentView(const Segment& segment, Eigen::Index n, double t_begin, double t_end)
      : SegmentView(t_begin, t_end), segment_(&segment), n_(n), z_(segment.initial_state().size()) {}
  Eigen::Index dof() const override { return n_; }
  const ContactSet& active() const override { return none_; }
  void state(double t, Eigen::Ref<Eigen::VectorXd> x, Eigen::Ref<Eigen::VectorXd> v) const override {
    segment_->state_unstored(t - segment_->t0(), z_);
    x = z_.head(n_);
    v = z_.segment(n_, n_);
  }
  double force(Eigen::Index, double) const override { throw std::logic_error("friction segment: no stops held"); }
  Minimum force_minimum(Eigen::Index) const override { throw std::logic_error("friction segment: no stops held"); }
  std::vector<Minimum> force_local_minima(Eigen::Index) const override { return {}; }

 private:
  const Segment* segment_;
  Eigen::Index n_;
  mutable Eigen::VectorXd z_;
  ContactSet none_;
};

}  // namespace

FrictionSimulator::FrictionSimulator(const LinearSystem& system, std::vector<FrictionContact> contacts,
                                     SimulatorOptions options)
    : system_(&system), contacts_(validated_friction(std::move(contacts), system.dof())), options_(options) {
  options_.validate();
}

FrictionSimulator::~FrictionSimulator() = default;

const FrictionSimulator::Mode& FrictionSimulator::mode(const std::vector<FrictionState>& states) {
  auto it = modes_.find(states);
  if (it == modes_.end()) {
    const Tables tab(*system_, contacts_);
    it = modes_.emplace(states, std::make_unique<Mode>(*system_, tab, states, options_.flow)).first;
  }
  return *it->second;
}

/// z = [x; v; cos Ωt; sin Ωt; 1; cos k₁Ωt; sin k₁Ωt; …] (flow.hpp's layout).
Eigen::VectorXd detail::augmented_state(const LinearSystem& sys, double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v) {
  const Eigen::Index n = sys.dof();
  const HarmonicForcing& f = sys.forcing();
  Eigen::VectorXd z(augmented_size(n, f));
  z << x, v, std::cos(f.frequency * t), std::sin(f.frequency * t), 1.0,
      Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(f.harmonics.size()));
  for (std::size_t h = 0; h < f.harmonics.size(); ++h) {
    const double rate = f.harmonics[h].rate(f.frequency);
    z(2 * n + 3 + 2 * static_cast<Eigen::Index>(h)) = std::cos(rate * t);
    z(2 * n + 4 + 2 * static_cast<Eigen::Index>(h)) = std::sin(rate * t);
  }
  return z;
}

FrictionModeRows friction_mode_rows(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K,
                                    const HarmonicForcing& forcing, const std::vector<FrictionContact>& contacts,
                                    const std::vector<FrictionState>& states) {
  const Tables tab(M, C, K, forcing, contacts);
  FrictionModeRows out;
  out.generator = FrictionSimulator::Mode::mode_generator(M, C, K, forcing, tab, states, out.force);
  out.guards = FrictionSimulator::Mode::mode_guards(tab, states, out.force, nullptr, nullptr);
  out.relative = tab.u_rows;
  return out;
}

Eigen::VectorXd FrictionSimulator::relative_velocities(double t, const Eigen::VectorXd& v) const {
  const Tables tab(*system_, contacts_);
  return tab.u_rows * detail::augmented_state(*system_, t, Eigen::VectorXd::Zero(tab.n), v);
}

Eigen::VectorXd FrictionSimulator::forces(double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v,
                                          const std::vector<FrictionState>& states) const {
  const Tables tab(*system_, contacts_);
  Eigen::MatrixXd F, A;
  tab.mode_rows(states, F, A);
  return F * detail::augmented_state(*system_, t, x, v);
}

namespace detail {

Eigen::MatrixXd friction_guard_rows(const FrictionTables& tab, const std::vector<FrictionState>& states,
                                    const Eigen::MatrixXd& force_rows, std::vector<int>* contact,
                                    std::vector<char>* force_guard) {
  return FrictionSimulator::Mode::mode_guards(tab, states, force_rows, contact, force_guard);
}

/// The resolution of friction.hpp: the states of every contact at z, given the old states, the
/// contact whose guard fired (−1: none, the start) and the tolerances. Returns false when no
/// assignment is consistent.
bool resolve_states(const Tables& tab, const Eigen::VectorXd& z, std::vector<FrictionState>& states, int fired,
                    double eps_v, double eps_f, double eps_a) {
  const auto m = static_cast<Eigen::Index>(states.size());
  const Eigen::VectorXd u = tab.u_rows * z;
  // A stuck contact whose guard fired: its holding force reached μ_s N (the event's definition),
  // so slipping against that force's direction is consistent whatever rounding left of its u' —
  // placed where the time resolution allows (late in a long run, |F'| × the spacing of doubles
  // near t exceeds any fixed tolerance), the force may be just short of the limit.
  double breakaway = 0.0;  // the fired contact's direction of slip (0: not a stuck contact's guard)
  if (fired >= 0 && states[static_cast<std::size_t>(fired)] == FrictionState::stuck)
    breakaway = tab.cached_rows(states).force.row(fired).dot(z) >= 0.0 ? -1.0 : 1.0;  // the force opposes the slip
  std::vector<Eigen::Index> cand;
  std::vector<FrictionState> trial(states.size());
  for (Eigen::Index j = 0; j < m; ++j) {
    const auto J = static_cast<std::size_t>(j);
    const bool near = std::abs(u(j)) <= eps_v;
    if (near || states[J] == FrictionState::stuck || j == fired) cand.push_back(j);
    else trial[J] = u(j) > 0.0 ? FrictionState::slip_positive : FrictionState::slip_negative;
  }
  const auto c = cand.size();
  if (c > 10) return false;
  std::size_t total = 1;
  for (std::size_t k = 0; k < c; ++k) total *= 3;
  // Options per candidate, in order: stuck, +, −; the fired contact may not keep its state.
  int best_stuck = -1;
  std::vector<FrictionState> best;
  for (int pass = 0; pass < 2 && best_stuck < 0; ++pass) {  // pass 1: the fired contact unrestricted
    for (std::size_t code = 0; code < total; ++code) {
      std::size_t rest = code;
      int stuck_count = 0;
      bool allowed = true;
      for (std::size_t k = 0; k < c; ++k) {
        const int option = static_cast<int>(rest % 3);
        rest /= 3;
        const FrictionState s = option == 0 ? FrictionState::stuck
                                : option == 1 ? FrictionState::slip_positive
                                              : FrictionState::slip_negative;
        const auto J = static_cast<std::size_t>(cand[k]);
        if (pass == 0 && cand[k] == fired && s == states[J]) allowed = false;
        trial[J] = s;
        stuck_count += s == FrictionState::stuck;
      }
      if (!allowed || stuck_count <= best_stuck) continue;
      const Tables::Rows& rows = tab.cached_rows(trial);
      const Eigen::VectorXd force = rows.force * z;
      const Eigen::VectorXd udot = tab.W.transpose() * (rows.accel * z) - tab.s2_rows * z;  // u' = Wᵀx'' − s''
      bool ok = true;
      for (std::size_t k = 0; k < c && ok; ++k) {
        const Eigen::Index j = cand[k];
        const FrictionState s = trial[static_cast<std::size_t>(j)];
        // A slip is consistent if it does not decelerate, to the tolerance of what located the
        // switch: a stuck force guard fires within eps_f of μ_s N, so at a stick → slip switch
        // with μ_s = μ_k the slip's u' = (F − μ_k N)(WᵀM⁻¹W) may be −eps_f (WᵀM⁻¹W) where the
        // exact value is 0 (and u'' > 0). A tolerance below that would refuse the slip, keep the
        // contact stuck (its force is within μ_s N + eps_f) and let the guard fire again at once,
        // for ever.
        if (s == FrictionState::stuck) ok = std::abs(force(j)) <= tab.limit_static(j) + eps_f;
        else if (pass == 0 && j == fired && breakaway != 0.0) ok = static_cast<double>(sign_of(s)) == breakaway;
        else ok = sign_of(s) * udot(j) >= -(eps_a + eps_f * tab.accel_per_force(j));
      }
      if (ok) {
        best_stuck = stuck_count;
        best = trial;
      }
    }
  }
  if (best_stuck < 0) return false;
  states = best;
  return true;
}

/// At a switch, the relative velocity u_j of every contact that sticks now or stuck until now is
/// set to 0 exactly: the smallest change of v in the metric of M (v −= M⁻¹W_S (W_SᵀM⁻¹W_S)⁻¹ u_S
/// over those contacts S). It is within the tolerance that located the switch (|u_j| ≤ eps_v
/// where a slip ends; rounding where a stuck contact, held at u = 0 by its mode, breaks away), and
/// it matters where it breaks away: a slip that starts with u a rounding error on the wrong side
/// of 0 (u' = 0 there when μ_s = μ_k) would meet its own guard, u back to 0, at once.
void settle_relative_velocities(const Tables& tab, const std::vector<FrictionState>& before,
                                const std::vector<FrictionState>& after, Eigen::VectorXd& z) {
  std::vector<Eigen::Index> S;
  for (std::size_t j = 0; j < after.size(); ++j)
    if ((after[j] == FrictionState::stuck || before[j] == FrictionState::stuck) && !tab.is_locked(static_cast<Eigen::Index>(j)))
      S.push_back(static_cast<Eigen::Index>(j));
  const Eigen::Index hc = tab.Wc.cols();  // held stops (friction_stops.cpp): their g' too
  if (S.empty() && hc == 0) return;
  const Eigen::VectorXd u_all = tab.u_rows * z;
  const auto ks = static_cast<Eigen::Index>(S.size());
  const Eigen::Index k = ks + hc;
  Eigen::MatrixXd MW(tab.n, k), D(k, k);
  Eigen::VectorXd u(k);
  for (Eigen::Index a = 0; a < ks; ++a) {
    MW.col(a) = tab.minv_W.col(S[static_cast<std::size_t>(a)]);
    u(a) = u_all(S[static_cast<std::size_t>(a)]);
  }
  if (hc > 0) {
    MW.rightCols(hc) = tab.minv_Wc;
    u.tail(hc) = tab.uc_rows * z;
  }
  for (Eigen::Index a = 0; a < k; ++a)
    for (Eigen::Index b = 0; b < k; ++b)
      D(a, b) = a < ks ? tab.W.col(S[static_cast<std::size_t>(a)]).dot(MW.col(b)) : tab.Wc.col(a - ks).dot(MW.col(b));
  z.segment(tab.n, tab.n) -= MW * D.ldlt().solve(u);
}

}  // namespace detail

namespace {

using detail::resolve_states;
using detail::settle_relative_velocities;

}  // namespace

FrictionSummary FrictionSimulator::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                                       const std::vector<Observer*>& observers,
                                       const std::vector<FrictionObserver*>& friction_observers) {
  const LinearSystem& sys = *system_;
  const Eigen::Index n = sys.dof();
  if (x0.size() != n || v0.size() != n)
    throw InvalidInput("initial state: x has " + std::to_string(x0.size()) + " and v has " +
                       std::to_string(v0.size()) + " entries, expected " + std::to_string(n));
  if (!x0.allFinite() || !v0.allFinite()) throw InvalidInput("initial state is not finite");
  if (!std::isfinite(t0) || !std::isfinite(t_end) || t_end < t0)
    throw InvalidInput("time span: [" + number_text(t0) + ", " + number_text(t_end) + "] must be finite with t_end ≥ t0");

  const Tables tab(sys, contacts_);
  const HarmonicForcing& f = sys.forcing();
  // Scales (simulator.hpp's): ω the forcing frequency or the fastest mode's; L from the state,
  // the static deflection of the forcing and of the friction limits, the surfaces' amplitudes.
  double omega = f.frequency;
  if (omega == 0.0) {
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(sys.stiffness(), sys.mass(), Eigen::EigenvaluesOnly);
    omega = std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
    if (omega == 0.0) omega = 1.0;
  }
  const double kmax = sys.stiffness().cwiseAbs().maxCoeff(), mmax = sys.mass().cwiseAbs().maxCoeff();
  const double stiff = std::max(kmax, mmax * omega * omega);
  double fmax = f.constant.cwiseAbs().maxCoeff() + f.cosine.cwiseAbs().maxCoeff() + f.sine.cwiseAbs().maxCoeff();
  for (const ForcingHarmonic& h : f.harmonics) fmax += h.cosine.cwiseAbs().maxCoeff() + h.sine.cwiseAbs().maxCoeff();
  double L = std::max({x0.cwiseAbs().maxCoeff(), v0.cwiseAbs().maxCoeff() / omega, fmax / stiff, 1e-300});
  for (Eigen::Index j = 0; j < tab.W.cols(); ++j)
    L = std::max({L, tab.limit_static(j) / stiff, std::abs(contacts_[static_cast<std::size_t>(j)].amplitude)});
  if (options_.length_scale > 0.0) L = options_.length_scale;
  const double V = L * omega, Fs = stiff * L, T = 2.0 * std::numbers::pi / omega;
  const double eps_v = options_.trigger * V, eps_f = options_.trigger * Fs, eps_a = options_.trigger * V * omega;
  const double resolution = 8.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(t_end), T);
  const double window = options_.event_window > 0.0 ? options_.event_window : T;

  FrictionSummary summary;
  summary.length_scale = L;
  summary.velocity_scale = V;
  summary.force_scale = Fs;
  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  std::vector<FrictionState> states(contacts_.size(), FrictionState::slip_positive);

  auto finish = [&](RunStatus status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    summary.t = t;
    summary.x = x;
    summary.v = v;
    summary.states = states;
    summary.modes_built = modes_.size();
    for (Observer* o : observers) o->end(t);
    return summary;
  };
  auto emit_changes = [&](const std::vector<FrictionState>& before, const Eigen::VectorXd& z, bool initial,
                          const std::vector<char>& candidate) {
    const Eigen::VectorXd force = mode(states).force_rows() * z;
    for (std::size_t j = 0; j < states.size(); ++j) {
      FrictionEventKind kind;
      if (initial) {
        if (!candidate[j]) continue;
        kind = states[j] == FrictionState::stuck ? FrictionEventKind::stick : FrictionEventKind::slip;
      } else if (states[j] == before[j]) {
        continue;
      } else if (states[j] == FrictionState::stuck) {
        kind = FrictionEventKind::stick;
      } else if (before[j] == FrictionState::stuck) {
        kind = FrictionEventKind::slip;
      } else {
        kind = FrictionEventKind::reversal;
      }
      (kind == FrictionEventKind::stick ? summary.sticks : kind == FrictionEventKind::slip ? summary.slips
                                                                                          : summary.reversals)++;
      const FrictionEvent e{t, static_cast<int>(j), kind, force(static_cast<Eigen::Index>(j))};
      for (FrictionObserver* o : friction_observers) o->friction_event(e, x, v);
    }
  };

  for (Observer* o : observers) o->begin(RunContext{n, 0, f.frequency}, t0);
  {
    // The start: the contacts at u = 0 are decided by the resolution.
    const LinearFlow& free_flow = mode(states).flow();
    const Eigen::VectorXd z = free_flow.augment(t, x, v);
    const Eigen::VectorXd u = tab.u_rows * z;
    std::vector<char> candidate(states.size());
    for (std::size_t j = 0; j < states.size(); ++j) {
      const auto J = static_cast<Eigen::Index>(j);
      candidate[j] = std::abs(u(J)) <= eps_v;
      if (!candidate[j]) states[j] = u(J) > 0.0 ? FrictionState::slip_positive : FrictionState::slip_negative;
    }
    const std::vector<FrictionState> before = states;
    if (!resolve_states(tab, z, states, -1, eps_v, eps_f, eps_a))
      return finish(RunStatus::numerical_failure,
                    "friction: no consistent stick/slip state at the start t = " + number_text(t));
    emit_changes(before, z, true, candidate);
  }

  std::deque<double> recent;
  Eigen::VectorXd z, zt;
  CrossingFinder finder;
  std::vector<FrictionObserver*> mode_observers;  // those that follow the modes and switches
  for (FrictionObserver* o : friction_observers)
    if (o->wants_modes()) mode_observers.push_back(o);
  FrictionSwitch sw;
  while (true) {
    const Mode& md = mode(states);
    const LinearFlow& flow = md.flow();
    z = flow.augment(t, x, v);
    Segment& segment = md.segment(t, z);
    const Eigen::Index rows = md.guards().count();
    finder.retarget(segment, md.triggers(eps_f, eps_v), resolution, true);
    const double step = 1.0 / std::max(flow.spectral_radius(), 1e-300);
    const double reach = std::min(t_end - t, flow.horizon());
    std::optional<Crossing> hit;
    try {
      for (double a = 0.0; a < reach && !hit;) {
        // Interruption and progress polled once per step of the search, as the event loop's
        // frame does for the impact engines (event_loop.hpp).
        if (options_.reached) options_.reached->store(t + a, std::memory_order_relaxed);
        if (options_.interrupt && options_.interrupt->load(std::memory_order_relaxed))
          return finish(RunStatus::interrupted, "interrupted at t = " + number_text(t + a) +
                                                    (a > 0.0 ? " (the state kept is the one at t = " + number_text(t) +
                                                                   ", where the segment began)"
                                                             : std::string()));
        const double b = std::min(a + step, reach);
        if (rows > 0) hit = finder.first(a, b);
        a = b;
      }
    } catch (const std::runtime_error& e) {
      return finish(RunStatus::numerical_failure, std::string("friction: event search failed: ") + e.what());
    }
    const double tau = hit ? hit->tau : reach;
    const double t_next = hit ? t + tau : (reach == t_end - t ? t_end : t + reach);
    ++summary.segments;
    for (FrictionObserver* o : mode_observers) o->friction_segment(t, t_next, states, z);
    {
      const FrictionSegmentView view(segment, n, t, t_next);
      for (Observer* o : observers) o->segment(view);
    }
    zt.resize(z.size());
    if (hit && t_next - t == hit->tau) segment.state(finder.crossing_sample(), zt);
    else segment.state(t_next - t, zt);
    t = t_next;
    x = zt.head(n);
    v = zt.segment(n, n);
    if (!x.allFinite() || !v.allFinite())
      return finish(RunStatus::numerical_failure, "friction: the state is not finite at t = " + number_text(t));
    if (!hit) {
      if (t >= t_end) return finish(RunStatus::completed, "");
      continue;
    }
    const int fired = md.contact_of(hit->row);
    const std::vector<FrictionState> before = states;
    if (!resolve_states(tab, zt, states, fired, eps_v, eps_f, eps_a))
      return finish(RunStatus::numerical_failure, "friction: no consistent stick/slip state at t = " + number_text(t) +
                                                      " (friction[" + std::to_string(fired) + "])");
    if (!mode_observers.empty()) {
      sw.t = t;
      sw.fired = fired;
      sw.guard_index = hit->row;
      sw.before = before;
      sw.after = states;
      sw.z_before = zt;
    }
    settle_relative_velocities(tab, before, states, zt);
    v = zt.segment(n, n);
    if (!mode_observers.empty()) {
      sw.z_after = zt;
      for (FrictionObserver* o : mode_observers) o->friction_switch(sw);
    }
    emit_changes(before, zt, false, {});
    recent.push_back(t);
    while (!recent.empty() && recent.front() < t - window) recent.pop_front();
    if (static_cast<long>(recent.size()) > options_.max_events)
      return finish(RunStatus::event_cap, "event cap: more than " + std::to_string(options_.max_events) +
                                              " friction events within " + number_text(window) +
                                              " time units at t = " + number_text(t) + ", friction[" +
                                              std::to_string(fired) + "]");
    if (t >= t_end) return finish(RunStatus::completed, "");
  }
}

FrictionEngine::FrictionEngine(LinearSystem system, std::vector<FrictionContact> contacts,
                               const SimulatorOptions& options)
    : system_(std::make_unique<LinearSystem>(std::move(system))),
      sim_(std::make_unique<FrictionSimulator>(*system_, std::move(contacts), options)) {}

namespace {

/// Friction events as the observers' Events.
struct ForwardEvents final : FrictionObserver {
  const std::vector<Observer*>* observers = nullptr;
  const FrictionSimulator* sim = nullptr;
  void friction_event(const FrictionEvent& e, const Eigen::VectorXd& /*x*/, const Eigen::VectorXd& v) override {
    const EventKind kind = e.kind == FrictionEventKind::stick  ? EventKind::friction_stick
                           : e.kind == FrictionEventKind::slip ? EventKind::friction_slip
                                                               : EventKind::friction_reversal;
    const double u = sim->relative_velocities(e.t, v)(e.contact);
    const Event out{e.t, e.contact, kind, u, u, e.force};
    for (Observer* o : *observers) o->event(out);
  }
};

}  // namespace

RunSummary FrictionEngine::run(double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, double t_end,
                               const std::vector<Observer*>& observers) {
  ForwardEvents forward;
  forward.observers = &observers;
  forward.sim = sim_.get();
  return run_summary(sim_->run(t0, x0, v0, t_end, observers, {&forward}));
}

RunSummary run_summary(const FrictionSummary& f) {
  RunSummary s;
  s.status = f.status;
  s.message = f.message;
  s.t = f.t;
  s.x = f.x;
  s.v = f.v;
  s.sticks = f.sticks;
  s.releases = f.slips + f.reversals;
  s.segments = f.segments;
  s.contact_sets_built = f.modes_built;
  s.sticking_flows_built = f.modes_built;
  s.length_scale = f.length_scale;
  s.velocity_scale = f.velocity_scale;
  s.force_scale = f.force_scale;
  return s;
}

}  // namespace vibro
