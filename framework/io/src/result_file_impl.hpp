#pragma once
// Private to vibro_io: the state of a ResultFile (ResultFile::Impl) and the layout its units
// share. The result file is written by:
//   result_file.cpp            /scene, /meta, groups of other run kinds, finishing, the lifetime
//   kinds/simulate_layout.cpp  the recorded groups (events, contacts, samples, poincare, stats)
//                              and a simulation's file
//   kinds/sweep_layout.cpp     /sweep and the recorded groups of a sweep, point by point
//   resume.cpp                 reopening an interrupted sweep (open_partial)
// over the HDF5 layer (hdf5_file.hpp). The layout is docs/results.md.
#include "hdf5_file.hpp"
#include "output_lock.hpp"

#include "vibro/io/result_file.hpp"

#include <Eigen/Dense>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace vibro::io {

namespace detail {

/// One recorded group of one run: `rows` rows in every dataset.
struct Table {
  std::string group;
  bool ragged = false;  ///< events, contacts: a sweep concatenates them with a `point` column
  std::size_t rows = 0;
  std::vector<Dataset> datasets;
};

/// One sweep point as written: its recorded groups and its row of each /sweep dataset.
struct PointRecord {
  std::vector<Table> tables;
  std::vector<double> values;
  std::int64_t status = 0;
  std::string message;  ///< why the point stopped early; empty when it completed
  std::vector<std::int64_t> counts;
  double t_end = 0.0;
  std::vector<double> x_end, v_end;
};

// The recorded groups (kinds/simulate_layout.cpp).

/// Whether a scene records samples (results.cpp).
bool records_samples(const RecordSpec& spec);
/// The recorded groups of a scene, as named in the file.
std::vector<std::string> recorded_groups(const RecordSpec& record);
/// Events and contacts: a sweep concatenates them; the others it stacks.
bool is_ragged(const std::string& group);
/// The groups a recording writes (`dof` columns of states, the stops' names). `compliant`: the
/// scene has compliant stops, so the event kinds' names include engage and disengage.
std::vector<Table> recorded_tables(const Recording& rec, Eigen::Index dof,
                                   const std::vector<std::string>& stop_names, bool compliant = false,
                                   bool friction = false);

// /scene and /meta (result_file.cpp).

/// The resolved scene as datasets of /scene.
std::vector<Dataset> scene_datasets(const Scene& scene);
/// Numeric attributes of /scene (the resolved run settings).
std::vector<std::pair<std::string, double>> scene_numbers(const Scene& scene);
/// The solver tolerances, written to /meta (and compared on resume).
std::vector<std::pair<std::string, double>> tolerances(const SimulatorOptions& o);
const char* status_name(RunStatus status);
/// Columns of /sweep/counts and the /meta attributes that sum them.
const std::vector<std::string>& count_names();
std::vector<std::int64_t> counts(const RunSummary& s);

}  // namespace detail

struct ResultFile::Impl {
  using Store = detail::Store;
  using Table = detail::Table;
  using PointRecord = detail::PointRecord;
  using Dims = detail::Dims;
  using Type = detail::Type;

  /// Held from before the file exists until after it is closed and published or removed.
  std::unique_ptr<detail::OutputLock> lock;
  std::string path, partial;
  std::string file_name;  ///< the open file: `partial`, or while resuming a rebuilt copy of it
  Store store;
  RecordSpec record;
  bool sweep_run = false;
  /// Whether an unfinished file stays on disk: a sweep's, for --resume, once its start is
  /// written; a simulation's never.
  bool keep_unfinished = false;
  std::string status = "running", message;  ///< written to /meta by finish()
  Eigen::Index dof = 0;
  std::vector<std::string> stops;
  bool compliant = false;  ///< the scene has compliant stops (events may be engage/disengage)
  bool friction = false;   ///< the scene has friction (events may be friction-stick, -slip, -reversal)
  bool simulation_written = false;
  bool sweep_begun = false;
  std::size_t completed = 0, total = 0, parameters = 0;
  bool finished = false;
  bool in_memory = false;        ///< create_in_memory(): no file on disk, nothing to rename
  std::vector<char> final_image; ///< in memory: the finished file's bytes (taken by finish())

  Impl(std::unique_ptr<detail::OutputLock> output_lock, std::string final_path, std::string file,
       Store::Mode mode, const Scene& scene);

  // result_file.cpp
  void write_scene(const Scene& scene) const;
  void write_meta(const RunMeta& meta, const Scene& scene) const;

  // kinds/simulate_layout.cpp
  /// The recording must carry exactly the groups the scene records.
  void require_groups(const Recording& rec) const;
  /// The recording's groups, every value checked finite (`where`: " (point p)" in a sweep).
  std::vector<Table> checked_tables(const Recording& rec, const std::string& where) const;

  // kinds/sweep_layout.cpp
  /// Creates /sweep for `names` over `points` points.
  void start_sweep(const std::vector<std::string>& names, std::size_t points);
  /// Appends one row (of shape row_shape) at index `row` of an extendible dataset, creating it.
  void put_row(const std::string& path, Type type, const Dims& row_shape, hsize_t row,
               const void* data) const;
  /// Fixed-size data of point p at [p, 0 … rows, …] of (points × rows × …) datasets.
  void append_stacked(const Table& table, hsize_t p) const;
  /// Ragged data of point p appended to 1-D datasets, with a `point` column.
  void append_ragged(const Table& table, hsize_t p) const;
  /// Writes point p's data and its rows of /sweep (not yet counted: see commit).
  void write_point(hsize_t p, const PointRecord& point) const;
  /// Counts the `completed` points, in this order: everything written is flushed, then the
  /// counter is set (in place) and flushed. A kill during the first flush leaves the old count,
  /// during the second either count, and each counted point is whole on disk.
  void commit() const;
  /// A finished sweep's /meta counts (sums over the points) and its status and message.
  void sum_sweep();
};

}  // namespace vibro::io
