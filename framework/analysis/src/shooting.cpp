#include "vibro/shooting.hpp"

#include "krylov.hpp"
#include "section.hpp"
#include "vibro/bounded_wait.hpp"
#include "vibro/friction_tangent.hpp"
#include "vibro/modal_tangent.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

namespace vibro {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

/// Systems of at least this many degrees of freedom factorise under run_bounded.
constexpr Index kBoundedFromCoordinates = 64;

VectorXd stacked(const VectorXd& x, const VectorXd& v) {
  VectorXd z(x.size() + v.size());
  z << x, v;
  return z;
}

/// Scales (L for positions, V for velocities) as a vector over (x, v).
VectorXd scales(Index n, double L, double V) {
  VectorXd s(2 * n);
  s << VectorXd::Constant(n, L), VectorXd::Constant(n, V);
  return s;
}

std::string text(double v) { return number_text(v); }

/// The run of one map evaluation, or a failure (inadmissible state, engine trouble).
struct Evaluation {
  bool ok = false;
  std::string why;
  TangentMap map;
  std::shared_ptr<ModalTangent> tangent;  // the modal engine's map as an operator
  double residual = std::numeric_limits<double>::infinity();
};

/// The scaled Newton step of F(z) = P(z) − z at an evaluation: (D⁻¹ (J − I) D) δ = −D⁻¹ F,
/// Δ = D δ, D = diag(L, V). `rcond`: the matrix's reciprocal condition (dense; 0 if singular),
/// or 1 when GMRES reached its tolerance and 0 when it did not (matrix-free).
struct NewtonStep {
  VectorXd delta, scale;
  double rcond = 0.0;
  std::string why;  // when rcond is 0
};

/// What shooting needs of an engine: plain runs, maps, Newton steps and multipliers. The dense
/// engine forms J (linearisation.hpp) and solves with LU; the modal engine applies J to vectors
/// (modal_tangent.hpp) and solves by GMRES, its multipliers by Arnoldi (krylov.hpp).
class Backend {
 public:
  virtual ~Backend() = default;
  virtual Index dof() const = 0;
  virtual double frequency() const = 0;
  /// The state at `to` from z at `from`; throws InvalidInput if the run stops early.
  VectorXd advance(double from, const VectorXd& z, double to) {
    const RunSummary s = run(from, z, to);
    if (s.status != RunStatus::completed)
      throw InvalidInput("shooting: the guess's run stopped early (" + std::string(to_string(s.status)) + "): " + s.message);
    return stacked(s.x, s.v);
  }
  /// The events and held phases over [t0, t1] (for the choice of section).
  virtual TangentMap probe(double t0, const VectorXd& z, double t1) = 0;
  virtual Evaluation evaluate(double t0, const VectorXd& z, double t1) = 0;
  virtual NewtonStep newton_step(const Evaluation& e, const VectorXd& z) = 0;
  virtual FloquetMultipliers multipliers(const Evaluation& e, int k) = 0;
  /// `e` made usable again after other runs: a modal record is valid only until the engine's
  /// next run (modal_tangent.hpp), so the modal backend evaluates again; a dense map is kept.
  virtual Evaluation refresh(Evaluation e, double /*t0*/, const VectorXd& /*z*/, double /*t1*/) { return e; }
  int products = 0;  // J·v products (matrix-free)

