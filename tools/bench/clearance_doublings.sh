#!/usr/bin/env bash
# The period doublings of the three-mass clearance chain's period-1 branch against a brute-force
# diagram: the continuation of experiments/examples/three_mass_clearance_continuation.yaml (from
# the non-sticking orbit at Ω = 0.7 down to 0.3, no seed) and the up/down diagram of
# experiments/examples/three_mass_clearance_diagram.yaml over the same range; then
# tools/figures/clearance_doublings.py fails unless every doubling the diagram shows is located by
# the continuation between the two diagram values around it. Minutes on 2 cores.
#   bash tools/bench/clearance_doublings.sh [BUILD_DIR] [OUT_DIR]
source "$(dirname "$0")/../experiments/preamble.sh" clearance_doublings /tmp/clearance_doublings "$@"
start=$SECONDS
"$vibro" run experiments/examples/three_mass_clearance_continuation.yaml -o "$d/continuation.h5" --force 2>&1 | quiet
echo "continuation: $(( SECONDS - start )) s"
start=$SECONDS
"$vibro" run experiments/examples/three_mass_clearance_diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | quiet |
  head -5
echo "diagram: $(( SECONDS - start )) s"
$py tools/figures/clearance_doublings.py "$d/diagram.h5" "$d/continuation.h5"
