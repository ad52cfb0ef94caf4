#!/bin/sh
# lidartag-spy --help names a documentation file that exists (installed, or in a build tree the
# source tree's): a first-time user follows it.
# Usage: check_spy_help.sh LIDARTAG_SPY
set -eu
doc=$("$1" --help | sed -n 's/^Documentation: \(.*\) (section.*/\1/p')
echo "Documentation: $doc"
[ -n "$doc" ] || { echo "FAIL: no Documentation line"; exit 1; }
[ -f "$doc" ] || { echo "FAIL: $doc does not exist"; exit 1; }