 protected:
  virtual RunSummary run(double from, const VectorXd& z, double to) = 0;
  /// A step with the scales D = diag(L, V) of the map's run.
  static NewtonStep scaled_step(const TangentMap& m) {
    NewtonStep s;
    s.scale = scales(m.x0.size(), m.summary.length_scale, m.summary.velocity_scale);
    return s;
  }
  /// Completes an evaluation from its map (ok, why, residual).
  static Evaluation finish(Evaluation e) {
    if (e.map.summary.status != RunStatus::completed) {
      e.why = std::string("the run stopped early (") + to_string(e.map.summary.status) + "): " + e.map.summary.message;
      return e;
    }
    e.ok = true;
    e.residual = periodicity_residual(e.map);
    return e;
  }
};

/// Newton steps by LU on the full J and all 2n multipliers from its reduced map: the dense
/// engine's linear algebra, on maps that carry J (TangentMap::jacobian, reduced, lift).
///
/// The LU and the eigenvalues of a large system (seconds from a few hundred coordinates on)
/// cannot be polled: from kBoundedFromCoordinates degrees of freedom on they run under
/// run_bounded with the run's interrupt flag (bounded_wait.hpp), on copies of their inputs; the
/// same code on the same data, so the same bits. Raising the flag throws Interrupted, which
/// shoot() reports as an interrupted map.
class FullJacobianBackend : public Backend {
 public:
  explicit FullJacobianBackend(const std::atomic<bool>* interrupt) : interrupt_(interrupt) {}
  NewtonStep newton_step(const Evaluation& e, const VectorXd& z) override {
    const TangentMap& m = e.map;
    const Index n = m.x0.size();
    NewtonStep s = scaled_step(m);
    const VectorXd F = stacked(m.x1, m.v1) - z;
    const MatrixXd A = s.scale.cwiseInverse().asDiagonal() * (m.jacobian - MatrixXd::Identity(2 * n, 2 * n)) *
                       s.scale.asDiagonal();
    const auto [rcond, delta] =
        bounded(n, [A, b = VectorXd(-F.cwiseQuotient(s.scale))]() -> std::pair<double, VectorXd> {
          const Eigen::FullPivLU<MatrixXd> lu(A);
          const double rc = lu.isInvertible() ? lu.rcond() : 0.0;
          return {rc, rc > 0.0 ? VectorXd(lu.solve(b)) : VectorXd()};
        });
    s.rcond = rcond;
    if (s.rcond > 0.0) s.delta = delta;
    return s;
  }
  FloquetMultipliers multipliers(const Evaluation& e, int k) override {
    return bounded(e.map.x0.size(), [m = e.map, k] { return floquet_multipliers(m, k); });
  }

 protected:
  template <class F>
  auto bounded(Index n, F fn) const -> decltype(fn()) {
    return run_bounded(n >= kBoundedFromCoordinates ? interrupt_ : nullptr, std::move(fn));
  }
  const std::atomic<bool>* interrupt_;

  /// The map with J from `linearise`, or the failure it threw.
  template <class Linearise>
  static Evaluation evaluate_with(Linearise&& linearise_map) {
    Evaluation e;
    try {
      e.map = linearise_map();
    } catch (const InvalidInput& err) {
      e.why = err.what();
      return e;
    }
    return finish(std::move(e));
  }
};

class DenseBackend final : public FullJacobianBackend {
 public:
  DenseBackend(const ImpactSystem& system, const SimulatorOptions& solver, const LinearisationOptions& o)
      : FullJacobianBackend(solver.interrupt), system_(system), solver_(solver), options_(o) {
    options_.jacobian = true;
  }
  Index dof() const override { return system_.dof(); }
  double frequency() const override { return system_.system().forcing().frequency; }
  TangentMap probe(double t0, const VectorXd& z, double t1) override {
    LinearisationOptions probe;
    probe.jacobian = false;
    probe.features = true;
    return linearise(system_, solver_, t0, z.head(dof()), z.tail(dof()), t1, probe);
  }
  Evaluation evaluate(double t0, const VectorXd& z, double t1) override {
    return evaluate_with([&] { return linearise(system_, solver_, t0, z.head(dof()), z.tail(dof()), t1, options_); });
  }

 protected:
  RunSummary run(double from, const VectorXd& z, double to) override {
    Simulator sim(system_, solver_);
    return sim.run(from, z.head(dof()), z.tail(dof()), to);
  }

