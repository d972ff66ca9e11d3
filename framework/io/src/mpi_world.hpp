#pragma once
// Private to vibro_io: the processes of an MPI run, for the run kinds that split their work
// across them (run.kind: sweep in kinds/sweep.cpp and mpi_sweep.cpp, basin in kinds/basin.cpp).
#include <utility>

namespace vibro::io::detail {

/// Rank and size of MPI_COMM_WORLD if MPI is running, else 0 and 1.
std::pair<int, int> world();

}  // namespace vibro::io::detail
