// MCAP writer (mcap.dev/spec). Every record is <opcode u8><content length u64><content>, little
// endian; strings are <u32 length><bytes>, maps and arrays <u32 byte length><entries>. The file:
//   magic, Header, data section (Chunks, each followed by its Message Index records), Data End,
//   summary section (Schema, Channel, Statistics, Chunk Index groups), Summary Offset records,
//   Footer, magic.
// Offsets in Message Index records count from the start of the chunk's uncompressed records;
// Chunk Index offsets and lengths count whole records (opcode and length included) from the
// start of the file.
#include "lidartag/driver/bag/mcap_writer.hpp"

#include <lz4frame.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "internal.hpp"

namespace lidartag::driver::bag {
namespace {

constexpr std::string_view kMagic = "\x89MCAP0\r\n";
constexpr uint8_t kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05,
                  kChunk = 0x06, kMessageIndex = 0x07, kChunkIndex = 0x08, kStatistics = 0x0B,
                  kSummaryOffset = 0x0E, kDataEnd = 0x0F;
constexpr size_t kRecordHead = 9;  // opcode + u64 length

template <class T, class Out>
void put(Out& out, T value) {
  const auto at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &value, sizeof(T));
}

template <class Out>
void put_bytes(Out& out, const void* data, size_t n) {
  const auto at = out.size();
  out.resize(at + n);
  if (n > 0) std::memcpy(out.data() + at, data, n);
}

template <class Out>
void put_string(Out& out, std::string_view s) {
  put(out, static_cast<uint32_t>(s.size()));
  put_bytes(out, s.data(), s.size());
}

// Starts a record: the opcode and a length patched by end_record().
template <class Out>
size_t begin_record(Out& out, uint8_t op) {
  put(out, op);
  const size_t at = out.size();
  put(out, uint64_t{0});
  return at;
}

template <class Out>
void end_record(Out& out, size_t length_at) {
  const uint64_t length = out.size() - length_at - 8;
  std::memcpy(out.data() + length_at, &length, 8);
}

std::span<const uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

std::string_view compression_name(McapCompression c) {
  switch (c) {
    case McapCompression::kZstd:
      return "zstd";
    case McapCompression::kLz4:
      return "lz4";
    case McapCompression::kNone:
      break;
  }
  return "";
}

}  // namespace

McapCompression parse_mcap_compression(std::string_view name) {
  if (name == "none" || name.empty()) return McapCompression::kNone;
  if (name == "zstd") return McapCompression::kZstd;
  if (name == "lz4") return McapCompression::kLz4;
  throw McapWriteError("unknown MCAP compression '" + std::string(name) + "' (none, zstd or lz4)");
}

struct McapWriter::Context {
  ZSTD_CCtx* zstd = nullptr;
  ~Context() { ZSTD_freeCCtx(zstd); }
};

McapWriter::McapWriter(const std::string& path, McapWriterOptions options)
    : path_(path), options_(std::move(options)), context_(std::make_unique<Context>()) {
  namespace fs = std::filesystem;
  if (options_.chunk_bytes == 0) throw McapWriteError(path + ": chunk_bytes must be >= 1");
  std::error_code ec;
  const auto st = fs::symlink_status(path, ec);
  if (!ec && fs::exists(st) && !fs::is_regular_file(st)) {
    throw McapWriteError(path + ": exists and is not a regular file (refused as an MCAP output)");
  }
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr) {
    throw McapWriteError(path + ": cannot create: " + std::strerror(errno));
  }
  std::setvbuf(file_, nullptr, _IOFBF, 1u << 20);
  if (options_.compression == McapCompression::kZstd) {
    context_->zstd = ZSTD_createCCtx();
    if (context_->zstd == nullptr) {
      std::fclose(file_);
      file_ = nullptr;
      throw McapWriteError(path + ": cannot create a zstd context");
    }
  }
  record_.clear();
  put_bytes(record_, kMagic.data(), kMagic.size());
  const size_t at = begin_record(record_, kHeader);
  put_string(record_, options_.profile);
  put_string(record_, options_.library);
  end_record(record_, at);
  emit(record_);
  if (!error_.empty()) {
    std::fclose(file_);
    file_ = nullptr;
    throw McapWriteError(error_);
  }
}

