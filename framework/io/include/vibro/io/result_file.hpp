#pragma once
/// \file result_file.hpp
/// The HDF5 result file of one run: ResultFile writes it, ResultReader reads it back (tests,
/// tools). The layout is docs/results.md; this header is its C++ side and does not include HDF5.
///
/// Life of a file:
///  * create() opens `OUT.partial` and writes /scene and the start of /meta;
///  * a simulation writes its recording once (write_simulation); a sweep calls begin_sweep(), then
///    append_point() for points 0, 1, 2, … in this order (the caller buffers points that complete
///    out of order). Each point is written whole and flushed, then counted in /sweep (attribute
///    `completed`) and flushed again: a sweep killed at any moment keeps the points it counted;
///  * finish() completes /meta and renames `OUT.partial` to `OUT` (std::rename, atomic).
///  * Destroyed without finish() (an exception, Ctrl-C handled by unwinding): a simulation's
///    `.partial` is deleted, a sweep's is kept, and open_partial() resumes it. It checks that the
///    scene is the same, then copies the counted points, each read back and checked, into a new
///    file that replaces the old one (HDF5 1.10 files are not crash-safe: a kill during a flush
///    can leave half-written metadata, which the copy leaves behind with the unfinished point).
///    A counted point that does not read back whole is dropped and computed again.
///
/// Usage (a sweep):
///     auto file = resume ? ResultFile::open_partial(out, scene)
///                        : ResultFile::create(out, scene, current_meta(threads));
///     file.begin_sweep({"forcing.frequency"}, grid.size());      // on resume: only checks
///     for (std::size_t p = file.completed_points(); p < grid.size(); ++p)
///       file.append_point(p, {grid[p]}, run_point(p));          // a Recording
///     file.finish(meta);
///
/// Every HDF5 failure becomes a ResultError naming the file and the object; a value that is not
/// finite is never written: ResultError names the dataset, the point and the entry. Use one
/// ResultFile from one thread.
#include "vibro/io/results.hpp"

#include <Eigen/Dense>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vibro::io {

/// A result file could not be written or read: "FILE: /OBJECT: what (HDF5: reason)".
class ResultError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One dataset of a result file: row-major values of `shape`, of one stored type, with
/// string-array attributes (e.g. `names` of an enumeration). The writer builds every dataset it
/// writes as one; run kinds that write their own groups pass them to ResultFile::write_group.
struct Dataset {
  /// The type stored in the file: 64-bit reals, 32- or 64-bit integers, UTF-8 strings.
  enum class Type { f64, i32, i64, str };
  std::string name;
  std::vector<std::size_t> shape;
  Type type = Type::f64;
  std::vector<double> reals;           ///< f64 values, or
  std::vector<std::int64_t> integers;  ///< i32 and i64 values, or
  std::vector<std::string> texts;      ///< str values
  std::vector<std::pair<std::string, std::vector<std::string>>> labels;
};

/// Writes one run's HDF5 file (docs/results.md).
class ResultFile {
 public:
  /// Starts `path + ".partial"`: /scene, and in /meta the facts of `meta` (version, commit, date,
  /// compiler, threads) and the scene's tolerances. First takes `path + ".lock"` and checks the
  /// target (docs/results.md, "Writing"): throws ResultError if another writer holds the lock,
  /// if `path` exists and not `overwrite` (--force), if `path` is a directory or the scene file,
  /// or if a `.partial` is in the way and not `overwrite`. The partial is created exclusively
  /// (never an existing file, never through a symbolic link).
  static ResultFile create(const std::string& path, const Scene& scene, const RunMeta& meta,
                           bool overwrite = false);
  /// Resumes the `.partial` of an interrupted sweep of `scene` (see above; the copy is written as
  /// `.partial.resume` and renamed over the `.partial`, which is untouched until then). Throws
  /// ResultError if there is none, if it is not a sweep, or if its /scene differs from `scene`
  /// (YAML text, any resolved value — e.g. another --set — or a tolerance). Then
  /// completed_points() says where to continue; begin_sweep() only checks the grid.
  /// Takes the lock and checks the target as create() does.
  static ResultFile open_partial(const std::string& path, const Scene& scene, bool overwrite = false);
  static std::string partial_path(const std::string& path) { return path + ".partial"; }
  /// The same file held in memory (nothing on disk; for library use, session.hpp): written as
  /// create() writes, finish() renames nothing, image() gives its bytes. Sweeps are not kept
  /// for --resume.
  static ResultFile create_in_memory(const Scene& scene, const RunMeta& meta);
  /// The bytes of the file (flushed): after finish(), the finished file; before, what is written
  /// so far (an interrupted sweep's counted points). Written to disk, they are an HDF5 file.
  std::vector<char> image() const;

