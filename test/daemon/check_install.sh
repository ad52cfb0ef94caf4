#!/bin/sh
# `cmake --install` (into a scratch DESTDIR, so nothing outside it is touched) puts the daemon's
# files where the unit and lidartag-spy look for them, the jar holding every LCM type.
# Usage: check_install.sh BUILD_DIR LCMTYPES_DIR JAR_TOOL
set -eu
build=$1
lcmtypes=$2
jar_tool=$3
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
DESTDIR=$root cmake --install "$build" >/dev/null
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
spy=$(find_one bin/lidartag-spy)
unit=$(find_one lib/systemd/system/lidartagd.service)
jar=$(find_one share/java/lidartag_lcmtypes.jar)
find_one share/doc/lidartag/daemon.md >/dev/null
config=$(find_one etc/lidartag/lidartagd.yaml)
[ $status -eq 0 ] || exit 1
# lcm-spy decodes what the jar holds: a class for each type of lcmtypes/.
classes=$("$jar_tool" tf "$jar")
for type in "$lcmtypes"/*.lcm; do
  name=$(basename "$type" .lcm)
  echo "$classes" | grep -qx "lidartag/$name.class" || {
    echo "the jar has no lidartag/$name.class"
    exit 1
  }
done
# The unit starts the installed binary with the installed configuration (paths without DESTDIR).
grep -q "^ExecStart=${daemon#"$root"} --config ${config#"$root"}\$" "$unit" || {
  echo "unit does not name the installed files:"
  grep ExecStart "$unit"
  exit 1
}
# The installed daemon accepts the installed configuration; the spy launcher finds the jar.
"$daemon" --config "$config" --print-config >/dev/null
[ "$(dirname "$spy")/../share/java/lidartag_lcmtypes.jar" -ef "$(find_one share/java/lidartag_lcmtypes.jar)" ]
echo "install: complete"
