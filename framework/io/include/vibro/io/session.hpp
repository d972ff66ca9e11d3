#pragma once
/// \file session.hpp
/// Runs computed into memory, for programs that use the framework as a library (the Python
/// module, framework/python): the result is the HDF5 file `vibro run` would write, held as bytes.
///
/// There is one code path for a run and its file. run_in_memory() is run_scene() (runner.hpp)
/// with the file created in memory (ResultFile::create_in_memory, HDF5's core driver) instead of
/// on disk, so its datasets are those of `vibro run` for the same scene, bit for bit; save_image()
/// writes them to disk as that file, ResultReader(image) reads them, load_image() reads a file
/// written by either. Only /meta's date, wall_time and threads describe the run itself.
///
/// Interruption: the caller owns a flag and raises it from another thread (the Python module
/// does on Ctrl-C); a simulation ends at its next event with status `interrupted`, a sweep keeps
/// the points it finished, a locate run ends its orbit searches. No signal handler is touched.
///
/// Usage:
///     std::atomic<bool> stop{false};
///     vibro::io::SceneDocument doc = vibro::io::SceneDocument::load("scene.yaml");
///     vibro::io::MemoryRun run = vibro::io::run_in_memory(doc, doc.build(), {.threads = 2, .interrupt = &stop});
///     vibro::io::ResultReader result(run.image);             // /events/t, /samples/x, …
///     vibro::io::save_image(run.image, "out.h5", false);     // the file `vibro run` writes
#include "vibro/io/runner.hpp"

#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace vibro::io {

struct MemoryRunOptions {
  int threads = 0;                         ///< sweeps and locate runs; 0: OpenMP's default
  std::atomic<bool>* interrupt = nullptr;  ///< raise to stop the run (see above)
  /// Progress on stderr as `vibro run` shows it: a redrawn line (`bar`, a terminal) or a line at
  /// each tenth of the run (`lines`); and `on_progress` (RunRequest::on_progress).
  bool bar = false, lines = false;
  std::function<void(double done, double total)> on_progress = nullptr;
};

/// A run held in memory.
struct MemoryRun {
  std::vector<char> image;  ///< the bytes of the result file
  int exit_code = 0;        ///< as `vibro run`: 0 completed, 1 stopped early, 130 interrupted
  std::string summary;      ///< the paragraph `vibro run` prints
};

/// Runs the scene as `vibro run` would (its run.kind: simulate, sweep or locate). Throws
/// SceneError for bad input before anything runs, InvalidInput for a start the engine refuses,
/// ResultError if a value cannot be written (it is not finite).
MemoryRun run_in_memory(const SceneDocument& doc, const Scene& scene, const MemoryRunOptions& options);

/// Writes `image` to `path`, whole or not at all: into a new file beside it, then renamed onto
/// it. Refuses (ResultError) to replace an existing file unless `overwrite`.
void save_image(const std::vector<char>& image, const std::string& path, bool overwrite);

/// The bytes of a result file. Throws ResultError if it cannot be read or is not a result file
/// (no /scene and /meta).
std::vector<char> load_image(const std::string& path);

}  // namespace vibro::io
