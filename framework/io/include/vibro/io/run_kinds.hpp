#pragma once
/// \file run_kinds.hpp
/// The run kinds: what a scene's `run.kind` can say, in one table. Each kind lives in one place,
/// framework/io/src/kinds/<name>.cpp (its public header, if it has one, in vibro/io/kinds/): the
/// parser of its own section of the scene (`run.<section>`), its run, the groups of its result
/// file and its progress lines. Everything else asks this table: the scene loader (which
/// `run.kind` values and `run` keys exist, which section is required, which belongs to which
/// kind), the runner (run_scene: which function runs the kind, which MPI processes take part,
/// whether it is stopped by signals, whether --resume applies), `vibro info`, the Python module
/// (`vibro.run_kinds()`) and a test that docs/scenes.md and docs/results.md describe every kind.
///
/// Adding a run kind: write src/kinds/<name>.cpp with its section parser and its run (copy one
/// of the others), declare its entry in src/kinds/kinds.hpp, list it in run_kinds.cpp, add its
/// settings to RunSpec (scene.hpp), the file to CMakeLists.txt, and its section and groups to
/// docs/scenes.md and docs/results.md.
///
/// Layers (each includes only those before it):
///   scene model (scene.hpp) ← result file (results.hpp, result_file.hpp; HDF5 only inside
///   src/hdf5_file, used by src/result_file.cpp, src/resume.cpp, src/result_reader.cpp and the
///   layouts src/kinds/{simulate,sweep}_layout.cpp) ← run request (run_request.hpp) ← scene
///   reading (src/scene_reader.hpp, src/scene_sections,
///   src/run_section) and what runs share (src/simulation, src/progress, src/interrupt,
///   src/sweep_plan.hpp) ← run kinds (src/kinds/) ← this table (run_kinds.cpp) ← scene building
///   (SceneDocument::build_checked, read_run in scene.cpp), runner, session, `vibro`.
/// Building a scene calls its kind's parser through the table, and some parsers build the scenes
/// of their grid values (SceneDocument::build_point): a recursion through the table at run time,
/// not an include or link cycle.
#include "vibro/io/run_request.hpp"

#include <string>
#include <vector>

namespace vibro::io {

namespace detail {
struct RunSection;  // a kind's section being read (src/run_section.hpp)
}  // namespace detail

/// One run kind.
struct RunKindInfo {
  const char* name = "";        ///< the `run.kind` value
  RunSpec::Kind kind = RunSpec::Kind::simulate;
  const char* summary = "";     ///< one line (`vibro info`, docs)
  const char* section = nullptr;  ///< its own key under `run` (`run.<section>`), or null
  /// The error when that section is required and missing ("missing: ..."); null: optional.
  const char* missing = nullptr;
  /// The groups it writes besides /scene and /meta (docs/results.md); recorded groups (events,
  /// samples, ...) are listed for the kinds that record them.
  std::vector<std::string> groups;
  bool resumable = false;      ///< `--resume` continues its interrupted file
  bool every_process = false;  ///< under MPI every process runs it (else rank 0 alone)
  /// The runner stops it on SIGINT/SIGTERM (through RunRequest::interrupt) and it writes what it
  /// did; kinds without it handle signals themselves.
  bool stoppable = false;
  /// Reads `run.<section>` (and checks what else the kind needs of the scene) into the RunSpec.
  void (*parse)(detail::RunSection&) = nullptr;
  /// Runs a scene of this kind. Throws SceneError for bad input before any file exists.
  RunReport (*run)(const SceneDocument& doc, const Scene& scene, const RunRequest& request) = nullptr;
};

/// Every run kind, in the order `run.kind`'s error message lists them.
const std::vector<RunKindInfo>& run_kinds();
/// The entry of `kind`.
const RunKindInfo& run_kind(RunSpec::Kind kind);
/// The entry named `name` (a `run.kind` value), or null.
const RunKindInfo* find_run_kind(const std::string& name);

}  // namespace vibro::io
