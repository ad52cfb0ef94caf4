// Copies a rotation between scans of possibly different column capacity, filled columns only: the
// hand-over from the capture reader's pool into the lock-free scan buffer.
#pragma once

#include "lidartag/driver/scan.hpp"

namespace lidartag::daemon {

// True when `dst` (sized by Scan::reserve) can hold `src`: enough rings x returns rows and columns.
bool fits(const Scan& src, const Scan& dst);

// Copies the cells of the filled columns, the per-column arrays and the per-rotation fields.
// `dst` keeps its storage and column capacity (no allocation). Returns false, leaving `dst`
// unchanged, when it does not fit.
[[nodiscard]] bool copy_scan(const Scan& src, Scan& dst);

}  // namespace lidartag::daemon
