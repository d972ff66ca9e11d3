/// \file friction_tangent.cpp
/// The tangent maps of friction runs (friction_tangent.hpp): a FrictionObserver that follows the
/// modes and switches of FrictionSimulator and composes the flows' propagators with the switches'
/// saltation matrices; the Lyapunov spectrum and the continuation engine built on it. (Shooting on
/// friction scenes is in shooting.cpp, beside the other engines' backends.)
#include "vibro/friction_tangent.hpp"

#include "friction_parts.hpp"
#include "mechanics.hpp"

#include <Eigen/QR>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <utility>

namespace vibro {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

/// The rows of every mode the run visits, with their parameter derivatives (when asked for).
struct ModeData {
  FrictionModeRows rows;
  MatrixXd dgenerator, dguards, drelative;  // d/dp (parameter runs)
  MatrixXd basis;                           // 2n × d: {W_Sᵀ δv = 0}
  int stuck = 0;
};

using detail::max_abs;
using detail::MovedData;
using detail::moved;
using detail::InteriorMinimum;

class FrictionTangentRecorder final : public FrictionObserver {
 public:
  FrictionTangentRecorder(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                          const FrictionSimulator& sim, const LinearisationOptions& options, TangentMap& out)
      : system_(system), contacts_(contacts), sim_(sim), options_(options), out_(out), n_(system.dof()),
        N_(augmented_size(system.dof(), system.forcing())) {
    frame_ = options.directions.size() > 0;
    carries_ = frame_ || options.jacobian;
    minv_ = system.mass().llt().solve(MatrixXd::Identity(n_, n_));
    W_.resize(n_, static_cast<Index>(contacts.size()));
    for (std::size_t j = 0; j < contacts.size(); ++j) W_.col(static_cast<Index>(j)) = contacts[j].tangent(n_);
    if (options.parameter) {
      const SystemDerivative& d = *options.parameter;
      d.validate(n_, 0);
      if (d.mass.size() && !d.mass.isZero(0.0))
        throw InvalidInput("linearisation (friction): the parameter moves the mass matrix; continue in Ω, the forcing, "
                           "C or K");
      if (!d.friction.empty() && d.friction.size() != contacts.size())
        throw InvalidInput("linearisation (friction): " + std::to_string(d.friction.size()) +
                           " contact derivatives for " + std::to_string(contacts.size()) + " frictional contacts");
      // The rows are polynomials of degree ≤ 2 in h along dD with M fixed (C, K and f enter
      // linearly, Ω linearly in the oscillator and the surfaces' velocities and quadratically in
      // their accelerations, a slip's force μ_k N and a stuck contact's limit μ_s N are bilinear in
      // (N, μ); M⁻¹ and W_SᵀM⁻¹W_S do not move), so the central difference below is their exact
      // derivative up to rounding, about ε‖rows‖/h: h moves the data by 1e-3 of its size.
      double size = 0.0, move = 0.0;
      detail::data_and_move(system, contacts, d, size, move);
      step_ = move > 0.0 ? 1e-3 * size / move : 0.0;
      if (step_ > 0.0) {
        plus_ = moved(system, contacts, d, step_);
        minus_ = moved(system, contacts, d, -step_);
      }
    }
  }

  bool wants_modes() const override { return true; }

  void friction_segment(double tb, double te, const std::vector<FrictionState>& states, const VectorXd& zb) override {
    ModeData& mode = mode_for(states);
    const Index N2 = 2 * n_;
    if (first_) {
      first_ = false;
      map_.start(N2, frame_, options_.directions);
      zeta_ = VectorXd::Zero(N_);
      if (options_.parameter) zeta_.segment(N2, N_ - N2) = oscillator_sensitivity(tb);
      for (std::size_t j = 0; j < states.size(); ++j)
        if (states[j] == FrictionState::stuck) {
          out_.starts_held = true;
          open_phase(static_cast<int>(j), tb);
        }
      out_.rate_start = (mode.rows.generator * zb).head(N2);
    }
    const double tau = te - tb;
    if (tau > 0.0 && (carries_ || options_.parameter)) {
      const MatrixXd& A = mode.rows.generator;
      if (options_.parameter) {
        MatrixXd block = MatrixXd::Zero(2 * N_, 2 * N_);
        block.topLeftCorner(N_, N_) = A * tau;
        block.topRightCorner(N_, N_) = mode.dgenerator * tau;
        block.bottomRightCorner(N_, N_) = A * tau;
        const MatrixXd E = block.exp();
        zeta_ = E.topLeftCorner(N_, N_) * zeta_ + E.topRightCorner(N_, N_) * zb;
        if (carries_) K_ = E.topLeftCorner(N2, N2) * K_;
      } else {
        const MatrixXd E = (A * tau).exp();
        K_ = E.topLeftCorner(N2, N2) * K_;
      }
    }
    // The least tangent dimension (friction_tangent.hpp): a contact stuck since the start has not
    // lost its direction (no stick's saltation yet).
    map_.reached(switched_ ? mode.basis.cols() : N2, mode.basis, options_.jacobian && !frame_);
    if (options_.features && tau > 0.0) {
      detail::slip_minima(mode.rows.generator, mode.rows.relative, states, tb, tau, zb, minima_);
      detail::stick_margins(mode.rows.generator, mode.rows.force, states, contacts_, nullptr, tb, tau, zb, stick_dips_);
    }
    last_ = &mode;
  }

