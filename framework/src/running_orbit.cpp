#include "vibro/running_orbit.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>

#include "vibro/system.hpp"

namespace vibro {

void RunningOrbitOptions::validate() const {
  if (max_period < 1) throw InvalidInput("orbit: max_period must be ≥ 1, got " + std::to_string(max_period));
  if (max_periods < 1) throw InvalidInput("orbit: max_periods must be ≥ 1, got " + std::to_string(max_periods));
  if (min_periods < 0) throw InvalidInput("orbit: min_periods must be ≥ 0, got " + std::to_string(min_periods));
  if (!(tolerance > 0.0) || !std::isfinite(tolerance))
    throw InvalidInput("orbit: tolerance must be a positive number, got " + number_text(tolerance));
  solver.validate();
}

Eigen::VectorXd RunningOrbit::sticking_fraction(std::size_t stops) const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(stops));
  if (k == 0) return f;
  for (const ContactPhase& p : phases) f(p.stop) += p.duration;
  return f / (k * period);
}

int RunningOrbit::phase_count(int stop) const {
  return static_cast<int>(std::count_if(phases.begin(), phases.end(),
                                        [stop](const ContactPhase& p) { return p.stop == stop; }));
}

int RunningOrbit::impact_count(int stop, double min_speed) const {
  return static_cast<int>(std::count_if(impacts.begin(), impacts.end(), [&](const OrbitImpact& i) {
    return i.stop == stop && i.speed > min_speed;
  }));
}

namespace {

/// A period-k orbit counts only if it is at least this many tolerances from repeating at every
/// proper divisor of k (see run_to_periodic_orbit).
constexpr double kDistinct = 1e3;

/// |Δx|∞/L and |Δv|∞/V between two states.
double distance(const Eigen::VectorXd& xa, const Eigen::VectorXd& va, const Eigen::VectorXd& xb,
                const Eigen::VectorXd& vb, double L, double V) {
  return std::max((xa - xb).cwiseAbs().maxCoeff() / L, (va - vb).cwiseAbs().maxCoeff() / V);
}

/// Records the orbit of period kT starting at (t, x, v): the phases that start in (t, t + kT]
/// (each complete, since the recording runs on to t + 2kT), a phase held through the whole
/// recording as one phase of length kT, and the impacts in (t, t + kT].
void record(Engine& sim, RunningOrbit& orbit) {
  const double span = orbit.k * orbit.period;
  const double t0 = orbit.t_start;
  ContactLog contacts;
  EventLog events;
  const RunSummary s = sim.run(t0, orbit.x, orbit.v, t0 + 2.0 * span, {&contacts, &events});
  if (s.status != RunStatus::completed) {
    orbit.status = s.status;
    orbit.message = s.message;
    return;
  }
  orbit.length_scale = s.length_scale;
  orbit.velocity_scale = s.velocity_scale;
  orbit.force_scale = s.force_scale;
  for (const ContactInterval& c : contacts.intervals) {
    const bool held_throughout = c.t_start <= t0 && !c.closed;
    if (!held_throughout && !(c.t_start > t0 && c.t_start <= t0 + span)) continue;
    ContactPhase p;
    p.stop = c.stop;
    p.t_start = held_throughout ? t0 : c.t_start;
    p.duration = held_throughout ? span : c.t_end - c.t_start;
    p.phase = std::fmod(p.t_start, span);
    if (p.phase < 0.0) p.phase += span;
    p.force_min = c.force_min;
    p.t_force_min = c.t_force_min;
    orbit.phases.push_back(p);
  }
  std::sort(orbit.phases.begin(), orbit.phases.end(),
            [](const ContactPhase& a, const ContactPhase& b) { return a.t_start < b.t_start; });
  for (const Event& e : events.events) {
    if (!(e.t > t0 && e.t <= t0 + span)) continue;
    if (e.kind == EventKind::impact) orbit.impacts.push_back({e.stop, e.t, e.v_before});
    if (e.kind == EventKind::chatter_limit) ++orbit.chatter_limits;
  }
}

}  // namespace

