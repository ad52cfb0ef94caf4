// Damaged copies of the real bags, made here in a temporary folder: truncated files, corrupt and
// unknown-compression chunks, wrong CRCs, random byte flips. Each gives a BagError at the open or a
// reading that ends or skips with the loss counted and described: never a crash, never more
// messages than the file holds. Also the chunk compressions the real files lack (bz2 in ROS 1, lz4
// in MCAP), made by recompressing a real chunk: the same messages come out.
#include <bzlib.h>
#include <gtest/gtest.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <random>

#include "bag/bag_files.hpp"
#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::driver::bag {
namespace {

using testing::bag;
using testing::read_bytes;
using testing::TempDir;
using testing::write_bytes;
using Bytes = std::vector<uint8_t>;

struct Outcome {
  bool opened = false;
  std::string open_error;
  uint64_t messages = 0;
  std::vector<Bytes> data;  // every message's bytes, in order
  ReadStats stats;
  std::string error;
  uint64_t counted() const {
    return stats.truncated + stats.skipped_chunks + stats.skipped_records + stats.read_errors;
  }
};

Outcome read_all(const std::string& path, bool keep = false) {
  Outcome o;
  std::unique_ptr<MessageReader> reader;
  try {
    reader = open_bag(path);
  } catch (const BagError& e) {
    o.open_error = e.what();
    return o;
  }
  o.opened = true;
  BagMessage m;
  while (reader->next(m)) {
    ++o.messages;
    if (keep) o.data.emplace_back(m.data.begin(), m.data.end());
  }
  o.stats = reader->stats();
  o.error = reader->error();
  return o;
}

// A reading of damaged bytes: an open error that names the file, or no more messages than the
// whole file has, and a loss (fewer messages) always counted and described.
void expect_handled(const Outcome& o, uint64_t full, const std::string& path,
                    const std::string& what) {
  SCOPED_TRACE(what);
  if (!o.opened) {
    EXPECT_NE(o.open_error.find(path), std::string::npos) << o.open_error;
    return;
  }
  EXPECT_LE(o.messages, full);
  if (o.messages < full) {
    EXPECT_GT(o.counted(), 0u) << o.messages << " of " << full;
    EXPECT_FALSE(o.error.empty());
  }
}

const std::vector<std::string> kFiles = {"ros1/ouster_os0-128_512x10_packets.bag",
                                         "ros1/luminar_pointcloud2_lz4.bag", "mcap/talker.mcap",
                                         "mcap/cdr_test_0.mcap"};

TEST(BagDamage, TruncatedCopiesOfEveryFormat) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  for (const std::string& name : kFiles) {
    const Bytes whole = read_bytes(bag(name));
    const uint64_t full = read_all(bag(name)).messages;
    const std::string path = dir.file("cut");
    int cut_short = 0;
    for (int k = 0; k < 40; ++k) {
      const size_t size = whole.size() * static_cast<size_t>(k) / 40;
      write_bytes(path, Bytes(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(size)));
      const Outcome o = read_all(path);
      expect_handled(o, full, path, name + " cut at " + std::to_string(size));
      if (o.opened && o.messages < full) ++cut_short;
    }
    EXPECT_GT(cut_short, 0) << name << ": no cut lost a message yet was read";
  }
}

TEST(BagDamage, TruncatedRosbag2) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const std::string src = bag("rosbag2/vlp32c");
  const std::string db = "1713492677464078412_0.db3";
  const Bytes whole = read_bytes(src + "/" + db);
  const std::string folder = dir.file("bag");
  std::filesystem::create_directories(folder);
  std::filesystem::copy_file(src + "/metadata.yaml", folder + "/metadata.yaml");
  for (int k = 0; k < 20; ++k) {
    const size_t size = whole.size() * static_cast<size_t>(k) / 20;
    write_bytes(folder + "/" + db,
                Bytes(whole.begin(), whole.begin() + static_cast<ptrdiff_t>(size)));
    expect_handled(read_all(folder), 5, folder, "cut at " + std::to_string(size));
  }
  // The file metadata.yaml lists, missing.
  std::filesystem::remove(folder + "/" + db);
  const Outcome o = read_all(folder);
  EXPECT_FALSE(o.opened);
  EXPECT_NE(o.open_error.find("which is not there"), std::string::npos) << o.open_error;
}

