#!/usr/bin/env bash
# Quick start, main job: installs the Debian packages, configures and builds, then replays the
# bundled demo capture (pcaps/demo.pcap: a simulated VLP-32C with two LiDARTags) through
# lidartagd. Each rotation's detections are printed; every LCM message goes to an LCM log file
# (/tmp/lidartag-demo.lcmlog, LCM's file:// provider), so no network is needed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo
cmake --build build -j "$(nproc)" --target lidartagd lidartag lidartag_lcmtypes_jar
build/bin/lidartagd --config config/demo.yaml --max-speed --print-detections "$@"
echo "LCM log: /tmp/lidartag-demo.lcmlog (lcm-logplayer, or build/bin/lidartag-spy to inspect)"
