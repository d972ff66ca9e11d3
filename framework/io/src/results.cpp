/// \file results.cpp
/// Recording (which observers a scene asks for) and RunMeta (results.hpp). The HDF5 result file
/// is written by result_file.cpp and the units it names.
#include "vibro/io/results.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <string>
#include <vector>

namespace vibro::io {

namespace detail {

// Declared in result_file_impl.hpp (the writer names the samples group by it).
bool records_samples(const RecordSpec& spec) {
  return spec.samples_per_period > 0 || !spec.sample_times.empty();
}

}  // namespace detail

namespace {

/// Sample times of one recorded span (absolute), ascending.
std::vector<double> sample_times(const Scene& scene, double t_start) {
  const RecordSpec& spec = scene.record;
  const double T = scene.period();
  const double span = scene.run.periods * T;
  std::vector<double> times;
  if (!spec.sample_times.empty()) {
    for (std::size_t i = 0; i < spec.sample_times.size(); ++i) {
      const double s = spec.sample_times[i];
      if (!std::isfinite(s) || s < 0.0 || s > span)
        throw InvalidInput("record.sample_times[" + std::to_string(i) + "] = " + number_text(s) +
                           ": must lie in the recorded span [0, " + number_text(span) +
                           "] (run.periods × period)");
      times.push_back(t_start + s);
    }
    std::sort(times.begin(), times.end());
  } else {
    const auto N = static_cast<double>(spec.samples_per_period);
    const auto count = static_cast<long>(std::floor(N * scene.run.periods + 1e-9));
    for (long i = 0; i < count; ++i) times.push_back(t_start + static_cast<double>(i) * T / N);
  }
  return times;
}

}  // namespace

Recording Recording::for_scene(const Scene& scene, double t_start) {
  const RecordSpec& spec = scene.record;
  const double periods = scene.run.periods;
  Recording rec;
  rec.t_start = t_start;
  rec.t_end = t_start + periods * scene.period();
  rec.periods = static_cast<std::size_t>(std::max(0.0, std::ceil(periods - 1e-9)));

  const bool forced = scene.forcing().frequency > 0.0;
  if (spec.statistics && !forced)
    throw InvalidInput("record.statistics: per-period statistics need a forcing frequency > 0");
  if (spec.poincare && !forced)
    throw InvalidInput("record.poincare: Poincaré sections need a forcing frequency > 0");

  if (spec.events) rec.events.emplace();
  if (spec.contacts) rec.contacts.emplace();
  if (detail::records_samples(spec)) rec.samples.emplace(sample_times(scene, t_start));
  if (spec.poincare) rec.poincare.emplace(t_start);
  if (spec.impact_map) rec.impact_map.emplace();
  if (spec.section) rec.section.emplace(spec.section->plane, spec.section->direction);
  if (spec.statistics) rec.statistics.emplace();
  rec.frame = ResultFrame::of(scene);
  return rec;
}

void Recording::map_to_result_frame() {
  if (frame.identity()) return;
  if (samples)
    for (Eigen::Index i = 0; i < samples->x.cols(); ++i)
      frame.to_result(samples->t[static_cast<std::size_t>(i)], samples->x.col(i), samples->v.col(i));
  if (poincare)
    for (std::size_t i = 0; i < poincare->t.size(); ++i) frame.to_result(poincare->t[i], poincare->x[i], poincare->v[i]);
  if (impact_map)
    for (std::size_t i = 0; i < impact_map->t.size(); ++i)
      frame.to_result(impact_map->t[i], impact_map->x[i], impact_map->v[i]);
  if (section)  // crossings of the scene's own coordinates; their states in the result's frame
    for (std::size_t i = 0; i < section->t.size(); ++i) frame.to_result(section->t[i], section->x[i], section->v[i]);
}

std::vector<Observer*> Recording::observers() {
  std::vector<Observer*> out;
  if (events) out.push_back(&*events);
  if (contacts) out.push_back(&*contacts);
  if (samples) out.push_back(&*samples);
  if (poincare) out.push_back(&*poincare);
  if (impact_map) out.push_back(&*impact_map);
  if (section) out.push_back(&*section);
  if (statistics) out.push_back(&*statistics);
  return out;
}

RunMeta current_meta(int threads) {
  RunMeta meta;
#ifdef VIBRO_VERSION
  meta.version = VIBRO_VERSION;
#else
  meta.version = "0.1.0";
#endif
#ifdef VIBRO_GIT_COMMIT
  meta.git_commit = VIBRO_GIT_COMMIT;
#else
  meta.git_commit = "unknown";
#endif
#if defined(__clang__)
  meta.compiler = __VERSION__;
#elif defined(__GNUC__)
  meta.compiler = "GCC " __VERSION__;
#elif defined(__VERSION__)
  meta.compiler = __VERSION__;
#else
  meta.compiler = "unknown";
#endif
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &utc);
  meta.date = date;
  meta.threads = threads;
  return meta;
}

}  // namespace vibro::io
