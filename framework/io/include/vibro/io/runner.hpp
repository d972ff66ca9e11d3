#pragma once
/// \file runner.hpp
/// Runs a scene and writes its result file: the engine behind `vibro run`. run_scene() looks the
/// scene's run.kind up in the table of run kinds (run_kinds.hpp) and runs it: what every kind
/// shares (the resource check before anything is allocated, which MPI processes run it, the
/// signal handlers of long runs, --resume only where it means something) is decided here, from
/// the table's entries, never by naming a kind.
///
/// simulate: the transient periods are simulated without recording, then the recorded periods
/// with the observers the scene asks for; one file.
///
/// Engines: a scene runs on the engine it resolves to (Scene::engine, `solver.engine` in
/// docs/scenes.md) — the dense Simulator, or the modal chain engine on the chain's modes, set up
/// once per simulation or sweep point. Everything else here (transient then recorded run, the
/// observers, the file, threads and processes) is the same for both; /meta records which ran.
/// run.kind: locate is dense-only (the scene loader refuses it with solver.engine: modal).
///
/// sweep: the grid of the swept paths (a 2-D grid varies its second parameter fastest; `reverse`
/// walks it backwards). Every point's scene is built and validated before anything is
/// simulated or written, so bad input never leaves a half-written file. Points run in parallel
/// with OpenMP (dynamic schedule: sticking-heavy points cost more) and are written in grid order,
/// so the file's data are identical for any number of threads. With `follow`, each point starts
/// from the state (x, v) the previous point reached, placed at initial.time; the points of a
/// 1-D followed sweep are therefore sequential, and a 2-D followed sweep follows along its second
/// parameter with its rows in parallel. Ctrl-C (SIGINT) or SIGTERM stops taking new points,
/// writes the finished ones and leaves OUT.partial for `--resume`.
///
/// MPI (a build that found MPI, started by `mpirun -np K`): the same sweep is split across K
/// processes, each running its points on its own OpenMP threads. Every process builds and
/// validates every point; rank 0 alone touches the file. It hands out units of work on request
/// (one point, or one followed row, at a time: dynamic load balancing), computes points itself
/// on its threads meanwhile, receives the other ranks' recordings and writes them in grid order
/// through the same code as a one-process run, so the file's data are bit for bit the same.
/// A 1-D followed sweep is one unit (it runs on one thread of one process); a 2-D followed sweep
/// is split by rows. Interruption, `--resume`, validation before writing and `.partial` +
/// rename are as above. Only /meta's `threads` (the sum over the processes), `wall_time` and
/// `date` differ from a one-process run, as they do between any two runs.
#include "vibro/io/run_request.hpp"

namespace vibro::io {

/// `doc` is the (already --set) scene document, `scene` its build(). Throws SceneError for bad
/// input found while preparing sweep points (before any file is created). Under MPI every
/// process calls it with the same arguments; the ranks other than 0 write nothing and return
/// exit code 0 and an empty summary (rank 0's report is the run's).
RunReport run_scene(const SceneDocument& doc, const Scene& scene, const RunRequest& request);

/// The processes of this run. In a build with MPI, MPI is started (MPI_THREAD_FUNNELED) only
/// when the process was launched by an MPI launcher, which sets OMPI_COMM_WORLD_SIZE (Open MPI)
/// or PMI_SIZE / PMIX_RANK (MPICH, PMIx launchers); a plain `vibro run` never starts MPI. Make
/// one in main() before anything else; the destructor ends MPI. Without MPI: rank 0 of 1.
///     int main(int argc, char** argv) {
///       const vibro::io::ProcessGroup processes(argc, argv);
///       ...  // run_scene(...) on every process; print only if processes.rank() == 0
///     }
class ProcessGroup {
 public:
  ProcessGroup(int& argc, char**& argv);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0, size_ = 1;
  [[maybe_unused]] bool started_ = false;  ///< this object started MPI and ends it (used with MPI only)
};

}  // namespace vibro::io