  void friction_switch(const FrictionSwitch& s) override {
    switched_ = true;
    const ModeData& before = mode_for(s.before);
    const ModeData& after = mode_for(s.after);
    const VectorXd ell = before.rows.guards.row(s.guard_index).transpose();
    const VectorXd fm = before.rows.generator * s.z_before, fp = after.rows.generator * s.z_after;
    // R_z = I − B U_S over the contacts stuck before or after.
    std::vector<Index> S;
    int changed = 0;
    for (std::size_t j = 0; j < s.after.size(); ++j) {
      if (s.after[j] == FrictionState::stuck || s.before[j] == FrictionState::stuck) S.push_back(static_cast<Index>(j));
      changed += s.after[j] != s.before[j];
    }
    MatrixXd B = MatrixXd::Zero(N_, static_cast<Index>(S.size())), U(static_cast<Index>(S.size()), N_);
    if (!S.empty()) {
      MatrixXd Ws(n_, static_cast<Index>(S.size()));
      for (std::size_t a = 0; a < S.size(); ++a) {
        Ws.col(static_cast<Index>(a)) = W_.col(S[a]);
        U.row(static_cast<Index>(a)) = after.rows.relative.row(S[a]);
      }
      const MatrixXd MW = minv_ * Ws;
      B.middleRows(n_, n_) = MW * (Ws.transpose() * MW).ldlt().solve(MatrixXd::Identity(Ws.cols(), Ws.cols()));
    }
    MatrixXd Rz = MatrixXd::Identity(N_, N_);
    if (!S.empty()) Rz -= B * U;
    const double rate = ell.dot(fm);
    const VectorXd jump = fp - Rz * fm;
    const MatrixXd Sal = Rz + jump * ell.transpose() / rate;
    const Index N2 = 2 * n_;
    if (carries_) K_ = Sal.topLeftCorner(N2, N2) * K_;
    if (options_.parameter) {
      VectorXd sp = jump * (before.dguards.row(s.guard_index).dot(s.z_before) / rate);
      if (!S.empty()) {
        MatrixXd dU(static_cast<Index>(S.size()), N_);
        for (std::size_t a = 0; a < S.size(); ++a) dU.row(static_cast<Index>(a)) = after.drelative.row(S[a]);
        sp -= B * (dU * s.z_before);
      }
      zeta_ = Sal * zeta_ + sp;
    }
    SaltationRecord r;
    r.t = s.t;
    r.guard_stop = s.fired;
    r.impact = false;
    r.guard_rate = rate;
    r.simultaneous = changed > 1;
    out_.saltations.push_back(r);
    if (changed > 1 && !out_.non_smooth) {
      out_.non_smooth = true;
      out_.non_smooth_reason = "several frictional contacts switched at t = " + number_text(s.t) +
                               " (taken as one switch: the map is not smooth there)";
    }
    // A normalised rate of the guard (continuation's "near a non-smooth point"): u' in V ω for a
    // slip's guard, F' in F ω for a stuck contact's.
    const bool force_guard = s.before[static_cast<std::size_t>(s.fired)] == FrictionState::stuck;
    rates_.push_back({std::abs(rate), force_guard});
    for (std::size_t j = 0; j < s.after.size(); ++j) {
      const bool was = s.before[j] == FrictionState::stuck, is = s.after[j] == FrictionState::stuck;
      if (is && !was) open_phase(static_cast<int>(j), s.t);
      if (was && !is) close_phase(static_cast<int>(j), s.t);
      if (options_.features && s.before[j] != FrictionState::stuck && s.after[j] != s.before[j])
        margins_.push_back({static_cast<int>(j), s.t, margin(s.after, static_cast<int>(j), s.z_after), is});
    }
  }

