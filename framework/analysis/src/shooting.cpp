#include "vibro/shooting.hpp"

#include "section.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace vibro {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

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
  double residual = std::numeric_limits<double>::infinity();
};

Evaluation evaluate(const ImpactSystem& system, const SimulatorOptions& solver, double t0, const VectorXd& z,
                    double t1, const LinearisationOptions& o) {
  const Index n = system.dof();
  Evaluation e;
  try {
    e.map = linearise(system, solver, t0, z.head(n), z.tail(n), t1, o);
  } catch (const InvalidInput& err) {
    e.why = err.what();
    return e;
  }
  if (e.map.summary.status != RunStatus::completed) {
    e.why = std::string("the run stopped early (") + to_string(e.map.summary.status) + "): " + e.map.summary.message;
    return e;
  }
  e.ok = true;
  e.residual = periodicity_residual(e.map);
  return e;
}

/// The scaled Newton step of F(z) = P(z) − z at an evaluation: (D⁻¹ (J − I) D) δ = −D⁻¹ F,
/// Δ = D δ, D = diag(L, V); returns δ and the matrix's reciprocal condition (0 if singular).
struct NewtonStep {
  VectorXd delta, scale;
  double rcond = 0.0;
};
NewtonStep newton_step(const TangentMap& m, const VectorXd& z) {
  const Index n = m.x0.size();
  NewtonStep s;
  s.scale = scales(n, m.summary.length_scale, m.summary.velocity_scale);
  const VectorXd F = stacked(m.x1, m.v1) - z;
  const MatrixXd A = s.scale.cwiseInverse().asDiagonal() * (m.jacobian - MatrixXd::Identity(2 * n, 2 * n)) *
                     s.scale.asDiagonal();
  const Eigen::FullPivLU<MatrixXd> lu(A);
  s.rcond = lu.isInvertible() ? lu.rcond() : 0.0;
  if (s.rcond > 0.0) s.delta = lu.solve(VectorXd(-F.cwiseQuotient(s.scale)));
  return s;
}

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
  const Index n = system.dof();
  const double omega = system.system().forcing().frequency;
  if (!(omega > 0.0)) throw InvalidInput("shooting: the forcing frequency must be > 0 (the orbit's period is 2π/Ω)");
  if (x.size() != n || v.size() != n)
    throw InvalidInput("shooting: the guess has " + std::to_string(x.size()) + " and " + std::to_string(v.size()) +
                       " entries, expected " + std::to_string(n));
  const double T = 2.0 * std::numbers::pi / omega;
  const int k = options.period;
  LinearisationOptions lo = options_map;
  lo.jacobian = true;

  ShootingResult out;
  out.k = k;
  // The section: phase θ, first reached after the guess time; then moved to [0, T).
  double theta = std::fmod(options.phase, 2.0 * std::numbers::pi);
  if (theta < 0.0) theta += 2.0 * std::numbers::pi;
  auto advance = [&](double from, const VectorXd& z, double to) {
    Simulator sim(system, options.solver);
    const RunSummary s = sim.run(from, z.head(n), z.tail(n), to);
    if (s.status != RunStatus::completed)
      throw InvalidInput("shooting: the guess's run stopped early (" + std::string(to_string(s.status)) + "): " + s.message);
    return stacked(s.x, s.v);
  };
  double t_section = theta / omega + T * std::ceil((t_guess - theta / omega) / T);
  VectorXd z = advance(t_guess, stacked(x, v), t_section);
  if (options.free_section) {
    // Where is the guess free over one period? Move the section into the middle of the longest
    // stretch free of events and held phases (section.hpp) if a stop is held at it or an event
    // falls within 1e-6 T of it.
    LinearisationOptions probe;
    probe.jacobian = false;
    probe.features = true;
    const TangentMap g = linearise(system, options.solver, t_section, z.head(n), z.tail(n), t_section + k * T, probe);
    if (g.summary.status == RunStatus::completed && detail::section_clearance(g) < 1e-6 * T) {
      const double mid = detail::free_section(g).first;
      if (mid > t_section) {
        z = advance(t_section, z, mid);
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

  Evaluation cur = evaluate(system, options.solver, t0, z, t1, lo);
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
    const NewtonStep ns = newton_step(cur.map, z);
    const VectorXd& D = ns.scale;
    if (ns.rcond < 1e-14) {
      out.status = ShootingStatus::singular;
      out.message = "J − I is singular at iteration " + std::to_string(it) + " (rcond " + text(ns.rcond) +
                    ", residual " + text(cur.residual) +
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
      Evaluation next = evaluate(system, options.solver, t0, trial, t1, lo);
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
      break;
    }
    out.residuals.push_back(cur.residual);
    if (step < 1.0) radius = std::max(0.5 * radius, 1e-12);
  }
  if (cur.residual <= options.tolerance && out.status == ShootingStatus::not_converged) {
    // Polish: one more Newton step (quadratic convergence takes the residual from the tolerance
    // to rounding), kept only if it lowers the residual.
    const NewtonStep ns = newton_step(cur.map, z);
    if (ns.rcond > 0.0) {
      const VectorXd trial = z + ns.scale.cwiseProduct(ns.delta);
      Evaluation next = evaluate(system, options.solver, t0, trial, t1, lo);
      if (next.ok && next.residual < cur.residual) {
        z = trial;
        cur = std::move(next);
        out.residuals.push_back(cur.residual);
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
    // The least period dividing k on which the orbit already closes.
    out.minimal_k = k;
    for (int d = 1; d < k; ++d) {
      if (k % d != 0) continue;
      const VectorXd zd = advance(t0, z, t0 + d * T);
      const double r = std::max((zd.head(n) - z.head(n)).cwiseAbs().maxCoeff() / out.length_scale,
                                (zd.tail(n) - z.tail(n)).cwiseAbs().maxCoeff() / out.velocity_scale);
      if (r <= 1e3 * options.tolerance) {
        out.minimal_k = d;
        break;
      }
    }
    out.multipliers = floquet_multipliers(cur.map, k);
  } else if (out.status == ShootingStatus::not_converged && out.message.empty()) {
    out.message = "not converged after " + std::to_string(options.max_iterations) + " iterations (residual " +
                  text(cur.residual) + " > tolerance " + text(options.tolerance) + ")";
  }
  out.map = std::move(cur.map);
  return out;
}

}  // namespace vibro