// The top-level records of an MCAP file: offset, opcode, length.
struct McapRecord {
  size_t offset;
  uint8_t op;
  uint64_t length;
};
std::vector<McapRecord> mcap_records(const Bytes& b) {
  std::vector<McapRecord> r;
  size_t pos = 8;
  while (pos + 9 <= b.size() - 8) {
    McapRecord rec{pos, b[pos], 0};
    std::memcpy(&rec.length, &b[pos + 1], 8);
    r.push_back(rec);
    if (rec.op == 0x02) break;
    pos += 9 + rec.length;
  }
  return r;
}
size_t first_chunk(const Bytes& b) {
  for (const McapRecord& r : mcap_records(b))
    if (r.op == 0x06) return r.offset;
  return 0;
}
// Chunk fields: start, end, uncompressed_size, crc at +9+24, compression string at +9+28.
constexpr size_t kChunkCrc = 9 + 24, kChunkCompression = 9 + 28;

TEST(BagDamage, McapWrongCrcCorruptChunkAndUnknownCompression) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const std::string path = dir.file("damaged.mcap");
  {
    // talker.mcap's zstd chunk carries the CRC of its records (read whole in BagContainers: the
    // CRC is computed right); a changed CRC is a mismatch.
    Bytes b = read_bytes(bag("mcap/talker.mcap"));
    const size_t chunk = first_chunk(b);
    ASSERT_GT(chunk, 0u);
    uint32_t crc = 0;
    std::memcpy(&crc, &b[chunk + kChunkCrc], 4);
    ASSERT_NE(crc, 0u) << "the chunk has a CRC to check";
    b[chunk + kChunkCrc] ^= 0x5A;
    write_bytes(path, b);
    const Outcome o = read_all(path);
    EXPECT_EQ(o.messages, 0u);
    EXPECT_EQ(o.stats.chunks, 1u);
    EXPECT_EQ(o.stats.skipped_chunks, 1u);
    EXPECT_NE(o.error.find("CRC mismatch"), std::string::npos) << o.error;
  }
  {
    // cdr_test_0.mcap's uncompressed chunk has no CRC (0: not checked); one that does not match
    // its records is found.
    Bytes b = read_bytes(bag("mcap/cdr_test_0.mcap"));
    const size_t chunk = first_chunk(b);
    ASSERT_GT(chunk, 0u);
    uint32_t crc = 0;
    std::memcpy(&crc, &b[chunk + kChunkCrc], 4);
    ASSERT_EQ(crc, 0u);
    crc = 0x12345678;
    std::memcpy(&b[chunk + kChunkCrc], &crc, 4);
    write_bytes(path, b);
    const Outcome o = read_all(path);
    EXPECT_EQ(o.messages, 0u);
    EXPECT_EQ(o.stats.skipped_chunks, 1u);
    EXPECT_NE(o.error.find("CRC mismatch"), std::string::npos) << o.error;
  }
  {
    // zstd chunk: a broken frame, an unknown compression.
    Bytes b = read_bytes(bag("mcap/talker.mcap"));
    const size_t chunk = first_chunk(b);
    ASSERT_GT(chunk, 0u);
    uint32_t n = 0;
    std::memcpy(&n, &b[chunk + kChunkCompression], 4);
    ASSERT_EQ(std::string(b.begin() + static_cast<ptrdiff_t>(chunk + kChunkCompression + 4),
                          b.begin() + static_cast<ptrdiff_t>(chunk + kChunkCompression + 4 + n)),
              "zstd");
    Bytes unknown = b;
    unknown[chunk + kChunkCompression + 4 + 3] = 'x';
    write_bytes(path, unknown);
    Outcome o = read_all(path);
    EXPECT_EQ(o.messages, 0u);
    EXPECT_EQ(o.stats.skipped_chunks, 1u);
    EXPECT_NE(o.error.find("unknown compression 'zstx'"), std::string::npos) << o.error;
    Bytes corrupt = b;
    const size_t frame = chunk + kChunkCompression + 4 + n + 8;  // after the records' length
    for (size_t i = 0; i < 4; ++i) corrupt[frame + i] = 0xEE;    // the zstd magic
    write_bytes(path, corrupt);
    o = read_all(path);
    EXPECT_EQ(o.messages, 0u);
    EXPECT_EQ(o.stats.skipped_chunks, 1u);
    EXPECT_NE(o.error.find("zstd"), std::string::npos) << o.error;
  }
}

