#!/usr/bin/env bash
# Long fuzzing campaign: every libFuzzer target (fuzz/, ASan + UBSan) for SECONDS each (default
# 600), or until --runs executions, JOBS targets at a time (default: one per core), at nice 19.
# Each target starts from its committed corpus (test/fuzz/corpus/<target>/), windows of the real
# captures in ../shared/captures when present, and what earlier campaigns found
# (build-fuzz/campaign/<target>/corpus/); crashing inputs are written beside that corpus.
# Prints a Markdown table (executions, exec/s, coverage, features, corpus, crashes) to paste into
# docs/robustness.md, and writes it to build-fuzz/campaign/summary.md; coverage (edges reached),
# features and corpus come from one pass over the target's final corpus and seeds (-runs=0).
#
# Usage: scripts/fuzz.sh [SECONDS] [--runs N] [--chunk N | --fork N] [--jobs J] [--targets "a b ..."]
#                        [--resume] [--merge]
#   --chunk   runs each target as a series of fuzzer processes of at most N executions, each
#             starting from the corpus the one before it left, until --runs or SECONDS. ASan's
#             allocator grows a long-lived process: fuzz_scene went from 3,000 exec/s and 170 MB
#             to a few hundred per second and 1 GB within 0.5-1 million inputs (docs/robustness.md);
#             a new process starts small again. Chunks of 1,000,000 were too long for scene.
#   --fork    runs each target on N cores in libFuzzer's fork mode: short fuzzing jobs, each a
#             fresh process (so ASan's growth stays bounded, as with --chunk), N at a time, their
#             findings merged into one corpus; a crash, leak, timeout or out-of-memory stops it.
#             --jobs then defaults to the number of cores divided by N (at least 1).
#   --resume  continues each target's last campaign (build-fuzz/campaign/<target>/): its executions
#             and time count towards --runs and the table, its log is kept and appended to. A
#             campaign too long for one sitting (the YAML targets run a few hundred inputs per
#             second) is run as several, like --chunk's processes with a gap between them.
#   --merge   minimises the campaign's new inputs into the committed corpus, in its merged/
#             subdirectory (the rest is what fuzz_make_seeds writes, checked by the ctest
#             fuzz_seeds_current); review the diff: inputs cut from ../shared/captures must not be
#             committed, and the merge skips them by taking only the campaign's own corpus directory.
# A timeout (10 s of wall-clock time) whose input then runs within the limit alone, at normal
# priority, was starvation by other work on the machine, not a slow input: it is kept as
# starved-<name> beside the corpus, listed at the end, and the campaign goes on.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=600 runs="" chunk="" fork="" jobs="" targets="" targets_given="" merge=0 resume=0
while (($#)); do
  case $1 in
    --runs) runs=$2; shift 2 ;;
    --chunk) chunk=$2; shift 2 ;;
    --fork) fork=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --targets) targets=$2 targets_given=1; shift 2 ;;
    --merge) merge=1; shift ;;
    --resume) resume=1; shift ;;
    [0-9]*) seconds=$1; shift ;;
    *) echo "usage: scripts/fuzz.sh [SECONDS] [--runs N] [--chunk N | --fork N] [--jobs J] [--targets LIST] [--resume] [--merge]" >&2
       exit 2 ;;
  esac
done
if [ -n "$fork" ]; then
  if [ -n "$chunk" ] || ! [[ $fork =~ ^[1-9][0-9]*$ ]]; then
    echo "scripts/fuzz.sh: --fork takes a number of cores and does not go with --chunk" >&2
    exit 2
  fi
  [ -n "$jobs" ] || jobs=$(( $(nproc) / fork > 0 ? $(nproc) / fork : 1 ))
fi
[ -n "$jobs" ] || jobs=$(nproc)
build=build-fuzz
cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++-14 \
  -DLIDARTAG_FUZZ=ON >/dev/null
cmake --build $build -j "$(nproc)" >/dev/null
[ -n "$targets" ] || targets=$(cut -d' ' -f1 $build/fuzz-targets.txt)
if [ -d ../shared/captures ]; then
  rm -rf $build/shared-seeds
  $build/bin/fuzz_make_seeds shared ../shared/captures $build/shared-seeds
fi
campaign=$build/campaign
mkdir -p $campaign

