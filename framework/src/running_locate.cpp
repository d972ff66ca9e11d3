#include "vibro/running_locate.hpp"

#include "vibro/bounded_wait.hpp"

#include <atomic>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "vibro/system.hpp"

namespace vibro {

const char* to_string(TransitionKind kind) {
  switch (kind) {
    case TransitionKind::rising: return "rising";
    case TransitionKind::vanishing: return "vanishing";
    case TransitionKind::drop: return "drop";
    case TransitionKind::period: return "period";
    case TransitionKind::periodicity: return "periodicity";
    case TransitionKind::other: return "other";
  }
  return "?";
}

void ScanOptions::validate() const {
  orbit.validate();
  if (first_transient < 0) throw InvalidInput("scan: first_transient must be ≥ 0");
  if (!(tolerance > 0.0) || !std::isfinite(tolerance))
    throw InvalidInput("scan: tolerance must be a positive number, got " + number_text(tolerance));
  if (max_transitions < 0) throw InvalidInput("scan: max_transitions must be ≥ 0");
  if (!(jump >= 0.0) || !std::isfinite(jump))
    throw InvalidInput("scan: jump must be a number ≥ 0, got " + number_text(jump));
}

namespace {

/// (periodic?, k, phases per orbit of each stop): what bisection compares.
std::vector<int> signature(const RunningOrbit& o, std::size_t stops) {
  std::vector<int> s{o.periodic ? 1 : 0, o.k};
  for (std::size_t j = 0; j < stops; ++j) s.push_back(o.phase_count(static_cast<int>(j)));
  return s;
}

/// The time at forcing frequency `omega_to` with the same forcing phase as t at `omega_from`.
double same_phase(double t, double omega_from, double omega_to) {
  const double two_pi = 2.0 * std::numbers::pi;
  double phase = std::fmod(omega_from * t, two_pi);
  if (phase < 0.0) phase += two_pi;
  return phase / omega_to;
}

class Continuation {
 public:
  Continuation(const EngineFamily& family, const ScanOptions& options)
      : family_(family), options_(options) {}

  /// The periodic orbit at p, starting from `from`'s final state (at the same forcing phase).
  ScanPoint from(const ScanPoint& previous, double p) {
    const std::unique_ptr<Engine> engine = family_(p);  // built once: a family may parse a scene per call
    const double t = same_phase(previous.orbit.t_start, omega(previous), engine->frequency());
    return solve(p, *engine, t, previous.orbit.x, previous.orbit.v, options_.orbit.min_periods);
  }

  ScanPoint at(double p, double t0, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
               long min_periods) {
    const std::unique_ptr<Engine> engine = family_(p);
    return solve(p, *engine, t0, x0, v0, min_periods);
  }

  long computed = 0;

 private:
  ScanPoint solve(double p, Engine& engine, double t0, const Eigen::VectorXd& x0,
                  const Eigen::VectorXd& v0, long min_periods) {
    RunningOrbitOptions o = options_.orbit;
    o.min_periods = min_periods;
    o.max_periods = std::max(o.max_periods, min_periods + o.max_period + 1);
    ++computed;
    return {p, run_to_periodic_orbit(engine, o, t0, x0, v0)};
  }

  double omega(const ScanPoint& s) const { return 2.0 * std::numbers::pi / s.orbit.period; }

