#pragma once
/// \file results.hpp
/// What one simulation records, and the HDF5 result file (layout in docs/results.md, kept
/// stable). HDF5 lives only here, at the edge.
///
/// One file per run (a sweep included):
///   /scene            attribute `yaml` (the scene text verbatim), `file`; resolved values as
///                     datasets (mass, damping, stiffness, forcing_*, stop_*, x0, v0)
///   /meta             attributes: version, git_commit, date, compiler, threads, tolerances,
///                     contact_sets_built, wall_time, event counts, status, message
///   /events/{t,stop,kind,v_before,v_after,force}       (kind: 0 impact, 1 stick, 2 release,
///                                                       3 chatter-limit; names as attribute)
///   /contacts/{stop,t_start,t_end,force_min,t_force_min,closed}
///   /samples/{t,x,v}  /poincare/{t,x,v}                (x, v: rows = times, columns = DOF)
///   /stats/{sticking_fraction,impacts}                 (rows = periods, columns = stops)
///   /impact_map/{t,stop,phase,velocity,x,v}  /section/{t,phase,direction,x,v}  (rows = crossings)
/// Only what the scene records exists. A sweep adds /sweep/values (points × parameters, the
/// paths as attribute `parameters`), /sweep/status; fixed-size data gain a leading point axis,
/// ragged data (events, contacts) are concatenated with a `point` column.
///
/// Files are written under `OUT.partial` and renamed on success; a sweep appends its points in
/// grid order as they complete (chunked, flushed), so an interrupted sweep keeps its finished
/// points and `vibro run --resume` continues it.
#include "vibro/io/result_frame.hpp"
#include "vibro/io/scene.hpp"

#include <optional>
#include <string>
#include <vector>

namespace vibro::io {

/// The observers one simulation uses (only those the scene asked for) and what they recorded.
struct Recording {
  std::optional<EventLog> events;
  std::optional<ContactLog> contacts;
  std::optional<Samples> samples;
  std::optional<Poincare> poincare;
  std::optional<ImpactMap> impact_map;
  std::optional<Section> section;
  std::optional<PeriodStatistics> statistics;
  RunSummary summary;
  double wall_seconds = 0.0;
  double t_start = 0.0;     ///< the recorded part starts here (after the transient)
  double t_end = 0.0;       ///< and ends here: t_start + run.periods·T; run the simulator to it
  std::size_t periods = 0;  ///< forcing periods begun in [t_start, t_end): rows of /stats
  /// The scene's map to the frame its results are written in (record.frame): samples, Poincaré
  /// points and the impact map are mapped by map_to_result_frame(), the final state (a sweep's
  /// x_end, v_end) when it is written; summary keeps the engine's frame (a followed sweep
  /// starts its next point from it).
  ResultFrame frame;

  /// Observers for the recorded part of a run starting at t_start. Samples are taken at
  /// t_start + i·T/N, i = 0 … ⌊N·periods⌋ - 1 (N = samples_per_period, T = scene.period()), or
  /// at t_start + sample_times[i]. Throws InvalidInput if statistics or Poincaré sections are
  /// asked for without forcing (Ω = 0) or a sample time lies outside [0, periods·T].
  ///     Recording rec = Recording::for_scene(scene, t_start);
  ///     rec.summary = simulator.run(t_start, x, v, rec.t_end, rec.observers());
  static Recording for_scene(const Scene& scene, double t_start);
  /// Pointers to the engaged observers: take them once the Recording is in its final place
  /// (moving or copying it leaves them pointing at the old one).
  std::vector<Observer*> observers();
  /// Maps the recorded states (samples, Poincaré points, impact map) to `frame`, once, after the run.
  void map_to_result_frame();
};

/// Facts about the run written to /meta.
struct RunMeta {
  std::string version, git_commit, date, compiler;
  int threads = 1;
  double wall_seconds = 0.0;
};

RunMeta current_meta(int threads);

class ResultFile;  // HDF5 writer (result_file.hpp)

}  // namespace vibro::io
