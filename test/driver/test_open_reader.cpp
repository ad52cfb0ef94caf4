// The vendor seam's factory (driver/sources): each source opened by content gives, through
// driver::ScanReader, exactly the rotations of its vendor's own reader; the seam's counters add
// up; setup errors are typed. Real data from ../shared/captures (skipped with a message when
// absent); the Ouster model names need none.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "driver/ouster_captures.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/sources/open_reader.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::driver {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const std::string kCaptures = LIDARTAG_SHARED_DIR "/captures";

#define REQUIRE_PATH(p) \
  if (!fs::exists(p))   \
  GTEST_SKIP() << (p) << " not found (the real captures live beside the project)"

// Every rotation through the seam.
std::vector<Scan> read_all(ScanReader& reader) {
  std::vector<Scan> out;
  Scan scan;
  for (;;) {
    const ReadResult r = reader.read(scan, 1000ms);
    if (r == ReadResult::kEnd) break;
    if (r == ReadResult::kRotation) out.push_back(scan);
  }
  return out;
}

void expect_same(const std::vector<Scan>& a, const std::vector<Scan>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(a[i].columns, b[i].columns);
    EXPECT_EQ(a[i].rings, b[i].rings);
    EXPECT_EQ(a[i].complete, b[i].complete);
    EXPECT_EQ(a[i].stamp_ns, b[i].stamp_ns);
    EXPECT_EQ(a[i].packets, b[i].packets);
    const size_t n = a[i].point_count();
    EXPECT_EQ(n, b[i].point_count());
    // Bit for bit over the filled cells.
    for (int ret = 0; ret < a[i].returns; ++ret)
      for (int ring = 0; ring < a[i].rings; ++ring)
        for (int c = 0; c < a[i].columns; ++c) {
          const size_t k = a[i].at(ret, ring, c);
          ASSERT_EQ(a[i].range[k], b[i].range[k]);
          ASSERT_EQ(a[i].x[k], b[i].x[k]);
          ASSERT_EQ(a[i].y[k], b[i].y[k]);
          ASSERT_EQ(a[i].z[k], b[i].z[k]);
          ASSERT_EQ(a[i].intensity[k], b[i].intensity[k]);
        }
  }
}

TEST(OpenReader, VelodynePcapGivesTheVelodyneReadersRotations) {
  const std::string pcap = kCaptures + "/vlp16_dual_nebula.pcap";
  REQUIRE_PATH(pcap);
  OpenedReader opened = open_capture(pcap, {});
  EXPECT_EQ(opened.vendor, Vendor::kVelodyne);
  EXPECT_EQ(opened.data_port, 2368);
  const std::vector<Scan> seam = read_all(*opened.reader);
  velodyne::CaptureReader own(pcap, {});
  std::vector<Scan> direct;
  while (const Scan* s = own.next()) direct.push_back(*s);
  expect_same(seam, direct);
  const ReaderCounts c = opened.reader->reader_counts();
  EXPECT_EQ(c.data_packets, own.counts().data_packets);
  EXPECT_EQ(c.decoded + c.refused, c.data_packets);
  EXPECT_EQ(opened.reader->description().model, "vlp16");
  EXPECT_EQ(opened.reader->description().return_mode, "dual");
}