  const EngineFamily& family_;
  const ScanOptions& options_;
};

/// Least interior force of stop j's phases, and its shortest phase / kT (∞ if it has none).
double least_force(const RunningOrbit& o, int stop) {
  double f = std::numeric_limits<double>::infinity();
  for (const ContactPhase& p : o.phases)
    if (p.stop == stop) f = std::min(f, p.force_min);
  return f;
}
double shortest_phase(const RunningOrbit& o, int stop) {
  double d = std::numeric_limits<double>::infinity();
  for (const ContactPhase& p : o.phases)
    if (p.stop == stop) d = std::min(d, p.duration / (o.k * o.period));
  return d;
}

/// Names the change between the bracket ends (see the header).
void classify(Transition& tr, std::size_t stops, double force_scale) {
  const RunningOrbit& a = tr.low.orbit;
  const RunningOrbit& b = tr.high.orbit;
  if (a.periodic != b.periodic) {
    tr.kind = TransitionKind::periodicity;
    return;
  }
  if (a.k != b.k) {
    tr.kind = TransitionKind::period;
    return;
  }
  int changed = 0;
  for (std::size_t j = 0; j < stops; ++j) {
    const int stop = static_cast<int>(j);
    const int na = a.phase_count(stop), nb = b.phase_count(stop);
    if (na == nb) continue;
    ++changed;
    tr.stop = stop;
    const RunningOrbit& fewer = na < nb ? a : b;
    const RunningOrbit& more = na < nb ? b : a;
    tr.force_limit = least_force(fewer, stop);
    tr.duration_limit = shortest_phase(more, stop);
    tr.kind = tr.force_limit / force_scale < tr.duration_limit ? TransitionKind::rising
                                                               : TransitionKind::vanishing;
  }
  if (changed != 1) {
    tr.kind = TransitionKind::other;
    tr.stop = -1;
  }
}

/// Ends the transition: bracket, orbits at its ends, evaluations.
void close(Transition& tr, ScanPoint lo, ScanPoint hi) {
  tr.p_low = std::min(lo.p, hi.p);
  tr.p_high = std::max(lo.p, hi.p);
  tr.p = 0.5 * (lo.p + hi.p);
  if (lo.p > hi.p) std::swap(lo, hi);
  tr.low = std::move(lo);
  tr.high = std::move(hi);
}

/// The stop whose sticking fraction differs most between two orbits, and by how much (none, 0 for
/// a scene without stops, where there is no fraction to compare).
std::pair<int, double> largest_jump(const RunningOrbit& a, const RunningOrbit& b, std::size_t stops) {
  if (!a.periodic || !b.periodic || stops == 0) return {-1, 0.0};
  const Eigen::VectorXd d = b.sticking_fraction(stops) - a.sticking_fraction(stops);
  Eigen::Index j = 0;
  const double size = d.cwiseAbs().maxCoeff(&j);
  return {static_cast<int>(j), size};
}

/// Refines [lo, hi] (see the header) and appends what it finds, in order of p.
class Locator {
 public:
  Locator(Continuation& c, std::size_t stops, const ScanOptions& options, std::vector<Transition>& out)
      : c_(c), stops_(stops), options_(options), out_(out) {}

  void explore(const ScanPoint& lo, const ScanPoint& hi, int depth_evaluations = 0) {
    if (static_cast<int>(out_.size()) >= options_.max_transitions) return;
    const bool same = signature(lo.orbit, stops_) == signature(hi.orbit, stops_);
    const auto [stop, jump] = largest_jump(lo.orbit, hi.orbit, stops_);
    if (std::abs(hi.p - lo.p) <= options_.tolerance) {
      if (!same) record(lo, hi, depth_evaluations);
      else if (options_.jump > 0.0 && jump > 0.5 * options_.jump) record_jump(lo, hi, stop, depth_evaluations);
      return;
    }
    if (same && !(options_.jump > 0.0 && jump > options_.jump)) return;
    const ScanPoint mid = c_.from(lo, 0.5 * (lo.p + hi.p));
    explore(lo, mid, depth_evaluations + 1);
    explore(mid, hi, depth_evaluations + 1);
  }

 private:
  void record(const ScanPoint& lo, const ScanPoint& hi, int evaluations) {
    Transition tr;
    tr.evaluations = evaluations;
    close(tr, lo, hi);
    classify(tr, stops_, std::max(lo.orbit.force_scale, hi.orbit.force_scale));
    out_.push_back(std::move(tr));
  }

  /// Equal signatures, sticking time still jumping at the tolerance: a phase cut short.
  void record_jump(const ScanPoint& lo, const ScanPoint& hi, int stop, int evaluations) {
    Transition tr;
    tr.evaluations = evaluations;
    const Eigen::VectorXd fl = lo.orbit.sticking_fraction(stops_), fh = hi.orbit.sticking_fraction(stops_);
    const ScanPoint& longer = fl(stop) > fh(stop) ? lo : hi;
    tr.stop = stop;
    tr.force_limit = least_force(longer.orbit, stop);
    tr.duration_limit = std::abs(fh(stop) - fl(stop));
    const double force_scale = std::max(lo.orbit.force_scale, hi.orbit.force_scale);
    tr.kind = tr.force_limit / force_scale < tr.duration_limit ? TransitionKind::rising
                                                               : TransitionKind::drop;
    close(tr, lo, hi);
    out_.push_back(std::move(tr));
  }