  void friction_event(const FrictionEvent& e, const Eigen::VectorXd& /*x*/, const Eigen::VectorXd& v) override {
    // Before the first segment: the start's decision of the contacts at u = 0 (friction.cpp
    // reports it as an event at t0), not a switch of the map. A stick phase that straddles t0 is
    // counted once, by its switches inside the run: the event signature of an orbit must not
    // change where a switch crosses the section.
    if (first_) return;
    const EventKind kind = e.kind == FrictionEventKind::stick  ? EventKind::friction_stick
                           : e.kind == FrictionEventKind::slip ? EventKind::friction_slip
                                                               : EventKind::friction_reversal;
    const double u = sim_.relative_velocities(e.t, v)(e.contact);
    out_.events.push_back({e.t, e.contact, kind, u, u, e.force});
  }

  /// After the run: the map's end, J, the reduced map, the scaled features.
  void finish(const FrictionSummary& f) {
    const Index N2 = 2 * n_;
    out_.t1 = f.t;
    out_.x1 = f.x;
    out_.v1 = f.v;
    if (!out_.events.empty() && out_.events.back().t == f.t) out_.ends_at_event = true;
    if (last_) out_.rate_end = (last_->rows.generator * augmented(f.t, f.x, f.v)).head(N2);
    for (const auto& open : open_)
      if (open.second >= 0) out_.phases[static_cast<std::size_t>(open.second)].t_end = f.t;
    map_.write(!first_, frame_, options_.jacobian, options_.directions, N2, out_);
    if (options_.parameter) out_.parameter = first_ ? VectorXd::Zero(N2) : VectorXd(zeta_.head(N2));
    const double V = f.velocity_scale, Fs = f.force_scale, L = f.length_scale;
    const double omega = L > 0.0 ? V / L : 1.0;
    double least = std::numeric_limits<double>::infinity();
    for (const auto& [rate, force] : rates_) least = std::min(least, rate / ((force ? Fs : V) * omega));
    out_.least_guard_rate = least;
    if (options_.features) {
      for (const Margin& m : margins_) out_.force_dips.push_back({m.contact, m.t, m.value, m.stuck});
      for (const InteriorMinimum& m : minima_) out_.force_dips.push_back({m.contact, m.t, m.value * Fs / V, false});
      for (const InteriorMinimum& m : stick_dips_) out_.force_dips.push_back({m.contact, m.t, m.value, false});
    }
  }

 private:
  struct Margin {
    int contact;
    double t, value;
    bool stuck;
  };

  ModeData& mode_for(const std::vector<FrictionState>& states) {
    auto it = modes_.find(states);
    if (it != modes_.end()) return it->second;
    ModeData d;
    d.rows = friction_mode_rows(system_.mass(), system_.damping(), system_.stiffness(), system_.forcing(), contacts_, states);
    if (step_ > 0.0) {
      const FrictionModeRows p = friction_mode_rows(system_.mass(), plus_.C, plus_.K, plus_.f, plus_.contacts, states);
      const FrictionModeRows m = friction_mode_rows(system_.mass(), minus_.C, minus_.K, minus_.f, minus_.contacts, states);
      d.dgenerator = (p.generator - m.generator) / (2.0 * step_);
      d.dguards = (p.guards - m.guards) / (2.0 * step_);
      d.drelative = (p.relative - m.relative) / (2.0 * step_);
    } else if (options_.parameter) {
      d.dgenerator = MatrixXd::Zero(N_, N_);
      d.dguards = MatrixXd::Zero(d.rows.guards.rows(), N_);
      d.drelative = MatrixXd::Zero(d.rows.relative.rows(), N_);
    }
    std::vector<Index> stuck;
    for (std::size_t j = 0; j < states.size(); ++j)
      if (states[j] == FrictionState::stuck) stuck.push_back(static_cast<Index>(j));
    d.stuck = static_cast<int>(stuck.size());
    d.basis = MatrixXd::Zero(2 * n_, 2 * n_);
    d.basis.topLeftCorner(n_, n_).setIdentity();
    Index cols = n_;
    if (stuck.empty()) {
      d.basis.bottomRightCorner(n_, n_).setIdentity();
      cols = 2 * n_;
    } else {
      MatrixXd Ws(n_, static_cast<Index>(stuck.size()));
      for (std::size_t a = 0; a < stuck.size(); ++a) Ws.col(static_cast<Index>(a)) = W_.col(stuck[a]);
      Index r = 0;
      const MatrixXd Q = detail::complement_basis(Ws, n_, &r);
      d.basis.block(n_, n_, n_, n_ - r) = Q;
      cols = 2 * n_ - r;
    }
    d.basis.conservativeResize(2 * n_, cols);
    return modes_.emplace(states, std::move(d)).first->second;
  }

