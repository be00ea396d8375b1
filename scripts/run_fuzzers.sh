#!/usr/bin/env bash
# Runs the libFuzzer targets of the `fuzz` preset (docs/testing.md), each for a bounded time, on
# a temporary copy of its seed corpus fuzz/corpus/<target>/ and the inputs of crashes fixed
# before, fuzz/regressions/<target>/ (the repository is not modified),
# with its dictionary. Fails on the first crash, sanitizer report or unexpected exception; the
# input that caused it is kept in build/fuzz/artifacts/.
#
#   bash scripts/run_fuzzers.sh [TARGET...]       # default: every target
#   FUZZ_SECONDS=60     time per target (default 60; 0 = no limit)
#   FUZZ_ARGS="..."     more libFuzzer options, e.g. "-runs=10000000"
# Needs `cmake --preset fuzz && cmake --build --preset fuzz` first.
set -euo pipefail
cd "$(dirname "$0")/.."
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_csv fuzz_rover_yaml fuzz_urdf)
seconds=${FUZZ_SECONDS:-60}
artifacts=$PWD/build/fuzz/artifacts
mkdir -p "$artifacts"
work=$(mktemp -d "${TMPDIR:-/tmp}/traverse-fuzz.XXXXXX")
trap 'rm -rf "$work"' EXIT
for t in "${targets[@]}"; do
  exe=build/fuzz/fuzz/$t
  [ -x "$exe" ] || { echo "run_fuzzers: $exe not built (cmake --build --preset fuzz)" >&2; exit 1; }
  cp -r "fuzz/corpus/$t" "$work/$t"
  # The inputs of crashes found and fixed (docs/results.md) are seeds too: they stay fixed.
  [ -d "fuzz/regressions/$t" ] && cp "fuzz/regressions/$t"/* "$work/$t/"
  echo "== $t: ${seconds}s on $(ls "$work/$t" | wc -l) seed files" >&2
  # shellcheck disable=SC2086
  "$exe" "$work/$t" -dict="fuzz/$t.dict" -max_total_time="$seconds" -timeout=30 \
    -print_final_stats=1 -artifact_prefix="$artifacts/$t-" ${FUZZ_ARGS:-} 2>"$work/$t.log" || {
    cp "$work/$t.log" "$artifacts/$t.log"
    grep -v "^INFO:\|^#[0-9]" "$work/$t.log" | head -n 80 >&2
    echo "run_fuzzers: $t failed; the input and the whole log are in $artifacts/" >&2
    exit 1
  }
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)|^Done" \
    "$work/$t.log" >&2
done
