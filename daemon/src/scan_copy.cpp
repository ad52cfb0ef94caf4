#include "lidartag/daemon/scan_copy.hpp"

#include <algorithm>

namespace lidartag::daemon {

namespace {

template <class T>
void copy_row(const std::vector<T>& from, size_t from_start, std::vector<T>& to, size_t to_start,
              size_t count) {
  const auto first = from.begin() + static_cast<std::ptrdiff_t>(from_start);
  std::copy(first, first + static_cast<std::ptrdiff_t>(count),
            to.begin() + static_cast<std::ptrdiff_t>(to_start));
}

}  // namespace

bool fits(const Scan& src, const Scan& dst) {
  if (src.columns < 0 || src.columns > dst.column_capacity) return false;
  const size_t rows = static_cast<size_t>(src.rings) * static_cast<size_t>(src.returns);
  const size_t needed = rows * static_cast<size_t>(dst.column_capacity);
  return dst.x.size() >= needed && dst.laser_id.size() >= src.laser_id.size() &&
         dst.column_azimuth_deg.size() >= static_cast<size_t>(src.columns);
}

bool copy_scan(const Scan& src, Scan& dst) {
  if (!fits(src, dst)) return false;
  dst.rings = src.rings;
  dst.returns = src.returns;
  dst.columns = src.columns;
  const auto n = static_cast<size_t>(src.columns);
  for (int ret = 0; ret < src.returns; ++ret) {
    for (int ring = 0; ring < src.rings; ++ring) {
      const size_t a = src.at(ret, ring, 0), b = dst.at(ret, ring, 0);
      copy_row(src.x, a, dst.x, b, n);
      copy_row(src.y, a, dst.y, b, n);
      copy_row(src.z, a, dst.z, b, n);
      copy_row(src.range, a, dst.range, b, n);
      copy_row(src.azimuth_deg, a, dst.azimuth_deg, b, n);
      copy_row(src.time_s, a, dst.time_s, b, n);
      copy_row(src.intensity, a, dst.intensity, b, n);
      copy_row(src.return_type, a, dst.return_type, b, n);
    }
  }
  copy_row(src.laser_id, 0, dst.laser_id, 0, src.laser_id.size());
  copy_row(src.column_azimuth_deg, 0, dst.column_azimuth_deg, 0, n);
  copy_row(src.column_time_s, 0, dst.column_time_s, 0, n);
  dst.sequence = src.sequence;
  dst.stamp_ns = src.stamp_ns;
  dst.model = src.model;
  dst.return_mode = src.return_mode;
  dst.complete = src.complete;
  dst.starts_at_cut = src.starts_at_cut;
  dst.ends_at_cut = src.ends_at_cut;
  dst.packets = src.packets;
  dst.missing_packets = src.missing_packets;
  dst.azimuth_jumps = src.azimuth_jumps;
  dst.rpm = src.rpm;
  return true;
}

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