  VectorXd augmented(double t, const VectorXd& x, const VectorXd& v) const {
    return detail::augmented_of(system_.forcing(), n_, N_, t, x, v);
  }
  VectorXd oscillator_sensitivity(double t) const {
    return detail::oscillator_sensitivity_of(system_.forcing(), options_.parameter->frequency, N_ - 2 * n_, t);
  }

  /// |F_j^hold| − μ_s N_j at z: the force that holds contact j (the others as in `states`).
  double margin(std::vector<FrictionState> states, int j, const VectorXd& z) {
    states[static_cast<std::size_t>(j)] = FrictionState::stuck;
    const ModeData& held = mode_for(states);
    const FrictionContact& c = contacts_[static_cast<std::size_t>(j)];
    return std::abs(held.rows.force.row(j).dot(z)) - c.static_coefficient * c.normal_load;
  }

  void open_phase(int j, double t) {
    open_[j] = static_cast<long>(out_.phases.size());
    out_.phases.push_back({j, t, t, false});
  }
  void close_phase(int j, double t) {
    auto it = open_.find(j);
    if (it == open_.end() || it->second < 0) return;
    HeldPhase& p = out_.phases[static_cast<std::size_t>(it->second)];
    p.t_end = t;
    p.closed = true;
    it->second = -1;
  }

  const LinearSystem& system_;
  const std::vector<FrictionContact>& contacts_;
  const FrictionSimulator& sim_;
  const LinearisationOptions& options_;
  TangentMap& out_;
  Index n_, N_;
  bool frame_ = false, carries_ = false, first_ = true, switched_ = false;
  MatrixXd minv_, W_;
  double step_ = 0.0;
  MovedData plus_, minus_;
  std::map<std::vector<FrictionState>, ModeData> modes_;
  detail::CarriedMap map_;
  MatrixXd& K_ = map_.K;
  VectorXd zeta_;
  const ModeData* last_ = nullptr;
  std::map<int, long> open_;
  std::vector<std::pair<double, bool>> rates_;
  std::vector<Margin> margins_;
  std::vector<InteriorMinimum> minima_;      // slipping contacts' σu minima (grazing-sliding)
  std::vector<InteriorMinimum> stick_dips_;  // stuck contacts' μ_s N − |F| minima (adding-sliding)
};

}  // namespace

TangentMap linearise(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                     const SimulatorOptions& solver, double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                     const LinearisationOptions& options) {
  if (options.directions.size() > 0 && options.directions.rows() != 2 * system.dof())
    throw InvalidInput("linearisation: directions have " + std::to_string(options.directions.rows()) +
                       " rows, expected 2n = " + std::to_string(2 * system.dof()));
  FrictionSimulator sim(system, contacts, solver);
  TangentMap out;
  out.t0 = t0;
  out.x0 = x0;
  out.v0 = v0;
  FrictionTangentRecorder recorder(system, sim.contacts(), sim, options, out);
  const FrictionSummary f = sim.run(t0, x0, v0, t1, {}, {&recorder});
  out.summary = run_summary(f);
  recorder.finish(f);
  return out;
}

