/// \file friction_stops_tangent.cpp
/// The tangent maps of runs with friction and stops (friction_tangent.hpp): a recorder that
/// follows the modes and events of FrictionStopSimulator and composes the modes' propagators with
/// the events' saltation matrices. An event's reset is the stops' resolution (mechanics.hpp's
/// reset, differentiated as linearisation.cpp does it: reset_derivative.hpp) followed by the
/// frictional contacts' settling (a linear projection of v, friction_stops.hpp), and its guard is
/// the row of the old mode that fired (FrictionStopModeRows::guards).
#include "vibro/friction_stops.hpp"
#include "vibro/friction_tangent.hpp"

#include "friction_parts.hpp"
#include "mechanics.hpp"
#include "reset_derivative.hpp"
#include "sign_changes.hpp"
#include "transition.hpp"

#include <Eigen/QR>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

namespace vibro {
namespace {

using detail::Dual;
using detail::Mechanics;
using detail::ResetRule;
using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

/// The scene's data moved by h along dD (M fixed): friction_parts.hpp's part and the stops'
/// canonical data (s0, sc, ss, the higher harmonics' coefficients, a compliant law's k_s, c_s, F_p).
struct MovedScene {
  detail::MovedData data;
  std::vector<Stop> stops;
};
MovedScene moved_scene(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                       const SystemDerivative& d, double h) {
  MovedScene out{detail::moved(scene.system(), contacts, d, h), scene.stops()};
  for (std::size_t j = 0; j < d.stops.size() && j < out.stops.size(); ++j) {
    const StopDerivative& ds = d.stops[j];
    Stop& st = out.stops[j];
    const double sign = st.kind == Stop::Kind::lower ? -1.0 : 1.0;  // s = sign · (the stop's own motion)
    st.position += sign * h * ds.offset;
    if (ds.cosine != 0.0 || ds.sine != 0.0) {  // sc = sign a cos φ, ss = −sign a sin φ
      const double sc = st.s_cos() + h * ds.cosine, ss = st.s_sin() + h * ds.sine;
      st.amplitude = std::hypot(sc, ss);
      st.phase = std::atan2(-sign * ss, sign * sc);
    }
    st.stiffness += h * ds.stiffness;
    st.damping += h * ds.damping;
    st.preload += h * ds.preload;
    for (std::size_t i = 0; i < st.harmonics.size(); ++i) {
      if (j < d.stop_harmonic_cosine.size() && i < d.stop_harmonic_cosine[j].size())
        st.harmonics[i].cosine += sign * h * d.stop_harmonic_cosine[j][i];
      if (j < d.stop_harmonic_sine.size() && i < d.stop_harmonic_sine[j].size())
        st.harmonics[i].sine += sign * h * d.stop_harmonic_sine[j][i];
    }
  }
  return out;
}

/// The rows of a mode the run visits, their parameter derivatives (parameter runs), the basis
/// of its tangent space and (features) its flow with the rows the features scan.
struct ModeData {
  FrictionStopModeRows rows;
  MatrixXd dgenerator, dguards, drelative, dheld_rates;
  MatrixXd basis;  // 2n × d: {N_Hᵀ δx = 0, [N_H W_S]ᵀ δv = 0}
  std::unique_ptr<LinearFlow> flow;
  std::unique_ptr<Functionals> scan;  // features: gaps, gap rates, held forces, their rates
};

class FrictionStopRecorder final : public Observer, public FrictionStopObserver {
 public:
  FrictionStopRecorder(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                       const SimulatorOptions& solver, const LinearisationOptions& options, TangentMap& out)
      : scene_(scene), contacts_(contacts), solver_(solver), options_(options), out_(out), n_(scene.dof()),
        N_(augmented_size(scene.dof(), scene.system().forcing())), ms_(static_cast<int>(scene.stop_count())),
        mech_(scene), mech0_(scene), phases_(out.phases, scene.stop_count() + contacts.size()) {
    frame_ = options.directions.size() > 0;
    carries_ = frame_ || options.jacobian;
    minv_ = scene.system().mass().llt().solve(MatrixXd::Identity(n_, n_));
    W_.resize(n_, static_cast<Index>(contacts.size()));
    for (std::size_t j = 0; j < contacts.size(); ++j) W_.col(static_cast<Index>(j)) = contacts[j].tangent(n_);
    if (!options.parameter) return;
    const SystemDerivative& d = *options.parameter;
    d.validate(n_, scene.stop_count());
    if (d.mass.size() && !d.mass.isZero(0.0))
      throw InvalidInput("linearisation (friction with stops): the parameter moves the mass matrix; continue in Ω, "
                         "the forcing, C, K, a stop's data or a contact's");
    if (!d.friction.empty() && d.friction.size() != contacts.size())
      throw InvalidInput("linearisation (friction with stops): " + std::to_string(d.friction.size()) +
                         " contact derivatives for " + std::to_string(contacts.size()) + " frictional contacts");
    for (std::size_t j = 0; j < d.stops.size(); ++j)
      if (d.stops[j].moves_law() && !scene.stops()[j].is_compliant())
        throw InvalidInput("parameter derivative: stop " + std::to_string(j) +
                           " is rigid; only a compliant stop's stiffness, damping and preload have derivatives");
    SystemDerivative stops_only = d;  // Mechanics differentiates the stops' part (no friction)
    stops_only.friction.clear();
    mechp_ = std::make_unique<Mechanics<Dual>>(scene, &stops_only);
    // The rows are polynomials of degree ≤ 4 in h along dD with M fixed (C, K, f, the stops'
    // data and the contacts' N, μ enter at most bilinearly, Ω up to its square, times a stop's or a
    // compliant law's data; M⁻¹ and the Delassus matrices do not move), so the five-point
    // difference below is their exact derivative up to rounding, about 2ε‖rows‖/h: h moves the
    // data by 1e-3 of its size.
    double size = 0.0, move = 0.0;
    detail::data_and_move(scene.system(), contacts, d, size, move);
    for (const Stop& st : scene.stops())
      size = std::max({size, std::abs(st.position), st.motion_extent(), st.stiffness, st.damping, st.preload});
    for (const StopDerivative& ds : d.stops)
      move = std::max({move, std::abs(ds.offset), std::abs(ds.cosine), std::abs(ds.sine), std::abs(ds.stiffness),
                       std::abs(ds.damping), std::abs(ds.preload)});
    for (const auto& list : {&d.stop_harmonic_cosine, &d.stop_harmonic_sine})
      for (const auto& v : *list)
        for (double x : v) move = std::max(move, std::abs(x));
    step_ = move > 0.0 ? 1e-3 * size / move : 0.0;
    if (step_ > 0.0)
      for (int k : {-2, -1, 1, 2}) moved_.push_back(moved_scene(scene, contacts, d, k * step_));
  }

