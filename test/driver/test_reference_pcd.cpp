// Agreement with another decoder's output (nebula's PCDs in ../shared/captures/reference). Not
// ground truth: the README there states what an independent decoder reaches, and so do we.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <unordered_map>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"

namespace lidartag::velodyne {
namespace {

struct Pt {
  float x, y, z;
  int ring;
};

// Voxel hash for nearest-neighbour queries within one voxel of a point.
class Grid {
 public:
  explicit Grid(double cell) : cell_(cell) {}
  void add(const Pt& p) { cells_[key(p.x, p.y, p.z)].push_back(p); }
  // Distance to the nearest point (of the same ring when ring >= 0); infinity if none near.
  double nearest(double x, double y, double z, int ring) const {
    double best = std::numeric_limits<double>::infinity();
    const auto ix = idx(x), iy = idx(y), iz = idx(z);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(pack(ix + dx, iy + dy, iz + dz));
          if (it == cells_.end()) continue;
          for (const Pt& p : it->second) {
            if (ring >= 0 && p.ring != ring) continue;
            best = std::min(best, std::hypot(p.x - x, p.y - y, p.z - z));
          }
        }
    return best;
  }

 private:
  int64_t idx(double v) const { return static_cast<int64_t>(std::floor(v / cell_)); }
  static uint64_t pack(int64_t x, int64_t y, int64_t z) {
    return (static_cast<uint64_t>(x & 0x1FFFFF) << 42) |
           (static_cast<uint64_t>(y & 0x1FFFFF) << 21) | static_cast<uint64_t>(z & 0x1FFFFF);
  }
  uint64_t key(double x, double y, double z) const { return pack(idx(x), idx(y), idx(z)); }
  double cell_;
  std::unordered_map<uint64_t, std::vector<Pt>> cells_;
};

struct Agreement {
  double median_mm, p95_mm;
  size_t unmatched;
};

Agreement compare(const std::string& capture, const std::string& reference, Model model,
                  size_t first_packet, size_t last_packet, bool by_ring) {
  Grid grid(0.1);
  {
    driver::PcapSource src(capture);
    Decoder decoder(Calibration::builtin(model));
    SensorClock clock;
    DecodedPacket out;
    driver::RawPacket pk;
    size_t index = 0;
    while (src.next(pk, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket) {
      if (pk.payload.size() != kDataPacketSize) continue;
      const size_t i = index++;
      if (decoder.decode(pk.payload, clock, pk.receive_time_ns, out) != DecodeStatus::kOk) continue;
      if (i < first_packet || i > last_packet) continue;
      for (int r = 0; r < out.returns; ++r)
        for (int c = 0; c < out.columns; ++c)
          for (int ring = 0; ring < out.rings; ++ring) {
            const auto k = static_cast<size_t>(out.at(r, c, ring));
            if (out.range[k] > 0) grid.add({out.x[k], out.y[k], out.z[k], ring});
          }
    }
  }
  const PcdCloud ref = read_pcd(reference);
  const auto& x = ref.field("x");
  const auto& y = ref.field("y");
  const auto& z = ref.field("z");
  std::vector<double> err;
  size_t unmatched = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const int ring = by_ring ? static_cast<int>(ref.field("channel")[i]) : -1;
    const double d = grid.nearest(x[i], y[i], z[i], ring);
    if (std::isinf(d)) {
      ++unmatched;
      continue;
    }
    err.push_back(d * 1000.0);
  }
  std::sort(err.begin(), err.end());
  return {err[err.size() / 2], err[err.size() * 95 / 100], unmatched};
}

std::string shared(const std::string& rel) {
  return std::string(LIDARTAG_SHARED_DIR) + "/" + rel;
}

TEST(ReferencePcd, Vlp16DualAgreesWithNebula) {
  const auto cap = shared("captures/vlp16_dual_nebula.pcap");
  const auto pcd = shared("captures/reference/vlp16_dual_nebula_scan.pcd");
  if (!std::filesystem::exists(cap) || !std::filesystem::exists(pcd))
    GTEST_SKIP() << "real captures not found under " << LIDARTAG_SHARED_DIR;
  // The reference rotation is made of packets 452..602; rings must agree too.
  const Agreement a = compare(cap, pcd, Model::kVLP16, 452, 602, true);
  RecordProperty("median_mm", std::to_string(a.median_mm));
  RecordProperty("p95_mm", std::to_string(a.p95_mm));
  std::cout << "vlp16 dual vs nebula: median " << a.median_mm << " mm, p95 " << a.p95_mm
            << " mm, unmatched " << a.unmatched << "\n";
  EXPECT_EQ(a.unmatched, 0u);
  // README: "within a few centimetres is expected"; an independent decoder reached 5 mm median
  // and 11 mm at the 95th percentile (we measure 5.1 / 11.7: nebula skips the vertical offsets
  // and, it seems, the azimuth interpolation of the second firing in dual mode).
  EXPECT_LE(a.median_mm, 6.0);
  EXPECT_LE(a.p95_mm, 15.0);
}

TEST(ReferencePcd, Vlp32cAgreesWithNebula) {
  const auto cap = shared("captures/vlp32c_nebula_fov.pcap");
  const auto pcd = shared("captures/reference/vlp32c_nebula_scan.pcd");
  if (!std::filesystem::exists(cap) || !std::filesystem::exists(pcd))
    GTEST_SKIP() << "real captures not found under " << LIDARTAG_SHARED_DIR;
  // xyz only; which rotation is not stated: match against the whole capture.
  const Agreement a = compare(cap, pcd, Model::kVLP32C, 0, SIZE_MAX, false);
  std::cout << "vlp32c vs nebula: median " << a.median_mm << " mm, p95 " << a.p95_mm
            << " mm, unmatched " << a.unmatched << "\n";
  EXPECT_EQ(a.unmatched, 0u);
  // README: an independent decoder reaches about 8 mm median, 26 mm at the 95th percentile.
  EXPECT_LE(a.median_mm, 8.0);
  EXPECT_LE(a.p95_mm, 26.0);
}

}  // namespace
}  // namespace lidartag::velodyne