TEST(OpenReader, OusterPcapWithItsMetadataBesideGivesTheOusterReadersFrames) {
  const std::string dir = ouster::testing::ouster_dir() + "/pcaps/";
  REQUIRE_PATH(dir);
  for (const std::string stem : {"OS-0-128-U1_v2.3.0_1024x10", "OS-1-32-G_v2.1.1_1024x10"}) {
    SCOPED_TRACE(stem);
    OpenedReader opened = open_capture(dir + stem + ".pcap", {});
    ASSERT_EQ(opened.vendor, Vendor::kOuster);
    EXPECT_EQ(opened.data_port, 7502);
    EXPECT_EQ(opened.aux_port, 7503);
    const std::vector<Scan> seam = read_all(*opened.reader);
    ouster::CaptureReader own(dir + stem + ".pcap", ouster::load_metadata(dir + stem + ".json"));
    std::vector<Scan> direct;
    while (const Scan* s = own.next()) direct.push_back(*s);
    expect_same(seam, direct);
    const ReaderCounts c = opened.reader->reader_counts();
    EXPECT_EQ(c.data_packets, own.counts().lidar_packets);
    EXPECT_EQ(c.aux_packets, own.counts().imu_packets);
    EXPECT_EQ(c.decoded + c.refused + c.refused_mismatch, c.data_packets);
  }
  // The description: the metadata's sensor and profile.
  OpenedReader os0 = open_capture(dir + "OS-0-128-U1_v2.3.0_1024x10.pcap", {});
  EXPECT_EQ(os0.reader->description().vendor, "ouster");
  EXPECT_EQ(os0.reader->description().model, "os0-128");
  EXPECT_EQ(os0.reader->description().return_mode, "RNG15_RFL8_NIR8");
}

TEST(OpenReader, OusterMetadataOfAnotherSensorIsCountedAsMismatch) {
  const std::string dir = ouster::testing::ouster_dir() + "/pcaps/";
  REQUIRE_PATH(dir);
  ScanSourceOptions o;
  o.metadata = dir + "OS-2-128-U1_v2.3.0_1024x10.json";  // RNG19: another packet size
  OpenedReader opened = open_capture(dir + "OS-0-128-U1_v2.3.0_1024x10.pcap", o);
  EXPECT_TRUE(read_all(*opened.reader).empty());
  const ReaderCounts c = opened.reader->reader_counts();
  EXPECT_EQ(c.data_packets, 64u);
  EXPECT_EQ(c.decoded, 0u);
  EXPECT_EQ(c.model_mismatch, 64u);
  EXPECT_EQ(c.refused_mismatch, 64u);
  EXPECT_EQ(c.refused, 0u);
  EXPECT_NE(opened.reader->mismatch_text().find("64 of 64 lidar packets are not"),
            std::string::npos)
      << opened.reader->mismatch_text();
}

TEST(OpenReader, ConfiguredModelsAreCheckedAgainstTheSource) {
  const std::string dir = ouster::testing::ouster_dir() + "/pcaps/";
  REQUIRE_PATH(dir);
  const std::string pcap = dir + "OS-0-128-U1_v2.3.0_1024x10.pcap";
  ScanSourceOptions o;
  o.ouster_model = "os0-128";
  EXPECT_NO_THROW((void)open_capture(pcap, o));
  o.ouster_model = "os1-128";
  EXPECT_THROW((void)open_capture(pcap, o), ouster::MetadataError);
  ScanSourceOptions velodyne_model;
  velodyne_model.velodyne_model = velodyne::Model::kVLP16;
  velodyne_model.metadata = dir + "OS-0-128-U1_v2.3.0_1024x10.json";
  EXPECT_THROW((void)open_capture(pcap, velodyne_model), std::invalid_argument);
  // Without metadata a Velodyne model reads the pcap as Velodyne's (the JSON beside is not used):
  // nothing decodes.
  velodyne_model.metadata.clear();
  OpenedReader opened = open_capture(pcap, velodyne_model);
  EXPECT_EQ(opened.vendor, Vendor::kVelodyne);
}