 private:
  const ImpactSystem& system_;
  SimulatorOptions solver_;
  LinearisationOptions options_;
};

/// The engine's run summary as shooting reads it (a friction run's, converted).
inline RunSummary summary_of(RunSummary s) { return s; }
inline RunSummary summary_of(const FrictionSummary& f) { return run_summary(f); }
/// The forcing of a model: a LinearSystem's own, an ImpactSystem's through its system.
inline const HarmonicForcing& forcing_of(const LinearSystem& s) { return s.forcing(); }
inline const HarmonicForcing& forcing_of(const ImpactSystem& s) { return s.system().forcing(); }

/// A scene whose tangent maps come from linearise(model, extra, …) and whose runs from
/// Engine(model, extra, solver): the Taylor engine (an ImpactSystem and its NonlinearForces), a
/// friction scene (a LinearSystem and its contacts), friction with stops (an ImpactSystem and its
/// contacts). The probe asks for the events only (no held phases: the maps refuse them).
template <class Model, class Extra, class Engine>
class EngineBackend final : public FullJacobianBackend {
 public:
  EngineBackend(const Model& model, const Extra& extra, const SimulatorOptions& solver, const LinearisationOptions& o)
      : FullJacobianBackend(solver.interrupt), model_(model), extra_(extra), solver_(solver), options_(o) {
    options_.jacobian = true;
  }
  Index dof() const override { return model_.dof(); }
  double frequency() const override { return forcing_of(model_).frequency; }
  TangentMap probe(double t0, const VectorXd& z, double t1) override {
    LinearisationOptions probe;
    probe.jacobian = false;
    return linearise(model_, extra_, solver_, t0, z.head(dof()), z.tail(dof()), t1, probe);
  }
  Evaluation evaluate(double t0, const VectorXd& z, double t1) override {
    return evaluate_with(
        [&] { return linearise(model_, extra_, solver_, t0, z.head(dof()), z.tail(dof()), t1, options_); });
  }

 protected:
  RunSummary run(double from, const VectorXd& z, double to) override {
    Engine sim(model_, extra_, solver_);
    return summary_of(sim.run(from, z.head(dof()), z.tail(dof()), to));
  }

 private:
  const Model& model_;
  const Extra& extra_;
  SimulatorOptions solver_;
  LinearisationOptions options_;
};
using TaylorBackend = EngineBackend<ImpactSystem, NonlinearForces, TaylorSimulator>;
using FrictionBackend = EngineBackend<LinearSystem, std::vector<FrictionContact>, FrictionSimulator>;
using FrictionStopBackend = EngineBackend<ImpactSystem, std::vector<FrictionContact>, FrictionStopSimulator>;

/// What every backend on the modal engine shares: its size and frequency, plain runs, probes.
template <class Base>
class OnModalEngine : public Base {
 public:
  template <class... Args>
  explicit OnModalEngine(ModalEngine& engine, Args&&... base) : Base(std::forward<Args>(base)...), engine_(engine) {}
  Index dof() const override { return engine_.simulator().modes().dof(); }
  double frequency() const override { return engine_.frequency(); }
  TangentMap probe(double t0, const VectorXd& z, double t1) override {
    return ModalTangent(engine_, t0, z.head(dof()), z.tail(dof()), t1).map();
  }

 protected:
  RunSummary run(double from, const VectorXd& z, double to) override {
    return engine_.run(from, z.head(dof()), z.tail(dof()), to);
  }
  ModalEngine& engine_;
};

/// The modal engine's maps with their full J (ModalTangent::fill_jacobian): self-contained, so
/// nothing needs refreshing after other runs.
class ModalJacobianBackend final : public OnModalEngine<FullJacobianBackend> {
 public:
  ModalJacobianBackend(ModalEngine& engine, const LinearisationOptions& o)
      : OnModalEngine(engine, engine.simulator().options().interrupt), options_(o) {
    options_.jacobian = true;
    options_.directions.resize(0, 0);
  }
  Evaluation evaluate(double t0, const VectorXd& z, double t1) override {
    return evaluate_with([&] { return linearise(engine_, t0, z.head(dof()), z.tail(dof()), t1, options_); });
  }

