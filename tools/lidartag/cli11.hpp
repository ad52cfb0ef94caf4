// CLI11 with GCC 12's -Wnull-dereference silenced: its string splitting trips a false positive
// inside libstdc++ when inlined at -O2. Include this instead of <CLI/CLI.hpp>.
#pragma once

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <CLI/CLI.hpp>
#pragma GCC diagnostic pop