  // ---- Observer: the events (friction events of contact j as index stop_count + j) ----
  void event(const Event& e) override {
    // Before the first segment a frictional contact's event is the start's decision of the
    // contacts at u = 0 (friction_stops.cpp reports it at t0), not a switch: skipped, as in
    // friction_tangent.cpp, so that an orbit's signature does not change where a switch crosses
    // the section.
    if (first_ && is_friction(e.kind)) return;
    events_.push_back(e);
    Event out = e;
    if (is_friction(e.kind)) out.stop += ms_;
    out_.events.push_back(out);
  }

  // ---- FrictionStopObserver ----
  void mode_segment(double tb, double te, const ContactSet& key, const std::vector<FrictionState>& states,
                    const VectorXd& zb) override {
    ModeData& mode = mode_for(key, states);
    const Index N2 = 2 * n_;
    if (first_) {
      first_ = false;
      map_.start(N2, frame_, options_.directions);
      zeta_ = VectorXd::Zero(N2);
      for (int j : mode.rows.held) phases_.open(j, tb);
      for (std::size_t j = 0; j < states.size(); ++j)
        if (states[j] == FrictionState::stuck) phases_.open(ms_ + static_cast<int>(j), tb);
      out_.starts_held = !mode.rows.held.empty() ||
                         std::find(states.begin(), states.end(), FrictionState::stuck) != states.end();
      out_.rate_start = (mode.rows.generator * zb).head(N2);
    }
    events_.clear();
    const double tau = te - tb;
    if (tau > 0.0 && (carries_ || options_.parameter)) {
      const MatrixXd& A = mode.rows.generator;
      if (options_.parameter) {
        MatrixXd block = MatrixXd::Zero(2 * N_, 2 * N_);
        block.topLeftCorner(N_, N_) = A * tau;
        block.topRightCorner(N_, N_) = mode.dgenerator * tau;
        block.bottomRightCorner(N_, N_) = A * tau;
        const MatrixXd E = block.exp();
        VectorXd zeta = VectorXd::Zero(N_);
        zeta.head(N2) = zeta_;
        zeta.tail(N_ - N2) = oscillator_sensitivity(tb);
        zeta_ = (E.topLeftCorner(N_, N_) * zeta + E.topRightCorner(N_, N_) * zb).head(N2);
        if (carries_) K_ = E.topLeftCorner(N2, N2) * K_;
      } else {
        K_ = (A * tau).exp().topLeftCorner(N2, N2) * K_;
      }
    }
    // The least tangent dimension (friction_tangent.hpp): before the first event nothing has
    // lost its direction (a held start keeps the start's own normal state).
    map_.reached(switched_ ? mode.basis.cols() : N2, mode.basis, options_.jacobian && !frame_);
    if (options_.features && tau > 0.0) features(mode, states, tb, tau, zb);
    last_ = &mode;
  }