 private:
  LinearisationOptions options_;
};

class ModalBackend final : public OnModalEngine<Backend> {
 public:
  ModalBackend(ModalEngine& engine, const KrylovOptions& krylov) : OnModalEngine(engine), krylov_(krylov) {}
  Evaluation evaluate(double t0, const VectorXd& z, double t1) override {
    Evaluation e;
    try {
      e.tangent = std::make_shared<ModalTangent>(engine_, t0, z.head(dof()), z.tail(dof()), t1);
    } catch (const InvalidInput& err) {
      e.why = err.what();
      return e;
    }
    e.map = e.tangent->map();
    return finish(std::move(e));
  }
  NewtonStep newton_step(const Evaluation& e, const VectorXd& z) override {
    const TangentMap& m = e.map;
    const Index n = m.x0.size();
    NewtonStep s = scaled_step(m);
    // In the free chain's modal coordinates (ModalTangent::apply_modal: O(N) per free flight and
    // free-flight impact). D = diag(L, V) commutes with Φ̃ = diag(Φ, Φ), so the scaled step is
    // δ = Φ̃ δ_modal.
    //
    // Preconditioned on the right by the free chain's own monodromy: between impacts the modes
    // do not interact, so J_free (no stop) is block diagonal in these coordinates — one 2 × 2
    // propagator per mode over kT — and a free-flight impact changes the map by a rank-2 term.
    // Hence (J − I)(J_free − I)⁻¹ = I + (a term of rank ≤ 2 × impacts, plus what held phases
    // add) and GMRES needs about that many products whatever N is (unpreconditioned, restarted
    // GMRES stalled at N = 4000 on the lightly damped low modes; measured in
    // tools/bench/bench_modal_shooting). A mode whose free multiplier is 1 (no damping, ω kT ∈ 2πℤ)
    // is left unpreconditioned.
    const VectorXd F = e.tangent->modal_coordinates(stacked(m.x1, m.v1) - z);
    const VectorXd D = s.scale;
    const ChainModes& modes = engine_.simulator().modes();
    Eigen::MatrixXd inverse(n, 4);  // rows: (P_k − I)⁻¹ of mode k, row-major
    for (Index k = 0; k < n; ++k) {
      double p[4];
      modes.mode_propagator(k, m.t1 - m.t0, p);
      const double a = p[0] - 1.0, b = p[1], c = p[2], d = p[3] - 1.0, det = a * d - b * c;
      if (std::abs(det) > 1e-12 * (std::abs(a * d) + std::abs(b * c)) && det != 0.0) inverse.row(k) << d / det, -b / det, -c / det, a / det;
      else inverse.row(k) << 1.0, 0.0, 0.0, 1.0;
    }
    auto precondition = [&](const VectorXd& q) -> VectorXd {
      VectorXd y = D.cwiseProduct(q), w(2 * n);
      for (Index k = 0; k < n; ++k) {
        w(k) = inverse(k, 0) * y(k) + inverse(k, 1) * y(n + k);
        w(n + k) = inverse(k, 2) * y(k) + inverse(k, 3) * y(n + k);
      }
      return w.cwiseQuotient(D);
    };
    const detail::Product A = [&](const VectorXd& q) -> VectorXd {
      const VectorXd pq = precondition(q);
      return VectorXd(e.tangent->apply_modal(D.cwiseProduct(pq))).cwiseQuotient(D) - pq;
    };
    const detail::GmresResult g =
        detail::gmres(A, -F.cwiseQuotient(D), krylov_.gmres_tolerance, krylov_.max_dimension, krylov_.max_products,
                      engine_.simulator().options().interrupt);
    products += g.products;
    if (g.converged) {
      s.rcond = 1.0;
      s.delta = e.tangent->physical_coordinates(precondition(g.x));
    } else {
      s.why = "GMRES reached a relative residual of " + text(g.relative_residual) + " after " +
              std::to_string(g.products) + " products (tolerance " + text(krylov_.gmres_tolerance) + ")";
    }
    return s;
  }
  Evaluation refresh(Evaluation /*e*/, double t0, const VectorXd& z, double t1) override {
    return evaluate(t0, z, t1);
  }
  FloquetMultipliers multipliers(const Evaluation& e, int k) override {
    const Index n2 = 2 * dof();
    const detail::Product J = [&](const VectorXd& q) -> VectorXd { return e.tangent->apply_modal(q); };
    const detail::ArnoldiResult a = detail::arnoldi(J, n2, krylov_.multipliers, krylov_.max_dimension, krylov_.arnoldi_tolerance,
                                                    engine_.simulator().options().interrupt);
    FloquetMultipliers f;
    f.products = a.products;
    f.leading_only = true;
    f.values = a.values;
    f.spectral_radius = a.values.size() ? std::abs(a.values(0)) : 0.0;
    f.converged = a.converged;
    const double tol = krylov_.arnoldi_tolerance * std::max(1.0, f.spectral_radius);
    while (f.converged_count < a.residuals.size() && a.residuals(f.converged_count) <= tol) ++f.converged_count;
    f.ritz_residual = a.residuals.size() ? a.residuals(0) : 0.0;
    f.stable = f.converged_count >= 1 && f.spectral_radius < 1.0;
    f.rate = std::pow(f.spectral_radius, 1.0 / k);
    return f;
  }