run_one() {
  local t=$1 dir=$campaign/$1
  local dict corpus
  dict=$(awk -v t="$t" '$1 == t {print $2}' $build/fuzz-targets.txt)
  corpus=$(awk -v t="$t" '$1 == t {print $3}' $build/fuzz-targets.txt)
  mkdir -p "$dir/corpus"
  rm -f "$dir"/crash-* "$dir"/leak-* "$dir"/timeout-* "$dir"/oom-* "$dir"/starved-*
  local args=(-timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$dir/")
  [ -n "$fork" ] && args+=(-fork="$fork" -ignore_crashes=0 -ignore_timeouts=0 -ignore_ooms=0)
  [ -n "$dict" ] && [ "$dict" != - ] && args+=(-dict="$dict")
  local extra=()
  [ -d "$build/shared-seeds/$corpus" ] && extra+=("$build/shared-seeds/$corpus")
  # One process, or (--chunk) a series of them, each for what is left of the runs and the time.
  local begin=$SECONDS done_runs=0 before_runs=0 before_time=0 n left
  if ((resume)) && [ -f "$dir/total" ]; then
    read -r before_runs before_time < "$dir/total"
    done_runs=$before_runs
    echo "fuzz.sh: resuming after $before_runs executions in $before_time s" >> "$dir/log.txt"
  else
    : > "$dir/log.txt"
  fi
  while :; do
    local limits=(-max_total_time=$((seconds - (SECONDS - begin))))
    if [ -n "$runs" ]; then
      left=$((runs - done_runs))
      ((left > 0)) || break
      n=$left
      [ -n "$chunk" ] && ((chunk < left)) && n=$chunk
      limits+=(-runs="$n")
    fi
    local mark
    mark=$(wc -l < "$dir/log.txt")
    # malloc_context_size=0: no allocation stack recorded per malloc (a third more inputs per
    # second on the YAML targets); a finding's report then lacks where its memory was allocated,
    # which replaying the input with the printed command gives.
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:malloc_context_size=0 \
      UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      nice -n 19 "$build/bin/fuzz_$t" "${args[@]}" "${limits[@]}" "$dir/corpus" \
      "test/fuzz/corpus/$corpus" "${extra[@]}" >> "$dir/log.txt" 2>&1 || true
    # This process's count only (one that died without final stats adds nothing). Fork mode's
    # parent prints no final stats: its count is that of its last progress line ("#N: cov: ...").
    if [ -n "$fork" ]; then
      n=$(tail -n +$((mark + 1)) "$dir/log.txt" | sed -n 's/^#\([0-9]*\): cov: .*/\1/p' | tail -1)
    else
      n=$(tail -n +$((mark + 1)) "$dir/log.txt" | sed -n 's/^stat::number_of_executed_units: *//p')
    fi
    done_runs=$((done_runs + ${n:-0}))
    echo "$done_runs $((before_time + SECONDS - begin))" > "$dir/total"
    # libFuzzer's -timeout is wall-clock time: a process at nice 19 starved by other work (a build,
    # the test command) stops on an input that is not slow. A timeout input that runs within the
    # limit alone, at normal priority, is set aside as starved-* and the campaign goes on.
    local starved=0
    for a in "$dir"/timeout-*; do
      [ -e "$a" ] || continue
      if ASAN_OPTIONS=detect_leaks=1 "$build/bin/fuzz_$t" -timeout=10 "$a" >/dev/null 2>&1; then
        mv "$a" "$dir/starved-${a##*/}"
        echo "fuzz.sh: ${a##*/} ran within -timeout=10 alone: starved, not slow; continuing" \
          >> "$dir/log.txt"
        starved=1
      fi
    done
    ls "$dir" | grep -qE '^(crash|leak|timeout|oom)-' && break
    [ -n "$chunk" ] || ((starved)) || break
    ((SECONDS - begin < seconds)) || break
  done
  echo "$done_runs $((before_time + SECONDS - begin))" > "$dir/total"
  # The table's coverage: one pass over the campaign's corpus and its seeds (-runs=0), whose
  # "INITED cov:" counts the code's edges reached. Fork mode's own "cov:" is no such count: it
  # starts equal to the seeds' features ("cov: 1584 ft: 1584" for calibration's 14 seeds), so it
  # depends on the start (calibration resumed on a grown corpus reported more than its 4,653 edges).
  ASAN_OPTIONS=detect_leaks=0:malloc_context_size=0 nice -n 19 "$build/bin/fuzz_$t" -runs=0 \
    "$dir/corpus" "test/fuzz/corpus/$corpus" "${extra[@]}" > "$dir/coverage.txt" 2>&1 || true
}
export -f run_one
export build campaign seconds runs chunk fork resume

start=$(date +%s)
echo "fuzzing $(echo $targets | wc -w) targets, ${runs:+$runs runs or }$seconds s each, $jobs at a time${fork:+, each on $fork cores}"
printf '%s\n' $targets | xargs -P "$jobs" -I{} bash -c 'run_one {}'

summary=$campaign/summary.md
{
  echo "| target | executions | exec/s | coverage | features | corpus | crashes |"
  echo "|---|---:|---:|---:|---:|---:|---:|"
  for t in $targets; do
    log=$campaign/$t/log.txt
    # Executions over every process of the target, and their rate over its wall-clock time.
    read -r execs took < "$campaign/$t/total" || true
    rate=$( ((${took:-0} > 0)) && echo $((execs / took)) || echo "?")
    last=$(grep -E '^#[0-9]+' "$log" | tail -1)
    # The corpus pass's figures when there is one (see run_one), else the last progress line's.
    inited=$(grep -m1 'INITED cov:' "$campaign/$t/coverage.txt" 2>/dev/null || true)
    [ -n "$inited" ] && last=$inited
    cov=$(echo "$last" | sed -n 's/.* cov: \([0-9]*\).*/\1/p')
    ft=$(echo "$last" | sed -n 's/.* ft: \([0-9]*\).*/\1/p')
    corp=$(echo "$last" | sed -n 's/.* corp: \([0-9]*\).*/\1/p')
    crashes=$(ls "$campaign/$t" | grep -cE '^(crash|leak|timeout|oom)-' || true)
    printf '| %s | %s | %s | %s | %s | %s | %s |\n' "$t" "${execs:-?}" "${rate:-?}" "${cov:-?}" \
      "${ft:-?}" "${corp:-?}" "$crashes"
  done
} > $summary
cat $summary
echo
echo "$(($(date +%s) - start)) s; machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "command: scripts/fuzz.sh $seconds${runs:+ --runs $runs}${chunk:+ --chunk $chunk}${fork:+ --fork $fork} --jobs $jobs${targets_given:+ --targets \"$targets\"}$( ((resume)) && echo " --resume")"
for t in $targets; do
  for a in "$campaign/$t"/starved-*; do
    [ -e "$a" ] && echo "starved (ran within the limit alone; not counted): $a"
  done
done
failed=0
for t in $targets; do
  for a in "$campaign/$t"/crash-* "$campaign/$t"/leak-* "$campaign/$t"/timeout-* "$campaign/$t"/oom-*; do
    [ -e "$a" ] || continue
    echo "FOUND: $a (reproduce: $build/bin/fuzz_$t $a)"
    failed=1
  done
done
if ((merge)); then
  added=0
  for t in $targets; do
    corpus=$(awk -v t="$t" '$1 == t {print $3}' $build/fuzz-targets.txt)
    # libFuzzer merges into its first directory, whose inputs (read recursively) are what the
    # campaign's must add to; a copy of the committed corpus takes them, and what is new goes
    # to merged/.
    dest=test/fuzz/corpus/$corpus tmp=$(mktemp -d)
    cp -r "$dest/." "$tmp/"
    "$build/bin/fuzz_$t" -merge=1 "$tmp" "$campaign/$t/corpus" \
      > "$campaign/$t/merge.txt" 2>&1 || echo "merge of $t failed: $campaign/$t/merge.txt"
    mkdir -p "$dest/merged"
    for f in "$tmp"/*; do
      if [ -f "$f" ] && [ ! -e "$dest/${f##*/}" ]; then
        mv "$f" "$dest/merged/"
        added=$((added + 1))
      fi
    done
    rmdir "$dest/merged" 2>/dev/null || true
    rm -rf "$tmp"
  done
  echo "merged into test/fuzz/corpus/<corpus>/merged/: $added new files"
fi
exit $failed
