#!/bin/sh
# `cmake --install` (into a scratch DESTDIR, so nothing outside it is touched) puts every file where
# the unit, lidartag-spy, Python and CMake look for them: programs, unit and configuration, the
# jars (one class per LCM type), headers, libraries and the CMake package, the .lcm files, the
# demo capture and configuration, docs and the Debian copyright file, the Python module, and the
# man pages and bash completion when the build made them.
# Usage: check_install.sh BUILD_DIR LCMTYPES_DIR JAR_TOOL [PYTHON]
set -eu
build=$1
lcmtypes=$2
jar_tool=$3
python=${4:-}
source_dir=$(cd "$lcmtypes/.." && pwd)
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
DESTDIR=$root cmake --install "$build" >/dev/null
prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$build/CMakeCache.txt")
status=0
find_one() {
  found=$(find "$root" -path "*/$1" | head -n 1)
  if [ -z "$found" ]; then
    echo "missing: $1" >&2
    status=1
  fi
  echo "$found"
}
daemon=$(find_one bin/lidartagd)
find_one bin/lidartag >/dev/null
spy=$(find_one bin/lidartag-spy)
unit=$(find_one lib/systemd/system/lidartagd.service)
jar=$(find_one share/java/lidartag_lcmtypes.jar)
spy_jar=$(find_one share/java/lidartag_spy.jar)
config=$(find_one etc/lidartag/lidartagd.yaml)
docs=$(dirname "$(find_one share/doc/lidartag/copyright)")
for f in README.md daemon.md driver.md detector.md simulator.md; do
  [ -f "$docs/$f" ] || { echo "missing: share/doc/lidartag/$f" >&2; status=1; }
done
# Libraries, headers and the CMake package.
for lib in assembly velodyne driver_io velodyne_io families detector sim config; do
  find_one "liblidartag_$lib.a" >/dev/null
done
for header in driver/scan.hpp driver/columns.hpp driver/velodyne/io/capture_reader.hpp \
  driver/velodyne/io/pcd.hpp driver/io/pcap_source.hpp \
  detector/detector.hpp detector/cloud_scan.hpp sim/simulator.hpp daemon/config.hpp; do
  find_one "include/lidartag/$header" >/dev/null
done
find_one cmake/lidartag/lidartagConfig.cmake >/dev/null
find_one cmake/lidartag/lidartagConfigVersion.cmake >/dev/null
find_one cmake/lidartag/lidartagTargets.cmake >/dev/null
# Data.
data=$(dirname "$(find_one share/lidartag/demo.pcap)")
cmp -s "$data/demo.pcap" "$source_dir/pcaps/demo.pcap" || { echo "demo.pcap differs" >&2; status=1; }
[ $status -eq 0 ] || exit 1

for type in "$lcmtypes"/*.lcm; do
  name=$(basename "$type" .lcm)
  cmp -s "$type" "$data/lcmtypes/$name.lcm" || {
    echo "share/lidartag/lcmtypes/$name.lcm is not lcmtypes/$name.lcm"
    exit 1
  }
  [ -f "$(dirname "$(find_one include/lidartag/daemon/config.hpp)")/../$name.hpp" ] || {
    echo "no header include/lidartag/$name.hpp"
    exit 1
  }
done
# lcm-spy decodes what the jar holds: a class for each type of lcmtypes/.
classes=$("$jar_tool" tf "$jar")
for type in "$lcmtypes"/*.lcm; do
  name=$(basename "$type" .lcm)
  echo "$classes" | grep -qx "lidartag/$name.class" || {
    echo "the jar has no lidartag/$name.class"
    exit 1
  }
done
"$jar_tool" tf "$spy_jar" | grep -qx "lidartag/spy/LogReplay.class" || {
  echo "lidartag_spy.jar has no lidartag/spy/LogReplay.class"
  exit 1
}
# The unit starts the installed binary with the installed configuration (paths without DESTDIR).
grep -q "^ExecStart=${daemon#"$root"} --config ${config#"$root"}\$" "$unit" || {
  echo "unit does not name the installed files:"
  grep ExecStart "$unit"
  exit 1
}
# The installed daemon accepts the installed configurations; the demo's names the installed
# capture.
"$daemon" --config "$config" --print-config >/dev/null
"$daemon" --config "$data/demo.yaml" --print-config |
  grep -q "file: \"\\?$prefix/share/lidartag/demo.pcap\"\\?\$" || {
  echo "the installed demo.yaml does not name $prefix/share/lidartag/demo.pcap"
  exit 1
}
# The spy launcher finds the jars and names the installed documentation.
[ "$(dirname "$spy")/../share/java/lidartag_lcmtypes.jar" -ef "$jar" ]
[ "$(dirname "$spy")/../share/java/lidartag_spy.jar" -ef "$spy_jar" ]
doc=$("$spy" --help | sed -n 's/^Documentation: \([^ ]*\).*/\1/p')
[ -f "$root$doc" ] || { echo "lidartag-spy --help names $doc, not installed"; exit 1; }
# The copyright file is in Debian's machine-readable format.
head -n 1 "$docs/copyright" |
  grep -qx "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/"
# The Python module, from where it was installed, with Debian's python3.
if [ -n "$python" ]; then
  init=$(find_one dist-packages/lidartag/__init__.py)
  find "$(dirname "$init")" -name '_lidartag*.so' | grep -q . || { echo "no _lidartag*.so"; exit 1; }
  PYTHONPATH=$(dirname "$(dirname "$init")") "$python" -c "
import lidartag, sys
assert lidartag.__file__.startswith('$root'), lidartag.__file__
rotation = next(iter(lidartag.read('$data/demo.pcap')))
assert len(lidartag.Detector('$data/demo.yaml').detect(rotation)) == 2
"
fi
# Man pages and bash completion: whatever the build generated is installed.
for page in "$build"/share/man/man1/*; do
  [ -e "$page" ] || { echo "note: the build made no man pages"; break; }
  find_one "share/man/man1/$(basename "$page")" >/dev/null
done
for completion in "$build"/share/bash-completion/completions/*; do
  [ -e "$completion" ] || { echo "note: the build made no bash completion"; break; }
  find_one "share/bash-completion/completions/$(basename "$completion")" >/dev/null
done
[ $status -eq 0 ] || exit 1
echo "install: complete"
