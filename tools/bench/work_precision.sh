#!/usr/bin/env bash
# Work-precision report: the framework against conventional integrators with its own event rules
# (Dormand–Prince 5(4) and DOP853 with dense output, and SUNDIALS' ARKODE and CVODE when built
# with it), on four problems. ONE command; builds nothing.
#
#   bash tools/bench/work_precision.sh            # full run (~10-30 min on 2 shared cores): writes
#                                                 #   docs/accuracy-work-precision.md and
#                                                 #   docs/figures/work_precision_<a|b|c|d>.png
#   bash tools/bench/work_precision.sh --quick    # smoke test (~1 min): 20 periods, fewer settings;
#                                                 #   writes into build/release/work_precision_quick/
#   options: --build DIR (default build/release), --docs DIR (where the report goes),
#            --problems abcd (a subset)
#
# Needs a Release build of the bench first:
#   cmake --preset dev && cmake --build --preset dev --target work_precision
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build="$root/build/release"
docs=""
quick=()
problems=abcd
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) quick=(--quick); shift ;;
    --build) build=$2; shift 2 ;;
    --docs) docs=$2; shift 2 ;;
    --problems) problems=$2; shift 2 ;;
    *) echo "usage: $0 [--quick] [--build DIR] [--docs DIR] [--problems abcd]" >&2; exit 2 ;;
  esac
done
bin="$build/tools/bench/work_precision"
if [[ ! -x "$bin" ]]; then
  echo "work_precision.sh: $bin not found; build it first:" >&2
  echo "  cmake --preset dev && cmake --build --preset dev --target work_precision" >&2
  exit 2
fi
if [[ -z "$docs" ]]; then
  if [[ ${#quick[@]} -gt 0 ]]; then docs="$build/work_precision_quick"; else docs="$root/docs"; fi
fi
data="$build/work_precision_data"
[[ ${#quick[@]} -gt 0 ]] && data+="_quick"
mkdir -p "$data" "$docs/figures"
rm -f "$data/work_precision.csv" "$data/work_precision.json"

load_before=$(cut -d' ' -f1-3 /proc/loadavg)
start=$(date +%s)
# One thread: the bench itself is single-threaded; keep Eigen/OpenMP from spawning any.
OMP_NUM_THREADS=1 "$bin" "${quick[@]}" --problems "$problems" --out "$data"
wall=$(( $(date +%s) - start ))
load_after=$(cut -d' ' -f1-3 /proc/loadavg)

command="bash tools/bench/work_precision.sh"
[[ ${#quick[@]} -gt 0 ]] && command+=" --quick"
[[ "$problems" != abcd ]] && command+=" --problems $problems"
# The engine's curves at commit 2de0370 (kept data, docs/data/) are drawn dashed beside the new ones.
before="$root/docs/data/work_precision_at_2de0370.csv"
/usr/bin/python3 "$root/tools/bench/plot_work_precision.py" --data "$data" --docs "$docs" \
  --load-before "$load_before" --load-after "$load_after" --wall "$wall" --command "$command" \
  $([[ -f "$before" ]] && printf -- '--before %s' "$before")
echo "work_precision.sh: wrote $docs/accuracy-work-precision.md and $docs/figures/work_precision_*.png (${wall} s)"
