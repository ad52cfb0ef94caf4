// ouster::CaptureReader on the real Ouster captures (../shared/captures/ouster; skipped when
// absent): frames whole or not, IMU packets apart, destaggering, metadata the packets contradict;
// and what destaggering changes for the detector (nothing: each ring's cells keep their azimuth
// order, only where a ring's cells begin moves).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include "driver/ouster_captures.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"

namespace lidartag::driver::ouster {
namespace {

namespace fs = std::filesystem;
using testing::capture_files;
using testing::ouster_dir;

std::string pcap_of(const std::string& stem) {
  return ouster_dir() + "/pcaps/" + stem + ".pcap";
}
SensorInfo info_of(const std::string& stem) {
  return load_metadata(ouster_dir() + "/pcaps/" + stem + ".json");
}

// Every frame of a capture, copied out of the reader's scans.
std::vector<Scan> read_all(CaptureReader& reader) {
  std::vector<Scan> out;
  while (const Scan* s = reader.next()) out.push_back(*s);
  return out;
}

TEST(OusterCaptureReader, FramesAreWholeWhenEveryPacketCameAndImuIsCountedApart) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  for (const auto& c : capture_files()) {
    SCOPED_TRACE(c.pcap);
    CaptureReader reader(pcap_of(c.pcap), info_of(c.metadata));
    const std::vector<Scan> frames = read_all(reader);
    const auto& n = reader.counts();
    EXPECT_EQ(n.lidar_packets, c.lidar_packets);
    EXPECT_EQ(n.imu_packets, c.imu_packets);
    EXPECT_EQ(n.other_packets, 0u);
    EXPECT_EQ(reader.decoder_stats().rejected(), 0u);
    EXPECT_EQ(reader.metadata_mismatch(), "");
    ASSERT_EQ(frames.size(), c.frames);
    EXPECT_EQ(n.frames, c.frames);
    // 64 packets of 16 columns a frame; the FUSA capture holds 8 packets of one frame.
    EXPECT_EQ(reader.frame_packets(), 64);
    const bool part = c.lidar_packets < 64 * c.frames;
    for (const Scan& s : frames) {
      EXPECT_EQ(s.complete, !part) << "frame " << s.sequence;
      EXPECT_EQ(s.packets, part ? c.lidar_packets : 64u);
    }
    EXPECT_EQ(n.whole_frames, part ? 0u : c.frames);
    // A partial frame (128 of 1024 columns) is not destaggered: its cells have no partners.
    EXPECT_EQ(n.destaggered, part ? 0u : c.frames);
    EXPECT_NO_THROW(reader.require_frames(c.pcap));
  }
}

TEST(OusterCaptureReader, CaptureTimingReplaysAtTheCapturesPaceWithTheSameFrames) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  const std::string stem = "OS-2-128-U1_v2.3.0_1024x10";
  CaptureReader fast(pcap_of(stem), info_of(stem));
  const auto a = read_all(fast);
  CaptureReaderOptions options;
  options.source.pacing = ReplayPacing::kCaptureTime;
  options.source.rate = 1.0;
  CaptureReader paced(pcap_of(stem), info_of(stem), options);
  const auto t0 = std::chrono::steady_clock::now();
  const auto b = read_all(paced);
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& n = paced.counts();
  const double span_s = static_cast<double>(n.last_time_ns - n.first_time_ns) * 1e-9;
  EXPECT_GT(span_s, 0.05);  // a frame at 10 Hz, and the IMU packets around it
  EXPECT_GE(elapsed_s, 0.9 * span_s);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(a[0].point_count(), b[0].point_count());
  EXPECT_EQ(n.lidar_packets, fast.counts().lidar_packets);
  EXPECT_EQ(n.imu_packets, fast.counts().imu_packets);
}

// The widest spread of the azimuths of a column's cells (over the rings), degrees.
double widest_column_spread(const Scan& s) {
  double widest = 0;
  for (int col = 0; col < s.columns; ++col) {
    double lo = 1e9, hi = -1e9;
    const double ref = s.column_azimuth_deg[static_cast<size_t>(col)];
    for (int ring = 0; ring < s.rings; ++ring) {
      const size_t i = s.at(0, ring, col);
      if (s.range[i] <= 0) continue;
      double d = s.azimuth_deg[i] - ref;  // unwrapped around the column's azimuth
      d -= 360.0 * std::round(d / 360.0);
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
    if (hi >= lo) widest = std::max(widest, hi - lo);
  }
  return widest;
}

// Per ring, the cells' azimuths never step back more than once around the ring (the wrap): the
// ring's columns are in azimuth order, the order eq. (1) reads neighbours in.
int worst_ring_descents(const Scan& s) {
  int worst = 0;
  for (int ring = 0; ring < s.rings; ++ring) {
    int descents = 0;
    double prev = -1;
    for (int col = 0; col < s.columns; ++col) {
      const size_t i = s.at(0, ring, col);
      if (s.range[i] <= 0) continue;
      if (prev >= 0 && s.azimuth_deg[i] < prev) ++descents;
      prev = s.azimuth_deg[i];
    }
    worst = std::max(worst, descents);
  }
  return worst;
}

TEST(OusterCaptureReader, DestaggeredColumnsPointOneWayAndRingsStayInAzimuthOrder) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  for (const char* stem :
       {"OS-0-128-U1_v2.3.0_1024x10", "OS-2-128-U1_v2.3.0_1024x10", "OS-1-32-G_v2.1.1_1024x10"}) {
    SCOPED_TRACE(stem);
    CaptureReaderOptions staggered_options;
    staggered_options.destagger = false;
    CaptureReader staggered(pcap_of(stem), info_of(stem), staggered_options);
    CaptureReader destaggered(pcap_of(stem), info_of(stem));
    const auto a = read_all(staggered);
    const auto b = read_all(destaggered);
    ASSERT_EQ(a.size(), 1u);
    ASSERT_EQ(b.size(), 1u);
    const double column_deg = 360.0 / a[0].columns;
    // Staggered, a column's cells spread over the beams' azimuth offsets (several columns);
    // destaggered, within about one column.
    EXPECT_GT(widest_column_spread(a[0]), 3 * column_deg);
    EXPECT_LT(widest_column_spread(b[0]), 1.5 * column_deg);
    EXPECT_LE(worst_ring_descents(a[0]), 1);
    EXPECT_LE(worst_ring_descents(b[0]), 1);
  }
}

