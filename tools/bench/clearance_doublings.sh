#!/usr/bin/env bash
# The period doublings of the three-mass clearance chain's period-1 branch against a brute-force
# diagram: the continuation of experiments/examples/three_mass_clearance_continuation.yaml (from
# the non-sticking orbit at Ω = 0.7 down to 0.3, no seed) and the up/down diagram of
# experiments/examples/three_mass_clearance_diagram.yaml over the same range; then
# tools/figures/clearance_doublings.py checks every located doubling by finite-difference
# multipliers and fails unless every change of period 1 <-> 2 the diagram shows is accounted for
# (a doubling located there, or what the branch's orbits, a longer run and continuation of the
# period-2 orbit show it to be instead). Minutes on 2 cores.
#   bash tools/bench/clearance_doublings.sh [BUILD_DIR] [OUT_DIR]
source "$(dirname "$0")/../experiments/preamble.sh" clearance_doublings /tmp/clearance_doublings "$@"
start=$SECONDS
"$vibro" run experiments/examples/three_mass_clearance_continuation.yaml -o "$d/continuation.h5" --force 2>&1 | quiet
echo "continuation: $(( SECONDS - start )) s"
start=$SECONDS
"$vibro" run experiments/examples/three_mass_clearance_diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | quiet |
  head -5
echo "diagram: $(( SECONDS - start )) s"
start=$SECONDS
$py tools/figures/clearance_doublings.py experiments/examples/three_mass_clearance_continuation.yaml \
  "$d/diagram.h5" "$d/continuation.h5" 2>&1 | quiet
echo "checks: $(( SECONDS - start )) s"
