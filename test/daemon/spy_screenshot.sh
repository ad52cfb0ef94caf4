#!/bin/sh
# Screenshot of lidartag-spy (lcm-spy with lidartag's types) showing lidartagd's channels decoded,
# under Xvfb, inside a private network namespace (multicast on lo only).
# Usage: test/daemon/spy_screenshot.sh BUILD_DIR OUTPUT.png   (from the repository root)
# Needs: xvfb-run, imagemagick (import), unshare -n permission, pcaps/demo.pcap.
set -eu
build=$(cd "$1" && pwd)
out=$2
case "$out" in /*) ;; *) out=$(pwd)/$out ;; esac
export build out
exec unshare -n sh -c '
  ip link set lo up && ip route add 224.0.0.0/4 dev lo
  xvfb-run -a -s "-screen 0 1280x900x24" sh -c "
    \"$build/bin/lidartag-spy\" >/tmp/lidartag-spy.log 2>&1 &
    spy=\$!
    sleep 3
    \"$build/bin/lidartagd\" --config config/demo.yaml --lcm-url \"\" --rate 1 --loop \
      --log-level warn &
    daemon=\$!
    sleep 8
    import -window root \"$out\"
    kill \$daemon \$spy
    wait \$daemon || true
  "
'
