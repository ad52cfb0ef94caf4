#!/bin/bash
# bench/compare_rotations.sh OLD_DIGEST NEW_DIGEST: two builds of bench's rotation_digest (e.g. one
# built at an earlier commit) over every capture of ../shared/captures and pcaps/, their
# mutations (bench/mutate_captures.py) and three cut azimuths. Prints the first difference and
# exits 1, or says how many lines matched.
set -euo pipefail
old=$1 new=$2
here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
captures=("$here"/pcaps/*.pcap)
[ -d "$here/../shared/captures" ] && captures=("$here"/../shared/captures/*.pcap "${captures[@]}")
/usr/bin/python3 "$here/bench/mutate_captures.py" "$work/mutated" "${captures[@]}"
for f in "${captures[@]}" "$work"/mutated/*.pcap; do
  for cut in 180 0 90; do
    echo "== $(basename "$f") cut $cut" | tee -a "$work/old" >> "$work/new"
    "$old" "$f" "$cut" >> "$work/old"
    "$new" "$f" "$cut" >> "$work/new"
  done
done
if ! diff -u "$work/old" "$work/new" | head -20; then
  echo "compare_rotations: the builds differ"
  exit 1
fi
echo "compare_rotations: identical: $(wc -l < "$work/new") lines, $(grep -c '^rotation' "$work/new") rotations of $(grep -c '^==' "$work/new") runs"