RunningOrbit run_to_periodic_orbit(const ImpactSystem& scene, const RunningOrbitOptions& options, double t0,
                          const Eigen::VectorXd& x0, const Eigen::VectorXd& v0) {
  DenseEngine engine(scene, options.solver);
  return run_to_periodic_orbit(engine, options, t0, x0, v0);
}

RunningOrbit run_to_periodic_orbit(Engine& sim, const RunningOrbitOptions& options, double t0,
                          const Eigen::VectorXd& x0, const Eigen::VectorXd& v0) {
  options.validate();
  const double omega = sim.frequency();
  if (!(omega > 0.0)) throw InvalidInput("orbit: periodic orbits need a forcing frequency > 0");
  RunningOrbit orbit;
  orbit.period = 2.0 * std::numbers::pi / omega;
  orbit.residual = std::numeric_limits<double>::infinity();

  // Poincaré states z_n = z(t0 + nT), the last max_period + 1 of them.
  std::deque<std::pair<Eigen::VectorXd, Eigen::VectorXd>> history{{x0, v0}};
  Eigen::VectorXd x = x0, v = v0;
  double L = 0.0, V = 0.0;
  for (long n = 1; n <= options.max_periods; ++n) {
    // Each period from t0 + (n-1)T exactly (not accumulated), so t stays exact to one rounding.
    const double ta = t0 + static_cast<double>(n - 1) * orbit.period;
    const double tb = t0 + static_cast<double>(n) * orbit.period;
    const RunSummary s = sim.run(ta, x, v, tb);
    orbit.periods_run = n;
    if (s.status != RunStatus::completed) {
      orbit.status = s.status;
      orbit.message = s.message;
      orbit.t_start = s.t;
      orbit.x = s.x;
      orbit.v = s.v;
      return orbit;
    }
    x = s.x;
    v = s.v;
    L = s.length_scale;
    V = s.velocity_scale;
    history.emplace_back(x, v);
    if (history.size() > static_cast<std::size_t>(options.max_period) + 1) history.pop_front();
    if (n < options.min_periods) continue;
    std::vector<double> d(history.size(), 0.0);  // d[k] = |z_n − z_{n−k}|
    for (int k = 1; k < static_cast<int>(history.size()); ++k) {
      const auto& [xk, vk] = history[history.size() - 1 - static_cast<std::size_t>(k)];
      d[static_cast<std::size_t>(k)] = distance(x, v, xk, vk, L, V);
      orbit.residual = std::min(orbit.residual, d[static_cast<std::size_t>(k)]);
      if (d[static_cast<std::size_t>(k)] > options.tolerance) continue;
      // A period-1 orbit approached with a multiplier near −1 passes the k = 2 test first
      // (|z_n − z_{n−2}| ≈ |μ+1|/|μ| · |z_n − z_{n−1}|). A true period-k orbit is far from
      // repeating at every proper divisor of k; otherwise keep running until the smaller period
      // is met.
      bool distinct = true;
      for (int q = 1; q < k; ++q)
        if (k % q == 0 && d[static_cast<std::size_t>(q)] <= kDistinct * options.tolerance) distinct = false;
      if (!distinct) break;
      orbit.periodic = true;
      orbit.k = k;
      orbit.residual = d[static_cast<std::size_t>(k)];
      break;
    }
    if (orbit.periodic) break;
  }
  orbit.t_start = t0 + static_cast<double>(orbit.periods_run) * orbit.period;
  orbit.x = x;
  orbit.v = v;
  if (!orbit.periodic) {
    orbit.message = "not periodic within " + std::to_string(options.max_periods) +
                    " periods (least residual " + number_text(orbit.residual) + " for k ≤ " +
                    std::to_string(options.max_period) + ")";
    return orbit;
  }
  record(sim, orbit);
  return orbit;
}

}  // namespace vibro
