// Ouster captures of the simulator: the packet encoder against the decoder's readers (every
// profile), the metadata writer against the loader (both layouts), and simulated OS1-64 / OS1-128
// captures written as pcap + metadata, read back by the project's Ouster decoder and ScanBatcher,
// destaggered and detected against the simulator's truth.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "../../bench/sim_scans.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/ouster/encoder.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/sim/ouster_sim.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim {
namespace {

namespace fs = std::filesystem;
namespace ouster = driver::ouster;
using ouster::Field;
using ouster::Profile;

constexpr std::array<Profile, 5> kProfiles = {
    Profile::kLegacy, Profile::kRng19Rfl8Sig16Nir16, Profile::kRng19Rfl8Sig16Nir16Dual,
    Profile::kRng15Rfl8Nir8, Profile::kFusaRng15Rfl8Nir8Dual};

uint32_t field_of(const ouster::ProfileSpec& spec, const uint8_t* pixel, Field f) {
  const ouster::FieldSpec* s = ouster::find_field(spec, f);
  return s ? ouster::field_value(pixel, *s) : 0u;
}

// Random columns encoded, then read back with the decoder's own readers: headers and every field
// the profile carries, at its width and resolution.
TEST(OusterEncoder, EveryProfileReadsBackWhatWasEncoded) {
  std::mt19937 gen(7);
  for (Profile profile : kProfiles) {
    SCOPED_TRACE(std::string(ouster::profile_name(profile)));
    ouster::SensorInfo info =
        ouster::nominal_sensor_info(ouster::Model::kOs1_128, 1024, 10, profile);
    const auto format = ouster::PacketFormat::of(info);
    const auto& spec = *format.spec;
    std::vector<ouster::ColumnPixels> cols(static_cast<size_t>(format.columns));
    for (size_t c = 0; c < cols.size(); ++c) {
      auto& col = cols[c];
      col.timestamp_ns = 1'700'000'000'000'000'000ull + c * 97'656;
      col.measurement_id = static_cast<uint16_t>(1000 + c);
      col.valid = c != 5;  // one invalid column
      for (size_t r = 0; r < 128; ++r) {
        col.range_mm[r] = static_cast<uint32_t>(gen() % 300000);
        col.reflectivity[r] = static_cast<uint8_t>(gen());
        col.signal[r] = static_cast<uint16_t>(gen());
        col.near_ir[r] = static_cast<uint16_t>(gen() % 4096);
        col.range2_mm[r] = static_cast<uint32_t>(gen() % 300000);
        col.reflectivity2[r] = static_cast<uint8_t>(gen());
        col.signal2[r] = static_cast<uint16_t>(gen());
      }
    }
    ouster::PacketHeader h;
    h.packet_type = ouster::kLidarPacketType;
    h.frame_id = 4321;
    h.init_id = 0x123456;
    h.serial_number = 992000000001;
    std::vector<uint8_t> out(format.packet_bytes);
    std::vector<uint8_t> short_out(format.packet_bytes - 1);
    EXPECT_FALSE(ouster::encode_lidar_packet(format, h, 1024, cols, short_out));
    ASSERT_TRUE(ouster::encode_lidar_packet(format, h, 1024, cols, out));
    const auto back = ouster::read_packet_header(out.data(), format);
    EXPECT_EQ(back.frame_id, 4321u);
    if (profile != Profile::kLegacy) {
      EXPECT_EQ(back.packet_type, ouster::kLidarPacketType);
      EXPECT_EQ(back.init_id, 0x123456u);
      EXPECT_EQ(back.serial_number, 992000000001u);
    }
    // A field keeps the value's bits it has room for, at its resolution.
    auto kept = [&](Field f, uint32_t v) {
      const ouster::FieldSpec* s = ouster::find_field(spec, f);
      if (!s) return 0u;
      const uint64_t mask = (1ull << s->bits) - 1ull;
      return static_cast<uint32_t>(((uint64_t(v) >> s->upshift) & mask) << s->upshift);
    };
    for (int c = 0; c < format.columns; ++c) {
      const auto& col = cols[static_cast<size_t>(c)];
      const auto ch = ouster::read_column_header(out.data(), format, c);
      EXPECT_EQ(ch.timestamp_ns, col.timestamp_ns);
      EXPECT_EQ(ch.measurement_id, col.measurement_id);
      EXPECT_EQ(ch.valid(), col.valid);
      if (profile == Profile::kLegacy) {
        EXPECT_EQ(ch.frame_id, 4321u);
        EXPECT_EQ(ch.encoder_count, col.measurement_id * ouster::kEncoderCountsPerTurn / 1024u);
      }
      for (int r = 0; r < format.pixels; ++r) {
        const auto u = static_cast<size_t>(r);
        const uint8_t* px = format.pixel(out.data(), c, r);
        const bool v = col.valid;
        ASSERT_EQ(field_of(spec, px, Field::kRange), v ? kept(Field::kRange, col.range_mm[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kReflectivity),
                  v ? kept(Field::kReflectivity, col.reflectivity[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kSignal), v ? kept(Field::kSignal, col.signal[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kNearIr),
                  v ? kept(Field::kNearIr, col.near_ir[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kRange2),
                  v ? kept(Field::kRange2, col.range2_mm[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kReflectivity2),
                  v ? kept(Field::kReflectivity2, col.reflectivity2[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kSignal2),
                  v ? kept(Field::kSignal2, col.signal2[u]) : 0u);
        ASSERT_EQ(field_of(spec, px, Field::kFlags), 0u);
      }
    }
  }
}

void expect_same(const ouster::SensorInfo& a, const ouster::SensorInfo& b) {
  EXPECT_EQ(a.prod_line, b.prod_line);
  EXPECT_EQ(a.firmware, b.firmware);
  EXPECT_EQ(a.serial_number, b.serial_number);
  EXPECT_EQ(a.init_id, b.init_id);
  EXPECT_EQ(a.nested_layout, b.nested_layout);
  EXPECT_EQ(a.beam_altitude_deg, b.beam_altitude_deg);
  EXPECT_EQ(a.beam_azimuth_deg, b.beam_azimuth_deg);
  EXPECT_EQ(a.lidar_origin_to_beam_origin_mm, b.lidar_origin_to_beam_origin_mm);
  EXPECT_EQ(a.lidar_to_sensor_transform, b.lidar_to_sensor_transform);
  EXPECT_EQ(a.mode_columns, b.mode_columns);
  EXPECT_EQ(a.mode_rate_hz, b.mode_rate_hz);
  EXPECT_EQ(a.pixels_per_column, b.pixels_per_column);
  EXPECT_EQ(a.columns_per_packet, b.columns_per_packet);
  EXPECT_EQ(a.columns_per_frame, b.columns_per_frame);
  EXPECT_EQ(a.column_window, b.column_window);
  EXPECT_EQ(a.pixel_shift_by_row, b.pixel_shift_by_row);
  EXPECT_EQ(a.profile, b.profile);
  EXPECT_EQ(a.data_format_reported, b.data_format_reported);
}

TEST(OusterMetadataWriter, WrittenThenLoadedGivesTheSameSensorInfoInBothLayouts) {
  const fs::path dir =
      fs::temp_directory_path() / ("lidartag_ouster_meta_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (Profile profile : kProfiles)
    for (bool nested : {true, false})
      for (auto model : {ouster::Model::kOs1_64, ouster::Model::kOs1_128}) {
        ouster::SensorInfo info = ouster::nominal_sensor_info(model, 2048, 10, profile);
        info.nested_layout = nested;
        info.serial_number = 122246000293;
        info.init_id = 0xabcdef;
        info.beam_altitude_deg[3] = 1.0 / 3.0;  // not representable in a few decimals
        const std::string path = (dir / "m.json").string();
        ouster::write_metadata(info, path);
        expect_same(ouster::load_metadata(path), info);
        expect_same(ouster::parse_metadata(ouster::metadata_to_json(info)), info);
      }
  fs::remove_all(dir);
  EXPECT_THROW(ouster::write_metadata(
                   ouster::nominal_sensor_info(ouster::Model::kOs1_64, 1024, 10, Profile::kLegacy),
                   "/nonexistent-dir/m.json"),
               ouster::MetadataError);
}

constexpr std::array<ouster::Model, 6> kModels = {ouster::Model::kOs1_64, ouster::Model::kOs1_128,
                                                  ouster::Model::kOs0_32, ouster::Model::kOs0_128,
                                                  ouster::Model::kOs2_32, ouster::Model::kOs2_128};

TEST(OusterModels, BeamTablesAndPixelShiftsAgree) {
  for (auto model : kModels)
    for (int columns : {512, 1024, 2048}) {
      const auto info = ouster::nominal_sensor_info(model, columns, 10, Profile::kLegacy);
      const auto& spec = ouster::model_spec(model);
      SCOPED_TRACE(std::string(spec.name));
      EXPECT_EQ(ouster::model_from_name(spec.name), model);
      EXPECT_EQ(ouster::model_name(info), spec.name);
      ASSERT_EQ(info.beam_altitude_deg.size(), static_cast<size_t>(spec.beams));
      ASSERT_EQ(info.beam_azimuth_deg.size(), static_cast<size_t>(spec.beams));
      if (spec.altitude_table_deg.empty()) {  // the OS1's evenly spaced beams
        EXPECT_DOUBLE_EQ(info.beam_altitude_deg.front(), 22.5);
        EXPECT_DOUBLE_EQ(info.beam_altitude_deg.back(), -22.5);
      }
      // The first beam the top one, altitudes falling.
      for (size_t b = 1; b < info.beam_altitude_deg.size(); ++b)
        EXPECT_LT(info.beam_altitude_deg[b], info.beam_altitude_deg[b - 1]);
      // What the loader accepts: the metadata written and read back.
      expect_same(ouster::parse_metadata(ouster::metadata_to_json(info)), info);
      for (size_t b = 0; b < info.beam_azimuth_deg.size(); ++b) {
        // A beam's azimuth offset is its pixel shift in columns, to half a column.
        EXPECT_NEAR(info.pixel_shift_by_row[b], info.beam_azimuth_deg[b] * columns / 360.0, 0.5);
      }
    }
  EXPECT_EQ(ouster::nominal_sensor_info(ouster::Model::kOs1_64, 1024, 10, Profile::kLegacy)
                .pixel_shift_by_row[0],
            12);
  EXPECT_THROW(ouster::nominal_sensor_info(ouster::Model::kOs1_64, 2048, 20, Profile::kLegacy),
               std::invalid_argument);
  EXPECT_EQ(ouster::model_from_name("os1-128"), ouster::Model::kOs1_128);
  EXPECT_FALSE(ouster::model_from_name("vlp32c").has_value());
}

// The OS0 and OS2 tables are those of the real units whose metadata lies beside their captures in
// ../shared/captures/ouster/pcaps: beam altitudes and azimuths, beam origin offset, the
// lidar-to-sensor transform, and the product line.
TEST(OusterModels, Os0AndOs2TablesAreThoseOfTheRealUnits) {
  const std::string dir = std::string(LIDARTAG_SHARED_DIR) + "/captures/ouster/pcaps/";
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " absent: the real units' metadata is not here";
  const std::vector<std::pair<ouster::Model, std::string>> units = {
      {ouster::Model::kOs0_32, "OS-0-32-U1_v2.2.0_1024x10"},
      {ouster::Model::kOs0_128, "OS-0-128-U1_v2.3.0_1024x10"},
      {ouster::Model::kOs2_32, "OS-2-32-U0_v2.0.0_1024x10"},
      {ouster::Model::kOs2_128, "OS-2-128-U1_v2.3.0_1024x10"}};
  for (const auto& [model, stem] : units) {
    SCOPED_TRACE(stem);
    const ouster::SensorInfo real = ouster::load_metadata(dir + stem + ".json");
    const ouster::SensorInfo sim = ouster::nominal_sensor_info(model, 1024, 10, real.profile);
    EXPECT_EQ(sim.prod_line, real.prod_line);
    EXPECT_EQ(sim.beam_altitude_deg, real.beam_altitude_deg);
    EXPECT_EQ(sim.beam_azimuth_deg, real.beam_azimuth_deg);
    EXPECT_EQ(sim.lidar_origin_to_beam_origin_mm, real.lidar_origin_to_beam_origin_mm);
    EXPECT_EQ(sim.lidar_to_sensor_transform, real.lidar_to_sensor_transform);
    EXPECT_EQ(ouster::model_name(sim), ouster::model_spec(model).name);
  }
}

TEST(OusterScene, SensorKeysParseAndBadOnesAreRefusedNamingTheKey) {
  const Scene s = parse_scene("sensor: {model: os1-128, lidar_mode: 2048x10, profile: legacy}\n");
  ASSERT_TRUE(s.sensor.ouster.has_value());
  EXPECT_EQ(s.sensor.ouster->model, ouster::Model::kOs1_128);
  EXPECT_EQ(s.sensor.ouster->columns, 2048);
  EXPECT_EQ(s.sensor.ouster->rate_hz, 10);
  EXPECT_EQ(s.sensor.ouster->profile, Profile::kLegacy);
  const Scene d = parse_scene("sensor: {model: os1-64}\n");
  ASSERT_TRUE(d.sensor.ouster.has_value());
  EXPECT_EQ(d.sensor.ouster->columns, 1024);
  EXPECT_EQ(d.sensor.ouster->profile, Profile::kRng19Rfl8Sig16Nir16);
  EXPECT_FALSE(parse_scene("sensor: {model: vlp16}\n").sensor.ouster.has_value());
  const Scene dual = parse_scene("sensor: {model: os0-128, profile: rng19_dual}\n");
  ASSERT_TRUE(dual.sensor.ouster.has_value());
  EXPECT_EQ(dual.sensor.ouster->model, ouster::Model::kOs0_128);
  EXPECT_EQ(dual.sensor.ouster->profile, Profile::kRng19Rfl8Sig16Nir16Dual);
  EXPECT_EQ(parse_scene("sensor: {model: os2-32, profile: RNG19_RFL8_SIG16_NIR16_DUAL}\n")
                .sensor.ouster->profile,
            Profile::kRng19Rfl8Sig16Nir16Dual);
  EXPECT_EQ(parse_scene("sensor: {model: os1-128, profile: fusa_dual}\n").sensor.ouster->profile,
            Profile::kFusaRng15Rfl8Nir8Dual);
  EXPECT_EQ(parse_scene("sensor: {model: os2-32, profile: FUSA_RNG15_RFL8_NIR8_DUAL}\n")
                .sensor.ouster->profile,
            Profile::kFusaRng15Rfl8Nir8Dual);
  auto refused = [](const std::string& yaml, const std::string& key) {
    try {
      parse_scene(yaml);
      ADD_FAILURE() << yaml << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  refused("sensor: {model: os1-64, lidar_mode: 2048x20}\n", "sensor.lidar_mode");
  refused("sensor: {model: os1-64, lidar_mode: 1024}\n", "sensor.lidar_mode");
  refused("sensor: {model: os1-64, profile: dual}\n", "sensor.profile");
  refused("sensor: {model: os1-64, rpm: 600}\n", "sensor.rpm");
  refused("sensor: {model: vlp16, lidar_mode: 1024x10}\n", "sensor.lidar_mode");
  refused("sensor: {model: os9-64}\n", "sensor.model");
}

struct Case {
  const char* name;
  ouster::Model model;
  int columns;
  Profile profile;
  double distance_m = 5.0;  // of the tag, ahead
};

void PrintTo(const Case& c, std::ostream* os) {
  *os << c.name;
}

class OusterSimCapture : public ::testing::TestWithParam<Case> {};

// The accuracy scene: a 1.2 m tag16h5 on a stand, diamond mount, c.distance_m ahead (5 m), turned
// 20 deg.
Scene tag_scene(const Case& c) {
  Scene s;
  s.sensor.ouster = OusterSensorOptions{c.model, c.columns, 10, c.profile};
  s.sensor.height = 1.0;
  TagOptions t;
  t.family = "tag16h5";
  t.id = 7;
  t.size = 1.2;
  t.center = {c.distance_m, 0.3, 1.1};
  const double a = 20.0 * std::numbers::pi / 180.0;
  t.normal = {-std::cos(a), std::sin(a), 0.0};
  t.rotation_deg = 45.0;
  t.stand.enabled = true;
  s.tags.push_back(t);
  return s;
}

// The scene written as NAME.pcap + NAME.json, read back from the files by the project's Ouster
// decoder and ScanBatcher, each frame destaggered and detected.
TEST_P(OusterSimCapture, WrittenCaptureDecodesAndTheTagIsDetectedAtItsTruth) {
  const Case& c = GetParam();
  constexpr int kRotations = 6;
  const Simulator simulator(tag_scene(c));
  const fs::path dir =
      fs::temp_directory_path() / ("lidartag_ouster_sim_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string pcap = (dir / (std::string(c.name) + ".pcap")).string();
  const std::string meta = (dir / (std::string(c.name) + ".json")).string();
  RunStats stats;
  Truth truth;
  {
    driver::PcapWriter writer(pcap);
    truth = simulator.run(
        kRotations, 11,
        [&](std::span<const uint8_t> payload, int64_t t, uint16_t port) {
          writer.write_udp(payload, t, port);
        },
        &stats);
    writer.close();
  }
  ouster::write_metadata(ouster_sensor_info(simulator.scene().sensor), meta);
  EXPECT_EQ(truth.model, std::string(ouster::model_spec(c.model).name));
  EXPECT_EQ(stats.data_packets, static_cast<uint64_t>((kRotations * c.columns + 64) / 16));

  const ouster::SensorInfo info = ouster::load_metadata(meta);
  ouster::Decoder decoder(info);
  driver::ScanBatcher batcher(ouster::sensor_layout(info),
                              static_cast<uint8_t>(ouster::kReturnModeBase + uint8_t(info.profile)),
                              info.returns(), driver::BatcherOptions{});
  driver::PcapSourceOptions po;
  po.data_port = ouster::kLidarPort;
  po.position_port = ouster::kImuPort;
  driver::PcapSource source(pcap, po);
  driver::RawPacket raw;
  ouster::PacketColumns parsed;
  detector::DetectorOptions options;
  options.tag_sizes_m = {1.2};
  options.families = {"tag16h5"};
  detector::Detector det(options);
  detector::ScanResult result;
  std::vector<Scan> scans(1);
  int complete = 0, detected = 0, wrong = 0, false_pos = 0;
  uint64_t packets = 0;
  double worst_m = 0.0;
  auto score = [&](Scan& scan) {
    if (!scan.complete) return;
    ++complete;
    ASSERT_EQ(scan.columns, c.columns);
    ASSERT_TRUE(decoder.destagger(scan));
    const auto it = std::find_if(
        truth.rotations.begin(), truth.rotations.end(),
        [&](const RotationTruth& r) { return std::llabs(r.stamp_ns - scan.stamp_ns) < 1000; });
    ASSERT_NE(it, truth.rotations.end()) << "no truth rotation stamped " << scan.stamp_ns;
    det.detect(scan, result);
    const TagTruth& tag = it->tags[0];
    bool found = false;
    for (const auto& d : result.detections) {
      if ((d.position - tag.position).norm() >= tag.size / 2) {
        ++false_pos;
      } else if (d.family != tag.family || d.id != tag.id) {
        ++wrong;
      } else {
        found = true;
        worst_m = std::max(worst_m, (d.position - tag.position).norm());
      }
    }
    detected += found ? 1 : 0;
  };
  while (source.next(raw, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket) {
    if (raw.destination_port != ouster::kLidarPort) continue;
    ++packets;
    ASSERT_EQ(decoder.parse(raw.payload, parsed), ouster::DecodeStatus::kOk);
    if (batcher.add(parsed, scans.back())) {
      score(scans.back());
    }
  }
  while (batcher.flush(scans.back())) score(scans.back());
  fs::remove_all(dir);
  EXPECT_EQ(packets, stats.data_packets);
  EXPECT_EQ(decoder.stats().rejected(), 0u);
  EXPECT_EQ(complete, kRotations);
  std::printf(
      "%s: %d of %d frames detected, worst position error %.3f m, %d wrong ids, %d false "
      "positives, %.0f tag returns a frame\n",
      c.name, detected, complete, worst_m, wrong, false_pos,
      double(truth.rotations[0].tags[0].returns));
  EXPECT_GE(detected, kRotations - 1);
  EXPECT_LT(worst_m, 0.05);
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(false_pos, 0);
}

INSTANTIATE_TEST_SUITE_P(
    Models, OusterSimCapture,
    ::testing::Values(
        Case{"os1_64_1024_rng19", ouster::Model::kOs1_64, 1024, Profile::kRng19Rfl8Sig16Nir16},
        Case{"os1_128_1024_legacy", ouster::Model::kOs1_128, 1024, Profile::kLegacy},
        Case{"os1_128_2048_rng19", ouster::Model::kOs1_128, 2048, Profile::kRng19Rfl8Sig16Nir16},
        Case{"os1_64_1024_rng19_dual", ouster::Model::kOs1_64, 1024,
             Profile::kRng19Rfl8Sig16Nir16Dual},
        Case{"os0_128_1024_rng19_dual", ouster::Model::kOs0_128, 1024,
             Profile::kRng19Rfl8Sig16Nir16Dual},
        Case{"os1_128_1024_fusa_dual", ouster::Model::kOs1_128, 1024,
             Profile::kFusaRng15Rfl8Nir8Dual},
        Case{"os0_32_2048_rng19", ouster::Model::kOs0_32, 2048, Profile::kRng19Rfl8Sig16Nir16, 3.0},
        Case{"os2_128_1024_rng19", ouster::Model::kOs2_128, 1024, Profile::kRng19Rfl8Sig16Nir16,
             10.0},
        Case{"os2_32_1024_legacy", ouster::Model::kOs2_32, 1024, Profile::kLegacy}),
    [](const auto& p) { return std::string(p.param.name); });

// The simulator's dual-return captures (RNG19_RFL8_SIG16_NIR16_DUAL, FUSA_RNG15_RFL8_NIR8_DUAL)
// through the project's decoder: every packet's headers and fields, read with the decoder's readers
// and encoded again, give the packet's bytes bit for bit (nothing written outside the profile's
// fields: FUSA's header with its 32-bit frame id, its pixels of 8 bytes without SIGNAL); each
// frame's cells are the packets' fields exactly (return 0 RANGE and REFLECTIVITY, kStrongest;
// return 1 RANGE2 and REFLECTIVITY2, kSecond; kNone where a range is 0); a second return only
// beside a first, the first the stronger in SIGNAL where the profile carries it; and the tag's
// edges give second returns.
class OusterSimDual : public ::testing::TestWithParam<Profile> {};

TEST_P(OusterSimDual, SecondReturnIsWrittenAsTheDecoderReadsIt) {
  constexpr int kRotations = 2;
  const Simulator simulator(tag_scene({"os1_64_dual", ouster::Model::kOs1_64, 1024, GetParam()}));
  const ouster::SensorInfo info = ouster_sensor_info(simulator.scene().sensor);
  ASSERT_EQ(info.returns(), 2);
  std::vector<std::vector<uint8_t>> packets;
  simulator.run(
      kRotations, 5,
      [&](std::span<const uint8_t> payload, int64_t, uint16_t port) {
        if (port == ouster::kLidarPort) packets.emplace_back(payload.begin(), payload.end());
      },
      nullptr);
  ouster::Decoder decoder(info);
  const ouster::PacketFormat& format = decoder.format();
  const auto& spec = *format.spec;
  using F = Field;

  // Bit for bit: decode the fields, encode them again.
  std::vector<ouster::ColumnPixels> cols(static_cast<size_t>(format.columns));
  std::vector<uint8_t> again(format.packet_bytes);
  size_t seconds = 0, firsts = 0, weaker_first = 0;
  for (const auto& p : packets) {
    for (int c = 0; c < format.columns; ++c) {
      const auto ch = ouster::read_column_header(p.data(), format, c);
      auto& col = cols[static_cast<size_t>(c)];
      col.timestamp_ns = ch.timestamp_ns;
      col.measurement_id = ch.measurement_id;
      col.valid = ch.valid();
      for (int r = 0; r < format.pixels; ++r) {
        const auto u = static_cast<size_t>(r);
        const uint8_t* px = format.pixel(p.data(), c, r);
        col.range_mm[u] = field_of(spec, px, F::kRange);
        col.reflectivity[u] = static_cast<uint8_t>(field_of(spec, px, F::kReflectivity));
        col.signal[u] = static_cast<uint16_t>(field_of(spec, px, F::kSignal));
        col.near_ir[u] = static_cast<uint16_t>(field_of(spec, px, F::kNearIr));
        col.range2_mm[u] = field_of(spec, px, F::kRange2);
        col.reflectivity2[u] = static_cast<uint8_t>(field_of(spec, px, F::kReflectivity2));
        col.signal2[u] = static_cast<uint16_t>(field_of(spec, px, F::kSignal2));
        firsts += col.range_mm[u] != 0 ? 1u : 0u;
        if (col.range2_mm[u] == 0) continue;
        ++seconds;
        EXPECT_NE(col.range_mm[u], 0u) << "a second return without a first";
        weaker_first += col.signal[u] < col.signal2[u] ? 1u : 0u;
      }
    }
    ASSERT_TRUE(ouster::encode_lidar_packet(format, ouster::read_packet_header(p.data(), format),
                                            info.columns_per_frame, cols, again));
    ASSERT_EQ(again, p);
  }
  // The stand's legs and the tag's edges in front of the wall: two echoes in a footprint.
  EXPECT_GT(seconds, 20u);
  EXPECT_LT(seconds, firsts / 4);
  // The first return is the strongest echo (FUSA's packets carry no SIGNAL to compare).
  if (ouster::find_field(spec, F::kSignal) != nullptr) {
    EXPECT_EQ(weaker_first, 0u);
  } else {
    EXPECT_EQ(ouster::find_field(spec, F::kSignal2), nullptr);
  }

  // The frames' cells are the fields, exactly.
  driver::ScanBatcher batcher(ouster::sensor_layout(info),
                              static_cast<uint8_t>(ouster::kReturnModeBase + uint8_t(info.profile)),
                              info.returns(), driver::BatcherOptions{});
  std::vector<Scan> scans(1);
  ouster::PacketColumns parsed;
  int checked_frames = 0;
  size_t second_cells = 0;
  auto check = [&](const Scan& scan) {
    if (!scan.complete) return;
    ++checked_frames;
    ASSERT_EQ(scan.returns, 2);
    for (const auto& p : packets) {
      for (int c = 0; c < format.columns; ++c) {
        const auto ch = ouster::read_column_header(p.data(), format, c);
        // The frame's packets: column times from the frame's first column's.
        const auto dt = int64_t(ch.timestamp_ns) - scan.stamp_ns;
        if (dt < 0 || dt >= 100'000'000) continue;
        const int m = ch.measurement_id;
        for (int ring = 0; ring < scan.rings; ++ring) {
          const int row = decoder.beam_of_ring()[static_cast<size_t>(ring)];
          const uint8_t* px = format.pixel(p.data(), c, row);
          for (int ret = 0; ret < 2; ++ret) {
            const size_t i = scan.at(ret, ring, m);
            const uint32_t mm = field_of(spec, px, ret == 0 ? F::kRange : F::kRange2);
            const uint32_t refl =
                field_of(spec, px, ret == 0 ? F::kReflectivity : F::kReflectivity2);
            ASSERT_EQ(scan.range[i], static_cast<float>(mm * 1e-3)) << ring << " " << m;
            if (mm == 0) {
              ASSERT_EQ(scan.return_type[i], ReturnType::kNone);
              continue;
            }
            ASSERT_EQ(scan.intensity[i], refl);
            ASSERT_EQ(scan.return_type[i], ret == 0 ? ReturnType::kStrongest : ReturnType::kSecond);
            second_cells += ret == 1 ? 1u : 0u;
          }
        }
      }
    }
  };
  for (const auto& p : packets) {
    ASSERT_EQ(decoder.parse(p, parsed), ouster::DecodeStatus::kOk);
    if (batcher.add(parsed, scans.back())) check(scans.back());
  }
  while (batcher.flush(scans.back())) check(scans.back());
  EXPECT_EQ(checked_frames, kRotations);
  EXPECT_GT(second_cells, 0u);
}

INSTANTIATE_TEST_SUITE_P(Profiles, OusterSimDual,
                         ::testing::Values(Profile::kRng19Rfl8Sig16Nir16Dual,
                                           Profile::kFusaRng15Rfl8Nir8Dual),
                         [](const auto& p) {
                           return p.param == Profile::kFusaRng15Rfl8Nir8Dual ? "fusa_dual"
                                                                             : "rng19_dual";
                         });

// FUSA_RNG15_RFL8_NIR8_DUAL against RNG19_RFL8_SIG16_NIR16_DUAL, the same OS1-128 scene and seed:
// the same echoes, so every pixel's returns are the RNG19 dual's with RANGE and RANGE2 in 8 mm
// steps (the field's 15 bits shifted up by 3) and the same REFLECTIVITY and REFLECTIVITY2; the
// packet headers carry the same frame ids, the columns the same times and measurement ids. Through
// the decoder, destaggered, the tag is found in every frame, within a few millimetres of where the
// RNG19 dual frame puts it and within 1 cm of its truth.
TEST(OusterSimFusa, FramesAreTheRng19DualOnesInEightMillimetreStepsAndTheTagIsFound) {
  constexpr int kRotations = 4;
  using F = Field;
  const Case fusa{"os1_128_fusa", ouster::Model::kOs1_128, 1024, Profile::kFusaRng15Rfl8Nir8Dual};
  Case rng19 = fusa;
  rng19.profile = Profile::kRng19Rfl8Sig16Nir16Dual;
  const Simulator sim_fusa(tag_scene(fusa)), sim_rng19(tag_scene(rng19));
  auto packets_of = [](const Simulator& sim) {
    std::vector<std::vector<uint8_t>> packets;
    sim.run(
        2, 9,
        [&](std::span<const uint8_t> payload, int64_t, uint16_t port) {
          if (port == ouster::kLidarPort) packets.emplace_back(payload.begin(), payload.end());
        },
        nullptr);
    return packets;
  };
  const auto pf = packets_of(sim_fusa), pr = packets_of(sim_rng19);
  ASSERT_EQ(pf.size(), pr.size());
  const auto ff = ouster::PacketFormat::of(ouster_sensor_info(sim_fusa.scene().sensor));
  const auto fr = ouster::PacketFormat::of(ouster_sensor_info(sim_rng19.scene().sensor));
  ASSERT_EQ(ff.frame_id_bits, 32);
  size_t seconds = 0;
  for (size_t p = 0; p < pf.size(); ++p) {
    ASSERT_EQ(pf[p].size(), ff.packet_bytes);
    EXPECT_EQ(ouster::read_packet_header(pf[p].data(), ff).frame_id,
              ouster::read_packet_header(pr[p].data(), fr).frame_id);
    for (int c = 0; c < ff.columns; ++c) {
      const auto hf = ouster::read_column_header(pf[p].data(), ff, c);
      const auto hr = ouster::read_column_header(pr[p].data(), fr, c);
      ASSERT_EQ(hf.timestamp_ns, hr.timestamp_ns);
      ASSERT_EQ(hf.measurement_id, hr.measurement_id);
      ASSERT_EQ(hf.valid(), hr.valid());
      for (int r = 0; r < ff.pixels; ++r) {
        const uint8_t* a = ff.pixel(pf[p].data(), c, r);
        const uint8_t* b = fr.pixel(pr[p].data(), c, r);
        for (const auto& [range, refl] :
             {std::pair{F::kRange, F::kReflectivity}, std::pair{F::kRange2, F::kReflectivity2}}) {
          const uint32_t mm = field_of(*fr.spec, b, range);
          ASSERT_EQ(field_of(*ff.spec, a, range), mm & ~7u) << p << " " << c << " " << r;
          ASSERT_EQ(field_of(*ff.spec, a, refl), field_of(*fr.spec, b, refl));
          seconds += range == F::kRange2 && mm != 0 ? 1u : 0u;
        }
      }
    }
  }
  EXPECT_GT(seconds, 20u);

  // Both through the decoder and the detector.
  detector::DetectorOptions options;
  options.tag_sizes_m = {1.2};
  options.families = {"tag16h5"};
  // One detector for both: a Detection's family names the detector's own dictionary, so the
  // detector outlives the detections kept.
  detector::Detector det(options);
  auto detect_all = [&](const Simulator& sim) {
    detector::ScanResult result;
    std::vector<std::vector<detector::Detection>> found;
    eval::SimScans scans(sim);
    const Truth truth = scans.run(kRotations, 3, [&](const Scan& scan, size_t) {
      EXPECT_TRUE(scan.complete);
      EXPECT_EQ(scan.returns, 2);
      det.detect(scan, result);
      found.push_back(result.detections);
    });
    return std::pair{truth, found};
  };
  const auto [truth, found] = detect_all(sim_fusa);
  const auto [truth_rng19, found_rng19] = detect_all(sim_rng19);
  ASSERT_EQ(found.size(), static_cast<size_t>(kRotations));
  ASSERT_EQ(found_rng19.size(), found.size());
  double worst_m = 0.0, worst_apart_m = 0.0;
  for (size_t i = 0; i < found.size(); ++i) {
    SCOPED_TRACE(i);
    const eval::TagScore score = eval::score_tag(found[i], truth.rotations[i].tags[0]);
    EXPECT_TRUE(score.detected);
    EXPECT_FALSE(score.wrong_id);
    ASSERT_EQ(found[i].size(), 1u);
    ASSERT_EQ(found_rng19[i].size(), 1u);
    EXPECT_EQ(found[i][0].id, found_rng19[i][0].id);
    EXPECT_EQ(truth_rng19.rotations[i].stamp_ns, truth.rotations[i].stamp_ns);
    worst_m = std::max(worst_m, score.translation_m);
    worst_apart_m =
        std::max(worst_apart_m, (found[i][0].position - found_rng19[i][0].position).norm());
  }
  std::printf("fusa_dual: worst position error %.4f m, %.4f m from the rng19_dual frames' tag\n",
              worst_m, worst_apart_m);
  EXPECT_LT(worst_m, 0.01);
  EXPECT_LT(worst_apart_m, 0.008);
}

// The same scene in memory (eval::SimScans, what the benches and `lidartag plan` use): every
// frame delivered complete, destaggered, in the truth's order, and detected at its truth.
TEST(OusterSimScans, InMemoryFramesAreDestaggeredAndTheTagIsDetectedAtItsTruth) {
  constexpr int kRotations = 4;
  const Simulator simulator(
      tag_scene({"os1_64", ouster::Model::kOs1_64, 1024, Profile::kRng19Rfl8Sig16Nir16}));
  eval::SimScans scans(simulator);
  detector::DetectorOptions options;
  options.tag_sizes_m = {1.2};
  options.families = {"tag16h5"};
  detector::Detector det(options);
  detector::ScanResult result;
  std::vector<int64_t> stamps;
  int detected = 0, wrong = 0;
  double worst_m = 0.0;
  std::vector<std::vector<detector::Detection>> found;
  const Truth truth = scans.run(kRotations, 3, [&](const Scan& scan, size_t index) {
    EXPECT_EQ(index, stamps.size());
    EXPECT_TRUE(scan.complete);
    EXPECT_EQ(scan.columns, 1024);
    EXPECT_EQ(scan.rings, 64);
    stamps.push_back(scan.stamp_ns);
    det.detect(scan, result);
    found.push_back(result.detections);
  });
  ASSERT_EQ(stamps.size(), static_cast<size_t>(kRotations));
  for (size_t i = 0; i < stamps.size(); ++i) {
    EXPECT_LT(std::llabs(stamps[i] - truth.rotations[i].stamp_ns), 1000);
    const eval::TagScore score = eval::score_tag(found[i], truth.rotations[i].tags[0]);
    detected += score.detected ? 1 : 0;
    wrong += score.wrong_id ? 1 : 0;
    if (score.detected) worst_m = std::max(worst_m, score.translation_m);
  }
  EXPECT_GE(detected, kRotations - 1);
  EXPECT_EQ(wrong, 0);
  EXPECT_LT(worst_m, 0.05);
}

}  // namespace
}  // namespace lidartag::sim
