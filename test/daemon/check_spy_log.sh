#!/bin/sh
# lidartag-spy --log: the demo's LCM log (every channel, written by lidartagd) replayed into lcm-spy
# under Xvfb: it ends by itself with exit status 0 and no Java stack trace, after the spy decoded
# every message of every channel. Skipped (77) without xvfb-run or java.
# Usage: check_spy_log.sh BUILD_DIR CONFIG CAPTURE
set -eu
build=$1
config=$2
capture=$3
command -v xvfb-run >/dev/null && command -v java >/dev/null || {
  echo "skipped: needs xvfb-run and java"
  exit 77
}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$build/bin/lidartagd" --config "$config" --replay "$capture" --max-speed --log-level warn \
  --lcm-url "file://$dir/demo.lcmlog?mode=w" --set lcm.publish_raw=true \
  --set lcm.publish_tag_points=true --set lcm.cloud_decimation=10
status=0
timeout 120 xvfb-run -a "$build/bin/lidartag-spy" --log "$dir/demo.lcmlog" --speed 0 \
  >"$dir/out" 2>"$dir/err" || status=$?
cat "$dir/out"
fail() {
  echo "FAIL: $1"
  echo "--- stderr:"
  cat "$dir/err"
  exit 1
}
[ $status -eq 0 ] || fail "exit status $status"
! grep -q -e Exception -e "^\s*at " "$dir/err" || fail "a Java stack trace"
line=$(grep "^lidartag-spy: end of log" "$dir/out") || fail "no end-of-log line"
replayed=$(echo "$line" | sed -n 's/.*: \([0-9]*\) events replayed, \([0-9]*\) received.*/\1 \2/p')
set -- $replayed
[ "${1:-0}" -gt 1500 ] && [ "$1" = "$2" ] || fail "replayed/received: $replayed"
for channel in LIDARTAG_DETECTIONS LIDARTAG_STATUS LIDARTAG_RAW LIDARTAG_TAG_POINTS LIDARTAG_CLOUD; do
  grep -q "^  $channel .* lidartag\.[a-z_]*_t  *0 errors$" "$dir/out" ||
    fail "$channel not decoded by the spy"
done
! grep -q undecodable "$dir/out" || fail "an undecodable channel"
# A log that is not there: one line, status 1.
status=0
timeout 60 xvfb-run -a "$build/bin/lidartag-spy" --log "$dir/missing.lcmlog" >/dev/null \
  2>"$dir/err" || status=$?
[ $status -eq 1 ] && grep -q "cannot read LCM log" "$dir/err" || fail "missing log: status $status"
echo "lidartag-spy --log: clean end of log"
