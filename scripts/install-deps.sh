#!/usr/bin/env bash
# Installs every Debian 12 package the project needs to build, test and run. Idempotent.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config git clang-format
  libeigen3-dev libnlopt-dev libnlopt-cxx-dev libtbb-dev libboost-dev libboost-system-dev
  libpcap-dev liblcm-dev liblcm-bin liblcm-java libglib2.0-dev libsystemd-dev
  libspdlog-dev libfmt-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
  # VeloView XML calibration files; PCD binary_compressed (LZF)
  libtinyxml2-dev liblzf-dev
  # camera-LiDAR calibration: PNG and JPEG images (libapriltag-dev: AprilTag 3 finds the tags in them)
  libpng-dev libjpeg-dev libapriltag-dev
  # ROS bags and MCAP (driver/bag): rosbag2 sqlite3 storage; bz2, lz4 and zstd chunks
  libsqlite3-dev libbz2-dev liblz4-dev libzstd-dev
  # MCAP chunk CRC-32 at memory speed (ISA-L's crc32_gzip_refl)
  libisal-dev
  # the Python module (for /usr/bin/python3) and its tests
  python3-dev pybind11-dev python3-numpy python3-pytest
  libgtest-dev libgmock-dev libbenchmark-dev
  iproute2 util-linux
  # lidartag tag/render: Cairo (PDF, SVG, PNG); the tests rasterise with poppler and librsvg;
  # man pages by help2man at build time
  libcairo2-dev libfontconfig-dev zlib1g-dev poppler-utils librsvg2-bin help2man
  # bash completion: generated from --help by tools/scripts/bash_completion.py
  python3
  # bench_accuracy: the plot docs/accuracy.png
  gnuplot-nox
  # lidartagd: LCM type jar and lcm-spy (Java 17), the lcm-spy screenshot under Xvfb, systemd-analyze
  liblcm-java libjchart2d-java openjdk-17-jdk-headless xvfb xauth imagemagick systemd
  # Fuzz targets (libFuzzer and the sanitizers' runtimes of clang 14); lidartagd.service booted in
  # a container (scripts/systemd-container-test.sh)
  clang-14 libclang-rt-14-dev mmdebstrap systemd-container
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