 private:
  KrylovOptions krylov_;
};

ShootingResult shoot_with(Backend& backend, const ShootingOptions& options, double t_guess, const VectorXd& x,
                          const VectorXd& v);

}  // namespace

void ShootingOptions::validate() const {
  if (period < 1 || period > 1024)
    throw InvalidInput("shooting.period = " + std::to_string(period) + ": must be in [1, 1024]");
  if (!std::isfinite(phase)) throw InvalidInput("shooting.phase = " + text(phase) + ": must be finite");
  if (!(tolerance > 0.0) || !(tolerance < 1e-2))
    throw InvalidInput("shooting.tolerance = " + text(tolerance) + ": must be in (0, 1e-2)");
  if (max_iterations < 1) throw InvalidInput("shooting.max_iterations = " + std::to_string(max_iterations) + ": must be ≥ 1");
  if (!(trust_radius > 0.0) || !std::isfinite(trust_radius))
    throw InvalidInput("shooting.trust_radius = " + text(trust_radius) + ": must be a finite number > 0");
  solver.validate();
}

const char* to_string(ShootingStatus s) {
  switch (s) {
    case ShootingStatus::converged: return "converged";
    case ShootingStatus::not_converged: return "not converged";
    case ShootingStatus::map_failed: return "map failed";
    case ShootingStatus::singular: return "singular Jacobian";
  }
  return "?";
}

double periodicity_residual(const TangentMap& m) {
  const double L = m.summary.length_scale, V = m.summary.velocity_scale;
  return std::max((m.x1 - m.x0).cwiseAbs().maxCoeff() / L, (m.v1 - m.v0).cwiseAbs().maxCoeff() / V);
}

FloquetMultipliers floquet_multipliers(const TangentMap& m, int k) {
  FloquetMultipliers f;
  const Index n2 = m.jacobian.rows();
  const Index d = m.reduced.rows();
  f.structural_zeros = static_cast<int>(n2 - d);
  f.values = Eigen::VectorXcd::Zero(n2);
  if (d > 0) {
    Eigen::VectorXcd mu = m.reduced.eigenvalues();
    std::sort(mu.data(), mu.data() + d, [](const std::complex<double>& a, const std::complex<double>& b) {
      if (std::abs(a) != std::abs(b)) return std::abs(a) > std::abs(b);
      if (a.real() != b.real()) return a.real() > b.real();
      return a.imag() > b.imag();
    });
    f.values.head(d) = mu;
    f.spectral_radius = std::abs(mu(0));
  }
  f.stable = f.spectral_radius < 1.0;
  f.rate = std::pow(f.spectral_radius, 1.0 / k);
  return f;
}

ShootingResult shoot(const ImpactSystem& system, const ShootingOptions& options, double t_guess,
                     const VectorXd& x, const VectorXd& v, const LinearisationOptions& options_map) {
  options.validate();
  DenseBackend backend(system, options.solver, options_map);
  return shoot_with(backend, options, t_guess, x, v);
}

ShootingResult shoot(const ImpactSystem& system, const NonlinearForces& forces, const ShootingOptions& options,
                     double t_guess, const VectorXd& x, const VectorXd& v, const LinearisationOptions& options_map) {
  options.validate();
  TaylorBackend backend(system, forces, options.solver, options_map);
  return shoot_with(backend, options, t_guess, x, v);
}

ShootingResult shoot(const LinearSystem& system, const std::vector<FrictionContact>& contacts,
                     const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v,
                     const LinearisationOptions& options_map) {
  options.validate();
  FrictionBackend backend(system, contacts, options.solver, options_map);
  return shoot_with(backend, options, t_guess, x, v);
}

ShootingResult shoot(const ImpactSystem& scene, const std::vector<FrictionContact>& contacts,
                     const ShootingOptions& options, double t_guess, const VectorXd& x, const VectorXd& v,
                     const LinearisationOptions& options_map) {
  options.validate();
  FrictionStopBackend backend(scene, contacts, options.solver, options_map);
  return shoot_with(backend, options, t_guess, x, v);
}

ShootingResult shoot(ModalEngine& engine, const ShootingOptions& options, double t_guess, const VectorXd& x,
                     const VectorXd& v, const KrylovOptions& krylov) {
  options.validate();
  krylov.validate();
  ModalBackend backend(engine, krylov);
  ShootingResult out = shoot_with(backend, options, t_guess, x, v);
  out.krylov_products = backend.products;
  return out;
}

