// mpi_sweep_driver: `vibro run` for the MPI tests, with the one thing the command does not offer:
// RunRequest::interrupt_after, which stops a sweep as Ctrl-C would once that many points are
// written, without timing a real signal. Used by tests/io/test_mpi_sweep.py only.
//
//   mpirun -np 2 mpi_sweep_driver SCENE OUT.h5 THREADS INTERRUPT_AFTER
//
// Exit code: the run's (0, 1, 130), 2 bad input, 3 the file could not be written.
#include "vibro/io/result_file.hpp"
#include "vibro/io/runner.hpp"
#include "vibro/io/scene.hpp"

#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  const vibro::io::ProcessGroup processes(argc, argv);
  if (argc != 5) {
    std::fprintf(stderr, "usage: mpi_sweep_driver SCENE OUT.h5 THREADS INTERRUPT_AFTER\n");
    return 2;
  }
  try {
    const vibro::io::SceneDocument doc = vibro::io::SceneDocument::load(argv[1]);
    vibro::io::RunRequest request{argv[2], std::atoi(argv[3]), false, false};
    request.interrupt_after = static_cast<std::size_t>(std::atol(argv[4]));
    const vibro::io::RunReport report = vibro::io::run_scene(doc, doc.build(), request);
    if (processes.rank() == 0) std::fprintf(stderr, "%s\n", report.summary.c_str());
    return report.exit_code;
  } catch (const vibro::io::SceneError& e) {
    if (processes.rank() == 0) std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const vibro::io::ResultError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  }
}
