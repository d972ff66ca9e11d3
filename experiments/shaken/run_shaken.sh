#!/usr/bin/env bash
# The shaken impact oscillator, the README's section: runs the two scenes of experiments/shaken,
# draws the figure and prints every number the README quotes.
#   * diagram.yaml: brute-force bifurcation diagram over Ω ∈ [0.4, 2.4], up and down;
#   * continuation.yaml: the periodic orbit continued in Ω from 1.5 over [1, 2.2] (fold, grazing).
#
#   bash experiments/shaken/run_shaken.sh [BUILD_DIR] [OUT_DIR]
#
# BUILD_DIR defaults to build/release, OUT_DIR to docs/figures/shaken (PNG and PDF; result files
# in OUT_DIR/data, which git ignores). About 10 s on 2 cores.
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_shaken docs/figures/shaken "$@"
"$vibro" run experiments/shaken/diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | quiet
"$vibro" run experiments/shaken/continuation.yaml -o "$d/continuation.h5" --force 2>&1 | quiet
$py experiments/shaken/figures.py "$d/diagram.h5" "$d/continuation.h5" "$out"
