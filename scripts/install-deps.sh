#!/usr/bin/env bash
# Installs the Debian 12 packages the project needs, with apt (as root, or through sudo).
# Idempotent: only the missing ones are installed.
#   scripts/install-deps.sh          everything: build, test, run, package, fuzz (scripts/run-tests.sh)
#   scripts/install-deps.sh --demo   only what scripts/run-demo.sh builds and runs: lidartagd and
#                                    lidartag (compiler, CMake, Ninja and the libraries they link)
#   scripts/install-deps.sh --list [--demo]   prints the package names, one a line; installs nothing
# One list: `demo` is the part run-demo.sh needs; the full install is `demo` and `more` together.
set -euo pipefail

# What run-demo.sh needs: configure with LIDARTAG_BUILD_TESTS=OFF and LIDARTAG_BUILD_BENCHMARKS=OFF,
# build the targets lidartagd and lidartag, run lidartagd on pcaps/demo.pcap.
demo=(
  g++ cmake ninja-build pkg-config
  libeigen3-dev libnlopt-dev libnlopt-cxx-dev libtbb-dev libboost-dev libboost-system-dev
  # liblcm-dev brings lcm-gen (liblcm-bin); LCM's pkg-config file needs GLib's
  libpcap-dev liblcm-dev liblcm-bin libglib2.0-dev libsystemd-dev
  libspdlog-dev libfmt-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
  # VeloView XML calibration files; PCD binary_compressed (LZF)
  libtinyxml2-dev liblzf-dev
  # camera-LiDAR calibration: PNG and JPEG images (libapriltag-dev: AprilTag 3 finds the tags in them)
  libpng-dev libjpeg-dev libapriltag-dev
  # ROS bags and MCAP (driver/bag): rosbag2 sqlite3 storage; bz2, lz4 and zstd chunks
  libsqlite3-dev libbz2-dev liblz4-dev libzstd-dev
  # MCAP chunk CRC-32 at memory speed (ISA-L's crc32_gzip_refl)
  libisal-dev
  # lidartag tag/render: Cairo (PDF, SVG, PNG)
  libcairo2-dev libfontconfig-dev zlib1g-dev
)

# The rest, for scripts/run-tests.sh and development.
more=(
  # dpkg-dev (in build-essential): dpkg-shlibdeps for the Debian package (cpack)
  build-essential git clang-format
  # the Python module (for /usr/bin/python3) and its tests
  python3-dev pybind11-dev python3-numpy python3-pytest
  libgtest-dev libgmock-dev libbenchmark-dev
  iproute2 util-linux
  # the tests rasterise lidartag tag/render's output with poppler and librsvg; man pages by
  # help2man at build time
  poppler-utils librsvg2-bin help2man
  # bash completion: generated from --help by tools/scripts/bash_completion.py
  python3
  # bench_accuracy: the plot docs/accuracy.png
  gnuplot-nox
  # lidartagd: LCM type jar and lidartag-spy (lcm-spy, Java 17), the lcm-spy screenshot under
  # Xvfb, systemd-analyze
  liblcm-java libjchart2d-java openjdk-17-jdk-headless xvfb xauth imagemagick systemd
  # Fuzz targets (libFuzzer and the sanitizers' runtimes of clang 14); lidartagd.service booted in
  # a container (scripts/systemd-container-test.sh)
  clang-14 libclang-rt-14-dev mmdebstrap systemd-container
)

list=false
subset=all
for arg in "$@"; do
  case "$arg" in
    --demo) subset=demo ;;
    --list) list=true ;;
    *)
      echo "usage: scripts/install-deps.sh [--demo] [--list]" >&2
      exit 2
      ;;
  esac
done
packages=("${demo[@]}")
[ "$subset" = demo ] || packages+=("${more[@]}")
if $list; then
  printf '%s\n' "${packages[@]}"
  exit 0
fi

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