McapWriter::~McapWriter() {
  try {
    close();
  } catch (const std::exception&) {
    // error() keeps the reason; a destructor cannot report it.
  }
}

uint16_t McapWriter::add_schema(std::string_view name, std::string_view encoding,
                                std::string_view data) {
  if (closed()) throw McapWriteError(path_ + ": add_schema after close");
  if (schema_records_.size() >= 0xFFFEu) throw McapWriteError(path_ + ": too many schemas");
  const auto id = static_cast<uint16_t>(schema_records_.size() + 1);
  std::string rec;
  const size_t at = begin_record(rec, kSchema);
  put(rec, id);
  put_string(rec, name);
  put_string(rec, encoding);
  put_string(rec, data);  // <u32 length><bytes>, as a string is
  end_record(rec, at);
  put_bytes(chunk_, rec.data(), rec.size());
  schema_records_.push_back(std::move(rec));
  return id;
}

uint16_t McapWriter::add_channel(std::string_view topic, uint16_t schema,
                                 std::string_view message_encoding,
                                 const std::map<std::string, std::string>& metadata) {
  if (closed()) throw McapWriteError(path_ + ": add_channel after close");
  if (schema > schema_records_.size()) {
    throw McapWriteError(path_ + ": channel '" + std::string(topic) + "' names schema " +
                         std::to_string(schema) + ", which was not added");
  }
  if (channels_.size() >= 0xFFFFu) throw McapWriteError(path_ + ": too many channels");
  const auto id = static_cast<uint16_t>(channels_.size());
  ChannelInfo info;
  info.schema = schema;
  const size_t at = begin_record(info.record, kChannel);
  put(info.record, id);
  put(info.record, schema);
  put_string(info.record, topic);
  put_string(info.record, message_encoding);
  std::string map;
  for (const auto& [k, v] : metadata) {
    put_string(map, k);
    put_string(map, v);
  }
  put_string(info.record, map);
  end_record(info.record, at);
  put_bytes(chunk_, info.record.data(), info.record.size());
  channels_.push_back(std::move(info));
  return id;
}

bool McapWriter::write(uint16_t channel, uint64_t log_time_ns, uint64_t publish_time_ns,
                       std::span<const uint8_t> data) {
  if (closed() || !error_.empty() || channel >= channels_.size()) {
    ++stats_.failed_messages;  // an unknown channel is the caller's bug, not the file's
    return false;
  }
  ChannelInfo& ch = channels_[channel];
  const uint64_t offset = chunk_.size();
  put(chunk_, kMessage);
  put(chunk_, static_cast<uint64_t>(2 + 4 + 8 + 8 + data.size()));
  put(chunk_, channel);
  put(chunk_, ch.sequence++);
  put(chunk_, log_time_ns);
  put(chunk_, publish_time_ns);
  put_bytes(chunk_, data.data(), data.size());
  ch.index.emplace_back(log_time_ns, offset);
  ++ch.count;
  if (!chunk_has_messages_) {
    chunk_start_time_ = chunk_end_time_ = log_time_ns;
  } else {
    chunk_start_time_ = std::min(chunk_start_time_, log_time_ns);
    chunk_end_time_ = std::max(chunk_end_time_, log_time_ns);
  }
  if (stats_.messages == 0) {
    start_time_ = end_time_ = log_time_ns;
  } else {
    start_time_ = std::min(start_time_, log_time_ns);
    end_time_ = std::max(end_time_, log_time_ns);
  }
  chunk_has_messages_ = true;
  ++stats_.messages;
  if (chunk_.size() >= options_.chunk_bytes) flush_chunk();
  return error_.empty();
}

