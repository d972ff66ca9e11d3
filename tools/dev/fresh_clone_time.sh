#!/usr/bin/env bash
# Times the README's two set-up commands, each in its own fresh clone of this repository's HEAD
# (no build folder, no compiler cache): the numbers the README's first screen quotes.
#
#   bash tools/dev/fresh_clone_time.sh          # both commands, one after the other
#   bash tools/dev/fresh_clone_time.sh main     # the main job's command only
#   bash tools/dev/fresh_clone_time.sh tests    # the test command only
#
# The commands are read from the README's first two ```sh blocks, so what is timed is what a
# newcomer types. Run it on an otherwise idle machine: a build shares the cores with anything else.
set -euo pipefail
here="$(cd "$(dirname "$0")/../.." && pwd)"
which="${1:-both}"

# The n-th (1-based) ```sh block's command line (its lines that are not comments).
command_of() {
  awk -v want="$1" '
    /^```sh/ { block++; inside = (block == want); next }
    /^```/   { inside = 0; next }
    inside && !/^#/ && NF { print }' "$here/README.md"
}

run() {
  local label="$1" cmd="$2" dir
  dir="$(mktemp -d /tmp/vibro-fresh-XXXXXX)"
  git clone -q "$here" "$dir/clone"
  echo "== $label: $cmd"
  local start end
  start=$(date +%s.%N)
  (cd "$dir/clone" && bash -c "$cmd") > "$dir/log.txt" 2>&1 || { echo "failed: see $dir/log.txt"; exit 1; }
  end=$(date +%s.%N)
  awk -v s="$start" -v e="$end" -v l="$label" 'BEGIN { printf "%s: %.1f s (%.1f min)\n", l, e - s, (e - s) / 60 }'
  grep -E "tests passed|Total Test time" "$dir/log.txt" || true
  rm -rf "$dir"
}

[[ "$which" == both || "$which" == main ]] && run "main job" "$(command_of 1)"
[[ "$which" == both || "$which" == tests ]] && run "tests" "$(command_of 2)"
exit 0
