#!/usr/bin/env bash
# Sweeps at scale: the rising study's frequency sweep — the paper's system of
# experiments/wagg2004/fig2_sticking_orbit.yaml (Wagg 2004) swept over Ω in [0.25, 0.27] (the
# range of its fig. 5, through the rising event), 2000 independent points (no follow), each
# 200 transient + 200 recorded periods, recording statistics, contacts and Poincaré sections.
# Points per second on 1 and 2 OpenMP threads in one process, and on 2 MPI processes × 1 thread
# (when vibro was built with MPI and mpirun exists); then a check that all files hold the same data.
#
#   bash tools/bench/sweep_scale.sh [--quick] [BUILD_DIR]     # BUILD_DIR defaults to build/release
#
# --quick: 100 points instead of 2000 (about 1/20 of the time). Meaningful only in a Release
# build; the load average is printed, since other jobs on the machine slow every row.
set -euo pipefail
cd "$(dirname "$0")/../.."
points=2000
if [[ "${1:-}" == "--quick" ]]; then
  points=100
  shift
fi
build=${1:-build/release}
vibro=$build/tools/vibro/vibro
[[ -x "$vibro" ]] || { echo "no $vibro: build the vibro target first" >&2; exit 2; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

# The scene: fig. 2's file up to its `record` section, then the sweep's record and run.
scene=$out/rising_sweep.yaml
sed '/^record:/,$d' experiments/wagg2004/fig2_sticking_orbit.yaml > "$scene"
cat >> "$scene" <<EOF
record: {statistics: true, contacts: true, poincare: true}
run:
  kind: sweep
  transient_periods: 200
  periods: 200
  sweep:
    parameters:
      - {path: forcing.frequency, linspace: [0.25, 0.27, $points]}
EOF

seconds() {  # seconds of wall time of a command
  local s; s=$(date +%s.%N)
  "$@" 2>/dev/null
  /usr/bin/python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$s" "$(date +%s.%N)"
}
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
t1=$(seconds "$vibro" run "$scene" -o "$out/t1.h5" --threads 1)
t2=$(seconds "$vibro" run "$scene" -o "$out/t2.h5" --threads 2)
tm=none
if command -v mpirun >/dev/null && ldd "$vibro" | grep -q libmpi; then
  # Root (CI containers) needs Open MPI's consent; --bind-to none lets the OS place the processes.
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  tm=$(seconds mpirun --oversubscribe --bind-to none -np 2 "$vibro" run "$scene" -o "$out/m2.h5" --threads 1)
fi
/usr/bin/python3 - "$points" "$t1" "$t2" "$tm" "$(nproc)" "$load_before" "$(cut -d' ' -f1-3 /proc/loadavg)" <<'PY'
import sys
n, t1, t2 = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
print(f"rising sweep: {n} points × (200 + 200) periods, Ω in [0.25, 0.27]")
print("| run | wall s | points/s | speed-up |\n|---|---|---|---|")
print(f"| 1 process, 1 thread | {t1:.2f} | {n / t1:.2f} | 1 |")
print(f"| 1 process, 2 threads | {t2:.2f} | {n / t2:.2f} | {t1 / t2:.2f} |")
if sys.argv[4] != "none":
    tm = float(sys.argv[4])
    print(f"| mpirun -np 2, 1 thread each | {tm:.2f} | {n / tm:.2f} | {t1 / tm:.2f} |")
else:
    print("(no MPI row: vibro was built without MPI or mpirun is missing)")
print(f"nproc = {sys.argv[5]}, load average before {sys.argv[6]}, after {sys.argv[7]}")
PY
/usr/bin/python3 - "$out" <<'PY'
import os, sys, h5py, numpy as np
def same_data(x, y):  # numbers bit for bit; strings (object arrays) by value
    return x.tobytes() == y.tobytes() if x.dtype.kind in "fiub" else np.array_equal(x, y)
d = sys.argv[1]
files = [os.path.join(d, f) for f in ("t1.h5", "t2.h5", "m2.h5") if os.path.exists(os.path.join(d, f))]
ref = h5py.File(files[0], "r")
names = []
ref.visit(lambda n: names.append(n) if isinstance(ref[n], h5py.Dataset) else None)
for other in files[1:]:
    with h5py.File(other, "r") as g:
        same = all(same_data(np.asarray(ref[n][()]), np.asarray(g[n][()])) for n in names)
        print(f"data of {os.path.basename(other)} identical to {os.path.basename(files[0])}: {same}")
PY