  void mode_switch(const FrictionStopSwitch& sw) override {
    switched_ = true;
    const Index n = n_, N2 = 2 * n;
    ModeData& before = mode_for(sw.key_before, sw.before);
    ModeData& after = mode_for(sw.key_after, sw.after);
    const detail::Transition tr = detail::classify(events_);
    const double t = sw.t;
    const VectorXd x = sw.z_before.head(n), vm = sw.z_before.segment(n, n);
    const VectorXd fm = before.rows.generator * sw.z_before;  // augmented: with the oscillator's rates
    const VectorXd fp = (after.rows.generator * sw.z_after).head(N2);

    // The guard that fired: h = ℓᵀz.
    if (sw.guard_row < 0 || sw.guard_row >= before.rows.guards.rows())
      throw std::logic_error("linearisation (friction with stops): an event without the guard that fired");
    const VectorXd ell = before.rows.guards.row(sw.guard_row).transpose();
    const double hdot = ell.dot(fm);

    // The stops' reset (mechanics.hpp) with the engine's decisions, the friction states before
    // the event in its chatter rule.
    ResetRule rule;
    rule.held_before = sw.key_before;
    for (int j : tr.impacting)
      if (!scene_.stops()[static_cast<std::size_t>(j)].is_compliant()) rule.impacting.push_back(j);
    rule.caught = tr.caught;
    rule.impulse = detail::impulse_set(mech_, sw.key_before, rule.impacting, rule.caught, vm, t);
    rule.held_after = detail::set_union(sw.held_by_stops, mech_.engaged_part(sw.key_after));
    rule.rule = solver_.chatter_rule;
    const bool chatter = !rule.caught.empty() && rule.rule != ChatterRule::first_order;
    if (chatter) set_friction_part(sw.before, sw.held_by_stops);
    const detail::ResetDerivative r1 = detail::reset_derivative(mech0_, rule, x, vm, t, fm.head(N2));

    // The frictional contacts' settling: v⁺ = v₁ − B U z₁ over the contacts stuck before or
    // after (not locked by the held stops) and the held stops (friction.cpp), U the rows of their
    // relative velocities and normal rates, B = M⁻¹ [W_S N_H] D⁻¹, D = [W_S N_H]ᵀ M⁻¹ [W_S N_H].
    std::vector<Index> S;
    for (std::size_t j = 0; j < sw.after.size(); ++j)
      if ((sw.after[j] == FrictionState::stuck || sw.before[j] == FrictionState::stuck) && !after.rows.locked[j])
        S.push_back(static_cast<Index>(j));
    const auto ks = static_cast<Index>(S.size()), hc = static_cast<Index>(after.rows.held.size()), k = ks + hc;
    MatrixXd Bv(n, k), U(k, N_), dU(k, N_);
    if (k > 0) {
      MatrixXd Wk(n, k);
      for (Index a = 0; a < ks; ++a) {
        Wk.col(a) = W_.col(S[static_cast<std::size_t>(a)]);
        U.row(a) = after.rows.relative.row(S[static_cast<std::size_t>(a)]);
        if (options_.parameter) dU.row(a) = after.drelative.row(S[static_cast<std::size_t>(a)]);
      }
      for (Index a = 0; a < hc; ++a) Wk.col(ks + a) = scene_.stops()[static_cast<std::size_t>(after.rows.held[static_cast<std::size_t>(a)])].normal(n);
      if (hc > 0) {
        U.bottomRows(hc) = after.rows.held_rates;
        if (options_.parameter) dU.bottomRows(hc) = after.dheld_rates;
      }
      const MatrixXd MW = minv_ * Wk;
      Bv = MW * (Wk.transpose() * MW).ldlt().solve(MatrixXd::Identity(k, k));
    }
    // P₂ δz₁ (δz₁ augmented): the settling's derivative, on the velocity rows.
    auto settle = [&](const VectorXd& dz) {
      VectorXd out = dz.head(N2);
      if (k > 0) out.tail(n) -= Bv * (U * dz);
      return out;
    };
    MatrixXd Rz(N2, N2);
    for (Index i = 0; i < N2; ++i) {
      VectorXd dz = VectorXd::Zero(N_);
      dz.head(N2) = r1.state.col(i);
      Rz.col(i) = settle(dz);
    }
    VectorXd dz = fm;  // along the flow: the stops' c, the oscillator's rate
    dz.head(N2) = r1.along_flow;
    const VectorXd c = settle(dz);
    const VectorXd hz = ell.head(N2);
    MatrixXd jump = Rz;  // the saltation matrix
    if (hdot != 0.0) jump += (fp - c) * hz.transpose() / hdot;
    if (carries_) K_ = jump * K_;
    if (options_.parameter) {
      const VectorXd osc = oscillator_sensitivity(t);
      VectorXd dzp(N_);
      if (chatter) set_friction_part(sw.before, sw.held_by_stops, true);
      dzp.head(N2) = detail::reset_parameter(*mechp_, rule, x, vm, t);
      dzp.tail(N_ - N2) = osc;
      VectorXd sp = settle(dzp);
      if (k > 0) sp.tail(n) -= Bv * (dU * sw.z_after);  // dU has no x, v columns: z₁'s are not needed
      const double hp = before.dguards.row(sw.guard_row).dot(sw.z_before) + ell.tail(N_ - N2).dot(osc);
      if (hdot != 0.0) sp += (fp - c) * (hp / hdot);
      zeta_ = jump * zeta_ + sp;
    }

    SaltationRecord rec = detail::record_of(t, mech_.held_part(sw.key_before), tr, mech_.held_part(sw.key_after));
    rec.guard_rate = hdot;
    const bool stop_guard = sw.guard_row < before.rows.stop_rows;
    rec.impact = sw.guard_row < before.rows.opening_rows;
    rec.simultaneous = rule.impacting.size() > 1;
    rec.guard_stop = stop_guard ? row_stop(sw) : ms_ + fired_contact(before, sw);
    out_.saltations.push_back(rec);
    if ((sw.guards_fired > 1 || rule.impacting.size() > 1) && !out_.non_smooth) {
      out_.non_smooth = true;
      out_.non_smooth_reason = "several guards fired together at t = " + number_text(t) +
                               " (taken as one event with the guard that fired first: the map is not smooth there)";
    }
    // Normalised guard rates (continuation's "near a non-smooth point"): a gap's rate (an impact,
    // a compliant switch) in V, a slip's u' in V ω, a force's rate (a held stop's, a stuck
    // contact's) in F ω.
    Rate::Kind kind = Rate::force;
    if (stop_guard && (rec.impact || scene_.stops()[static_cast<std::size_t>(rec.guard_stop)].is_compliant()))
      kind = Rate::gap;
    else if (!stop_guard && sw.before[static_cast<std::size_t>(rec.guard_stop - ms_)] != FrictionState::stuck)
      kind = Rate::slip;
    rates_.push_back({std::abs(hdot), kind});

    // Phases: held stops as stops, stuck contacts as stop_count + j.
    ContactSet was = mech_.held_part(sw.key_before), is = mech_.held_part(sw.key_after);
    for (std::size_t j = 0; j < sw.after.size(); ++j) {
      if (sw.before[j] == FrictionState::stuck) was.push_back(ms_ + static_cast<int>(j));
      if (sw.after[j] == FrictionState::stuck) is.push_back(ms_ + static_cast<int>(j));
    }
    phases_.change(t, was, is);
    if (options_.features) {
      const VectorXd a = fm.segment(n, n);
      for (int j : rule.impacting)
        out_.impacts.push_back({j, t, mech_.gap_rate(j, vm, t), mech_.normal_dot(j, a) - mech_.stop_position(j, t, 2)});
      for (std::size_t j = 0; j < sw.after.size(); ++j)
        if (sw.before[j] != FrictionState::stuck && sw.after[j] != sw.before[j])
          margins_.push_back({ms_ + static_cast<int>(j), t, margin(sw.key_after, sw.after, static_cast<int>(j), sw.z_after),
                              sw.after[j] == FrictionState::stuck});
    }
    events_.clear();
    t_last_switch_ = t;
  }