TEST(BagDamage, McapStatisticsWithAShortCountEntry) {
  LIDARTAG_REQUIRE_BAGS();
  // The summary's Statistics record with its per-channel count map one byte short: the last
  // entry is cut (a hang once, found by a byte-flip run under ASan); the messages are still read.
  Bytes b = read_bytes(bag("mcap/talker.mcap"));
  uint64_t summary = 0;
  std::memcpy(&summary, &b[b.size() - 8 - 29 + 9], 8);
  ASSERT_GT(summary, 8u);
  size_t stats = 0;
  for (size_t pos = summary; pos + 9 < b.size() - 8 - 29;) {
    uint64_t length = 0;
    std::memcpy(&length, &b[pos + 1], 8);
    if (b[pos] == 0x0B) stats = pos;
    pos += 9 + length;
  }
  ASSERT_GT(stats, 0u);
  // message_count 8, schema_count 2, four u32 counts 16, two times 16: the map's length next.
  const size_t map_len = stats + 9 + 8 + 2 + 16 + 16;
  uint32_t n = 0;
  std::memcpy(&n, &b[map_len], 4);
  ASSERT_GT(n, 0u);
  --n;
  std::memcpy(&b[map_len], &n, 4);
  TempDir dir;
  const std::string path = dir.file("stats.mcap");
  write_bytes(path, b);
  const Outcome o = read_all(path);
  EXPECT_TRUE(o.opened) << o.open_error;
  EXPECT_EQ(o.messages, 20u);
}

// Offset of the first occurrence of `text` in `b` at or after `from` (b.size() if none).
size_t find(const Bytes& b, std::string_view text, size_t from = 0) {
  const auto it =
      std::search(b.begin() + static_cast<ptrdiff_t>(from), b.end(), text.begin(), text.end(),
                  [](uint8_t x, char y) { return x == static_cast<uint8_t>(y); });
  return static_cast<size_t>(it - b.begin());
}

TEST(BagDamage, Ros1CorruptChunkAndUnknownCompression) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const std::string path = dir.file("damaged.bag");
  const Bytes b = read_bytes(bag("ros1/luminar_pointcloud2_lz4.bag"));
  // The third chunk's lz4 frame loses its magic.
  size_t chunk = 0;
  for (int i = 0; i < 3; ++i) chunk = find(b, "compression=lz4", chunk + 1);
  ASSERT_LT(chunk, b.size());
  const size_t frame = find(b, std::string_view("\x04\x22\x4d\x18", 4), chunk);
  ASSERT_LT(frame, b.size());
  Bytes corrupt = b;
  corrupt[frame] = 0;
  write_bytes(path, corrupt);
  Outcome o = read_all(path);
  EXPECT_EQ(o.stats.skipped_chunks, 1u);
  EXPECT_EQ(o.stats.chunks, 6u);
  EXPECT_GT(o.messages, 0u);
  EXPECT_LT(o.messages, 15u);
  EXPECT_NE(o.error.find("chunk skipped: lz4"), std::string::npos) << o.error;
  // Every chunk's compression unknown: nothing read, six chunks counted.
  Bytes unknown = b;
  for (size_t at = find(unknown, "compression=lz4"); at < unknown.size();
       at = find(unknown, "compression=lz4", at + 1))
    unknown[at + 14] = '5';
  write_bytes(path, unknown);
  o = read_all(path);
  EXPECT_EQ(o.messages, 0u);
  EXPECT_EQ(o.stats.skipped_chunks, 6u);
  EXPECT_NE(o.error.find("unknown compression 'lz5'"), std::string::npos) << o.error;
}

TEST(BagDamage, RandomByteFlipsNeverCrash) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  std::mt19937 rng(34);
  for (const std::string& name : kFiles) {
    const Bytes whole = read_bytes(bag(name));
    const uint64_t full = read_all(bag(name)).messages;
    const std::string path = dir.file("flipped");
    for (int k = 0; k < 60; ++k) {
      Bytes b = whole;
      const int flips = 1 + k % 8;
      for (int f = 0; f < flips; ++f)
        b[std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng)] ^=
            static_cast<uint8_t>(1u << (rng() % 8));
      write_bytes(path, b);
      const Outcome o = read_all(path);
      // Flips may also change counts or lengths: never more than the file can hold.
      if (o.opened) {
        EXPECT_LE(o.messages, full + 64) << name;
      }
    }
  }
}

