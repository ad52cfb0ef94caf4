#include "lidartag/daemon/decimated_cloud.hpp"

namespace lidartag::daemon {

void DecimatedCloud::clear() {
  decimation = columns = 0;
  x.clear();
  y.clear();
  z.clear();
  intensity.clear();
  ring.clear();
}

void decimate_scan(const Scan& scan, int decimation, DecimatedCloud& out) {
  out.clear();
  if (decimation <= 0) return;
  out.decimation = decimation;
  for (int col = 0; col < scan.columns; col += decimation) {
    ++out.columns;
    for (int ret = 0; ret < scan.returns; ++ret) {
      for (int r = 0; r < scan.rings; ++r) {
        const size_t i = scan.at(ret, r, col);
        if (!scan.valid(i)) continue;
        out.x.push_back(scan.x[i]);
        out.y.push_back(scan.y[i]);
        out.z.push_back(scan.z[i]);
        out.intensity.push_back(scan.intensity[i]);
        out.ring.push_back(static_cast<uint8_t>(r));
      }
    }
  }
}

}  // namespace lidartag::daemon