namespace {

/// lyapunov.hpp's QR method on a friction run, once per forcing period (friction's saltations
/// are bounded: no impact speed divides them; with stops those of impacts enter as for stops
/// alone): `run(t, x, v, t1)` a plain run, `map(t, x, v, t1, options)` the tangent map.
template <class Run, class Map>
LyapunovResult friction_lyapunov(Index n, double omega, double t0, const VectorXd& x0, const VectorXd& v0,
                                 const LyapunovOptions& options, Run run, Map map) {
  options.validate();
  const Index n2 = 2 * n;
  if (!(omega > 0.0)) throw InvalidInput("lyapunov: the forcing frequency must be > 0 (exponents are averaged per period)");
  if (options.count > n2)
    throw InvalidInput("lyapunov.count = " + std::to_string(options.count) + ": at most 2n = " + std::to_string(n2));
  const Index p = options.count > 0 ? options.count : n2;
  const double T = 2.0 * std::numbers::pi / omega;
  LyapunovResult out;
  out.period = T;
  double t = t0;
  VectorXd x = x0, v = v0;
  if (options.transient > 0) {
    const RunSummary s = run(t, x, v, t + options.transient * T);
    if (s.status != RunStatus::completed) {
      out.status = s.status;
      out.message = "transient: " + s.message;
      return out;
    }
    t = s.t, x = s.x, v = s.v;
  }
  MatrixXd Q = MatrixXd::Identity(n2, p);
  VectorXd sums = VectorXd::Zero(p);
  Index least = n2;
  LinearisationOptions lo;
  lo.jacobian = false;
  const long total = options.align + options.periods;
  for (long k = 0; k < total; ++k) {
    lo.directions = Q;
    const TangentMap m = map(t, x, v, t + T, lo);
    if (m.summary.status != RunStatus::completed) {
      out.status = m.summary.status;
      out.message = m.summary.message;
      return out;
    }
    t = m.t1, x = m.x1, v = m.v1;
    const Eigen::HouseholderQR<MatrixXd> qr(m.products);
    const MatrixXd R = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    Q = qr.householderQ() * MatrixXd::Identity(n2, p);
    for (Index i = 0; i < p; ++i)
      if (R(i, i) < 0.0) Q.col(i) = -Q.col(i);
    if (k < options.align) continue;
    least = std::min(least, m.free_dimension);
    for (Index i = 0; i < p; ++i) sums(i) += std::log(std::abs(R(i, i)));
    const long done = k - options.align + 1;
    if (options.history_every > 0 && done % options.history_every == 0)
      out.history.push_back(sums.head(std::min(p, least)) / (static_cast<double>(done) * T));
  }
  out.least_free_dimension = least;
  out.exponents = sums / (static_cast<double>(options.periods) * T);
  out.structural = static_cast<int>(std::max<Index>(0, p - least));
  for (Index i = std::min(p, least); i < p; ++i) out.exponents(i) = -std::numeric_limits<double>::infinity();
  out.t_end = t;
  out.x_end = x;
  out.v_end = v;
  return out;
}

}  // namespace

LyapunovResult lyapunov_spectrum(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                                 const SimulatorOptions& solver, double t0, const VectorXd& x0, const VectorXd& v0,
                                 const LyapunovOptions& options) {
  FrictionSimulator sim(system, contacts, solver);
  return friction_lyapunov(
      system.dof(), system.forcing().frequency, t0, x0, v0, options,
      [&](double t, const VectorXd& x, const VectorXd& v, double t1) { return run_summary(sim.run(t, x, v, t1)); },
      [&](double t, const VectorXd& x, const VectorXd& v, double t1, const LinearisationOptions& lo) {
        return linearise(system, contacts, solver, t, x, v, t1, lo);
      });
}

LyapunovResult lyapunov_spectrum(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                                 const SimulatorOptions& solver, double t0, const VectorXd& x0, const VectorXd& v0,
                                 const LyapunovOptions& options) {
  FrictionStopSimulator sim(scene, contacts, solver);
  return friction_lyapunov(
      scene.dof(), scene.system().forcing().frequency, t0, x0, v0, options,
      [&](double t, const VectorXd& x, const VectorXd& v, double t1) { return sim.run(t, x, v, t1); },
      [&](double t, const VectorXd& x, const VectorXd& v, double t1, const LinearisationOptions& lo) {
        return linearise(scene, contacts, solver, t, x, v, t1, lo);
      });
}

