#pragma once
// Private to vibro_io: the entry of every run kind in the table (run_kinds.hpp), each defined in
// its own file kinds/<name>.cpp beside its section parser and its run.
#include "vibro/io/run_kinds.hpp"

namespace vibro::io::detail {

RunKindInfo simulate_kind();
RunKindInfo sweep_kind();
RunKindInfo locate_kind();
RunKindInfo continue_kind();
RunKindInfo basin_kind();
RunKindInfo diagram_kind();
RunKindInfo lyapunov_kind();
RunKindInfo orbit_kind();

}  // namespace vibro::io::detail
