#!/bin/sh
# ctest fuzz_seeds_current: the committed seeds (test/fuzz/corpus/) and generated dictionaries
# (fuzz/dict/) are what fuzz_make_seeds writes from today's sources, so a format or config key
# added since cannot leave the fuzzers on stale seeds. Besides the generated files a corpus
# directory may hold only inputs that found a defect (regression_*) and what a campaign's
# `scripts/fuzz.sh --merge` added (merged/): a fuzzer run that was given a committed directory
# first writes its new inputs there, and this test is what catches them.
#   check_seeds.sh MAKE_SEEDS CORPUS_DIR DICT_DIR SCRATCH
set -eu
make_seeds=$1 corpus=$2 dict=$3 scratch=$4
rm -rf "$scratch" && mkdir -p "$scratch/corpus" "$scratch/dict"
"$make_seeds" committed "$scratch/corpus" "$scratch/dict"
fix="run build-fuzz/bin/fuzz_make_seeds committed test/fuzz/corpus fuzz/dict and remove inputs"
fix="$fix no one meant to commit (git status test/fuzz/corpus)"
if ! diff -r -x 'regression_*' -x merged "$scratch/corpus" "$corpus" >"$scratch/corpus.diff"; then
  head -n 40 "$scratch/corpus.diff"
  echo "FAIL: test/fuzz/corpus is not what fuzz_make_seeds writes; $fix" >&2
  exit 1
fi
status=0
for f in "$scratch"/dict/*; do
  if ! cmp -s "$f" "$dict/${f##*/}"; then
    diff "$f" "$dict/${f##*/}" | head -n 20 || true
    echo "FAIL: fuzz/dict/${f##*/} is not what fuzz_make_seeds writes; $fix" >&2
    status=1
  fi
done
[ $status -eq 0 ] && echo "seeds and generated dictionaries are current: $(find "$corpus" -type f |
  wc -l) inputs in $(ls "$corpus" | wc -l) corpora"
exit $status
