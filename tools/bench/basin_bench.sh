#!/usr/bin/env bash
# Basin benchmark: experiments/chaos/basin_wagg.yaml, the paper's system at Ω = 1.2,
# a 256 × 256 grid of starts on 2 threads (the target: ≤ 10 min on 2 cores), and points/s on
# 1 thread, 2 threads and `mpirun -np 2` (1 thread each) over the first ROWS rows of the grid
# (same rows, same files: the three are checked bit for bit equal).
# Usage: bash tools/bench/basin_bench.sh [build dir] [ROWS (default 64)] [OUT.h5 for the full run]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
rows=${2:-64}
full=${3:-}
vibro=$(realpath "$build/tools/vibro/vibro")
scene=experiments/chaos/basin_wagg.yaml
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# The first `rows` rows: the row grid's end moved so that its spacing stays that of 256 rows.
last=$(/usr/bin/python3 -c "import sys; r=int(sys.argv[1]); print(-0.29 + (0.6 + 0.29) * (r - 1) / 255)" "$rows")
part=(--set "run.basin.parameters[0].linspace[1]=$last" --set "run.basin.parameters[0].linspace[2]=$rows")
line() { grep -o 'in [0-9.]* s ([0-9.]* points/s).*' "$1"; }
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg), nproc $(nproc)"
"$vibro" run "$scene" -o "$out/t1.h5" --threads 1 "${part[@]}" > "$out/t1.log" 2>&1
echo "1 thread,   $rows x 256: $(line "$out/t1.log")"
"$vibro" run "$scene" -o "$out/t2.h5" --threads 2 "${part[@]}" > "$out/t2.log" 2>&1
echo "2 threads,  $rows x 256: $(line "$out/t2.log")"
if command -v mpirun > /dev/null; then
  mpirun --allow-run-as-root --oversubscribe -np 2 "$vibro" run "$scene" -o "$out/m2.h5" --threads 1 "${part[@]}" > "$out/m2.log" 2>&1
  echo "mpirun -np 2 (1 thread each), $rows x 256: $(line "$out/m2.log")"
fi
/usr/bin/python3 - "$out" <<'PY'
import sys, os, h5py, numpy as np
d = sys.argv[1]
files = [f for f in ("t1.h5", "t2.h5", "m2.h5") if os.path.exists(os.path.join(d, f))]
ref = h5py.File(os.path.join(d, files[0]))
for f in files[1:]:
    b = h5py.File(os.path.join(d, f))
    for n in ("basin/label", "basin/periods_used", "attractors/x", "attractors/v"):
        if not np.array_equal(ref[n][()], b[n][()]):
            sys.exit(f"error: {f} differs from {files[0]} in {n}")
print(f"identical labels, periods_used and attractors: {', '.join(files)}")
PY
if [ -n "$full" ]; then
  "$vibro" run "$scene" -o "$full" --threads 2 --force > "$out/full.log" 2>&1
  echo "full 256 x 256 on 2 threads:"
  cat "$out/full.log"
fi
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
