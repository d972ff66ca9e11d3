#!/usr/bin/env bash
# A bifurcation study end to end (the README's section): the three-mass chain of
# experiments/examples/three_mass_switching.yaml — a stop below mass 0, a clearance between masses
# 1 and 2, r = 0.8, forced on mass 2 — as a researcher runs it, one `vibro run` per question:
#   * continuation with branch switching over Ω ∈ [0.5, 2] (experiments/examples/three_mass_switching.yaml);
#   * plane.yaml: its folds, period doublings and grazings followed in (Ω, forcing amplitude);
#   * diagram.yaml: the brute-force diagram, up and down, each value settled;
#   * basin.yaml: the basins of the coexisting orbits at Ω = 1.85;
#   * impact_map.yaml: the impact map in the window at Ω = 1.6 that no period fits.
# Then draws docs/figures/three_mass_study/three_mass_study.png and prints the numbers the README
# quotes. study.py does the same from Python in one script.
#
#   bash experiments/three_mass_study/run_study.sh [BUILD_DIR] [OUT_DIR]
#
# BUILD_DIR defaults to build/release, OUT_DIR to docs/figures/three_mass_study (result files in
# OUT_DIR/data, which git ignores).
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_study docs/figures/three_mass_study "$@"
"$vibro" run experiments/examples/three_mass_switching.yaml -o "$d/continuation.h5" --force 2>&1 | quiet
[ -f experiments/three_mass_study/plane.yaml ] &&
  "$vibro" run experiments/three_mass_study/plane.yaml -o "$d/plane.h5" --force 2>&1 | quiet
"$vibro" run experiments/three_mass_study/diagram.yaml -o "$d/diagram.h5" --force --threads 2 2>&1 | quiet
"$vibro" run experiments/three_mass_study/basin.yaml -o "$d/basin.h5" --force --threads 2 2>&1 | quiet
"$vibro" run experiments/three_mass_study/impact_map.yaml -o "$d/impact_map.h5" --force 2>&1 | quiet
PYTHONPATH="$build/python${PYTHONPATH:+:$PYTHONPATH}" $py experiments/three_mass_study/figures.py "$d" "$out"