  /// After the run: the map's end, J, the reduced map, the scaled features.
  void finish(const RunSummary& f) {
    const Index N2 = 2 * n_;
    out_.t1 = f.t;
    out_.x1 = f.x;
    out_.v1 = f.v;
    if (!out_.saltations.empty() && t_last_switch_ == f.t) out_.ends_at_event = true;
    if (last_) out_.rate_end = (last_->rows.generator * augmented(f.t, f.x, f.v)).head(N2);
    phases_.end(f.t);
    map_.write(!first_, frame_, options_.jacobian, options_.directions, N2, out_);
    if (options_.parameter) out_.parameter = first_ ? VectorXd(VectorXd::Zero(N2)) : zeta_;
    const double V = f.velocity_scale, Fs = f.force_scale, L = f.length_scale;
    const double omega = L > 0.0 ? V / L : 1.0;
    double least = std::numeric_limits<double>::infinity();
    for (const Rate& r : rates_)
      least = std::min(least, r.value / (r.kind == Rate::gap ? V : r.kind == Rate::slip ? V * omega : Fs * omega));
    out_.least_guard_rate = least;
    if (options_.features) {
      for (const Margin& m : margins_) out_.force_dips.push_back({m.contact, m.t, m.value, m.stuck});
      for (const detail::InteriorMinimum& m : minima_)
        out_.force_dips.push_back({ms_ + m.contact, m.t, m.value * Fs / V, false});
      for (const detail::InteriorMinimum& m : stick_dips_) out_.force_dips.push_back({ms_ + m.contact, m.t, m.value, false});
    }
  }

