#!/usr/bin/env bash
# lidartagd under a real systemd: boots a minimal Debian 12 container with systemd as PID 1
# (mmdebstrap + systemd-nspawn, private network: only its own lo), installs the project's .deb
# and checks lidartagd.service as shipped: Type=notify reaches active, STATUS= lines show, UDP
# reception and LCM multicast work under DynamicUser and the unit's hardening, the watchdog
# restarts a stalled daemon (SIGSTOP), journald shows the log levels; then the capture drop-in
# (config/lidartagd-capture.conf): interface capture fails without it and works with it.
#
# Usage: scripts/systemd-container-test.sh [BUILD_DIR]   (default build-release)
#   BUILD_DIR: configured with -DCMAKE_INSTALL_PREFIX=/usr and built (lidartagd, lidartag,
#   bench_load); the .deb is made there with cpack. The root file system (debootstrapped from the
#   configured apt mirror) is cached as BUILD_DIR/systemd-test/rootfs-<hash>.tar.
# Exit status: 0 all checks passed, 1 a check failed, 77 skipped (not root, no mmdebstrap or
# systemd-nspawn, or containers cannot boot here), with the reason on standard output.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-release}
work=$build/systemd-test
skip() {
  echo "skipped: $*"
  exit 77
}
[ "$(id -u)" -eq 0 ] || skip "needs root (mmdebstrap and systemd-nspawn)"
command -v mmdebstrap >/dev/null || skip "no mmdebstrap (apt-get install mmdebstrap)"
command -v systemd-nspawn >/dev/null || skip "no systemd-nspawn (apt-get install systemd-container)"
for f in bin/lidartagd bin/bench_load; do
  [ -x "$build/$f" ] || { echo "no $build/$f: build $build first" >&2; exit 1; }
done
grep -q '^CMAKE_INSTALL_PREFIX:PATH=/usr$' "$build/CMakeCache.txt" ||
  { echo "$build is not configured with -DCMAKE_INSTALL_PREFIX=/usr" >&2; exit 1; }
start=$(date +%s)

# ---- The package and what it depends on. ----
rm -f "$build"/lidartag_*.deb
(cd "$build" && cpack -G DEB >/dev/null 2>&1) || { echo "cpack failed" >&2; exit 1; }
deb=$(ls "$build"/lidartag_*.deb)
# Depends: "a (>= 1), b | c, d": the first of each alternative, without versions.
deps=$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed 's/|.*//; s/(.*)//; s/ //g' | paste -sd, -)
include="systemd,systemd-sysv,dbus,iproute2,procps,liblcm-bin,$deps"
mkdir -p "$work"
rootfs=$work/rootfs-$(echo "$include" | sha256sum | cut -c1-12).tar
if [ ! -f "$rootfs" ]; then
  echo "== mmdebstrap bookworm (cached as $rootfs)"
  mmdebstrap --quiet --format=tar --variant=minbase --include="$include" bookworm "$rootfs.part"
  mv "$rootfs.part" "$rootfs"
fi
root=$work/root
rm -rf "$root"
mkdir -p "$root"
tar -C "$root" -xf "$rootfs"
nspawn() { systemd-nspawn --quiet -D "$root" --register=no --keep-unit "$@"; }

# ---- Install: the .deb, the demo capture, the sender, the checks. ----
cp "$deb" "$root/var/cache/lidartag.deb"
nspawn --pipe -- dpkg -i /var/cache/lidartag.deb >/dev/null 2>&1 ||
  { echo "dpkg -i failed:"; nspawn --pipe -- dpkg -i /var/cache/lidartag.deb; exit 1; }
install -D -m 0644 pcaps/demo.pcap "$root/usr/share/lidartag-test/demo.pcap"
install -D -m 0755 "$build/bin/bench_load" "$root/usr/local/bin/bench_load"
install -D -m 0644 config/lidartagd-capture.conf "$root/usr/share/lidartag-test/capture.conf"
# The test configuration replaces the shipped one: a looping replay (heartbeat and detections on
# LCM multicast) and a UDP sensor on 127.0.0.1, status twice a second, debug level (the status
# lines at debug priority).
cat > "$root/etc/lidartag/lidartagd.yaml" <<'EOF'
sensors:
  - name: replay
    channel_prefix: REPLAY_
    model: vlp32c
    source: {kind: pcap, file: /usr/share/lidartag-test/demo.pcap, rate: 1, loop: true}
  - name: udp
    channel_prefix: UDP_
    source: {kind: udp, bind_address: 127.0.0.1, data_port: 2368, position_port: 8308}
lcm:
  url: ""
status:
  period_s: 0.5
logging:
  level: debug
detector:
  tag_sizes_m: [0.8, 0.6]
  families: [tag16h5]