TEST(OpenReader, BagsByContentVelodyneAsThePcapOusterWithItsMetadataTopic) {
  const std::string bags = kCaptures + "/bags";
  REQUIRE_PATH(bags);
  OpenedReader bag = open_capture(bags + "/rosbag2/vlp32c", {});
  EXPECT_EQ(bag.vendor, Vendor::kVelodyne);
  EXPECT_NE(bag.what.find("topic /sensing/lidar/front/velodyne_packets"), std::string::npos);
  OpenedReader pcap = open_capture(kCaptures + "/vlp32c_nebula_fov.pcap", {});
  expect_same(read_all(*bag.reader), read_all(*pcap.reader));

  OpenedReader ouster = open_capture(bags + "/ros1/ouster_os0-128_512x10_packets.bag", {});
  ASSERT_EQ(ouster.vendor, Vendor::kOuster);
  const std::vector<Scan> frames = read_all(*ouster.reader);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_TRUE(frames[0].complete);
  EXPECT_EQ(frames[0].columns, 512);
  EXPECT_EQ(frames[0].rings, 128);
  EXPECT_GT(frames[0].point_count(), 0u);
  const ReaderCounts c = ouster.reader->reader_counts();
  EXPECT_EQ(c.data_packets, 32u);
  EXPECT_EQ(c.decoded, 32u);
  EXPECT_EQ(c.aux_packets, 10u);  // the IMU topic's packets, apart
  EXPECT_EQ(ouster.reader->description().model, "os0-128");

  // A topic of point clouds, a topic that is not there.
  const std::string luminar = bags + "/ros1/luminar_pointcloud2_lz4.bag";
  EXPECT_THROW((void)open_capture(luminar, {}), bag::BagError);
  ScanSourceOptions missing;
  missing.topic = "/nope";
  EXPECT_THROW((void)open_capture(luminar, missing), bag::BagError);
}

// A bag replayed at capture timing waits for its packets' stamps, as a pcap does (rate 4: a
// quarter of the recorded time at least).
TEST(OpenReader, ABagIsPacedByItsStampsLikeAPcap) {
  const std::string bag = kCaptures + "/bags/rosbag2/vlp16_dual";
  REQUIRE_PATH(bag);
  ScanSourceOptions o;
  o.replay.pacing = ReplayPacing::kCaptureTime;
  o.replay.rate = 4.0;
  OpenedReader opened = open_capture(bag, o);
  const auto start = std::chrono::steady_clock::now();
  const std::vector<Scan> paced = read_all(*opened.reader);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_GE(paced.size(), 3u);
  const double recorded_s =
      static_cast<double>(paced.back().stamp_ns - paced.front().stamp_ns) * 1e-9;
  EXPECT_GT(recorded_s, 0.2);
  EXPECT_GE(wall_s, 0.9 * recorded_s / o.replay.rate);
  // The same rotations as unpaced.
  expect_same(paced, read_all(*open_capture(bag, {}).reader));
}

// A time window on a pcap (ScanSourceOptions::start_s, duration_s): exactly the packets received
// in [first + start, first + start + duration) are read, those outside counted apart; the window
// is the same for a replay at capture timing, which does not wait for the packets before it.
TEST(OpenReader, ATimeWindowOnAPcapKeepsThePacketsInItAndCountsTheRest) {
  const std::string pcap = kCaptures + "/vlp16_dual_nebula.pcap";
  REQUIRE_PATH(pcap);
  // The window's packets counted independently, from the pcap's own packets.
  const double start_s = 0.15, duration_s = 0.2;
  uint64_t inside_data = 0, outside = 0, all = 0;
  {
    PcapSource source(pcap);
    RawPacket p;
    int64_t first = 0;
    while (source.next(p, 0ms) == ReadStatus::kPacket) {
      if (all++ == 0) first = p.receive_time_ns;
      const double t = static_cast<double>(p.receive_time_ns - first) * 1e-9;
      if (t >= start_s && t < start_s + duration_s)
        inside_data += p.destination_port == kDefaultDataPort ? 1 : 0;
      else
        ++outside;
    }
  }
  ASSERT_GT(inside_data, 100u);
  ASSERT_GT(outside, 100u);
  ScanSourceOptions o;
  o.start_s = start_s;
  o.duration_s = duration_s;
  OpenedReader whole = open_capture(pcap, {});
  OpenedReader cut = open_capture(pcap, o);
  const std::vector<Scan> all_rotations = read_all(*whole.reader);
  const std::vector<Scan> rotations = read_all(*cut.reader);
  EXPECT_EQ(cut.reader->reader_counts().data_packets, inside_data);
  EXPECT_EQ(cut.reader->source_stats().outside_window, outside);
  EXPECT_EQ(whole.reader->source_stats().outside_window, 0u);
  ASSERT_FALSE(rotations.empty());
  EXPECT_LT(rotations.size(), all_rotations.size());
  // Each rotation's stamp lies inside the window of the whole capture's.
  EXPECT_GE(rotations.front().stamp_ns, all_rotations.front().stamp_ns);

  // At capture timing: a late window takes about its own duration, not the time up to its end
  // (the packets before it are not waited for); the same packets as unpaced.
  ScanSourceOptions late;
  late.start_s = 0.3;
  late.duration_s = 0.05;
  OpenedReader fast = open_capture(pcap, late);
  (void)read_all(*fast.reader);
  late.replay.pacing = ReplayPacing::kCaptureTime;
  OpenedReader paced = open_capture(pcap, late);
  const auto t0 = std::chrono::steady_clock::now();
  (void)read_all(*paced.reader);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GT(fast.reader->reader_counts().data_packets, 0u);
  EXPECT_EQ(paced.reader->reader_counts().data_packets, fast.reader->reader_counts().data_packets);
  EXPECT_GE(wall_s, 0.8 * late.duration_s);
  EXPECT_LT(wall_s, 0.8 * late.start_s);

  // Bad windows and a window on a looped replay are refused.
  ScanSourceOptions bad;
  bad.start_s = -1;
  EXPECT_THROW((void)open_capture(pcap, bad), std::invalid_argument);
  bad.start_s = 0;
  bad.duration_s = 0;
  EXPECT_THROW((void)open_capture(pcap, bad), std::invalid_argument);
  ScanSourceOptions looped = late;
  looped.replay.loop = true;
  EXPECT_THROW((void)open_capture(pcap, looped), std::invalid_argument);
}

