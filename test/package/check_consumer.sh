#!/bin/sh
# A downstream project against an installed lidartag: `cmake --install --strip` (what the package
# ships: archives without their debug information) into a scratch DESTDIR,
# then test/package/consumer configured with find_package(lidartag) (CMAKE_PREFIX_PATH at the
# scratch prefix), built and run on the installed demo capture and configuration.
# Usage: check_consumer.sh BUILD_DIR CONSUMER_SOURCE_DIR
set -eu
build=$(cd "$1" && pwd)
source=$2
# Inside the build tree (not /tmp), so that ccache finds the consumer's objects again.
root=$build/package-test/root
rm -rf "$root"
mkdir -p "$root"
DESTDIR=$root cmake --install "$build" --strip >/dev/null
prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$build/CMakeCache.txt")
launcher=$(sed -n 's/^CMAKE_CXX_COMPILER_LAUNCHER:[A-Z]*=//p' "$build/CMakeCache.txt")
consumer=$build/package-test/consumer
rm -rf "$consumer"
cmake -S "$source" -B "$consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$root$prefix" ${launcher:+-DCMAKE_CXX_COMPILER_LAUNCHER=$launcher} \
  >"$build/package-test/configure.log" 2>&1 || {
  cat "$build/package-test/configure.log"
  exit 1
}
cmake --build "$consumer" >"$build/package-test/build.log" 2>&1 || {
  cat "$build/package-test/build.log"
  exit 1
}
out=$("$consumer/consumer")
echo "$out"
lcm_count=$(find "$(dirname "$source")/../../lcmtypes" -name '*.lcm' | wc -l)
expected="rotations 10 detections 20 decoded 20 scene hdl32e lcm files $lcm_count"
[ "$out" = "$expected" ] || {
  echo "expected: $expected"
  exit 1
}
rm -rf "$root"
echo "find_package(lidartag): a downstream project builds and runs"