EOF
# Multicast needs a route: on lo, before lidartagd starts.
cat > "$root/etc/systemd/system/multicast-route.service" <<'EOF'
[Unit]
Description=multicast route on lo (test)
Before=lidartagd.service
[Service]
Type=oneshot
RemainAfterExit=yes
ExecStart=/usr/sbin/ip link set lo up
ExecStart=/usr/sbin/ip route replace 224.0.0.0/4 dev lo
[Install]
WantedBy=multi-user.target
EOF
cat > "$root/etc/systemd/system/lidartag-check.service" <<'EOF'
[Unit]
Description=lidartagd checks (test)
After=multi-user.target multicast-route.service
Requires=multicast-route.service
[Service]
Type=oneshot
ExecStart=/usr/local/bin/lidartag-check
ExecStopPost=/usr/bin/systemctl --no-block poweroff
StandardOutput=journal+console
[Install]
WantedBy=multi-user.target
EOF
cat > "$root/usr/local/bin/lidartag-check" <<'EOF'
#!/bin/bash
# Runs inside the container; results into /var/lib/lidartag-check/result (PASS/FAIL lines).
out=/var/lib/lidartag-check
mkdir -p $out
exec > $out/result 2>&1
pass() { echo "PASS $*"; }
fail() { echo "FAIL $*"; }
prop() { systemctl show -p "$1" --value lidartagd; }
waitfor() {  # waitfor SECONDS COMMAND...: until the command succeeds
  local n=$(($1 * 10)); shift
  for ((i = 0; i < n; i++)); do "$@" && return 0; sleep 0.1; done
  return 1
}
count() { grep -a -o "$2" "$1" 2>/dev/null | wc -l; }

# 1. Type=notify: start returns once READY=1 was sent; active.
lcm-logger -f --flush-interval=100 $out/multicast.lcmlog > $out/logger.txt 2>&1 &
logger=$!
sleep 0.5
if systemctl start lidartagd; then pass "systemctl start returned (READY=1)"; else fail "start"; fi
[ "$(prop ActiveState)" = active ] && [ "$(prop SubState)" = running ] &&
  pass "active (running), Type=$(prop Type)" || fail "state $(prop ActiveState)/$(prop SubState)"
pid=$(prop MainPID)
# 2. DynamicUser: an unprivileged user of the dynamic range, no capabilities.
uid=$(awk '/^Uid:/ {print $2}' /proc/$pid/status)
caps=$(awk '/^CapEff:/ {print $2}' /proc/$pid/status)
user=$(ps -o user= -p $pid)
[ "$uid" -ge 61184 ] && [ "$uid" -le 65519 ] && [ "$caps" = 0000000000000000 ] &&
  pass "runs as dynamic user $user (uid $uid), CapEff $caps" ||
  fail "uid $uid user $user CapEff $caps"
# 3. STATUS= lines: systemd shows the daemon's status text, refreshed.
sleep 1.5
s1=$(prop StatusText)
sleep 1.5
s2=$(prop StatusText)
[ -n "$s1" ] && [ "$s1" != "$s2" ] && pass "STATUS: $s2" || fail "StatusText '$s1' then '$s2'"
# 4. UDP reception under the hardening: the demo sent to 127.0.0.1:2368 gives detections on the
#    UDP sensor's multicast channel.
/usr/local/bin/bench_load send --capture /usr/share/lidartag-test/demo.pcap --seconds 3 \
  > $out/sender.txt 2>&1 || fail "sender: $(cat $out/sender.txt)"
sleep 1.5
kill -INT $logger; wait $logger
udp=$(count $out/multicast.lcmlog UDP_LIDARTAG_DETECTIONS)
replay=$(count $out/multicast.lcmlog REPLAY_LIDARTAG_DETECTIONS)
status=$(count $out/multicast.lcmlog REPLAY_LIDARTAG_STATUS)
[ "$udp" -ge 20 ] && pass "UDP: $udp detection messages received over UDP, published on multicast" ||
  fail "UDP detections on multicast: $udp ($(cat $out/sender.txt))"
[ "$replay" -ge 20 ] && [ "$status" -ge 5 ] &&
  pass "LCM multicast: $replay replay detection and $status status messages (lcm-logger)" ||
  fail "multicast: $replay detection, $status status messages"
# 5. Log levels in the journal: info at priority 6, the periodic status at debug (7), no raw
#    "<N>" prefixes left in the messages.
journalctl -u lidartagd -p 6..6 -o cat | grep -q "running: 2 sensor(s)" &&
  pass "journal: 'running:' at priority info" || fail "no 'running:' at priority 6"
journalctl -u lidartagd -p 7..7 -o cat | grep -q "status:" &&
  pass "journal: status lines at priority debug" || fail "no 'status:' at priority 7"