 private:
  struct Margin {
    int contact;
    double t, value;
    bool stuck;
  };
  struct Rate {
    enum Kind { gap, slip, force };
    double value;
    Kind kind;
  };

  static bool is_friction(EventKind k) {
    return k == EventKind::friction_stick || k == EventKind::friction_slip || k == EventKind::friction_reversal;
  }

  ModeData& mode_for(const ContactSet& key, const std::vector<FrictionState>& states) {
    auto it = modes_.find({key, states});
    if (it != modes_.end()) return *it->second;
    auto d = std::make_unique<ModeData>();
    const LinearSystem& sys = scene_.system();
    d->rows = friction_stop_mode_rows(sys.mass(), sys.damping(), sys.stiffness(), sys.forcing(), scene_.stops(),
                                      contacts_, key, states);
    if (step_ > 0.0) {
      std::vector<FrictionStopModeRows> r;
      for (const MovedScene& m : moved_)
        r.push_back(friction_stop_mode_rows(sys.mass(), m.data.C, m.data.K, m.data.f, m.stops, m.data.contacts, key,
                                            states));
      // Five points −2h, −h, h, 2h: (8 (R₁ − R₋₁) − (R₂ − R₋₂)) / 12h.
      auto five = [&](auto get) {
        return MatrixXd((8.0 * (get(r[2]) - get(r[1])) - (get(r[3]) - get(r[0]))) / (12.0 * step_));
      };
      d->dgenerator = five([](const FrictionStopModeRows& x) -> const MatrixXd& { return x.generator; });
      d->dguards = five([](const FrictionStopModeRows& x) -> const MatrixXd& { return x.guards; });
      d->drelative = five([](const FrictionStopModeRows& x) -> const MatrixXd& { return x.relative; });
      d->dheld_rates = five([](const FrictionStopModeRows& x) -> const MatrixXd& { return x.held_rates; });
    } else if (options_.parameter) {
      d->dgenerator = MatrixXd::Zero(N_, N_);
      d->dguards = MatrixXd::Zero(d->rows.guards.rows(), N_);
      d->drelative = MatrixXd::Zero(d->rows.relative.rows(), N_);
      d->dheld_rates = MatrixXd::Zero(d->rows.held_rates.rows(), N_);
    }
    // The tangent space: held stops fix their normal position and rate, stuck contacts their
    // relative velocity.
    const auto h = static_cast<Index>(d->rows.held.size());
    MatrixXd Nh(n_, h);
    for (Index a = 0; a < h; ++a) Nh.col(a) = scene_.stops()[static_cast<std::size_t>(d->rows.held[static_cast<std::size_t>(a)])].normal(n_);
    std::vector<Index> stuck;
    for (std::size_t j = 0; j < states.size(); ++j)
      if (states[j] == FrictionState::stuck) stuck.push_back(static_cast<Index>(j));
    MatrixXd Nv(n_, h + static_cast<Index>(stuck.size()));
    Nv.leftCols(h) = Nh;
    for (std::size_t a = 0; a < stuck.size(); ++a) Nv.col(h + static_cast<Index>(a)) = W_.col(stuck[a]);
    const MatrixXd Px = detail::complement_basis(Nh, n_), Pv = detail::complement_basis(Nv, n_);
    d->basis = MatrixXd::Zero(2 * n_, Px.cols() + Pv.cols());
    d->basis.topLeftCorner(n_, Px.cols()) = Px;
    d->basis.bottomRightCorner(n_, Pv.cols()) = Pv;
    if (options_.features) {
      // Rows: every stop's gap, its rate, the held stops' forces (−F = λ) and their rates.
      d->flow = std::make_unique<LinearFlow>(d->rows.generator, n_, sys.forcing().frequency, solver_.flow);
      MatrixXd rows(2 * ms_ + 2 * h, N_);
      for (int j = 0; j < ms_; ++j) {
        const VectorXd g = mech_.gap_row(j);
        rows.row(j) = g.transpose();
        rows.row(ms_ + j) = g.transpose() * d->rows.generator;
      }
      if (h > 0) {
        rows.middleRows(2 * ms_, h) = -d->rows.held_force;
        rows.middleRows(2 * ms_ + h, h) = -d->rows.held_force * d->rows.generator;
      }
      d->scan = std::make_unique<Functionals>(*d->flow, rows);
    }
    return *modes_.emplace(std::make_pair(key, states), std::move(d)).first->second;
  }

