// Ouster metadata in both layouts (every file of ../shared/captures/ouster/metadata loads, each of
// metadata/malformed is refused naming the key), and packets refused by size and identity.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>

#include "driver/md5.hpp"
#include "driver/ouster_captures.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/ouster/metadata.hpp"

namespace lidartag::driver::ouster {
namespace {

namespace fs = std::filesystem;
using testing::ouster_dir;

TEST(Md5, KnownVectorsOfRfc1321) {
  auto md5 = [](const std::string& s) {
    lidartag::testing::Md5 h;
    h.update(s.data(), s.size());
    return h.hex();
  };
  EXPECT_EQ(md5(""), "d41d8cd98f00b204e9800998ecf8427e");
  EXPECT_EQ(md5("abc"), "900150983cd24fb0d6963f7d28e17f72");
  EXPECT_EQ(md5("message digest"), "f96b697d7cb7938d525a2f31aaf161d0");
  EXPECT_EQ(md5("12345678901234567890123456789012345678901234567890123456789012345678901234567890"),
            "57edf4a22be3c955ac49da2e2107b67a");
}

TEST(OusterMetadata, EveryFileLoadsInEitherLayout) {
  const fs::path dir = ouster_dir() + "/metadata";
  if (!fs::exists(dir)) GTEST_SKIP() << "Ouster captures not found at " << dir;
  int flat = 0, nested = 0;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".json") files.push_back(e.path());
  for (const auto& e : fs::directory_iterator(ouster_dir() + "/pcaps"))
    if (e.path().extension() == ".json" && e.path().string().find("_digest") == std::string::npos)
      files.push_back(e.path());
  ASSERT_GE(files.size(), 30u);
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.filename().string());
    SensorInfo s;
    ASSERT_NO_THROW(s = load_metadata(f.string()));
    ++(s.nested_layout ? nested : flat);
    const auto n = s.beam_altitude_deg.size();
    EXPECT_TRUE(n == 16 || n == 32 || n == 64 || n == 128);
    EXPECT_EQ(s.beam_azimuth_deg.size(), n);
    EXPECT_EQ(static_cast<size_t>(s.pixels_per_column), n);
    EXPECT_EQ(s.pixel_shift_by_row.size(), n);
    EXPECT_EQ(s.columns_per_frame, s.mode_columns);
    EXPECT_GT(s.lidar_origin_to_beam_origin_mm, 0.0);
    EXPECT_LE(s.column_window[0], s.column_window[1]);
    EXPECT_EQ(s.lidar_to_sensor_transform[15], 1.0);
    // The packet size of its profile and shape is one a UDP datagram carries.
    EXPECT_LT(PacketFormat::of(s).packet_bytes, 65507u);
  }
  EXPECT_GE(flat, 10);
  EXPECT_GE(nested, 8);
}