if journalctl -u lidartagd -o cat | grep -q '^<[0-7]>'; then fail "raw <N> prefixes in messages"
else pass "journal: no raw <N> prefixes"; fi
# 6. The watchdog: SIGSTOP freezes the daemon; WatchdogSec=5s must kill it and Restart=on-failure
#    start a new one (READY again).
restarts=$(prop NRestarts)
kill -STOP $pid
t0=$(date +%s.%N)
if waitfor 40 bash -c "[ \"\$(systemctl show -p NRestarts --value lidartagd)\" -gt $restarts ] &&
                       [ \"\$(systemctl show -p ActiveState --value lidartagd)\" = active ] &&
                       [ \"\$(systemctl show -p SubState --value lidartagd)\" = running ]"; then
  t1=$(date +%s.%N)
  pass "watchdog: stalled daemon killed and restarted in $(awk "BEGIN {printf \"%.1f\", $t1 - $t0}") s (pid $pid -> $(prop MainPID))"
else
  fail "watchdog: no restart (NRestarts $(prop NRestarts), $(prop ActiveState)/$(prop SubState))"
fi
journalctl -u lidartagd -o cat | grep -q "Watchdog timeout" &&
  pass "journal: $(journalctl -u lidartagd -o cat | grep -m1 'Watchdog timeout')" ||
  fail "no 'Watchdog timeout' in the journal"
# 7. Interface capture: without the drop-in the unit has no CAP_NET_RAW and no AF_PACKET: it fails
#    to start; with config/lidartagd-capture.conf it captures the demo on lo.
systemctl stop lidartagd
sed -i 's/^    source: {kind: udp, bind_address: 127.0.0.1,/    source: {kind: interface, interface: lo,/' \
  /etc/lidartag/lidartagd.yaml
systemctl reset-failed lidartagd 2>/dev/null
if systemctl start lidartagd 2>/dev/null; then fail "capture started without the drop-in"
else
  journalctl -u lidartagd -o cat | grep -q "cannot capture on 'lo'" &&
    pass "capture without the drop-in refused: $(journalctl -u lidartagd -o cat | grep -m1 "cannot capture on 'lo'")" ||
    fail "capture refused without the reason in the journal"
fi
systemctl stop lidartagd 2>/dev/null; systemctl reset-failed lidartagd 2>/dev/null
mkdir -p /etc/systemd/system/lidartagd.service.d
cp /usr/share/lidartag-test/capture.conf /etc/systemd/system/lidartagd.service.d/capture.conf
systemctl daemon-reload
lcm-logger -f --flush-interval=100 $out/capture.lcmlog > /dev/null 2>&1 &
logger=$!
sleep 0.5
if systemctl start lidartagd; then
  pid=$(prop MainPID)
  caps=$(awk '/^CapEff:/ {print $2}' /proc/$pid/status)
  [ "$caps" = 0000000000002000 ] && pass "with the drop-in: CapEff $caps (CAP_NET_RAW only)" ||
    fail "with the drop-in: CapEff $caps"
  /usr/local/bin/bench_load send --capture /usr/share/lidartag-test/demo.pcap --seconds 3 \
    > $out/sender2.txt 2>&1
  sleep 1.5
  kill -INT $logger; wait $logger
  captured=$(count $out/capture.lcmlog UDP_LIDARTAG_DETECTIONS)
  [ "$captured" -ge 20 ] && pass "capture: $captured detection messages from packets captured on lo" ||
    fail "capture: $captured detection messages"
else
  fail "start with the capture drop-in: $(journalctl -u lidartagd -o cat | tail -3)"
  kill -INT $logger
fi
systemctl stop lidartagd
[ "$(prop Result)" = success ] && pass "stopped cleanly (Result=success)" || fail "stop: $(prop Result)"
journalctl -u lidartagd -o short-monotonic > $out/journal.txt
echo DONE
EOF
chmod 0755 "$root/usr/local/bin/lidartag-check"
nspawn --pipe -- systemctl enable multicast-route.service lidartag-check.service >/dev/null 2>&1
# The package enables nothing by itself; the checks start it.
nspawn --pipe -- systemctl disable lidartagd.service >/dev/null 2>&1 || true

# ---- Boot; the check unit powers the container off. ----
echo "== booting the container (systemd as PID 1, private network)"
set +e
timeout 300 systemd-nspawn --quiet -D "$root" --register=no --keep-unit --private-network \
  --boot > "$work/boot.log" 2>&1
boot=$?
set -e
result=$root/var/lib/lidartag-check/result
if [ ! -f "$result" ]; then
  if grep -q "Failed to\|not supported\|Operation not permitted" "$work/boot.log"; then
    skip "the container did not boot here (exit $boot): $(grep -m1 'Failed to\|not supported\|Operation not permitted' "$work/boot.log")"
  fi
  echo "no result (boot exit $boot); boot log:"
  tail -30 "$work/boot.log"
  exit 1
fi
cp "$root/var/lib/lidartag-check/journal.txt" "$work/journal.txt" 2>/dev/null || true
cat "$result"
echo "== $(grep -c '^PASS' "$result") passed, $(grep -c '^FAIL' "$result") failed," \
  "$(($(date +%s) - start)) s (journal: $work/journal.txt)"
grep -q '^DONE' "$result" && ! grep -q '^FAIL' "$result"