TEST(BagDamage, CorruptVelodyneScanMessagesAreCountedNotDecodedPast) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const std::string src = bag("rosbag2/vlp32c"), db = "1713492677464078412_0.db3";
  const std::string folder = dir.file("bag");
  std::filesystem::create_directories(folder);
  std::filesystem::copy_file(src + "/metadata.yaml", folder + "/metadata.yaml");
  std::mt19937 rng(7);
  const Bytes whole = read_bytes(src + "/" + db);
  for (int k = 0; k < 20; ++k) {
    Bytes b = whole;
    for (int f = 0; f < 16; ++f)
      b[std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng)] ^= 0xFF;
    write_bytes(folder + "/" + db, b);
    try {
      velodyne::CaptureReader reader(std::make_unique<BagPacketSource>(folder),
                                     velodyne::CaptureReaderOptions{});
      int n = 0;
      while (reader.next() != nullptr) ++n;
      EXPECT_LE(reader.source_stats().packets, 5u * 76u);
    } catch (const BagError& e) {
      EXPECT_NE(std::string(e.what()).find(folder), std::string::npos) << e.what();
    }
  }
}

// A ROS 1 bag whose one uncompressed chunk is rewritten with `compress` under `compression`; the
// index position in the bag header is moved along.
Bytes recompress_ros1_chunk(const Bytes& b, const std::string& compression,
                            const std::function<Bytes(const Bytes&)>& compress) {
  auto u32 = [&](size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, &b[at], 4);
    return v;
  };
  const size_t header_record = 13;
  const size_t chunk =
      header_record + 8 + u32(header_record) + u32(header_record + 4 + u32(header_record));
  const uint32_t header_len = u32(chunk);
  const uint32_t data_len = u32(chunk + 4 + header_len);
  const size_t data = chunk + 8 + header_len;
  const Bytes raw(b.begin() + static_cast<ptrdiff_t>(data),
                  b.begin() + static_cast<ptrdiff_t>(data + data_len));
  const Bytes packed = compress(raw);
  Bytes header;
  auto field = [&](const std::string& name, const Bytes& value) {
    const auto len = static_cast<uint32_t>(name.size() + 1 + value.size());
    header.insert(header.end(), reinterpret_cast<const uint8_t*>(&len),
                  reinterpret_cast<const uint8_t*>(&len) + 4);
    header.insert(header.end(), name.begin(), name.end());
    header.push_back('=');
    header.insert(header.end(), value.begin(), value.end());
  };
  const auto size = static_cast<uint32_t>(raw.size());
  field("op", {0x05});
  field("compression", Bytes(compression.begin(), compression.end()));
  field("size", Bytes(reinterpret_cast<const uint8_t*>(&size),
                      reinterpret_cast<const uint8_t*>(&size) + 4));
  Bytes out(b.begin(), b.begin() + static_cast<ptrdiff_t>(chunk));
  const auto hl = static_cast<uint32_t>(header.size()), dl = static_cast<uint32_t>(packed.size());
  out.insert(out.end(), reinterpret_cast<const uint8_t*>(&hl),
             reinterpret_cast<const uint8_t*>(&hl) + 4);
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), reinterpret_cast<const uint8_t*>(&dl),
             reinterpret_cast<const uint8_t*>(&dl) + 4);
  out.insert(out.end(), packed.begin(), packed.end());
  out.insert(out.end(), b.begin() + static_cast<ptrdiff_t>(data + data_len), b.end());
  const auto delta = static_cast<int64_t>(out.size()) - static_cast<int64_t>(b.size());
  const size_t index_pos = find(out, "index_pos=") + 10;
  int64_t pos = 0;
  std::memcpy(&pos, &out[index_pos], 8);
  pos += delta;
  std::memcpy(&out[index_pos], &pos, 8);
  return out;
}

