#!/usr/bin/env bash
# Parallel sweep speed-up: the same 64-point sweep on 1 and 2 threads, in one run, plus a check
# that both files hold identical data. Usage: bash tools/bench/sweep_speedup.sh [build dir]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
vibro=$build/tools/vibro/vibro
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
time_of() {
  local s; s=$(date +%s.%N)
  "$vibro" run tools/bench/sweep_bench.yaml -o "$out/$1.h5" --threads "$1" 2>/dev/null
  /usr/bin/python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$s" "$(date +%s.%N)"
}
t1=$(time_of 1)
t2=$(time_of 2)
/usr/bin/python3 - "$t1" "$t2" "$(nproc)" "$(cut -d' ' -f1-3 /proc/loadavg)" <<'PY'
import sys
t1, t2 = float(sys.argv[1]), float(sys.argv[2])
print("| threads | wall s | points/s |\n|---|---|---|")
print(f"| 1 | {t1:.2f} | {64 / t1:.1f} |")
print(f"| 2 | {t2:.2f} | {64 / t2:.1f} |")
print(f"speed-up on 2 threads: {t1 / t2:.2f} (nproc = {sys.argv[3]}, load average {sys.argv[4]})")
PY
/usr/bin/python3 - "$out/1.h5" "$out/2.h5" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
names = []
a.visit(lambda n: names.append(n) if isinstance(a[n], h5py.Dataset) else None)
same = all(np.array_equal(a[n][()], b[n][()]) for n in names)
print("data identical on 1 and 2 threads:", same)
PY
