#!/usr/bin/env bash
# Long chains: runs the 1000-mass sticking chain with the modal engine and draws its
# figure (tools/figures/chain_sticking.py) into docs/figures/chains/ (PNG and PDF).
#
#   bash experiments/chains/run_chains.sh [BUILD_DIR] [OUT_DIR]
#
# About 5 s after the build. The benchmark behind the README's long-chain table is separate:
# build/release/tools/bench/bench_chain --impacts 400 --dense (about 4 minutes).
source "$(dirname "$0")/../../tools/experiments/preamble.sh" run_chains docs/figures/chains "$@"
"$vibro" run experiments/chains/chain_1000_sticking.yaml -o "$d/chain_1000_sticking.h5" --force
$py tools/figures/chain_sticking.py "$d/chain_1000_sticking.h5" "$out"