TEST(BagDamage, Ros1Bz2AndLz4ChunksReadAsTheUncompressedOne) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const std::string name = "ros1/ouster_os0-128_512x10_packets.bag";
  const Outcome plain = read_all(bag(name), true);
  ASSERT_EQ(plain.messages, 43u);
  const Bytes b = read_bytes(bag(name));
  const auto bz2 = [](const Bytes& raw) {
    Bytes out(raw.size() + raw.size() / 100 + 600);
    auto n = static_cast<unsigned>(out.size());
    EXPECT_EQ(BZ2_bzBuffToBuffCompress(reinterpret_cast<char*>(out.data()), &n,
                                       const_cast<char*>(reinterpret_cast<const char*>(raw.data())),
                                       static_cast<unsigned>(raw.size()), 9, 0, 0),
              BZ_OK);
    out.resize(n);
    return out;
  };
  const auto lz4 = [](const Bytes& raw) {
    Bytes out(LZ4F_compressFrameBound(raw.size(), nullptr));
    const size_t n = LZ4F_compressFrame(out.data(), out.size(), raw.data(), raw.size(), nullptr);
    EXPECT_FALSE(LZ4F_isError(n));
    out.resize(n);
    return out;
  };
  for (const auto& [compression, compress] :
       std::vector<std::pair<std::string, std::function<Bytes(const Bytes&)>>>{{"bz2", bz2},
                                                                               {"lz4", lz4}}) {
    SCOPED_TRACE(compression);
    const std::string path = dir.file(compression + ".bag");
    const Bytes packed = recompress_ros1_chunk(b, compression, compress);
    EXPECT_LT(packed.size(), b.size());
    write_bytes(path, packed);
    const Outcome o = read_all(path, true);
    EXPECT_EQ(o.messages, 43u);
    EXPECT_EQ(o.data, plain.data);
    EXPECT_EQ(o.error, "");
    // The same, truncated inside the compressed chunk: counted, described.
    write_bytes(path,
                Bytes(packed.begin(), packed.begin() + static_cast<ptrdiff_t>(packed.size() / 2)));
    const Outcome cut = read_all(path);
    EXPECT_EQ(cut.messages, 0u);
    EXPECT_EQ(cut.stats.truncated, 1u);
    EXPECT_FALSE(cut.error.empty());
  }
}

TEST(BagDamage, McapLz4ChunkReadsAsTheZstdOne) {
  LIDARTAG_REQUIRE_BAGS();
  TempDir dir;
  const Outcome zstd = read_all(bag("mcap/talker.mcap"), true);
  ASSERT_EQ(zstd.messages, 20u);
  Bytes b = read_bytes(bag("mcap/talker.mcap"));
  const size_t chunk = first_chunk(b);
  ASSERT_GT(chunk, 0u);
  // Rebuild the chunk record: the same records (from the reading above they are not available as
  // a block, so decompress the original frame), lz4-compressed.
  uint64_t length = 0, size = 0, records_len = 0;
  std::memcpy(&length, &b[chunk + 1], 8);
  std::memcpy(&size, &b[chunk + 9 + 16], 8);
  const size_t compression_at = chunk + kChunkCompression;
  uint32_t n = 0;
  std::memcpy(&n, &b[compression_at], 4);
  const size_t records_at = compression_at + 4 + n;
  std::memcpy(&records_len, &b[records_at], 8);
  Bytes raw(size);
  ASSERT_EQ(ZSTD_decompress(raw.data(), raw.size(), &b[records_at + 8], records_len), size);
  Bytes packed(LZ4F_compressFrameBound(raw.size(), nullptr));
  packed.resize(LZ4F_compressFrame(packed.data(), packed.size(), raw.data(), raw.size(), nullptr));
  Bytes body(b.begin() + static_cast<ptrdiff_t>(chunk + 9),
             b.begin() + static_cast<ptrdiff_t>(compression_at));  // times, size, crc
  const uint32_t lz4_len = 3;
  body.insert(body.end(), reinterpret_cast<const uint8_t*>(&lz4_len),
              reinterpret_cast<const uint8_t*>(&lz4_len) + 4);
  body.insert(body.end(), {'l', 'z', '4'});
  const uint64_t packed_len = packed.size();
  body.insert(body.end(), reinterpret_cast<const uint8_t*>(&packed_len),
              reinterpret_cast<const uint8_t*>(&packed_len) + 8);
  body.insert(body.end(), packed.begin(), packed.end());
  Bytes out(b.begin(), b.begin() + static_cast<ptrdiff_t>(chunk));
  out.push_back(0x06);
  const uint64_t body_len = body.size();
  out.insert(out.end(), reinterpret_cast<const uint8_t*>(&body_len),
             reinterpret_cast<const uint8_t*>(&body_len) + 8);
  out.insert(out.end(), body.begin(), body.end());
  out.insert(out.end(), b.begin() + static_cast<ptrdiff_t>(chunk + 9 + length), b.end());
  const std::string path = dir.file("lz4.mcap");
  write_bytes(path, out);
  const Outcome o = read_all(path, true);
  EXPECT_EQ(o.messages, 20u);
  EXPECT_EQ(o.data, zstd.data);
  EXPECT_EQ(o.stats.skipped_chunks, 0u);
}

}  // namespace
}  // namespace lidartag::driver::bag