TEST(OusterMetadata, FieldsOfBothLayoutsAgree) {
  const std::string dir = ouster_dir() + "/metadata/";
  if (!fs::exists(dir)) GTEST_SKIP() << "Ouster captures not found at " << dir;
  // The same sensor and firmware, written in both layouts.
  for (const char* stem :
       {"2_5_0_os-992146000760-128", "3_0_1_os-122246000293-128", "2_2_os-992119000444-128"}) {
    SCOPED_TRACE(stem);
    const SensorInfo a = load_metadata(dir + stem + ".json");
    const SensorInfo b = load_metadata(dir + stem + "_legacy.json");
    EXPECT_TRUE(a.nested_layout);
    EXPECT_FALSE(b.nested_layout);
    EXPECT_EQ(a.beam_altitude_deg, b.beam_altitude_deg);
    EXPECT_EQ(a.beam_azimuth_deg, b.beam_azimuth_deg);
    EXPECT_EQ(a.lidar_origin_to_beam_origin_mm, b.lidar_origin_to_beam_origin_mm);
    EXPECT_EQ(a.lidar_to_sensor_transform, b.lidar_to_sensor_transform);
    EXPECT_EQ(a.pixel_shift_by_row, b.pixel_shift_by_row);
    EXPECT_EQ(a.column_window, b.column_window);
    EXPECT_EQ(a.profile, b.profile);
    EXPECT_EQ(a.serial_number, b.serial_number);
    EXPECT_EQ(a.init_id, b.init_id);
    EXPECT_EQ(a.mode_columns, b.mode_columns);
    EXPECT_EQ(a.mode_rate_hz, b.mode_rate_hz);
    EXPECT_NE(a.serial_number, 0u);
  }
  // Values read, not defaulted: a capture's metadata.
  const SensorInfo s =
      load_metadata(ouster_dir() + "/pcaps/OS-1-128_767798045_1024x10_20230712_120049.json");
  EXPECT_EQ(s.profile, Profile::kFusaRng15Rfl8Nir8Dual);
  EXPECT_EQ(s.serial_number, 122246000293u);
  EXPECT_EQ(s.init_id, 390076u);
  EXPECT_EQ(s.prod_line, "OS-1-128");
  EXPECT_EQ(s.lidar_origin_to_beam_origin_mm, 16.721);
  EXPECT_EQ(s.pixel_shift_by_row[0], 12);
  EXPECT_EQ(s.returns(), 2);
  const SensorInfo w = load_metadata(dir + "2_0_0_os1-992008000494-128_col_win_legacy.json");
  EXPECT_EQ(w.column_window[0], 2014);
  EXPECT_EQ(w.column_window[1], 2036);
  EXPECT_EQ(w.mode_columns, 2048);
  const SensorInfo legacy = load_metadata(ouster_dir() + "/pcaps/OS-1-32-G_v2.1.1_1024x10.json");
  EXPECT_EQ(legacy.profile, Profile::kLegacy);  // no udp_profile_lidar
  EXPECT_EQ(legacy.firmware, "v2.1.1");
  // Firmware 1.x reported no data format: its defaults.
  const SensorInfo old = load_metadata(dir + "1_12_os1-991937000062-64_legacy.json");
  EXPECT_FALSE(old.data_format_reported);
  EXPECT_EQ(old.columns_per_packet, 16);
  EXPECT_EQ(old.pixels_per_column, 64);
}

TEST(OusterMetadata, MalformedFilesAreRefusedNamingTheKey) {
  const std::string dir = ouster_dir() + "/metadata/malformed/";
  if (!fs::exists(dir)) GTEST_SKIP() << "Ouster captures not found at " << dir;
  // Each file, and the key its message must name.
  const std::map<std::string, std::string> expected = {
      {"complete_but_all_zeros_legacy.json", "beam_altitude_angles"},
      {"garbled_legacy_and_nonlegacy.json", "layouts mixed"},
      {"incomplete_data_format_legacy.json", "data_format.columns_per_frame"},
      {"incomplete_data_format_nonlegacy.json", "lidar_data_format.pixels_per_column"},
      {"incomplete_no_calref_nonlegacy.json", "calibration_status"},
      {"incomplete_no_sensor_info_nonlegacy.json", "sensor_info"},
      {"incorrect_nbeam_angles_legacy_113.json", "beam_azimuth_angles"},
      {"legacy_with_calibration_status.json", "calibration_status"},
  };
  size_t seen = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    SCOPED_TRACE(name);
    ++seen;
    try {
      (void)load_metadata(e.path().string());
      ADD_FAILURE() << "accepted";
    } catch (const MetadataError& err) {
      const std::string what = err.what();
      ASSERT_TRUE(expected.count(name)) << "unexpected file; message: " << what;
      EXPECT_NE(what.find(expected.at(name)), std::string::npos) << what;
      EXPECT_NE(what.find(name), std::string::npos) << "names the file: " << what;
    }
  }
  EXPECT_EQ(seen, expected.size());
  EXPECT_THROW((void)parse_metadata("{\"beam_intrinsics\": 3"), MetadataError);
  EXPECT_THROW((void)parse_metadata("[1, 2]"), MetadataError);
  EXPECT_THROW((void)load_metadata(dir + "no such file.json"), MetadataError);
}

