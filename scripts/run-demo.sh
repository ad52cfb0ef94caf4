#!/usr/bin/env bash
# Quick start, main job: installs the Debian packages the demo needs (scripts/install-deps.sh
# --demo: compiler, CMake, Ninja and the libraries of lidartagd and lidartag; no test, benchmark,
# Python or Java packages), configures without the tests and benchmarks, builds lidartagd and
# lidartag, then replays the bundled demo capture (pcaps/demo.pcap: a simulated VLP-32C with two
# LiDARTags) through lidartagd. Each rotation's detections are printed; every LCM message goes to
# an LCM log file (/tmp/lidartag-demo.lcmlog, LCM's file:// provider), so no network is needed.
# Where a JDK 17 is installed (scripts/install-deps.sh without --demo), the LCM types jar and
# lidartag-spy's jar are built too.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh --demo
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLIDARTAG_BUILD_TESTS=OFF \
  -DLIDARTAG_BUILD_BENCHMARKS=OFF
targets=(lidartagd lidartag)
# The jar targets exist only where CMake found a JDK 17 and /usr/share/java/lcm.jar (daemon/).
# (grep reads all of the list: with -q it could stop early and fail the pipe.)
if cmake --build build --target help | grep '^lidartag_lcmtypes_jar:' >/dev/null; then
  targets+=(lidartag_lcmtypes_jar lidartag_spy_jar)
fi
cmake --build build -j "$(nproc)" --target "${targets[@]}"
build/bin/lidartagd --config config/demo.yaml --max-speed --print-detections "$@"
echo "LCM log: /tmp/lidartag-demo.lcmlog (lcm-logplayer; or build/bin/lidartag-spy, which needs"
echo "a display and the Java packages of scripts/install-deps.sh)"
