# The common start of every experiment's run script, sourced (not run):
#
#   source "$(dirname "$0")/../../tools/experiments/preamble.sh" NAME DEFAULT_OUT "$@"
#
# Moves to the repository's root and sets
#   build  the build directory (first argument of the run script; default build/release),
#   out    the output directory (second argument; default DEFAULT_OUT),
#   d      "$out/data", created, where result files go (git ignores it),
#   vibro  the CLI of that build (the script stops with exit 2 and a one-line message if it is
#          not built), py the Python interpreter figure scripts run with, VIBRO_BUILD (exported)
#          where they find that build's Python module (tools/figures/common.py: vibro_module);
# prints the machine's load (the times the scripts print are read beside it) and defines
#   quiet  a filter for a run's output that drops the progress lines ("vibro: …" and continuation's
#          "  branch k=…"); errors ("error: …") and summaries pass.
# The run script's own arguments are untouched (a sourced file's shifts do not reach its caller).
set -euo pipefail
experiment_name=$1
experiment_default_out=$2
shift 2
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=${1:-build/release}
out=${2:-$experiment_default_out}
vibro="$build/tools/vibro/vibro"
py=/usr/bin/python3
export VIBRO_BUILD="$build"
[ -x "$vibro" ] || {
  echo "$experiment_name: $vibro not found: build first (cmake --preset release && cmake --build --preset release)" >&2
  exit 2
}
d="$out/data"
mkdir -p "$d"
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg), nproc $(nproc)"
quiet() { grep -v -e '^  branch k=' -e '^vibro: ' || true; }
