#include "vibro/io/run_kinds.hpp"

#include "kinds/kinds.hpp"

#include <stdexcept>

namespace vibro::io {

const std::vector<RunKindInfo>& run_kinds() {
  static const std::vector<RunKindInfo> table{
      detail::simulate_kind(), detail::sweep_kind(),   detail::locate_kind(),   detail::continue_kind(),
      detail::basin_kind(),    detail::diagram_kind(), detail::lyapunov_kind(), detail::orbit_kind(),
  };
  return table;
}

const RunKindInfo& run_kind(RunSpec::Kind kind) {
  for (const RunKindInfo& k : run_kinds())
    if (k.kind == kind) return k;
  throw std::logic_error("run_kind: a run kind missing from the table");
}

const RunKindInfo* find_run_kind(const std::string& name) {
  for (const RunKindInfo& k : run_kinds())
    if (name == k.name) return &k;
  return nullptr;
}

const char* to_string(RunSpec::Kind kind) { return run_kind(kind).name; }

}  // namespace vibro::io
