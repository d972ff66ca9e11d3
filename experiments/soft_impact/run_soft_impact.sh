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
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_soft_impact docs/figures/soft_impact "$@"
"$vibro" run experiments/soft_impact/diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | quiet
"$vibro" run experiments/soft_impact/continuation.yaml -o "$d/continuation.h5" --force 2>&1 | quiet
$py experiments/soft_impact/figures.py "$d/diagram.h5" "$d/continuation.h5" "$out"
