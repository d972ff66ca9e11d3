/// \file lyapunov.cpp
/// The QR method of lyapunov.hpp. On the dense engine the frame is also re-orthonormalised after
/// every event (orthonormal_frame.hpp), and a period's R is the product of the events' triangular
/// factors and the period's own, its diagonal the product of theirs:
///
///     log|R_ii^{(k)}| = log|R_ii(end of period)| + Σ_events log|R_ii(event)|.
///
/// Re-orthonormalising once per period only loses the small directions: on a chaotic orbit with
/// dozens of impacts per period, one period's product of saltation matrices and flows can have a
/// condition number beyond 1/ε (the paper's system with C = 0, r = 1 at Ω = 0.255 reaches 4e17),
/// and the least R_ii of its QR is then rounding (that system's spectrum summed to 6e-4 instead
/// of 0 over 4000 periods; tests/analysis/test_lyapunov.cpp). One event's saltation matrix alone
/// is far better conditioned (like 1/u² at worst, u its impact speed). The modal engine's
/// matrix-free frame (modal_tangent.hpp) is still re-orthonormalised once per period only.
#include "vibro/lyapunov.hpp"

#include "vibro/modal_tangent.hpp"

#include "orthonormal_frame.hpp"

#include <Eigen/QR>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

namespace vibro {

void LyapunovOptions::validate() const {
  if (count < 0) throw InvalidInput("lyapunov.count = " + std::to_string(count) + ": must be ≥ 0 (0: all)");
  if (transient < 0 || align < 0) throw InvalidInput("lyapunov.transient and align must be ≥ 0");
  if (periods < 1) throw InvalidInput("lyapunov.periods = " + std::to_string(periods) + ": must be ≥ 1");
  if (history_every < 0) throw InvalidInput("lyapunov.history_every must be ≥ 0");
}

namespace {

/// One forcing period from (t, x, v) with the frame Q: the run and J·Q.
struct Period {
  RunSummary summary;
  double t1 = 0.0;
  Eigen::VectorXd x1, v1;
  Eigen::MatrixXd products;
  Eigen::VectorXd log_growth;  ///< log|U_ii| already taken out of the products (empty: none)
  Eigen::Index free_dimension = 0;
};
using Runner = std::function<RunSummary(double, const Eigen::VectorXd&, const Eigen::VectorXd&, double)>;
using Stepper =
    std::function<Period(double, const Eigen::VectorXd&, const Eigen::VectorXd&, double, const Eigen::MatrixXd&)>;

/// The QR method of the file comment, on any engine's periods.
/// `frame` (2n × p, orthonormal columns): the first frame Q, as a function of p (default: the
/// first p unit vectors).
LyapunovResult spectrum(Eigen::Index n, double omega, const Runner& run, const Stepper& step, double t0,
                        const Eigen::VectorXd& x0, const Eigen::VectorXd& v0, const LyapunovOptions& options,
                        const std::function<Eigen::MatrixXd(Eigen::Index)>& frame = {}) {
  options.validate();
  const Eigen::Index n2 = 2 * n;
  if (!(omega > 0.0)) throw InvalidInput("lyapunov: the forcing frequency must be > 0 (exponents are averaged per period)");
  if (options.count > n2)
    throw InvalidInput("lyapunov.count = " + std::to_string(options.count) + ": at most 2n = " + std::to_string(n2));
  const Eigen::Index p = options.count > 0 ? options.count : n2;
  const double T = 2.0 * std::numbers::pi / omega;

  LyapunovResult out;
  out.period = T;
  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  if (options.transient > 0) {
    const RunSummary s = run(t, x, v, t + options.transient * T);
    if (s.status != RunStatus::completed) {
      out.status = s.status;
      out.message = "transient: " + s.message;
      return out;
    }
    t = s.t, x = s.x, v = s.v;
  }
  Eigen::MatrixXd Q = frame ? frame(p) : Eigen::MatrixXd::Identity(n2, p);
  Eigen::VectorXd sums = Eigen::VectorXd::Zero(p);
  Eigen::Index least = n2;
  const long total = options.align + options.periods;
  for (long k = 0; k < total; ++k) {
    const Period m = step(t, x, v, t + T, Q);
    if (m.summary.status != RunStatus::completed) {
      out.status = m.summary.status;
      out.message = m.summary.message;
      return out;
    }
    t = m.t1, x = m.x1, v = m.v1;
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(m.products);
    Eigen::MatrixXd R = qr.matrixQR().topRows(p).triangularView<Eigen::Upper>();
    Q = qr.householderQ() * Eigen::MatrixXd::Identity(n2, p);
    // Signs: Q R with R's diagonal positive (flip the columns whose R_ii < 0).
    for (Eigen::Index i = 0; i < p; ++i)
      if (R(i, i) < 0.0) Q.col(i) = -Q.col(i);
    if (k < options.align) continue;
    least = std::min(least, m.free_dimension);
    for (Eigen::Index i = 0; i < p; ++i) sums(i) += std::log(std::abs(R(i, i)));
    if (m.log_growth.size() == p) sums += m.log_growth;
    const long done = k - options.align + 1;
    if (options.history_every > 0 && done % options.history_every == 0) {
      const Eigen::Index finite = std::min(p, least);
      out.history.push_back(sums.head(finite) / (static_cast<double>(done) * T));
    }
  }
  out.least_free_dimension = least;
  out.exponents = sums / (static_cast<double>(options.periods) * T);
  out.structural = static_cast<int>(std::max<Eigen::Index>(0, p - least));
  for (Eigen::Index i = std::min(p, least); i < p; ++i) out.exponents(i) = -std::numeric_limits<double>::infinity();
  out.t_end = t;
  out.x_end = x;
  out.v_end = v;
  return out;
}

Period period_of(const TangentMap& m, Eigen::MatrixXd products) {
  return {m.summary, m.t1, m.x1, m.v1, std::move(products), {}, m.free_dimension};
}

}  // namespace

LyapunovResult lyapunov_spectrum(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                                 const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                                 const LyapunovOptions& options) {
  Simulator sim(system, solver);
  const Runner run = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1) {
    return sim.run(t, x, v, t1);
  };
  const Stepper step = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1,
                           const Eigen::MatrixXd& Q) {
    detail::CarriedFrame f = detail::carry_orthonormal_frame(system, solver, t, x, v, t1, Q);
    Period period = period_of(f.map, std::move(f.map.products));
    period.log_growth = std::move(f.log_growth);
    return period;
  };
  return spectrum(system.dof(), system.system().forcing().frequency, run, step, t0, x0, v0, options);
}

