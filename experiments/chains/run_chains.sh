#!/usr/bin/env bash
# Long chains: runs the 1000-mass sticking chain with the modal engine and draws its
# figure (tools/figures/chain_sticking.py) into docs/figures/chains/ (PNG and PDF).
#
#   bash experiments/chains/run_chains.sh [BUILD_DIR] [OUT_DIR]
#
# About 5 s after the build. The benchmark behind the README's long-chain table is separate:
# build/release/tools/bench/bench_chain --impacts 400 --dense (about 4 minutes).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
out=${2:-docs/figures/chains}
vibro="$build/tools/vibro/vibro"
[ -x "$vibro" ] || { echo "run_chains: $vibro not found: build first (cmake --preset release && cmake --build --preset release)" >&2; exit 2; }
mkdir -p "$out/data"
"$vibro" run experiments/chains/chain_1000_sticking.yaml -o "$out/data/chain_1000_sticking.h5" --force
/usr/bin/python3 tools/figures/chain_sticking.py "$out/data/chain_1000_sticking.h5" "$out"
