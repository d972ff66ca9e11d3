#include "vibro/lyapunov.hpp"

#include <Eigen/QR>

#include <cmath>
#include <limits>
#include <numbers>

namespace vibro {

void LyapunovOptions::validate() const {
  if (count < 0) throw InvalidInput("lyapunov.count = " + std::to_string(count) + ": must be ≥ 0 (0: all)");
  if (transient < 0 || align < 0) throw InvalidInput("lyapunov.transient and align must be ≥ 0");
  if (periods < 1) throw InvalidInput("lyapunov.periods = " + std::to_string(periods) + ": must be ≥ 1");
  if (history_every < 0) throw InvalidInput("lyapunov.history_every must be ≥ 0");
}

LyapunovResult lyapunov_spectrum(const ImpactSystem& system, const SimulatorOptions& solver, double t0,
                                 const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                                 const LyapunovOptions& options) {
  options.validate();
  const Eigen::Index n = system.dof(), n2 = 2 * n;
  const double omega = system.system().forcing().frequency;
  if (!(omega > 0.0)) throw InvalidInput("lyapunov: the forcing frequency must be > 0 (exponents are averaged per period)");
  if (options.count > n2)
    throw InvalidInput("lyapunov.count = " + std::to_string(options.count) + ": at most 2n = " + std::to_string(n2));
  const Eigen::Index p = options.count > 0 ? options.count : n2;
  const double T = 2.0 * std::numbers::pi / omega;

  LyapunovResult out;
  out.period = T;
  Simulator sim(system, solver);
  double t = t0;
  Eigen::VectorXd x = x0, v = v0;
  if (options.transient > 0) {
    const RunSummary s = sim.run(t, x, v, t + options.transient * T);
    if (s.status != RunStatus::completed) {
      out.status = s.status;
      out.message = "transient: " + s.message;
      return out;
    }
    t = s.t, x = s.x, v = s.v;
  }
  Eigen::MatrixXd Q = Eigen::MatrixXd::Identity(n2, p);
  Eigen::VectorXd sums = Eigen::VectorXd::Zero(p);
  Eigen::Index least = n2;
  LinearisationOptions lo;
  lo.jacobian = false;
  const long total = options.align + options.periods;
  for (long k = 0; k < total; ++k) {
    lo.directions = Q;
    const TangentMap m = linearise(system, solver, t, x, v, t + T, lo);
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

}  // namespace vibro
