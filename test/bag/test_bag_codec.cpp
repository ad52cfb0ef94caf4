// The readers' shared byte codecs (driver/bag/src/internal.hpp): the CRC-32 that checks MCAP
// chunks (ISA-L's) against zlib's at every length, alignment and split, and the decompressor whose
// zstd and lz4 contexts are reused from chunk to chunk, also after a damaged chunk.
#include <gtest/gtest.h>
#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <cstdio>
#include <random>
#include <string_view>

#include "bag/bag_files.hpp"
#include "detector/count_allocations.hpp"
#include "internal.hpp"
#include "lidartag/driver/bag/mcap_writer.hpp"
#include "lidartag/driver/bag/message_reader.hpp"

namespace lidartag::driver::bag::detail {
namespace {

using Bytes = std::vector<uint8_t>;

uint32_t zlib_crc(std::span<const uint8_t> b, uint32_t crc = 0) {
  return static_cast<uint32_t>(::crc32_z(crc, b.data(), b.size()));
}

Bytes random_bytes(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  Bytes b(n);
  for (auto& x : b) x = static_cast<uint8_t>(rng());
  return b;
}

// The readers' crc32() (ISA-L's) and zlib's are the same function of the bytes.
TEST(BagCrc32, CheckValueOfTheStandard) {
  const std::string_view s = "123456789";
  const std::span<const uint8_t> digits(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  EXPECT_EQ(crc32(digits), 0xCBF43926u);
  // The same digits repeated past the folding paths' 64- and 256-byte minimums.
  Bytes many;
  for (int i = 0; i < 100; ++i) many.insert(many.end(), s.begin(), s.end());
  EXPECT_EQ(crc32(many), zlib_crc(many));
}

TEST(BagCrc32, MatchesZlibAtEveryLengthAndAlignment) {
  const Bytes data = random_bytes(4096 + 64, 1);
  for (size_t offset = 0; offset < 16; ++offset)
    for (size_t n = 0; n <= 1100; ++n) {
      const std::span<const uint8_t> s(data.data() + offset, n);
      ASSERT_EQ(crc32(s), zlib_crc(s)) << "offset " << offset << " length " << n;
    }
  // All zeros and all ones (no accidental cancellation in the fold).
  for (const uint8_t fill : {uint8_t{0}, uint8_t{0xFF}}) {
    const Bytes same(5000, fill);
    EXPECT_EQ(crc32(same), zlib_crc(same));
  }
}

TEST(BagCrc32, ContinuesAcrossSplitsAndFromAnyStart) {
  const Bytes data = random_bytes(1 << 20, 2);
  const std::span<const uint8_t> all(data);
  const uint32_t whole = zlib_crc(data);
  EXPECT_EQ(crc32(all), whole);
  std::mt19937 rng(3);
  for (int i = 0; i < 100; ++i) {
    const size_t cut = rng() % data.size();
    EXPECT_EQ(crc32(all.subspan(cut), crc32(all.first(cut))), whole) << "cut at " << cut;
  }
  // A CRC continued from any value matches zlib's continuation.
  for (const uint32_t start : {0u, 1u, 0xFFFFFFFFu, 0x12345678u})
    EXPECT_EQ(crc32(all.first(777), start), zlib_crc(all.first(777), start));
}

TEST(BagCrc32, ChangesWithEveryFlippedBit) {
  Bytes data = random_bytes(1000, 4);
  const uint32_t good = crc32(data);
  for (size_t bit = 0; bit < data.size() * 8; bit += 7) {
    data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    EXPECT_NE(crc32(data), good) << "bit " << bit;
    data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
  }
}

Bytes zstd(const Bytes& raw) {
  Bytes out(ZSTD_compressBound(raw.size()));
  out.resize(ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), 3));
  return out;
}

Bytes lz4(const Bytes& raw) {
  Bytes out(LZ4F_compressFrameBound(raw.size(), nullptr));
  out.resize(LZ4F_compressFrame(out.data(), out.size(), raw.data(), raw.size(), nullptr));
  return out;
}

// Compressible bytes: a repeated random pattern.
Bytes pattern(size_t n, uint32_t seed) {
  const Bytes unit = random_bytes(997, seed);
  Bytes b(n);
  for (size_t i = 0; i < n; ++i) b[i] = unit[i % unit.size()];
  return b;
}

TEST(BagDecompressor, ReusesItsContextsAcrossChunksAndAfterDamage) {
  Decompressor d;
  for (const std::string_view kind : {"zstd", "lz4"}) {
    SCOPED_TRACE(std::string(kind));
    const auto pack = [&](const Bytes& raw) { return kind == "zstd" ? zstd(raw) : lz4(raw); };
    Bytes out;
    for (uint32_t i = 0; i < 3; ++i) {
      const Bytes raw = pattern(100'000 + i * 1000, i);
      EXPECT_EQ(d.run(kind, pack(raw), raw.size(), out), "");
      EXPECT_EQ(out, raw);
    }
    // A frame cut in half, then a corrupt one: each reported, and the next whole frame still
    // decompresses with the same contexts.
    const Bytes raw = pattern(50'000, 9);
    Bytes cut = pack(raw);
    cut.resize(cut.size() / 2);
    EXPECT_NE(d.run(kind, cut, raw.size(), out), "");
    Bytes corrupt = pack(raw);
    for (size_t i = 4; i < corrupt.size(); i += 3) corrupt[i] ^= 0x5A;
    EXPECT_NE(d.run(kind, corrupt, raw.size(), out), "");
    EXPECT_EQ(d.run(kind, pack(raw), raw.size(), out), "");
    EXPECT_EQ(out, raw);
    // A declared size other than the frame's.
    EXPECT_NE(d.run(kind, pack(raw), raw.size() + 1, out), "");
    EXPECT_EQ(d.run(kind, pack(raw), raw.size(), out), "");
    EXPECT_EQ(out, raw);
  }
  Bytes out;
  EXPECT_EQ(d.run("", Bytes{1, 2, 3}, 3, out), "");
  EXPECT_EQ(out, (Bytes{1, 2, 3}));
  EXPECT_NE(d.run("none", Bytes{1, 2, 3}, 4, out), "");
  EXPECT_NE(d.run("brotli", Bytes{1, 2, 3}, 3, out), "");
}

// Reading MCAP chunks (stored, zstd, lz4) allocates once its buffers have reached the chunks'
// size: nothing per message or per chunk after that, whatever the topic filter passes over.
TEST(BagMcapReading, AllocatesNothingPerMessageOrChunkInSteadyState) {
  const testing::TempDir dir;
  for (const auto compression :
       {McapCompression::kNone, McapCompression::kZstd, McapCompression::kLz4}) {
    const std::string path = dir.file("steady_" + std::to_string(static_cast<int>(compression)));
    constexpr int kMessages = 400;
    {
      McapWriterOptions o;
      o.compression = compression;
      o.chunk_bytes = 64 << 10;
      McapWriter w(path, o);
      const uint16_t schema = w.add_schema("test/Blob", "ros2msg", "uint8[] data\n");
      const uint16_t wanted = w.add_channel("/wanted", schema, "cdr");
      const uint16_t other = w.add_channel("/other", schema, "cdr");
      // The same 17 messages in every chunk (4,000 bytes each): chunks of one size.
      for (int i = 0; i < kMessages; ++i) {
        const Bytes data = pattern(4000, static_cast<uint32_t>(i % 17));
        ASSERT_TRUE(w.write(i % 3 == 0 ? other : wanted, 1'000'000'000ULL + uint64_t(i) * 1000,
                            1'000'000'000ULL, data));
      }
      w.close();
    }
    ReaderOptions options;
    options.topics = {"/wanted"};
    const auto reader = open_bag(path, options);
    BagMessage m;
    uint64_t read = 0;
    while (reader->stats().chunks < 3 && reader->next(m)) ++read;  // the buffers grow here
    const long before = lidartag::testing::heap_allocations();
    while (reader->next(m)) ++read;
    EXPECT_EQ(lidartag::testing::heap_allocations() - before, 0);
    EXPECT_EQ(read, uint64_t{kMessages - (kMessages + 2) / 3});
    EXPECT_GT(reader->stats().chunks, 20u);
    EXPECT_EQ(reader->stats().skipped_chunks, 0u);
    EXPECT_EQ(reader->error(), "");
  }
}

}  // namespace
}  // namespace lidartag::driver::bag::detail