void McapWriter::fail(const std::string& what) {
  if (error_.empty()) error_ = path_ + ": " + what;
}

void McapWriter::emit(std::span<const uint8_t> bytes) {
  if (!error_.empty() || bytes.empty()) return;
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
    fail(std::string("write failed: ") + std::strerror(errno));
    return;
  }
  if (in_data_) data_crc_ = detail::crc32(bytes, data_crc_);
  offset_ += bytes.size();
  stats_.bytes = offset_;
}

void McapWriter::emit(const std::string& bytes) {
  emit(bytes_of(bytes));
}

// Writes the open chunk (compressed) and its Message Index records; the buffers are kept.
void McapWriter::flush_chunk() {
  if (chunk_.empty() || !error_.empty()) return;
  const std::span<const uint8_t> raw(chunk_);
  const uint32_t crc = detail::crc32(raw);
  std::span<const uint8_t> stored = raw;
  McapCompression compression = options_.compression;
  if (compression == McapCompression::kZstd) {
    compressed_.resize(ZSTD_compressBound(raw.size()));
    const size_t n = ZSTD_compressCCtx(context_->zstd, compressed_.data(), compressed_.size(),
                                       raw.data(), raw.size(), options_.zstd_level);
    if (ZSTD_isError(n)) {
      fail(std::string("zstd: ") + ZSTD_getErrorName(n));
      return;
    }
    stored = std::span<const uint8_t>(compressed_).first(n);
  } else if (compression == McapCompression::kLz4) {
    LZ4F_preferences_t prefs{};
    prefs.frameInfo.contentSize = raw.size();
    compressed_.resize(LZ4F_compressFrameBound(raw.size(), &prefs));
    const size_t n =
        LZ4F_compressFrame(compressed_.data(), compressed_.size(), raw.data(), raw.size(), &prefs);
    if (LZ4F_isError(n)) {
      fail(std::string("lz4: ") + LZ4F_getErrorName(n));
      return;
    }
    stored = std::span<const uint8_t>(compressed_).first(n);
  }
  const std::string_view name = compression_name(compression);

  ChunkIndex index;
  index.start_time = chunk_has_messages_ ? chunk_start_time_ : 0;
  index.end_time = chunk_has_messages_ ? chunk_end_time_ : 0;
  index.offset = offset_;
  index.compressed_size = stored.size();
  index.uncompressed_size = raw.size();

  record_.clear();
  const size_t at = begin_record(record_, kChunk);
  put(record_, index.start_time);
  put(record_, index.end_time);
  put(record_, static_cast<uint64_t>(raw.size()));
  put(record_, crc);
  put_string(record_, name);
  put(record_, static_cast<uint64_t>(stored.size()));
  // The records follow; the length counts them without copying them into record_.
  const uint64_t length = record_.size() - at - 8 + stored.size();
  std::memcpy(record_.data() + at, &length, 8);
  emit(record_);
  emit(stored);
  index.length = kRecordHead + length;

  // One Message Index per channel with messages in this chunk, in channel order.
  const uint64_t indexes_start = offset_;
  for (size_t c = 0; c < channels_.size(); ++c) {
    auto& entries = channels_[c].index;
    if (entries.empty()) continue;
    index.message_index_offsets.emplace_back(static_cast<uint16_t>(c), offset_);
    record_.clear();
    const size_t rat = begin_record(record_, kMessageIndex);
    put(record_, static_cast<uint16_t>(c));
    put(record_, static_cast<uint32_t>(entries.size() * 16));
    for (const auto& [time, off] : entries) {
      put(record_, time);
      put(record_, off);
    }
    end_record(record_, rat);
    emit(record_);
    entries.clear();
  }
  index.message_index_length = offset_ - indexes_start;
  if (!error_.empty()) return;
  chunk_indexes_.push_back(std::move(index));
  ++stats_.chunks;
  chunk_.clear();
  chunk_has_messages_ = false;
}

