#!/usr/bin/env bash
# Runs a fixed set of scenes — every run kind, both engines, every record option the experiments
# use — into OUT_DIR, for a restructuring that must leave every result bit for bit the same:
#
#   bash tools/dev/golden.sh BUILD_DIR OUT_DIR        # before, then after the change
#   /usr/bin/python3 tools/dev/same_results.py OUT_BEFORE OUT_AFTER
#
# Single-threaded (--threads 1 is not needed for sameness — files do not depend on the thread
# count — but keeps the machine free). Takes about two minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:?build dir}
out=${2:?output dir}
vibro="$build/tools/vibro/vibro"
mkdir -p "$out"
scenes=(
  experiments/wagg2004/fig2_sticking_orbit.yaml experiments/wagg2004/fig4_rising_sequence.yaml
  experiments/wagg2004/fig6_sticking_boundary.yaml experiments/wagg2004/rising_scan.yaml
  experiments/wagg2004/fig5_zoom.yaml experiments/wagg2004/continuation.yaml
  experiments/wagg2004/rising_curve.yaml
  experiments/examples/three_mass_rising.yaml experiments/examples/three_mass_chain.yaml
  experiments/examples/three_mass_sweep.yaml experiments/examples/three_mass_continuation.yaml
  experiments/examples/pd_cascade.yaml
  experiments/chaos/basin_wagg.yaml experiments/chaos/bifurcation_wagg.yaml
  experiments/chaos/lyapunov_chain.yaml
  experiments/chains/chain_10_4stops.yaml experiments/chains/chain_100_sticking.yaml
  experiments/chains/chain_100_every10.yaml experiments/chains/chain_200_continuation.yaml
  experiments/chains/chain_1000_orbit.yaml
)
for s in "${scenes[@]}"; do
  name=$(basename "$s" .yaml)
  start=$(date +%s.%N)
  status=0
  "$vibro" run "$s" -o "$out/$name.h5" --force > "$out/$name.txt" 2>&1 || status=$?
  printf '%-32s exit %d  %6.1f s\n' "$name" "$status" "$(echo "$(date +%s.%N) - $start" | bc)"
done
