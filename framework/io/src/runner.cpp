#include "vibro/io/runner.hpp"

#include "interrupt.hpp"
#include "mpi_world.hpp"

#include "vibro/io/resources.hpp"
#include "vibro/io/run_kinds.hpp"

#include <limits>
#include <optional>

namespace vibro::io {

RunReport run_scene(const SceneDocument& doc, const Scene& scene, const RunRequest& request) {
  check_run_resources(scene, checked_threads(request.threads, std::numeric_limits<std::size_t>::max()));  // before any file or allocation
  const RunKindInfo& kind = run_kind(scene.run.kind);
  // Under MPI only the kinds that split their work across the processes run on every one; any
  // other run is rank 0's alone.
  if (!kind.every_process && detail::world().first != 0) return {};
  // A rank other than 0 makes no lock: from here it polls the flag (interrupt.hpp).
  if (detail::world().first != 0) detail::disarm_exit_at_once();
  if (request.resume && !kind.resumable)
    throw SceneError(scene.file, 1, 1, "run.kind", "--resume continues an interrupted sweep; this scene is not a sweep");
  if (!kind.stoppable) return kind.run(doc, scene, request);
  // Long runs: SIGINT/SIGTERM stop them at the next event (a basin takes no new points) and
  // their file is written with what was done, status interrupted, exit code 130.
  RunRequest stoppable = request;
  std::optional<detail::InterruptGuard> guard;  // signals are the caller's when it gives its own flag
  if (!stoppable.interrupt) {
    guard.emplace();
    stoppable.interrupt = &detail::g_interrupted;
  }
  return kind.run(doc, scene, stoppable);
}

}  // namespace vibro::io
