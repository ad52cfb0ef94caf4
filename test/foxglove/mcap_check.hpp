// An independent check of an MCAP file's structure (mcap.dev/spec), for the writer's tests: the
// magic at both ends, the header, every data-section record, each chunk's size and CRC (zlib's
// crc32, not the project's) and records, each Message Index against the messages of its chunk,
// the Data End CRC, the summary's groups against the Summary Offset records, every Chunk Index
// against its chunk and message indexes, the Statistics against what the data section holds and
// the footer's summary CRC. Failures are gtest failures.
#pragma once

#include <gtest/gtest.h>
#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

namespace lidartag::testing {

struct McapCheck {
  bool ok = false;  // the structure was walked to the end
  uint64_t messages = 0, chunks = 0, schemas = 0, channels = 0;
  std::map<uint16_t, uint64_t> per_channel;  // messages found in the data section
  std::map<uint16_t, std::string> topics;
};

namespace mcap_check_detail {

struct Reader {
  const std::vector<uint8_t>& b;
  size_t pos;
  bool ok = true;
  template <class T>
  T get() {
    T v{};
    if (pos + sizeof(T) > b.size()) {
      ok = false;
      return v;
    }
    std::memcpy(&v, b.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  std::string str() {
    const auto n = get<uint32_t>();
    if (!ok || pos + n > b.size()) {
      ok = false;
      return {};
    }
    std::string s(reinterpret_cast<const char*>(b.data() + pos), n);
    pos += n;
    return s;
  }
};

inline uint32_t zcrc(const uint8_t* p, size_t n) {
  return static_cast<uint32_t>(::crc32(0L, p, static_cast<uInt>(n)));
}

inline std::vector<uint8_t> decompress(const std::string& compression, const uint8_t* p, size_t n,
                                       uint64_t size) {
  std::vector<uint8_t> out(size);
  if (compression.empty()) {
    EXPECT_EQ(n, size);
    out.assign(p, p + n);
  } else if (compression == "zstd") {
    const size_t got = ZSTD_decompress(out.data(), out.size(), p, n);
    EXPECT_FALSE(ZSTD_isError(got));
    EXPECT_EQ(got, size);
  } else if (compression == "lz4") {
    LZ4F_dctx* ctx = nullptr;
    EXPECT_FALSE(LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION)));
    size_t dst = out.size(), src = n;
    const size_t r = LZ4F_decompress(ctx, out.data(), &dst, p, &src, nullptr);
    EXPECT_EQ(r, 0u);
    EXPECT_EQ(dst, size);
    LZ4F_freeDecompressionContext(ctx);
  } else {
    ADD_FAILURE() << "unknown compression " << compression;
  }
  return out;
}

}  // namespace mcap_check_detail

inline McapCheck check_mcap(const std::string& path) {
  using namespace mcap_check_detail;
  McapCheck result;
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> b((std::istreambuf_iterator<char>(in)), {});
  const std::string magic("\x89MCAP0\r\n", 8);
  if (b.size() < 8 + 9 + 8 + 29 + 8) {
    ADD_FAILURE() << path << ": too short";
    return result;
  }
  EXPECT_EQ(std::string(b.begin(), b.begin() + 8), magic) << "leading magic";
  EXPECT_EQ(std::string(b.end() - 8, b.end()), magic) << "trailing magic";
  EXPECT_EQ(b[8], 0x01) << "header first";

  // The footer and the summary offsets it gives.
  const size_t footer_at = b.size() - 8 - 29;
  EXPECT_EQ(b[footer_at], 0x02) << "footer last";
  Reader f{b, footer_at + 9};
  const auto summary_start = f.get<uint64_t>();
  const auto summary_offset_start = f.get<uint64_t>();
  const auto summary_crc = f.get<uint32_t>();
  EXPECT_GT(summary_start, 0u);
  EXPECT_LE(summary_start, summary_offset_start);
  EXPECT_LE(summary_offset_start, footer_at);
  EXPECT_EQ(summary_crc, zcrc(b.data() + summary_start, footer_at + 9 + 16 - summary_start))
      << "summary CRC";

  // The data section, record by record.
  std::map<uint64_t, uint64_t> chunk_lengths;                     // chunk offset -> record length
  std::map<uint64_t, std::pair<uint16_t, size_t>> index_records;  // offset -> (channel, entries)
  std::map<uint64_t, uint64_t> chunk_index_lengths;  // chunk offset -> message index bytes
  uint64_t start_time = UINT64_MAX, end_time = 0;
  Reader r{b, 8};
  std::map<uint16_t, std::map<uint64_t, uint64_t>> chunk_messages;  // channel -> offset -> time
  uint64_t last_chunk = 0;
  bool data_end = false;
  while (r.ok && r.pos < summary_start) {
    const size_t at = r.pos;
    const auto op = r.get<uint8_t>();
    const auto len = r.get<uint64_t>();
    if (!r.ok || r.pos + len > b.size()) {
      ADD_FAILURE() << "record at " << at << " runs past the file";
      return result;
    }
    const size_t body = r.pos;
    r.pos += len;
    if (op == 0x0F) {
      Reader d{b, body};
      EXPECT_EQ(d.get<uint32_t>(), zcrc(b.data(), at)) << "data end CRC";
      data_end = true;
      EXPECT_EQ(r.pos, summary_start) << "the summary follows the Data End record";
      break;
    }
    if (op == 0x06) {
      Reader c{b, body};
      const auto t0 = c.get<uint64_t>(), t1 = c.get<uint64_t>();
      const auto size = c.get<uint64_t>();
      const auto crc = c.get<uint32_t>();
      const auto compression = c.str();
      const auto n = c.get<uint64_t>();
      EXPECT_EQ(c.pos + n, body + len) << "chunk records fill the chunk";
      const auto raw = decompress(compression, b.data() + c.pos, n, size);
      EXPECT_EQ(crc, zcrc(raw.data(), raw.size())) << "chunk CRC at " << at;
      ++result.chunks;
      chunk_lengths[at] = 9 + len;
      last_chunk = at;
      chunk_index_lengths[at] = 0;
      chunk_messages.clear();
      Reader cr{raw, 0};
      uint64_t ct0 = UINT64_MAX, ct1 = 0;
      while (cr.ok && cr.pos < raw.size()) {
        const size_t rat = cr.pos;
        const auto rop = cr.get<uint8_t>();
        const auto rlen = cr.get<uint64_t>();
        const size_t rbody = cr.pos;
        cr.pos += rlen;
        EXPECT_LE(cr.pos, raw.size());
        Reader m{raw, rbody};
        if (rop == 0x03) {
          ++result.schemas;
        } else if (rop == 0x04) {
          const auto id = m.get<uint16_t>();
          m.get<uint16_t>();
          result.topics[id] = m.str();
          ++result.channels;
        } else if (rop == 0x05) {
          const auto ch = m.get<uint16_t>();
          m.get<uint32_t>();
          const auto t = m.get<uint64_t>();
          chunk_messages[ch][rat] = t;
          ++result.per_channel[ch];
          ++result.messages;
          ct0 = std::min(ct0, t);
          ct1 = std::max(ct1, t);
          start_time = std::min(start_time, t);
          end_time = std::max(end_time, t);
        } else {
          ADD_FAILURE() << "record " << int(rop) << " in a chunk";
        }
      }
      if (ct0 != UINT64_MAX) {
        EXPECT_EQ(t0, ct0) << "chunk start time";
        EXPECT_EQ(t1, ct1) << "chunk end time";
      }
    } else if (op == 0x07) {
      Reader m{b, body};
      const auto ch = m.get<uint16_t>();
      const auto n = m.get<uint32_t>();
      EXPECT_EQ(n % 16, 0u);
      std::map<uint64_t, uint64_t> entries;
      for (uint32_t i = 0; i < n / 16; ++i) {
        const auto t = m.get<uint64_t>();
        entries[m.get<uint64_t>()] = t;
      }
      EXPECT_EQ(entries, chunk_messages[ch]) << "message index of channel " << ch;
      chunk_messages.erase(ch);
      index_records[at] = {ch, n / 16};
      chunk_index_lengths[last_chunk] += 9 + len;
    } else if (op == 0x03 || op == 0x04 || op == 0x05) {
      ADD_FAILURE() << "unchunked record " << int(op);
    }
  }
  EXPECT_TRUE(data_end) << "Data End record";

  // The summary: groups, then the Summary Offset records pointing at them.
  std::map<uint8_t, std::pair<uint64_t, uint64_t>> groups;  // op -> (start, length)
  Reader s{b, summary_start};
  uint64_t chunk_index_count = 0;
  while (s.ok && s.pos < summary_offset_start) {
    const size_t at = s.pos;
    const auto op = s.get<uint8_t>();
    const auto len = s.get<uint64_t>();
    const size_t body = s.pos;
    s.pos += len;
    auto& g = groups[op];
    if (g.second == 0) g.first = at;
    EXPECT_EQ(g.first + g.second, at) << "group of record " << int(op) << " contiguous";
    g.second += 9 + len;
    Reader x{b, body};
    if (op == 0x0B) {
      EXPECT_EQ(x.get<uint64_t>(), result.messages) << "statistics: messages";
      EXPECT_EQ(x.get<uint16_t>(), result.schemas) << "statistics: schemas";
      EXPECT_EQ(x.get<uint32_t>(), result.channels) << "statistics: channels";
      x.get<uint32_t>();
      x.get<uint32_t>();
      EXPECT_EQ(x.get<uint32_t>(), result.chunks) << "statistics: chunks";
      const auto t0 = x.get<uint64_t>(), t1 = x.get<uint64_t>();
      if (result.messages > 0) {
        EXPECT_EQ(t0, start_time);
        EXPECT_EQ(t1, end_time);
      }
      const auto n = x.get<uint32_t>();
      std::map<uint16_t, uint64_t> counts;
      for (uint32_t i = 0; i < n / 10; ++i) {
        const auto id = x.get<uint16_t>();
        counts[id] = x.get<uint64_t>();
      }
      for (const auto& [id, count] : counts) {
        const auto it = result.per_channel.find(id);
        EXPECT_EQ(count, it == result.per_channel.end() ? 0u : it->second) << "channel " << id;
      }
    } else if (op == 0x08) {
      ++chunk_index_count;
      const auto t0 = x.get<uint64_t>();
      const auto t1 = x.get<uint64_t>();
      (void)t0;
      (void)t1;
      const auto offset = x.get<uint64_t>();
      const auto length = x.get<uint64_t>();
      if (chunk_lengths.count(offset) == 0) {
        ADD_FAILURE() << "chunk index points at " << offset << ", not a chunk";
        continue;
      }
      EXPECT_EQ(chunk_lengths[offset], length);
      const auto n = x.get<uint32_t>();
      for (uint32_t i = 0; i < n / 10; ++i) {
        const auto ch = x.get<uint16_t>();
        const auto off = x.get<uint64_t>();
        EXPECT_TRUE(index_records.count(off)) << "message index offset " << off;
        EXPECT_EQ(index_records[off].first, ch);
        EXPECT_GT(off, offset);
      }
      EXPECT_EQ(x.get<uint64_t>(), chunk_index_lengths[offset]) << "message index length";
    }
  }
  EXPECT_EQ(s.pos, summary_offset_start);
  EXPECT_EQ(chunk_index_count, result.chunks) << "one chunk index per chunk";
  size_t offsets = 0;
  while (s.ok && s.pos < footer_at) {
    const auto op = s.get<uint8_t>();
    const auto len = s.get<uint64_t>();
    EXPECT_EQ(op, 0x0E);
    EXPECT_EQ(len, 17u);
    const auto group = s.get<uint8_t>();
    const auto start = s.get<uint64_t>();
    const auto length = s.get<uint64_t>();
    EXPECT_EQ(groups[group].first, start) << "summary offset of group " << int(group);
    EXPECT_EQ(groups[group].second, length);
    ++offsets;
  }
  EXPECT_EQ(offsets, groups.size()) << "a Summary Offset record per group";
  EXPECT_EQ(s.pos, footer_at);
  result.ok = r.ok && s.ok;
  return result;
}

}  // namespace lidartag::testing
