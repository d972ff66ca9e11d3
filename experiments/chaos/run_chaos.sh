#!/usr/bin/env bash
# Chaos and multistability, the README's section: runs the three scenes of
# experiments/chaos, draws their figures and prints every number the README quotes.
#   * bifurcation_wagg.yaml: the paper's system, brute-force diagram over Ω ∈ [0.24, 0.28], up
#     and down (marked with experiments/wagg2004/continuation.yaml's bifurcations, run too);
#   * lyapunov_chain.yaml: a two-mass chain's Lyapunov spectrum along Ω through its period-doubling
#     cascade into chaos;
#   * basin_wagg.yaml: the paper's system at Ω = 1.2, a 256 × 256 basin of two coexisting orbits.
# With `bench`, also tools/bench/basin_bench.sh (points/s on 1 and 2 threads and mpirun -np 2).
#
#   bash experiments/chaos/run_chaos.sh [BUILD_DIR] [OUT_DIR] [bench]
#
# BUILD_DIR defaults to build/release, OUT_DIR to docs/figures/chaos (PNG and PDF; result files in
# OUT_DIR/data, which git ignores). About a minute on 2 cores, 1.5 with `bench`.
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_chaos docs/figures/chaos "$@"

run() {  # scene file, result name, extra arguments: prints the command's summary and its wall time
  local s e
  s=$(date +%s.%N)
  "$vibro" run "$1" -o "$d/$2.h5" --force "${@:3}" 2>&1 | grep -v '^  branch k='  # not continuation's progress
  e=$(date +%s.%N)
  $py -c "import sys; print(f'== {sys.argv[1]}: {float(sys.argv[3]) - float(sys.argv[2]):.1f} s wall')" "$1" "$s" "$e"
}
run experiments/chaos/bifurcation_wagg.yaml bifurcation_wagg --threads 2
run experiments/wagg2004/continuation.yaml continuation
run experiments/chaos/lyapunov_chain.yaml lyapunov_chain
run experiments/chaos/basin_wagg.yaml basin_wagg --threads 2

$py tools/figures/bifurcation.py "$d/bifurcation_wagg.h5" --transitions "$d/continuation.h5" --mass 1 "$out"
$py tools/figures/lyapunov.py "$d/lyapunov_chain.h5" "$out"
$py tools/figures/basin.py "$d/basin_wagg.h5" "$out"

# The numbers quoted in the README, read back from the files.
$py - "$d" <<'PY'
import sys, h5py, numpy as np
d = sys.argv[1]
with h5py.File(f"{d}/bifurcation_wagg.h5") as f:
    g = f["diagram"]
    p = g["parameter"][()]
    for dirn in ("up", "down"):
        k = g[f"k_{dirn}"][()]
        print(f"diagram {dirn}: periods found {sorted(set(k.tolist()))}, not periodic at {np.count_nonzero(k == 0)} of {len(p)}")
    dx = np.abs(g["x_up"][()][:, -1, :] - g["x_down"][()][:, -1, :]).max(axis=1)
    apart = p[dx > 1e-6]
    print(f"diagram: up and down end on different states at {len(apart)} values"
          + (f" (Ω in [{apart.min():.5f}, {apart.max():.5f}])" if len(apart) else ""))
    print(f"diagram: wall {f['meta'].attrs['wall_time']:.1f} s")
with h5py.File(f"{d}/lyapunov_chain.h5") as f:
    g = f["lyapunov"]
    p, e, fin = g["parameter"][()], g["exponents"][()], g["finite"][()]
    chaotic = p[e[:, 0] > 1e-3]
    # Before chaos, λ1 rises towards 0 at each period doubling: its local maxima there.
    pre = np.nonzero(p < chaotic.min())[0]
    peaks = [i for i in pre[1:-1] if e[i, 0] > e[i - 1, 0] and e[i, 0] >= e[i + 1, 0] and e[i, 0] > -0.02]
    print("lyapunov: before chaos λ1 peaks at " + ", ".join(f"Ω = {p[i]:.3f} ({e[i, 0]:+.4f})" for i in peaks))
    print(f"lyapunov: λ1 > 0 at {len(chaotic)} of {len(p)} values, first at Ω = {chaotic.min():.4f}; "
          f"max λ1 = {e[:, 0].max():.4f} at Ω = {p[e[:, 0].argmax()]:.4f}; "
          f"structural (−∞) exponents at {np.count_nonzero((fin == 0).any(axis=1))} values "
          f"(how many at a value: {sorted(set((fin == 0).sum(axis=1).tolist()) - {0})}); "
          f"wall {f['meta'].attrs['wall_time']:.1f} s")
with h5py.File(f"{d}/basin_wagg.h5") as f:
    b, a = f["basin"], f["attractors"]
    label = b["label"][()]
    print(f"basin: {label.shape[0]} x {label.shape[1]}, attractors: periods {a['period'][()].tolist()}, "
          f"cells {a['cells'][()].tolist()}, not converged {np.count_nonzero(label == -1)}, "
          f"mean periods per point {b.attrs['mean_periods']}, "
          f"wall {f['meta'].attrs['wall_time']:.1f} s on {f['meta'].attrs['threads']} threads "
          f"({label.size / f['meta'].attrs['wall_time']:.0f} points/s)")
PY
if [ "${3:-}" = bench ]; then
  bash tools/bench/basin_bench.sh "$build" 64
fi