TEST(OusterPackets, WrongSizeInitIdSerialAndTypeAreCountedRejects) {
  const std::string stem = ouster_dir() + "/pcaps/OS-2-128-U1_v2.3.0_1024x10";
  if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
  Decoder decoder(load_metadata(stem + ".json"));
  const auto packets = testing::read_packets(stem + ".pcap");
  ASSERT_FALSE(packets.lidar.empty());
  std::vector<uint8_t> p = packets.lidar.front();
  PacketColumns out;
  ASSERT_EQ(decoder.parse(p, out), DecodeStatus::kOk);
  EXPECT_EQ(out.frame_id, 1259u);
  EXPECT_EQ(out.header.serial_number, 992210000957u);
  EXPECT_EQ(out.header.init_id, 5431293u);
  PacketColumns untouched;
  untouched.frame_id = 77;
  // Short, long, empty.
  EXPECT_EQ(decoder.parse(std::span(p.data(), p.size() - 1), untouched), DecodeStatus::kWrongSize);
  std::vector<uint8_t> longer = p;
  longer.push_back(0);
  EXPECT_EQ(decoder.parse(longer, untouched), DecodeStatus::kWrongSize);
  EXPECT_EQ(decoder.parse({}, untouched), DecodeStatus::kWrongSize);
  // Another configuration (init id), another sensor (serial number), not lidar data.
  std::vector<uint8_t> q = p;
  q[4] ^= 1;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kWrongInitId);
  q = p;
  q[9] ^= 0x10;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kWrongSerial);
  q = p;
  q[0] = 2;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kWrongPacketType);
  // A valid column's measurement id beyond the frame.
  q = p;
  q[32 + 8] = 0xFF;
  q[32 + 9] = 0xFF;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kBadMeasurementId);
  // A timestamp beyond what the assembly's time arithmetic holds (2^32 s).
  q = p;
  q[32 + 7] = 0x80;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kBadTimestamp);
  // Every column's status bit clear.
  q = p;
  const PacketFormat& f = decoder.format();
  for (int c = 0; c < f.columns; ++c) q[32 + static_cast<size_t>(c) * f.column_bytes + 10] = 0;
  EXPECT_EQ(decoder.parse(q, untouched), DecodeStatus::kNoValidColumn);
  EXPECT_EQ(untouched.frame_id, 77u);  // refused packets leave the output alone
  // Garbage of the right size.
  std::vector<uint8_t> junk(p.size(), 0xA5);
  EXPECT_NE(decoder.parse(junk, untouched), DecodeStatus::kOk);
  const DecoderStats& st = decoder.stats();
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kOk)], 1u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kWrongSize)], 3u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kWrongInitId)], 1u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kWrongSerial)], 1u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kWrongPacketType)], 2u);  // the junk's too
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kBadMeasurementId)], 1u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kNoValidColumn)], 1u);
  EXPECT_EQ(st.by_status[size_t(DecodeStatus::kBadTimestamp)], 1u);
  EXPECT_EQ(st.rejected(), 10u);
  // Checks off: a packet of another init id is taken.
  DecoderOptions lax;
  lax.check_init_id = false;
  Decoder tolerant(load_metadata(stem + ".json"), lax);
  q = p;
  q[4] ^= 1;
  EXPECT_EQ(tolerant.parse(q, out), DecodeStatus::kOk);
}

TEST(OusterPackets, ADecoderRefusesAHandMadeInfoThatContradictsItself) {
  SensorInfo s;
  s.pixels_per_column = 256;
  EXPECT_THROW(Decoder{s}, std::invalid_argument);
  s.pixels_per_column = 16;
  s.columns_per_packet = 16;
  s.columns_per_frame = s.mode_columns = 1024;
  s.mode_rate_hz = 10;
  s.beam_altitude_deg.assign(16, 1.0);
  s.beam_azimuth_deg.assign(15, 0.0);  // one short
  s.pixel_shift_by_row.assign(16, 0);
  EXPECT_THROW(Decoder{s}, std::invalid_argument);
  s.beam_azimuth_deg.assign(16, 0.0);
  EXPECT_NO_THROW(Decoder{s});
}

TEST(OusterPackets, SignalIntensityIsRefusedWhereTheProfileHasNone) {
  const std::string json = ouster_dir() + "/pcaps/OS-0-128-U1_v2.3.0_1024x10.json";
  if (!fs::exists(json)) GTEST_SKIP() << "Ouster captures not found at " << json;
  DecoderOptions o;
  o.intensity = IntensitySource::kSignal;
  EXPECT_THROW(Decoder(load_metadata(json), o), std::invalid_argument);
  EXPECT_NO_THROW(
      Decoder(load_metadata(ouster_dir() + "/pcaps/OS-2-128-U1_v2.3.0_1024x10.json"), o));
}

}  // namespace
}  // namespace lidartag::driver::ouster
