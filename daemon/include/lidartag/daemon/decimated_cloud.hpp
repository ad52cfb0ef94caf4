// The decimated copy of a rotation that the cloud channel publishes (lcm.cloud_decimation).
#pragma once

#include <cstdint>
#include <vector>

#include "lidartag/driver/scan.hpp"

namespace lidartag::daemon {

// The returns of every `decimation`-th column of a rotation (columns 0, k, 2k, ...), column after
// column, in each return after return and ring by ring; cells without a return are left out.
struct DecimatedCloud {
  int decimation = 0;  // k; 0: nothing taken
  int columns = 0;     // columns taken: ceil(scan columns / k)
  std::vector<float> x, y, z;
  std::vector<uint8_t> intensity;
  std::vector<uint8_t> ring;

  size_t size() const { return x.size(); }
  void clear();
};

// Fills `out` from `scan` (cleared first; `decimation` <= 0 leaves it empty). Reuses its storage:
// no allocation once it has grown to a rotation's points.
void decimate_scan(const Scan& scan, int decimation, DecimatedCloud& out);

}  // namespace lidartag::daemon
