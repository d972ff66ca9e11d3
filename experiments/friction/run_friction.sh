#!/usr/bin/env bash
# Dry friction, the README's section: Den Hartog's forced oscillator with Coulomb and viscous
# friction swept over the friction ratio and Ω (den_hartog.yaml), drawn against his closed form and
# his boundary of motion without stops; prints the numbers the README quotes and exits 1 if a
# simulated steady motion differs from the closed form (more than 1e-8 of its amplitude) or stops
# where the closed form says it does not (or the reverse).
#
#   bash experiments/friction/run_friction.sh [BUILD_DIR] [OUT_DIR]
#
# BUILD_DIR defaults to build/release, OUT_DIR to docs/figures/friction (result file in
# OUT_DIR/data, which git ignores).
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_friction docs/figures/friction "$@"
"$vibro" run experiments/friction/den_hartog.yaml -o "$d/den_hartog.h5" --force --threads 2 2>&1 | quiet
$py experiments/friction/figures.py "$d/den_hartog.h5" "$out"
