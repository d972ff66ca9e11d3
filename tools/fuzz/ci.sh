#!/usr/bin/env bash
# CI's reliability step (issue 15; .ci/run runs it after the README's test command): the sanitize
# preset (clang -O1, ASan + UBSan, every report fatal; docs/fuzzing.md) builds everything, the
# whole test suite runs on that build (`ctest --preset sanitize`: the Catch2 suites, the `vibro`
# command's hostile-user cases of tests/io/test_cli.sh, with the exclusions the preset names and
# docs/fuzzing.md explains), then each fuzz target runs FUZZ_SECONDS (default 60) from the seed
# corpus. Any build error, failed test, sanitizer report or fuzzer finding ends it with a
# non-zero status and the report on stderr. Each stage prints its time, so CI's log shows where
# the step's time goes (docs/fuzzing.md, "In CI").
set -euo pipefail
cd "$(dirname "$0")/../.."
fuzz_seconds=${FUZZ_SECONDS:-60}
start=$(date +%s)
cmake --preset sanitize > /dev/null
cmake --build --preset sanitize
echo "reliability: sanitize build $(( $(date +%s) - start )) s" >&2
ctest --preset sanitize
echo "reliability: build and test suite under ASan + UBSan $(( $(date +%s) - start )) s" >&2
bash tools/fuzz/run.sh "$fuzz_seconds"
echo "reliability: done in $(( $(date +%s) - start )) s" >&2
