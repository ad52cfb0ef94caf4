#!/bin/sh
# Runs one fuzz target for ctest.
#   run_fuzzer.sh corpus BIN CORPUS DICT          every committed input once
#   run_fuzzer.sh run BIN CORPUS DICT SECONDS SCRATCH [EXTRA_SEEDS]
#                                                 fuzz for SECONDS; new inputs go to SCRATCH (the
#                                                 committed corpus and EXTRA_SEEDS are only read)
# Fails on any crash, sanitizer report, leak, timeout (10 s per input) or out-of-memory (2 GB).
set -eu
mode=$1 bin=$2 corpus=$3 dict=$4 seconds=${5:-} scratch=${6:-} extra=${7:-}
[ -d "$corpus" ] || { echo "no corpus $corpus" >&2; exit 1; }
set -- -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
[ -n "$dict" ] && set -- "$@" -dict="$dict"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
case $mode in
  corpus)
    n=$(ls "$corpus" | wc -l)
    [ "$n" -gt 0 ] || { echo "empty corpus $corpus" >&2; exit 1; }
    echo "replaying $n inputs of $corpus"
    exec "$bin" "$@" -runs=0 "$corpus"
    ;;
  run)
    rm -rf "$scratch" && mkdir -p "$scratch"
    dirs="$corpus"
    [ -n "$extra" ] && [ -d "$extra" ] && dirs="$dirs $extra"
    # Artifacts (crashing inputs) beside the scratch corpus, named in the output.
    # shellcheck disable=SC2086
    exec "$bin" "$@" -max_total_time="$seconds" -artifact_prefix="$scratch/" "$scratch" $dirs
    ;;
  *) echo "usage: run_fuzzer.sh corpus|run ..." >&2; exit 2 ;;
esac