  ResultFile(ResultFile&&) noexcept;
  ResultFile& operator=(ResultFile&&) noexcept;
  ResultFile(const ResultFile&) = delete;
  ResultFile& operator=(const ResultFile&) = delete;
  /// Without finish(): closes the file, deletes it unless the run is a sweep.
  ~ResultFile();

  /// run.kind = simulate: writes the recorded groups and the run's counts and status to /meta.
  void write_simulation(const Recording& recording);

  /// run.kind = sweep: `parameters` are the swept paths (columns of /sweep/values), `points` the
  /// grid size. On a resumed file it only checks that both agree with the file.
  void begin_sweep(const std::vector<std::string>& parameters, std::size_t points);
  /// Appends point `index` (must equal completed_points()) with its parameter values, then
  /// flushes. Throws ResultError, leaving the file as before the call, if a value is not finite.
  void append_point(std::size_t index, const std::vector<double>& values,
                    const Recording& recording);
  std::size_t completed_points() const;

  /// Any other run kind (not simulate or sweep): writes group `/group` with `datasets` (no value
  /// may be non-finite: ResultError names it) and string attributes. Call set_outcome() before
  /// finish().
  void write_group(const std::string& group, const std::vector<Dataset>& datasets,
                   const std::vector<std::pair<std::string, std::string>>& attributes = {});
  /// Status and message for /meta (`completed`, or why not), and counts (name, value).
  void set_outcome(const std::string& status, const std::string& message,
                   const std::vector<std::pair<std::string, std::int64_t>>& counts = {});
  std::size_t total_points() const;
  /// State reached by the last completed point (for `follow` sweeps that resume); false if none.
  bool last_state(double& t, Eigen::VectorXd& x, Eigen::VectorXd& v) const;

  /// Writes wall time, threads and (sweep) the summed counts and status to /meta, closes the file
  /// and renames it to its final path. A sweep must have all its points.
  void finish(const RunMeta& meta);

  const std::string& path() const;  ///< the final path (without ".partial")

 private:
  struct Impl;
  explicit ResultFile(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Read access to a result file (or any HDF5 file) for tests and tools. Paths are absolute
/// HDF5 paths ("/events/t"); attributes live on an object ("/meta", "/scene", "/events/kind").
class ResultReader {
 public:
  explicit ResultReader(const std::string& path);
  /// Reads the bytes of a result file (ResultFile::image(), or a file's content) from memory.
  explicit ResultReader(const std::vector<char>& image);
  ResultReader(ResultReader&&) noexcept;
  ResultReader& operator=(ResultReader&&) noexcept;
  ~ResultReader();

  bool exists(const std::string& object) const;
  bool is_dataset(const std::string& object) const;
  /// Every group and dataset below the root, sorted ("/events", "/events/t", …).
  std::vector<std::string> objects() const;
  std::vector<std::size_t> shape(const std::string& dataset) const;
  /// "f64", "i32", "i64" or "str" (other types: "other").
  std::string type(const std::string& dataset) const;

  /// All values, row-major, converted to double (exact for our integers).
  std::vector<double> read(const std::string& dataset) const;
  std::vector<std::int64_t> read_integers(const std::string& dataset) const;
  std::vector<std::string> read_strings(const std::string& dataset) const;
  /// 1-D: one column; 2-D: as stored; more: first axis as rows, the others flattened.
  Eigen::MatrixXd read_matrix(const std::string& dataset) const;

  std::vector<std::string> attributes(const std::string& object) const;
  bool attribute_is_string(const std::string& object, const std::string& name) const;
  /// "str" (one string), "str[]" (an array of strings), "i64" or "f64" (numbers).
  std::string attribute_type(const std::string& object, const std::string& name) const;
  std::string attribute_string(const std::string& object, const std::string& name) const;
  std::vector<std::string> attribute_strings(const std::string& object,
                                             const std::string& name) const;
  double attribute_number(const std::string& object, const std::string& name) const;
  std::vector<double> attribute_numbers(const std::string& object, const std::string& name) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vibro::io
