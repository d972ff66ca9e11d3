#!/usr/bin/env bash
# The soft-impact oscillator, the README's section: runs the two scenes of experiments/soft_impact,
# draws the figure and prints every number the README quotes.
#   * diagram.yaml: brute-force bifurcation diagram over ω ∈ [0.8, 1.7], up and down;
#   * continuation.yaml: the periodic orbit continued in ω from the non-contacting orbit at 0.8
#     (grazing of the compliant stop, then the contacting branch's bifurcations).
#
#   bash experiments/soft_impact/run_soft_impact.sh [BUILD_DIR] [OUT_DIR]
#
# BUILD_DIR defaults to build/release, OUT_DIR to docs/figures/soft_impact (PNG and PDF; result
# files in OUT_DIR/data, which git ignores).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
out=${2:-docs/figures/soft_impact}
vibro="$build/tools/vibro/vibro"
py=/usr/bin/python3
[ -x "$vibro" ] || { echo "run_soft_impact: $vibro not found: build first (cmake --preset release && cmake --build --preset release)" >&2; exit 2; }
mkdir -p "$out/data"
d="$out/data"
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg), nproc $(nproc)"
"$vibro" run experiments/soft_impact/diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | grep -v '^vibro: diagram'
"$vibro" run experiments/soft_impact/continuation.yaml -o "$d/continuation.h5" --force 2>&1 | grep -v '^  branch k='
$py experiments/soft_impact/figures.py "$d/diagram.h5" "$d/continuation.h5" "$out"
