// Exactness against the Ouster SDK's own decoder: the MD5 digests of ../shared/captures/ouster
// (README there: `packet_hash` per key over all lidar packets, `scans` per whole frame) recomputed
// from what lidartag's Ouster packet readers decode, every key compared. The other captures: their
// packet and frame counts.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "driver/md5.hpp"
#include "driver/ouster_captures.hpp"
#include "lidartag/driver/ouster/decoder.hpp"

namespace lidartag::driver::ouster {
namespace {

namespace fs = std::filesystem;
using lidartag::testing::Md5;
using testing::capture_files;
using testing::ouster_dir;

// A field's value appended to a hash in the field's own integer type.
void put(Md5& h, FieldType t, uint32_t v) {
  switch (t) {
    case FieldType::kU8:
      h.update_value(static_cast<uint8_t>(v));
      break;
    case FieldType::kU16:
      h.update_value(static_cast<uint16_t>(v));
      break;
    case FieldType::kU32:
      h.update_value(v);
      break;
  }
}

// The column arrays' keys and how they are hashed.
struct ColumnKey {
  const char* name;
  int packet_bytes;  // per column in packet_hash
  int scan_bytes;    // per column in scans
};
constexpr ColumnKey kColumnKeys[] = {{"TIMESTAMP", 8, 8},
                                     {"ENCODER_COUNT", 4, 8},
                                     {"MEASUREMENT_ID", 2, 2},
                                     {"STATUS", 4, 8},
                                     {"FRAME_ID", 2, 0}};

uint64_t column_value(const ColumnHeader& h, std::string_view key) {
  if (key == "TIMESTAMP") return h.timestamp_ns;
  if (key == "ENCODER_COUNT") return h.encoder_count;
  if (key == "MEASUREMENT_ID") return h.measurement_id;
  if (key == "STATUS") return h.status;
  return h.frame_id;
}

void put_bytes(Md5& h, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) {
    const auto b = static_cast<uint8_t>(v >> (8 * i));
    h.update(&b, 1);
  }
}

struct Frame {
  uint32_t frame_id = 0;
  std::vector<std::vector<uint8_t>> packets;  // in file order
};

class OusterDigest : public ::testing::TestWithParam<size_t> {};

TEST_P(OusterDigest, EveryKeyOfEveryDigestMatches) {
  const auto& cf = capture_files()[GetParam()];
  const std::string stem = ouster_dir() + "/pcaps/" + cf.pcap;
  if (!fs::exists(stem + ".pcap")) GTEST_SKIP() << "Ouster captures not found at " << stem;
  ASSERT_TRUE(cf.has_digest);
  const SensorInfo info = load_metadata(ouster_dir() + "/pcaps/" + cf.metadata + ".json");
  Decoder decoder(info);
  const PacketFormat& f = decoder.format();
  const ProfileSpec& spec = *f.spec;
  const auto packets = testing::read_packets(stem + ".pcap");
  ASSERT_EQ(packets.lidar.size(), cf.lidar_packets);
  nlohmann::json digest;
  std::ifstream(stem + "_digest.json") >> digest;

  // packet_hash: over every lidar packet, per key.
  std::map<std::string, Md5> hashes;
  std::vector<Frame> frames;
  for (const auto& p : packets.lidar) {
    PacketColumns parsed;
    ASSERT_EQ(decoder.parse(p, parsed), DecodeStatus::kOk);
    if (frames.empty() || frames.back().frame_id != parsed.frame_id)
      frames.push_back({parsed.frame_id, {}});
    frames.back().packets.push_back(p);
    for (const ColumnKey& k : kColumnKeys)
      for (int c = 0; c < f.columns; ++c)
        put_bytes(hashes[k.name], column_value(read_column_header(p.data(), f, c), k.name),
                  k.packet_bytes);
    for (const FieldSpec& fs : spec.fields) {
      Md5& h = hashes[std::string(field_name(fs.field))];
      for (int row = 0; row < f.pixels; ++row)
        for (int c = 0; c < f.columns; ++c)
          put(h, fs.type, field_value(f.pixel(p.data(), c, row), fs));
    }
  }
  int compared = 0;
  for (const auto& [key, want] : digest["packet_hash"].items()) {
    ASSERT_TRUE(hashes.count(key)) << "packet_hash key " << key << " not decoded";
    EXPECT_EQ(hashes[key].hex(), want.get<std::string>()) << cf.pcap << " packet_hash " << key;
    ++compared;
  }
  std::cout << cf.pcap << ": packet_hash " << compared << " keys compared\n";

  // scans: per whole frame, each array H x W (staggered), columns by measurement id.
  const auto& scans = digest["scans"];
  ASSERT_EQ(frames.size(), scans.size());
  const auto w = static_cast<size_t>(info.columns_per_frame);
  const auto h = static_cast<size_t>(f.pixels);
  for (size_t i = 0; i < frames.size(); ++i) {
    const auto& want = scans[i];
    EXPECT_EQ(std::to_string(frames[i].frame_id), want["FRAME_ID"].get<std::string>());
    std::map<std::string, std::vector<uint64_t>> columns;
    std::map<std::string, std::vector<uint32_t>> image;
    for (const auto& p : frames[i].packets) {
      for (int c = 0; c < f.columns; ++c) {
        const ColumnHeader ch = read_column_header(p.data(), f, c);
        const size_t m = ch.measurement_id;
        ASSERT_LT(m, w);
        for (const ColumnKey& k : kColumnKeys) {
          auto& v = columns[k.name];
          v.resize(w);
          v[m] = column_value(ch, k.name);
        }
        for (const FieldSpec& fs : spec.fields) {
          auto& v = image[std::string(field_name(fs.field))];
          v.resize(w * h);
          for (size_t row = 0; row < h; ++row)
            v[row * w + m] = field_value(f.pixel(p.data(), c, static_cast<int>(row)), fs);
        }
      }
    }
    int scan_keys = 0;
    for (const auto& [key, value] : want.items()) {
      if (key == "FRAME_ID") continue;
      Md5 hash;
      bool known = false;
      for (const ColumnKey& k : kColumnKeys)
        if (key == k.name && k.scan_bytes > 0) {
          for (uint64_t v : columns[key]) put_bytes(hash, v, k.scan_bytes);
          known = true;
        }
      for (const FieldSpec& fs : spec.fields)
        if (key == field_name(fs.field)) {
          for (uint32_t v : image[key]) put(hash, fs.type, v);
          known = true;
        }
      ASSERT_TRUE(known) << "scans key " << key << " not decoded";
      EXPECT_EQ(hash.hex(), value.get<std::string>()) << cf.pcap << " scan " << i << " " << key;
      ++scan_keys;
    }
    std::cout << cf.pcap << ": frame " << frames[i].frame_id << " " << scan_keys + 1
              << " scans keys compared\n";
  }
}

INSTANTIATE_TEST_SUITE_P(Captures, OusterDigest, ::testing::Values(0, 1, 2, 3, 4),
                         [](const auto& p) {
                           std::string n = capture_files()[p.param].pcap;
                           for (char& c : n)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return n;
                         });

TEST(OusterCaptures, PacketAndFrameCountsWithImuCountedApart) {
  if (!fs::exists(ouster_dir() + "/pcaps")) GTEST_SKIP() << "Ouster captures not found";
  for (const auto& cf : capture_files()) {
    SCOPED_TRACE(cf.pcap);
    const SensorInfo info = load_metadata(ouster_dir() + "/pcaps/" + cf.metadata + ".json");
    Decoder decoder(info);
    const auto packets = testing::read_packets(ouster_dir() + "/pcaps/" + cf.pcap + ".pcap");
    EXPECT_EQ(packets.lidar.size(), cf.lidar_packets);
    EXPECT_EQ(packets.imu, cf.imu_packets);
    EXPECT_EQ(packets.imu_wrong_size, 0u);
    size_t frames = 0;
    uint32_t last = 0;
    for (const auto& p : packets.lidar) {
      PacketColumns parsed;
      ASSERT_EQ(decoder.parse(p, parsed), DecodeStatus::kOk);
      if (frames == 0 || parsed.frame_id != last) ++frames;
      last = parsed.frame_id;
    }
    EXPECT_EQ(frames, cf.frames);
    EXPECT_EQ(decoder.stats().rejected(), 0u);
  }
}

}  // namespace
}  // namespace lidartag::driver::ouster
