#!/usr/bin/env bash
# The rising study of Wagg (2004), reproduced: runs every scene of experiments/wagg2004 (and the
# three-mass chain beyond the paper), draws every figure, and prints the located bifurcations
# beside the paper's values; then the paper's branch by continuation (stability, folds, grazings,
# the coexisting orbits) beside the running method's transitions.
#
#   bash experiments/wagg2004/run_study.sh [BUILD_DIR] [OUT_DIR]
#
# BUILD_DIR defaults to build/release (cmake --preset release), OUT_DIR to docs/figures/wagg2004:
# figures go there as PNG and PDF (the README shows the PNGs), result files to OUT_DIR/data.
# Takes about 30 s on 2 cores once built.
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_study docs/figures/wagg2004 "$@"

run() {  # scene file, result name
  echo "== vibro run $1" >&2
  "$vibro" run "$1" -o "$d/$2.h5" --force  # a new study replaces the last one's results
}
run experiments/wagg2004/fig2_sticking_orbit.yaml fig2_sticking_orbit
run experiments/wagg2004/fig4_rising_sequence.yaml fig4_rising_sequence
run experiments/wagg2004/fig6_sticking_boundary.yaml fig6_sticking_boundary
run experiments/wagg2004/rising_scan.yaml rising_scan
run experiments/wagg2004/fig5_zoom.yaml fig5_zoom
run experiments/examples/three_mass_rising.yaml three_mass_rising
run experiments/wagg2004/continuation.yaml continuation

$py tools/figures/fig2_time_series.py "$d/fig2_sticking_orbit.h5" "$out"
$py tools/figures/fig3_phase_portraits.py "$d/fig2_sticking_orbit.h5" "$out"
$py tools/figures/fig4_rising_sequence.py "$d/fig4_rising_sequence.h5" "$out"
$py tools/figures/fig5_sticking_time.py "$d/rising_scan.h5" "$d/fig5_zoom.h5" "$out"
$py tools/figures/fig6_sticking_boundary.py "$d/fig6_sticking_boundary.h5" "$out"
$py tools/figures/three_mass_rising.py "$d/three_mass_rising.h5" "$out"
$py tools/figures/continuation.py "$d/continuation.h5" experiments/wagg2004/continuation.yaml "$build" "$out"
$py tools/figures/report_transitions.py "$d/rising_scan.h5" "$d/fig5_zoom.h5" | tee "$out/transitions.md"
$py tools/figures/report_continuation.py "$d/continuation.h5" "$d/rising_scan.h5" | tee "$out/continuation.md"
echo "Figures in $out (PNG and PDF), results in $d." >&2
