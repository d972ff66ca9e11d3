#include "vibro/io/recorded_gaps.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace vibro::io {
namespace {

struct Deepest {
  double excess = 0.0;  ///< depth − bound, > 0 if found
  double depth = 0.0, bound = 0.0, t = 0.0;
  std::size_t stop = 0;
};

/// g_j(t, x) of every stop against its bound, the deepest excess into `d`.
void scan(const std::vector<Stop>& stops, double frequency, double tolerance, double t_resolution, double t,
          const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::VectorXd>& v, Deepest& d) {
  constexpr double rounding = 16.0 * std::numeric_limits<double>::epsilon();
  for (std::size_t j = 0; j < stops.size(); ++j) {
    const Stop& s = stops[j];
    if (s.is_compliant()) continue;  // a compliant stop is penetrated while engaged (stops.hpp)
    const double g = stop_gap(s, frequency, t, x);
    // The gap's rate w_jᵀ v − s_j'(t), and the sizes its evaluation rounds (|x_i|, |x_k|, |s_j|).
    const bool general = s.kind == Stop::Kind::normal;
    const double sign = s.kind == Stop::Kind::lower ? -1.0 : 1.0;
    const double wv = general ? s.direction.dot(v) : sign * v(s.mass) - (s.other >= 0 ? v(s.other) : 0.0);
    double rate = wv - frequency * (-s.s_cos() * std::sin(frequency * t) + s.s_sin() * std::cos(frequency * t));
    if (s.has_higher_harmonics()) rate -= stop_higher_motion(s, frequency, t, 1);
    // For a general normal, the sizes rounded in nᵀx: Σ|n_l x_l|.
    const double size = (general ? s.direction.cwiseProduct(x).cwiseAbs().sum()
                                 : std::abs(x(s.mass)) + (s.other >= 0 ? std::abs(x(s.other)) : 0.0)) +
                        std::abs(s.position) + s.motion_extent();
    const double bound = tolerance + std::abs(rate) * t_resolution + rounding * size;
    const double excess = g - bound;
    if (!(excess <= d.excess)) {  // NaN too: a non-finite state is past every bound
      d.excess = std::isnan(excess) ? std::numeric_limits<double>::infinity() : excess;
      d.depth = g;
      d.bound = bound;
      d.t = t;
      d.stop = j;
    }
  }
}

}  // namespace

void check_recorded_gaps(const Scene& scene, Recording& rec) {
  RunSummary& s = rec.summary;
  if (s.status != RunStatus::completed || scene.stops.empty()) return;
  const double frequency = scene.forcing().frequency;
  const double tolerance = scene.solver.trigger * s.length_scale;
  // The event search places an event to within its time resolution, 8 ε max(|t|, T) (the
  // engines'), so a gap at an event may exceed the trigger by its rate times a few of those.
  const double t_far = std::max({std::abs(rec.t_start), std::abs(rec.t_end), std::abs(s.t)});
  const double t_resolution = 32.0 * std::numeric_limits<double>::epsilon() * std::max(t_far, s.time_scale);
  Deepest d;
  if (rec.samples)
    for (std::size_t k = 0; k < rec.samples->t.size(); ++k) {
      const auto c = static_cast<Eigen::Index>(k);
      scan(scene.stops, frequency, tolerance, t_resolution, rec.samples->t[k], rec.samples->x.col(c),
           rec.samples->v.col(c), d);
    }
  if (rec.poincare)
    for (std::size_t k = 0; k < rec.poincare->t.size(); ++k)
      scan(scene.stops, frequency, tolerance, t_resolution, rec.poincare->t[k], rec.poincare->x[k], rec.poincare->v[k], d);
  if (s.x.size() == scene.x0.size() && s.v.size() == scene.x0.size())
    scan(scene.stops, frequency, tolerance, t_resolution, s.t, s.x, s.v, d);
  if (!(d.excess > 0.0)) return;
  const Stop& stop = scene.stops[d.stop];
  s.status = RunStatus::numerical_failure;
  s.message = "a recorded state lies " + number_text(d.depth) + " past stop " + std::to_string(d.stop) + " (" +
              stop.name + ") at t = " + number_text(d.t) + ", beyond the gap tolerance " + number_text(d.bound) +
              " (trigger × L = " + number_text(tolerance) + ", L = " + number_text(s.length_scale) +
              ", and the event search's time resolution): the engine lost this stop; the states are kept for "
              "inspection, not as a result";
}

}  // namespace vibro::io