// A bag of Ouster packets takes the window too (from the bag's first message).
TEST(OpenReader, ATimeWindowOnAnOusterBagCountsTheMessagesOutsideIt) {
  const std::string bag = kCaptures + "/bags/ros1/ouster_os0-128_512x10_packets.bag";
  REQUIRE_PATH(bag);
  ScanSourceOptions o;
  o.start_s = 1000;  // past its end
  OpenedReader opened = open_capture(bag, o);
  EXPECT_TRUE(read_all(*opened.reader).empty());
  EXPECT_EQ(opened.reader->reader_counts().data_packets, 0u);
  // Every message of the bag: 32 lidar, 10 IMU and the metadata topic's one.
  EXPECT_EQ(opened.reader->source_stats().outside_window, 43u);
}

TEST(OusterModels, NamesFromTheMetadataAndTheirChecks) {
  ouster::SensorInfo info;
  info.pixels_per_column = 128;
  for (const auto& [line, name] :
       {std::pair{"OS-1-128", "os1-128"}, std::pair{"OS-0-128-U1", "os0-128"},
        std::pair{"OS1-128", "os1-128"}, std::pair{"", "os-128"}, std::pair{"lidar", "os-128"}}) {
    info.prod_line = line;
    EXPECT_EQ(ouster::model_name(info), name) << line;
  }
  info.prod_line = "OS-2-128";
  EXPECT_TRUE(ouster::describes_model(info, "os2-128"));
  EXPECT_TRUE(ouster::describes_model(info, "os-128"));
  EXPECT_FALSE(ouster::describes_model(info, "os1-128"));
  EXPECT_FALSE(ouster::describes_model(info, "os-64"));
  info.prod_line.clear();
  EXPECT_TRUE(ouster::describes_model(info, "os1-128"));  // no product line: the beams only
  EXPECT_FALSE(ouster::describes_model(info, "os1-64"));
  for (const char* ok : {"os0-32", "os1-128", "os2-64", "os-16"})
    EXPECT_TRUE(ouster::is_model_name(ok));
  for (const char* bad : {"os3-64", "os1-48", "OS1-128", "os1", "vlp16", ""})
    EXPECT_FALSE(ouster::is_model_name(bad)) << bad;
}

}  // namespace
}  // namespace lidartag::driver