  /// The frictional contacts in `states` for the chatter rule's forces (mechanics.hpp's
  /// FrictionPart), on mech0_ or (parameter) on mechp_ with the contacts' N, μ_k derivatives.
  void set_friction_part(const std::vector<FrictionState>& states, const ContactSet& held, bool parameter = false) {
    Mechanics<Dual>::FrictionPart part;
    part.slip_force = detail::VecT<Dual>::Zero(n_);
    MatrixXd Nh(n_, static_cast<Index>(held.size()));
    for (std::size_t a = 0; a < held.size(); ++a) Nh.col(static_cast<Index>(a)) = scene_.stops()[static_cast<std::size_t>(held[a])].normal(n_);
    std::vector<Index> stuck;
    for (std::size_t j = 0; j < states.size(); ++j) {
      const FrictionContact& c = contacts_[j];
      if (states[j] == FrictionState::stuck) {
        // A contact whose tangent the held stops' normals span takes no force (friction_stops.hpp).
        const bool locked = Nh.cols() > 0 && (W_.col(static_cast<Index>(j)) -
                                              Nh * Nh.colPivHouseholderQr().solve(VectorXd(W_.col(static_cast<Index>(j)))))
                                                     .norm() <= 1e-12 * W_.col(static_cast<Index>(j)).norm();
        if (!locked) stuck.push_back(static_cast<Index>(j));
        continue;
      }
      Dual N(c.normal_load), mu(c.kinetic_coefficient);
      if (parameter && j < options_.parameter->friction.size()) {
        N.d = options_.parameter->friction[j].normal_load;
        mu.d = options_.parameter->friction[j].kinetic_coefficient;
      }
      const Dual F = -(mu * N) * Dual(static_cast<double>(static_cast<int>(states[j])));
      for (Index i = 0; i < n_; ++i) part.slip_force(i) += F * Dual(W_(i, static_cast<Index>(j)));
    }
    part.stuck.resize(n_, static_cast<Index>(stuck.size()));
    for (std::size_t a = 0; a < stuck.size(); ++a) {
      for (Index i = 0; i < n_; ++i) part.stuck(i, static_cast<Index>(a)) = Dual(W_(i, stuck[a]));
      part.amplitude.push_back(Dual(contacts_[static_cast<std::size_t>(stuck[a])].amplitude));
      part.phase.push_back(Dual(contacts_[static_cast<std::size_t>(stuck[a])].phase));
    }
    (parameter ? *mechp_ : mech0_).set_friction(std::move(part));
  }