LyapunovResult lyapunov_spectrum(const ImpactSystem& system, const NonlinearForces& forces,
                                 const SimulatorOptions& solver, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options) {
  TaylorSimulator sim(system, forces, solver);
  const Runner run = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1) {
    return sim.run(t, x, v, t1);
  };
  const Stepper step = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1,
                           const Eigen::MatrixXd& Q) {
    detail::CarriedFrame f = detail::carry_orthonormal_frame(system, forces, solver, t, x, v, t1, Q);
    Period period = period_of(f.map, std::move(f.map.products));
    period.log_growth = std::move(f.log_growth);
    return period;
  };
  return spectrum(system.dof(), system.system().forcing().frequency, run, step, t0, x0, v0, options);
}

LyapunovResult lyapunov_spectrum(ModalEngine& engine, double t0, const Eigen::VectorXd& x0,
                                 const Eigen::VectorXd& v0, const LyapunovOptions& options) {
  const Runner run = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1) -> RunSummary {
    return engine.run(t, x, v, t1);
  };
  const Stepper step = [&](double t, const Eigen::VectorXd& x, const Eigen::VectorXd& v, double t1,
                           const Eigen::MatrixXd& Q) {
    const ModalTangent tangent(engine, t, x, v, t1);
    const TangentMap& m = tangent.map();
    if (m.summary.status != RunStatus::completed) return period_of(m, {});
    return period_of(m, tangent.apply_modal(Q));
  };
  // The dense engine's first frame (the first p unit vectors of (x, v)) in modal coordinates,
  // made orthonormal: for unit masses Φ̃⁻¹ is orthogonal and both engines then carry the same
  // frame, up to that fixed rotation.
  const ChainModes& modes = engine.simulator().modes();
  const auto frame = [&](Eigen::Index p) {
    const Eigen::Index n = modes.dof();
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(2 * n, p);
    Eigen::MatrixXd Y(n, 2 * p), U(n, 2 * p);
    Y << I.topRows(n), I.bottomRows(n);
    ChainModes::Workspace work;
    modes.tangent_to_modal(Y, U, work);
    Eigen::MatrixXd F(2 * n, p);
    F << U.leftCols(p), U.rightCols(p);
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(F);
    Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(2 * n, p);
    const Eigen::MatrixXd R = qr.matrixQR().topRows(p);
    for (Eigen::Index i = 0; i < p; ++i)
      if (R(i, i) < 0.0) Q.col(i) = -Q.col(i);
    return Q;
  };
  return spectrum(modes.dof(), engine.frequency(), run, step, t0, x0, v0, options, frame);
}

}  // namespace vibro