  Continuation& c_;
  std::size_t stops_;
  const ScanOptions& options_;
  std::vector<Transition>& out_;
};

}  // namespace

EngineFamily dense_family(SystemFamily family, const SimulatorOptions& solver) {
  return [family = std::move(family), solver](double p) -> std::unique_ptr<Engine> {
    return std::make_unique<DenseEngine>(family(p), solver);
  };
}

std::vector<ScanPoint> scan(const SystemFamily& family, const std::vector<double>& grid, double t0,
                            const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            const ScanOptions& options) {
  return scan(dense_family(family, options.orbit.solver), grid, t0, x0, v0, options);
}

std::vector<Transition> locate_between(const SystemFamily& family, const ScanPoint& lo,
                                       const ScanPoint& hi, const ScanOptions& options,
                                       long* orbits_computed) {
  return locate_between(dense_family(family, options.orbit.solver), lo, hi, options, orbits_computed);
}

ScanResult scan_and_locate(const SystemFamily& family, const std::vector<double>& grid, double t0,
                           const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                           const ScanOptions& options) {
  return scan_and_locate(dense_family(family, options.orbit.solver), grid, t0, x0, v0, options);
}

std::vector<ScanPoint> scan(const EngineFamily& family, const std::vector<double>& grid, double t0,
                            const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            const ScanOptions& options) {
  options.validate();
  if (grid.empty()) throw InvalidInput("scan: the grid is empty");
  for (std::size_t i = 1; i < grid.size(); ++i)
    if ((grid[i] - grid[i - 1]) * (grid[1] - grid[0]) <= 0.0)
      throw InvalidInput("scan: the grid must be strictly monotonic (at index " + std::to_string(i) + ")");
  Continuation c(family, options);
  std::vector<ScanPoint> points;
  points.push_back(c.at(grid[0], t0, x0, v0, options.first_transient));
  if (options.on_point) options.on_point(1);
  const std::atomic<bool>* stop = options.orbit.solver.interrupt;
  for (std::size_t i = 1; i < grid.size(); ++i) {
    if (stop && stop->load(std::memory_order_relaxed)) break;  // interrupted: the points scanned so far
    try {
      points.push_back(c.from(points.back(), grid[i]));
    } catch (const Interrupted&) {  // likewise, in the set-up of the point's engine (bounded_wait.hpp)
      break;
    }
    if (options.on_point) options.on_point(i + 1);
  }
  return points;
}

std::vector<Transition> locate_between(const EngineFamily& family, const ScanPoint& lo,
                                       const ScanPoint& hi, const ScanOptions& options,
                                       long* orbits_computed) {
  options.validate();
  Continuation c(family, options);
  std::vector<Transition> found;
  Locator(c, family(lo.p)->stop_count(), options, found).explore(lo, hi);
  if (orbits_computed) *orbits_computed += c.computed;
  return found;
}

void merge_doublings(std::vector<Transition>& sorted) {
  // A not-periodic orbit whose runs still came this close to closing was converging, slowly.
  constexpr double kNearlyClosed = 1e-3;
  const auto nearly = [](const RunningOrbit& o) {
    return !o.periodic && o.status == RunStatus::completed && o.residual <= kNearlyClosed;
  };
  std::vector<Transition> out;
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    if (i + 1 < sorted.size()) {
      const Transition& a = sorted[i];
      const Transition& b = sorted[i + 1];
      const RunningOrbit& below = a.low.orbit;
      const RunningOrbit& above = b.high.orbit;
      if (a.kind == TransitionKind::periodicity && b.kind == TransitionKind::periodicity && below.periodic &&
          above.periodic && nearly(a.high.orbit) && nearly(b.low.orbit) &&
          (above.k == 2 * below.k || below.k == 2 * above.k)) {
        Transition m;
        m.kind = TransitionKind::period;
        m.p_low = a.p_low;
        m.p_high = b.p_high;
        m.p = 0.5 * (m.p_low + m.p_high);
        m.low = a.low;
        m.high = b.high;
        m.evaluations = std::max(a.evaluations, b.evaluations);
        out.push_back(std::move(m));
        ++i;
        continue;
      }
    }
    out.push_back(std::move(sorted[i]));
  }
  sorted = std::move(out);
}

ScanResult scan_and_locate(const EngineFamily& family, const std::vector<double>& grid, double t0,
                           const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                           const ScanOptions& options) {
  ScanResult result;
  result.points = scan(family, grid, t0, x0, v0, options);
  result.orbits_computed = static_cast<long>(result.points.size());
  for (std::size_t i = 1; i < result.points.size(); ++i) {
    std::vector<Transition> found = locate_between(family, result.points[i - 1], result.points[i],
                                                   options, &result.orbits_computed);
    for (Transition& t : found) result.transitions.push_back(std::move(t));
  }
  std::sort(result.transitions.begin(), result.transitions.end(),
            [](const Transition& a, const Transition& b) { return a.p < b.p; });
  merge_doublings(result.transitions);
  return result;
}

}  // namespace vibro
