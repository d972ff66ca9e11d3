// The processes of a run: MPI started and ended (ProcessGroup, runner.hpp) and asked who we are
// (world(), mpi_world.hpp).
#include "mpi_world.hpp"

#include "vibro/io/runner.hpp"

#ifdef VIBRO_WITH_MPI
#define OMPI_SKIP_MPICXX 1  // the C interface only: MPI's C++ bindings are deprecated and
#define MPICH_SKIP_MPICXX 1  // would need the C++ MPI library at link time
#include <mpi.h>
#endif

#include <cstdlib>
#include <tuple>

namespace vibro::io {

ProcessGroup::ProcessGroup(int& argc, char**& argv) {
#ifdef VIBRO_WITH_MPI
  const bool launched = std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMI_SIZE") != nullptr ||
                        std::getenv("PMIX_RANK") != nullptr;
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (launched && !initialized) {
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    started_ = true;
  }
  std::tie(rank_, size_) = detail::world();
#else
  (void)argc;
  (void)argv;
#endif
}

ProcessGroup::~ProcessGroup() {
#ifdef VIBRO_WITH_MPI
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (started_ && !finalized) MPI_Finalize();
#endif
}

}  // namespace vibro::io

namespace vibro::io::detail {

/// Rank and size of MPI_COMM_WORLD if MPI is running, else 0 and 1.
std::pair<int, int> world() {
#ifdef VIBRO_WITH_MPI
  int initialized = 0, finalized = 0;
  MPI_Initialized(&initialized);
  MPI_Finalized(&finalized);
  if (initialized && !finalized) {
    int rank = 0, size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    return {rank, size};
  }
#endif
  return {0, 1};
}

}  // namespace vibro::io::detail