TEST(OusterCaptureReader, TheDetectorSeesAlmostTheSameEdgesStaggeredOrNot) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  detector::Detector detector(detector::DetectorOptions{});
  for (const auto& c : capture_files()) {
    SCOPED_TRACE(c.pcap);
    CaptureReaderOptions staggered_options;
    staggered_options.destagger = false;
    CaptureReader staggered(pcap_of(c.pcap), info_of(c.metadata), staggered_options);
    CaptureReader destaggered(pcap_of(c.pcap), info_of(c.metadata));
    const auto a = read_all(staggered);
    const auto b = read_all(destaggered);
    ASSERT_EQ(a.size(), b.size());
    for (size_t k = 0; k < a.size(); ++k) {
      detector::ScanResult ra, rb;
      detector.detect(a[k], ra);
      detector.detect(b[k], rb);
      // The same edges, up to where each ring's walk of eq. (1)'s one-edge rule starts (its first
      // column): a feature or two in thousands.
      EXPECT_GT(ra.features, 100);
      EXPECT_LE(std::abs(ra.features - rb.features), 2 + ra.features / 1000)
          << ra.features << " staggered, " << rb.features << " destaggered";
      EXPECT_LE(std::abs(ra.clusters - rb.clusters), 2 + ra.clusters / 100)
          << ra.clusters << " staggered, " << rb.clusters << " destaggered";
      std::printf("%s frame %zu: features %d / %d, clusters %d / %d (staggered / destaggered)\n",
                  c.pcap.c_str(), k, ra.features, rb.features, ra.clusters, rb.clusters);
      EXPECT_EQ(ra.detections.size(), 0u);  // no capture holds a tag
      EXPECT_EQ(rb.detections.size(), 0u);
    }
  }
}

TEST(OusterCaptureReader, MetadataOfAnotherSensorIsNamedWithWhatThePacketsFit) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  {  // Another profile and pixel count: every packet the wrong size.
    CaptureReader reader(pcap_of("OS-1-32-G_v2.1.1_1024x10"),
                         info_of("OS-2-128-U1_v2.3.0_1024x10"));
    EXPECT_TRUE(read_all(reader).empty());
    const std::string m = reader.metadata_mismatch();
    EXPECT_NE(m.find("64 of 64 lidar packets are not 24832 bytes"), std::string::npos) << m;
    EXPECT_NE(m.find("6464 bytes: LEGACY with 32 pixels and 16 columns per packet"),
              std::string::npos)
        << m;
    EXPECT_THROW(reader.require_frames("x"), MetadataMismatch);
  }
  {  // The same profile and size from another sensor: its init id and serial number.
    const SensorInfo other = info_of("OS-1-128_v2.3.0_1024x10");
    CaptureReader reader(pcap_of("OS-0-128-U1_v2.3.0_1024x10"), other);
    EXPECT_TRUE(read_all(reader).empty());
    const std::string m = reader.metadata_mismatch();
    EXPECT_NE(m.find("64 lidar packets carry init id"), std::string::npos) << m;
    EXPECT_NE(m.find(std::to_string(other.serial_number)), std::string::npos) << m;
    EXPECT_THROW(reader.require_frames("x"), MetadataMismatch);
  }
  {  // Columns per packet of another configuration.
    SensorInfo info = info_of("OS-2-128-U1_v2.3.0_1024x10");
    info.columns_per_packet = 8;
    CaptureReader reader(pcap_of("OS-2-128-U1_v2.3.0_1024x10"), info);
    EXPECT_TRUE(read_all(reader).empty());
    const std::string m = reader.metadata_mismatch();
    EXPECT_NE(m.find("RNG19_RFL8_SIG16_NIR16 with 128 pixels and 16 columns per packet"),
              std::string::npos)
        << m;
    EXPECT_THROW(reader.require_frames("x"), MetadataMismatch);
  }
}

TEST(OusterCaptureReader, FormatsOfSizeNameEachCapturesOwnFormat) {
  if (!fs::exists(ouster_dir())) GTEST_SKIP() << "Ouster captures not found at " << ouster_dir();
  for (const auto& c : capture_files()) {
    SCOPED_TRACE(c.pcap);
    const SensorInfo info = info_of(c.metadata);
    const std::string fits = formats_of_size(PacketFormat::of(info).packet_bytes);
    EXPECT_NE(fits.find(std::string(profile_name(info.profile)) + " with " +
                        std::to_string(info.pixels_per_column) + " pixels and " +
                        std::to_string(info.columns_per_packet) + " columns per packet"),
              std::string::npos)
        << fits;
  }
  EXPECT_EQ(formats_of_size(1000), "");
}

}  // namespace
}  // namespace lidartag::driver::ouster