  int row_stop(const FrictionStopSwitch& sw) const {
    // The stop rows list the open stops, then the key's stops, each in stop order.
    const Index r = sw.guard_row;
    int count = 0;
    for (int j = 0; j < ms_; ++j) {
      if (std::binary_search(sw.key_before.begin(), sw.key_before.end(), j)) continue;
      if (count++ == r) return j;
    }
    return sw.key_before[static_cast<std::size_t>(r - count)];
  }
  int fired_contact(const ModeData& mode, const FrictionStopSwitch& sw) const {
    // friction.hpp's guard order: one row per slipping contact, two per stuck one.
    Index r = sw.guard_row - mode.rows.stop_rows;
    for (std::size_t j = 0; j < sw.before.size(); ++j) {
      const Index rows = sw.before[j] == FrictionState::stuck ? 2 : 1;
      if (r < rows) return static_cast<int>(j);
      r -= rows;
    }
    return -1;
  }

  VectorXd augmented(double t, const VectorXd& x, const VectorXd& v) const {
    return detail::augmented_of(scene_.system().forcing(), n_, N_, t, x, v);
  }
  VectorXd oscillator_sensitivity(double t) const {
    return detail::oscillator_sensitivity_of(scene_.system().forcing(), options_.parameter->frequency, N_ - 2 * n_, t);
  }

  /// |F_j^hold| − μ_s N_j at z in the mode of `key` with contact j stuck (the others as in states).
  double margin(const ContactSet& key, std::vector<FrictionState> states, int j, const VectorXd& z) {
    states[static_cast<std::size_t>(j)] = FrictionState::stuck;
    const ModeData& held = mode_for(key, states);
    const FrictionContact& c = contacts_[static_cast<std::size_t>(j)];
    return std::abs(held.rows.force.row(j).dot(z)) - c.static_coefficient * c.normal_load;
  }

