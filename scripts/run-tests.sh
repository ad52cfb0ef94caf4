#!/usr/bin/env bash
# Quick start, tests: installs the Debian packages, configures, builds everything (Release, -O3)
# and runs every test (load runs and unprivileged runs of lidartagd among them); runs the Debian
# package under a real systemd in a container (skipped where containers cannot run); then the
# ThreadSanitizer build of the lock-free scan buffer, the AddressSanitizer +
# UndefinedBehaviorSanitizer build of the driver, detector and daemon-setup tests, and the
# libFuzzer targets (clang, ASan + UBSan) over their corpora and for a few seconds each.
# Usage: scripts/run-tests.sh [--no-sanitizers]   (the flag skips the sanitizer and fuzz builds)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)

# Warnings are errors here (LIDARTAG_WERROR; off by default so that users' builds never break on
# a compiler's new warning). The tests run on the Release build (-O3): what users and the Debian
# package get, and where GCC 12 warns most (-Wrestrict and -Warray-bounds false positives that
# -O2 does not show). The project has no assert(): NDEBUG changes no check. The TSan and fuzz
# builds below are RelWithDebInfo (-O2 -g; the ASan build -O1 -g1). Installed under /usr: the
# build the Debian package comes from.
echo "== Release build (-O3, warnings as errors) and every test =="
cmake -S . -B build-release -G Ninja -DCMAKE_BUILD_TYPE=Release -DLIDARTAG_WERROR=ON \
  -DCMAKE_INSTALL_PREFIX=/usr
cmake --build build-release -j "$jobs"
ctest --test-dir build-release --output-on-failure -j "$jobs"

# The package in a booted Debian 12 container, systemd as PID 1 (skipped, exit status 77, where
# containers cannot run: not root, no mmdebstrap or systemd-nspawn).
echo "== lidartagd.service under systemd (container) =="
status=0
scripts/systemd-container-test.sh build-release || status=$?
[ "$status" -eq 0 ] || [ "$status" -eq 77 ] || exit "$status"

if [ "${1:-}" != "--no-sanitizers" ]; then
  # Only some targets are built here, so their binaries run directly (ctest would list the rest
  # as not built).
  echo "== ThreadSanitizer: scan buffer =="
  cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLIDARTAG_SANITIZE=thread \
    -DLIDARTAG_BUILD_BENCHMARKS=OFF
  cmake --build build-tsan -j "$jobs" --target test_scan_buffer
  TSAN_OPTIONS="halt_on_error=1" timeout 600 build-tsan/bin/test_scan_buffer

  echo "== AddressSanitizer + UndefinedBehaviorSanitizer: driver, I/O, simulator, detector, daemon setup, tool =="
  # -O1 -g1 (line tables): what ASan's docs advise, and half the compile time of -O2 -g (the
  # largest build of this script).
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLIDARTAG_SANITIZE=address \
    -DLIDARTAG_BUILD_BENCHMARKS=OFF -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG"
  targets="test_driver_core test_driver_captures test_scan_buffer test_pcap_writer test_pcap_source
    test_udp_source test_live_source test_calibration_file test_pcd test_capture_reader test_sim
    test_capture_mutation test_ouster test_ouster_reader test_open_reader test_cli_ouster test_bag
    test_sim_ouster"
  # MCAP out: the writer, read back with the project's reader (issue 34).
  targets="$targets test_mcap_writer"
  # Other drivers' PointCloud2 layouts through the bag cloud reader, and as PCD files (issue 34).
  targets="$targets test_vendor_clouds test_vendor_pcds"
  # The daemon's configuration parsing, LCM URL/log/bus, recorder and setup checks.
  # (test_daemon_odometry runs the detection flow graph: as test_daemon_pipeline, it is left out,
  # TBB's graph_task destroys its task through a base pointer that UBSan's vptr check rejects.)
  targets="$targets test_daemon_config test_daemon_setup test_ego_motion_input"
  # The lidartag tool's drawing (tag, render), run as a user would (they build the tool).
  targets="$targets test_cli_tag test_cli_render"
  # Calibration: intrinsics files and the result's forms (issue 30).
  targets="$targets test_intrinsics_file test_calibration_report"
  # Camera images: corrupt and truncated PNG/JPEG files, the AprilTag wrapper's C memory.
  targets="$targets test_image_io test_image_tags"
  # The detector's unit tests, one target per stage (*_test).
  targets="$targets $(cmake --build build-asan --target help | sed -n 's/^\([a-z_]*_test\):.*/\1/p' | sort -u | tr '\n' ' ')"
  cmake --build build-asan -j "$jobs" --target $targets
  for t in $targets; do
    echo "-- $t"
    ASAN_OPTIONS="detect_leaks=1" UBSAN_OPTIONS="print_stacktrace=1" \
      LSAN_OPTIONS="suppressions=$PWD/test/tools/lsan.supp" timeout 900 "build-asan/bin/$t"
  done

  echo "== libFuzzer targets (clang-14, ASan + UBSan): every corpus once, every target 5 s, seeds current =="
  cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER=clang++-14 -DLIDARTAG_FUZZ=ON
  cmake --build build-fuzz -j "$jobs"
  # Windows of the real captures as extra seeds (never committed).
  rm -rf build-fuzz/shared-seeds
  if [ -d ../shared/captures ]; then
    build-fuzz/bin/fuzz_make_seeds shared ../shared/captures build-fuzz/shared-seeds
  fi
  ctest --test-dir build-fuzz --output-on-failure -j "$jobs"
fi
