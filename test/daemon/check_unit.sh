#!/bin/sh
# Checks config/lidartagd.service offline: `systemd-analyze verify` must print nothing (it exits 0
# on unknown keys and bad values, printing a warning), and `systemd-analyze security` must rate
# the exposure 3.0 or lower. Exit 77 (skipped) without systemd-analyze.
# Usage: check_unit.sh UNIT LIDARTAGD_BINARY
set -u
unit=$1
binary=$2
if ! command -v systemd-analyze >/dev/null 2>&1; then
  echo "systemd-analyze not installed: skipped"
  exit 77
fi
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
# verify checks that ExecStart exists: point it at the built binary and a real config file.
sed -e "s|/usr/bin/lidartagd|$binary|" -e "s|/etc/lidartag/lidartagd.yaml|$dir/lidartagd.yaml|" \
  "$unit" >"$dir/lidartagd.service"
: >"$dir/lidartagd.yaml"
out=$(cd "$dir" && systemd-analyze verify --man=no ./lidartagd.service 2>&1)
status=$?
if [ $status -ne 0 ] || [ -n "$out" ]; then
  echo "systemd-analyze verify (exit $status):"
  echo "$out"
  exit 1
fi
echo "systemd-analyze verify: clean"
security=$(cd "$dir" && systemd-analyze security --offline=true ./lidartagd.service 2>&1)
score=$(echo "$security" | sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\).*/\1/p')
echo "systemd-analyze security: exposure ${score:-?}"
if [ -z "$score" ]; then
  echo "$security"
  exit 1
fi
if ! awk -v s="$score" 'BEGIN { exit !(s <= 3.0) }'; then
  echo "$security"
  echo "exposure $score > 3.0"
  exit 1
fi