namespace {

class FrictionFamilyEngine final : public FamilyEngine {
 public:
  FrictionFamilyEngine(LinearSystem system, std::vector<FrictionContact> contacts, SystemDerivative d,
                       const SimulatorOptions& solver)
      : FamilyEngine(std::move(d)), system_(std::move(system)),
        contacts_(validated_friction(std::move(contacts), system_.dof())), solver_(solver) {
    derivative.validate(system_.dof(), 0);
    if (derivative.mass.size() && !derivative.mass.isZero(0.0))
      throw InvalidInput("continuation with friction: the parameter moves the mass matrix; continue in Ω, the "
                         "forcing, C or K");
  }
  Eigen::Index dof() const override { return system_.dof(); }
  std::size_t stop_count() const override { return contacts_.size(); }
  double frequency() const override { return system_.forcing().frequency; }
  TangentMap linearise(double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                       const LinearisationOptions& options) override {
    return vibro::linearise(system_, contacts_, solver_, t0, x0, v0, t1, options);
  }
  RunSummary run(double t0, const VectorXd& x0, const VectorXd& v0, double t1) override {
    FrictionSimulator sim(system_, contacts_, solver_);
    return run_summary(sim.run(t0, x0, v0, t1));
  }
  ShootingResult shoot(const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v) override {
    return vibro::shoot(system_, contacts_, options, t_guess, x, v);
  }
  /// A frictional contact has no impulse: its tangent and an empty jump (the grazing corner's
  /// step does not apply).
  std::pair<VectorXd, VectorXd> impact_direction(int j) const override {
    return {contacts_[static_cast<std::size_t>(j)].tangent(system_.dof()), VectorXd()};
  }

 private:
  LinearSystem system_;
  std::vector<FrictionContact> contacts_;
  SimulatorOptions solver_;
};

/// Friction with stops: the family's "stops" are the stops, then the contacts (stop_count() +
/// j for contact j, as the tangent maps number them).
class FrictionStopFamilyEngine final : public FamilyEngine {
 public:
  FrictionStopFamilyEngine(ImpactSystem scene, std::vector<FrictionContact> contacts, SystemDerivative d,
                           const SimulatorOptions& solver)
      : FamilyEngine(std::move(d)), scene_(std::move(scene)),
        contacts_(validated_friction(std::move(contacts), scene_.dof())), solver_(solver), mechanics_(scene_) {
    derivative.validate(scene_.dof(), scene_.stop_count());
    if (derivative.mass.size() && !derivative.mass.isZero(0.0))
      throw InvalidInput("continuation with friction: the parameter moves the mass matrix; continue in Ω, the "
                         "forcing, C, K, a stop's data or a contact's");
    if (!derivative.friction.empty() && derivative.friction.size() != contacts_.size())
      throw InvalidInput("continuation with friction: " + std::to_string(derivative.friction.size()) +
                         " contact derivatives for " + std::to_string(contacts_.size()) + " frictional contacts");
  }
  Eigen::Index dof() const override { return scene_.dof(); }
  std::size_t stop_count() const override { return scene_.stop_count() + contacts_.size(); }
  double frequency() const override { return scene_.system().forcing().frequency; }
  TangentMap linearise(double t0, const VectorXd& x0, const VectorXd& v0, double t1,
                       const LinearisationOptions& options) override {
    return vibro::linearise(scene_, contacts_, solver_, t0, x0, v0, t1, options);
  }
  RunSummary run(double t0, const VectorXd& x0, const VectorXd& v0, double t1) override {
    FrictionStopSimulator sim(scene_, contacts_, solver_);
    return sim.run(t0, x0, v0, t1);
  }
  ShootingResult shoot(const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v) override {
    return vibro::shoot(scene_, contacts_, options, t_guess, x, v);
  }
  /// A stop's as the dense engine's (mechanics.hpp); a contact's tangent and no jump.
  std::pair<VectorXd, VectorXd> impact_direction(int j) const override {
    const auto ms = static_cast<int>(scene_.stop_count());
    if (j < ms) return detail::lone_impact(mechanics_, j);
    return {contacts_[static_cast<std::size_t>(j - ms)].tangent(scene_.dof()), VectorXd()};
  }

 private:
  ImpactSystem scene_;
  std::vector<FrictionContact> contacts_;
  SimulatorOptions solver_;
  detail::Mechanics<double> mechanics_;
};

}  // namespace

std::unique_ptr<FamilyEngine> friction_stop_family_engine(ImpactSystem scene, std::vector<FrictionContact> contacts,
                                                          SystemDerivative derivative, const SimulatorOptions& solver) {
  return std::make_unique<FrictionStopFamilyEngine>(std::move(scene), std::move(contacts), std::move(derivative),
                                                    solver);
}

std::unique_ptr<FamilyEngine> friction_family_engine(LinearSystem system, std::vector<FrictionContact> contacts,
                                                     SystemDerivative derivative, const SimulatorOptions& solver) {
  return std::make_unique<FrictionFamilyEngine>(std::move(system), std::move(contacts), std::move(derivative), solver);
}

}  // namespace vibro