  /// The features of one segment: free stops' gap peaks, held stops' force dips (certified,
  /// sign_changes.hpp), slipping contacts' σu minima (friction_parts.hpp).
  void features(const ModeData& mode, const std::vector<FrictionState>& states, double tb, double tau,
                const VectorXd& zb) {
    detail::slip_minima(mode.rows.generator, mode.rows.relative, states, tb, tau, zb, minima_);
    detail::stick_margins(mode.rows.generator, mode.rows.force, states, contacts_, &mode.rows.locked, tb, tau, zb,
                          stick_dips_);
    const Segment seg(*mode.scan, tb, zb);
    const double resolution = 16.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(tb + tau), 1.0);
    for (int j = 0; j < ms_; ++j) {
      if (std::binary_search(mode.rows.held.begin(), mode.rows.held.end(), j)) continue;
      detail::SignChanges peaks(seg, ms_ + j, 1.0, resolution, solver_.interrupt);
      const double g_start = seg.value(j, 0.0);
      const double size = std::max({std::abs(g_start), std::abs(seg.value(j, 0.5 * tau)), std::abs(seg.value(j, tau))});
      for (double s : peaks.in(0.0, tau)) {
        const double g = seg.value(j, s);
        if (detail::flight_start_artifact(s, tau, g, g_start, size)) continue;
        out_.gap_peaks.push_back({j, tb + s, g});
      }
    }
    const auto h = static_cast<Index>(mode.rows.held.size());
    for (Index a = 0; a < h; ++a) {
      detail::SignChanges dips(seg, 2 * ms_ + h + a, -1.0, resolution, solver_.interrupt);
      for (double s : dips.in(0.0, tau))
        out_.force_dips.push_back({mode.rows.held[static_cast<std::size_t>(a)], tb + s, seg.value(2 * ms_ + a, s), false});
    }
  }

  const ImpactSystem& scene_;
  const std::vector<FrictionContact>& contacts_;
  SimulatorOptions solver_;
  const LinearisationOptions& options_;
  TangentMap& out_;
  Index n_, N_;
  int ms_;
  Mechanics<double> mech_;
  Mechanics<Dual> mech0_;
  std::unique_ptr<Mechanics<Dual>> mechp_;
  detail::PhaseBook phases_;
  bool frame_ = false, carries_ = false, first_ = true, switched_ = false;
  MatrixXd minv_, W_;
  double step_ = 0.0, t_last_switch_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<MovedScene> moved_;
  std::map<std::pair<ContactSet, std::vector<FrictionState>>, std::unique_ptr<ModeData>> modes_;
  detail::CarriedMap map_;
  MatrixXd& K_ = map_.K;
  VectorXd zeta_;
  const ModeData* last_ = nullptr;
  std::vector<Event> events_;
  std::vector<Rate> rates_;
  std::vector<Margin> margins_;
  std::vector<detail::InteriorMinimum> minima_;      // slipping contacts' σu minima (grazing-sliding)
  std::vector<detail::InteriorMinimum> stick_dips_;  // stuck contacts' μ_s N − |F| minima (adding-sliding)
};

}  // namespace

TangentMap linearise(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                     const SimulatorOptions& solver, double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                     const LinearisationOptions& options) {
  if (options.directions.size() > 0 && options.directions.rows() != 2 * scene.dof())
    throw InvalidInput("linearisation: directions have " + std::to_string(options.directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * scene.dof()));
  FrictionStopSimulator sim(scene, contacts, solver);
  TangentMap out;
  out.t0 = t0;
  out.x0 = x0;
  out.v0 = v0;
  FrictionStopRecorder recorder(scene, sim.contacts(), solver, options, out);
  out.summary = sim.run(t0, x0, v0, t1, {&recorder}, {&recorder});
  recorder.finish(out.summary);
  return out;
}

}  // namespace vibro