ShootingResult shoot_full_jacobian(ModalEngine& engine, const ShootingOptions& options, double t_guess,
                                  const VectorXd& x, const VectorXd& v, const LinearisationOptions& options_map) {
  options.validate();
  ModalJacobianBackend backend(engine, options_map);
  return shoot_with(backend, options, t_guess, x, v);
}

void KrylovOptions::validate() const {
  if (multipliers < 1) throw InvalidInput("krylov.multipliers = " + std::to_string(multipliers) + ": must be ≥ 1");
  if (max_dimension < 2) throw InvalidInput("krylov.max_dimension = " + std::to_string(max_dimension) + ": must be ≥ 2");
  if (max_products < 1) throw InvalidInput("krylov.max_products = " + std::to_string(max_products) + ": must be ≥ 1");
  if (!(gmres_tolerance > 0.0) || !(gmres_tolerance < 1.0))
    throw InvalidInput("krylov.gmres_tolerance = " + text(gmres_tolerance) + ": must be in (0, 1)");
  if (!(arnoldi_tolerance > 0.0) || !(arnoldi_tolerance < 1.0))
    throw InvalidInput("krylov.arnoldi_tolerance = " + text(arnoldi_tolerance) + ": must be in (0, 1)");
}

namespace {

ShootingResult shoot_unguarded(Backend& backend, const ShootingOptions& options, double t_guess, const VectorXd& x,
                               const VectorXd& v);

/// Shooting, an interruption during a bounded factorisation (Interrupted) reported as a map that
/// could not be evaluated, as an interrupted run is: the guess kept, message "interrupted".
ShootingResult shoot_with(Backend& backend, const ShootingOptions& options, double t_guess, const VectorXd& x,
                          const VectorXd& v) {
  try {
    return shoot_unguarded(backend, options, t_guess, x, v);
  } catch (const Interrupted&) {
    ShootingResult out;
    out.k = options.period;
    out.status = ShootingStatus::map_failed;
    out.message = "interrupted";
    out.x = x;
    out.v = v;
    return out;
  }
}

ShootingResult shoot_unguarded(Backend& backend, const ShootingOptions& options, double t_guess, const VectorXd& x,
                               const VectorXd& v) {
  const Index n = backend.dof();
  const double omega = backend.frequency();
  if (!(omega > 0.0)) throw InvalidInput("shooting: the forcing frequency must be > 0 (the orbit's period is 2π/Ω)");
  if (x.size() != n || v.size() != n)
    throw InvalidInput("shooting: the guess has " + std::to_string(x.size()) + " and " + std::to_string(v.size()) +
                       " entries, expected " + std::to_string(n));
  const double T = 2.0 * std::numbers::pi / omega;
  const int k = options.period;

  ShootingResult out;
  out.k = k;
  // The section: phase θ, first reached after the guess time; then moved to [0, T).
  double theta = std::fmod(options.phase, 2.0 * std::numbers::pi);
  if (theta < 0.0) theta += 2.0 * std::numbers::pi;
  double t_section = theta / omega + T * std::ceil((t_guess - theta / omega) / T);
  VectorXd z = backend.advance(t_guess, stacked(x, v), t_section);
  if (options.free_section) {
    // Where is the guess free over one period? Move the section into the middle of the longest
    // stretch free of events and held phases (section.hpp) if a stop is held at it or an event
    // falls within 1e-6 T of it.
    const TangentMap g = backend.probe(t_section, z, t_section + k * T);
    if (g.summary.status == RunStatus::completed && detail::section_clearance(g) < 1e-6 * T) {
      const double mid = detail::free_section(g).first;
      if (mid > t_section) {
        z = backend.advance(t_section, z, mid);
        t_section = mid;
        theta = std::fmod(omega * t_section, 2.0 * std::numbers::pi);
      }
    }
  }
  // The system is T-periodic: put the section in [0, T) (small t keeps ulp(t) small).
  double t0 = std::fmod(t_section, T);
  if (t0 < 0.0) t0 += T;
  out.phase = theta;
  out.t0 = t0;
  const double t1 = t0 + k * T;

  Evaluation cur = backend.evaluate(t0, z, t1);
  if (!cur.ok) {
    out.status = ShootingStatus::map_failed;
    out.message = "the map cannot be evaluated at the guess: " + cur.why;
    out.x = z.head(n);
    out.v = z.tail(n);
    return out;
  }
  out.residuals.push_back(cur.residual);
  double radius = options.trust_radius;
  for (int it = 0; it < options.max_iterations && cur.residual > options.tolerance; ++it) {
    const NewtonStep ns = backend.newton_step(cur, z);
    const VectorXd& D = ns.scale;
    if (ns.rcond < 1e-14) {
      out.status = ShootingStatus::singular;
      out.message = "J − I is singular at iteration " + std::to_string(it) + " (" +
                    (ns.why.empty() ? "rcond " + text(ns.rcond) : ns.why) + ", residual " + text(cur.residual) +
                    "): a multiplier is 1 (a fold) — continue in a parameter instead";
      break;
    }
    const VectorXd& delta = ns.delta;
    double step = 1.0;
    const double size = delta.cwiseAbs().maxCoeff();
    if (size > radius) step = radius / size;
    bool accepted = false;
    std::string why;
    for (int halving = 0; halving < 12; ++halving, step *= 0.5) {
      const VectorXd trial = z + D.cwiseProduct(delta * step);
      Evaluation next = backend.evaluate(t0, trial, t1);
      if (!next.ok) {
        why = next.why;
        continue;
      }
      if (next.residual < cur.residual) {
        if (step == 1.0 || size * step >= 0.99 * radius) radius = std::min(2.0 * radius, 4.0 * options.trust_radius);
        z = trial;
        cur = std::move(next);
        accepted = true;
        break;
      }
      why = "the residual did not decrease (" + text(next.residual) + " ≥ " + text(cur.residual) + ")";
    }
    out.iterations = it + 1;
    if (!accepted) {
      out.status = ShootingStatus::not_converged;
      out.message = "no acceptable step at iteration " + std::to_string(it + 1) + " (residual " + text(cur.residual) +
                    "; 12 halvings of the Newton step: " + why + ")";
      cur = backend.refresh(std::move(cur), t0, z, t1);
      break;
    }
    out.residuals.push_back(cur.residual);
    if (step < 1.0) radius = std::max(0.5 * radius, 1e-12);
  }
  if (cur.residual <= options.tolerance && out.status == ShootingStatus::not_converged) {
    // Polish: one more Newton step (quadratic convergence takes the residual from the tolerance
    // to rounding), kept only if it lowers the residual.
    const NewtonStep ns = backend.newton_step(cur, z);
    if (ns.rcond > 0.0) {
      const VectorXd trial = z + ns.scale.cwiseProduct(ns.delta);
      Evaluation next = backend.evaluate(t0, trial, t1);
      if (next.ok && next.residual < cur.residual) {
        z = trial;
        cur = std::move(next);
        out.residuals.push_back(cur.residual);
      } else {
        cur = backend.refresh(std::move(cur), t0, z, t1);
      }
    }
  }
  out.x = z.head(n);
  out.v = z.tail(n);
  out.residual = cur.residual;
  out.length_scale = cur.map.summary.length_scale;
  out.velocity_scale = cur.map.summary.velocity_scale;
  if (cur.residual <= options.tolerance) {
    out.status = ShootingStatus::converged;
    out.message.clear();
    // The multipliers first: the runs below end the validity of a modal record.
    out.multipliers = backend.multipliers(cur, k);
    // The least period dividing k on which the orbit already closes.
    out.minimal_k = k;
    for (int d = 1; d < k; ++d) {
      if (k % d != 0) continue;
      const VectorXd zd = backend.advance(t0, z, t0 + d * T);
      const double r = std::max((zd.head(n) - z.head(n)).cwiseAbs().maxCoeff() / out.length_scale,
                                (zd.tail(n) - z.tail(n)).cwiseAbs().maxCoeff() / out.velocity_scale);
      if (r <= 1e3 * options.tolerance) {
        out.minimal_k = d;
        break;
      }
    }
  } else if (out.status == ShootingStatus::not_converged && out.message.empty()) {
    out.message = "not converged after " + std::to_string(options.max_iterations) + " iterations (residual " +
                  text(cur.residual) + " > tolerance " + text(options.tolerance) + ")";
  }
  out.map = std::move(cur.map);
  return out;
}

}  // namespace

}  // namespace vibro
