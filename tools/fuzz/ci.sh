#!/usr/bin/env bash
# CI's reliability step (issue 15; .ci/run runs it after the README's test command). Within the
# few minutes CI can add (docs/fuzzing.md, "In CI"): the sanitize preset (clang -O1, ASan +
# UBSan, every report fatal) builds the `vibro` command and the two libFuzzer targets; the
# command's hostile-user tests (tests/io/test_cli.sh: exit codes, signals, full disk, concurrent
# writers, memory limits) run on that build; then each fuzz target runs FUZZ_SECONDS (default 30)
# from the seed corpus. Any build error, failed test, sanitizer report or fuzzer finding ends it
# with a non-zero status and the report on stderr. The whole sanitizer test suite is
# `cmake --build --preset sanitize && ctest --preset sanitize` (not run here: ~15 more minutes).
set -euo pipefail
cd "$(dirname "$0")/../.."
fuzz_seconds=${FUZZ_SECONDS:-30}
start=$(date +%s)
cmake --preset sanitize > /dev/null
cmake --build --preset sanitize --target vibro fuzz_scene fuzz_run
echo "reliability: sanitize build $(( $(date +%s) - start )) s" >&2
ctest --preset sanitize -R '^io: vibro command'
echo "reliability: build and command tests under ASan + UBSan $(( $(date +%s) - start )) s" >&2
bash tools/fuzz/run.sh "$fuzz_seconds"
echo "reliability: done in $(( $(date +%s) - start )) s" >&2