void McapWriter::write_summary() {
  // Data End: the CRC of every byte before it (magic included).
  record_.clear();
  size_t at = begin_record(record_, kDataEnd);
  put(record_, data_crc_);
  end_record(record_, at);
  emit(record_);
  in_data_ = false;

  // The summary and summary offset sections and the footer's first fields, built in memory so
  // that their CRC is one pass (one Chunk Index per chunk: small).
  const uint64_t summary_start = offset_;
  std::string s;
  struct Group {
    uint8_t op;
    uint64_t start, length;
  };
  std::vector<Group> groups;
  auto group = [&](uint8_t op, auto&& body) {
    const uint64_t start = s.size();
    body();
    if (s.size() > start) groups.push_back({op, summary_start + start, s.size() - start});
  };
  group(kSchema, [&] {
    for (const auto& r : schema_records_) s += r;
  });
  group(kChannel, [&] {
    for (const auto& c : channels_) s += c.record;
  });
  group(kStatistics, [&] {
    const size_t a = begin_record(s, kStatistics);
    put(s, stats_.messages);
    put(s, static_cast<uint16_t>(schema_records_.size()));
    put(s, static_cast<uint32_t>(channels_.size()));
    put(s, uint32_t{0});  // attachments
    put(s, uint32_t{0});  // metadata
    put(s, static_cast<uint32_t>(chunk_indexes_.size()));
    put(s, start_time_);
    put(s, end_time_);
    put(s, static_cast<uint32_t>(channels_.size() * 10));
    for (size_t c = 0; c < channels_.size(); ++c) {
      put(s, static_cast<uint16_t>(c));
      put(s, channels_[c].count);
    }
    end_record(s, a);
  });
  group(kChunkIndex, [&] {
    for (const auto& ci : chunk_indexes_) {
      const size_t a = begin_record(s, kChunkIndex);
      put(s, ci.start_time);
      put(s, ci.end_time);
      put(s, ci.offset);
      put(s, ci.length);
      put(s, static_cast<uint32_t>(ci.message_index_offsets.size() * 10));
      for (const auto& [channel, off] : ci.message_index_offsets) {
        put(s, channel);
        put(s, off);
      }
      put(s, ci.message_index_length);
      put_string(s, compression_name(options_.compression));
      put(s, ci.compressed_size);
      put(s, ci.uncompressed_size);
      end_record(s, a);
    }
  });
  const uint64_t summary_offset_start = summary_start + s.size();
  for (const auto& g : groups) {
    const size_t a = begin_record(s, kSummaryOffset);
    put(s, g.op);
    put(s, g.start);
    put(s, g.length);
    end_record(s, a);
  }
  // Footer: its CRC covers the summary, the summary offsets and the footer up to this field.
  put(s, kFooter);
  put(s, uint64_t{8 + 8 + 4});  // its length, fixed (and covered by the CRC)
  put(s, summary_start);
  put(s, summary_offset_start);
  const uint32_t crc = detail::crc32(bytes_of(s));
  put(s, crc);
  s.append(kMagic);
  emit(s);
}

void McapWriter::close() {
  if (closed()) return;
  if (error_.empty()) {
    flush_chunk();
    write_summary();
  }
  if (error_.empty() && std::fflush(file_) != 0)
    fail(std::string("flush: ") + std::strerror(errno));
  if (error_.empty() && ::fsync(fileno(file_)) != 0 && errno != EINVAL && errno != EROFS)
    fail(std::string("fsync: ") + std::strerror(errno));
  if (std::fclose(file_) != 0) fail(std::string("close: ") + std::strerror(errno));
  file_ = nullptr;
  if (!error_.empty()) throw McapWriteError(error_);
}

}  // namespace lidartag::driver::bag
