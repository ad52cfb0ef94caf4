// MCAP (mcap.dev/spec): magic "\x89MCAP0\r\n", records of <opcode u8><length u64><content>, the
// magic again at the end. Read front to back: Schema (0x03), Channel (0x04) and Message (0x05)
// records, at top level or inside Chunks (0x06: compression "", "zstd" or "lz4", checked against
// their uncompressed CRC-32 when it is not 0), one chunk in memory at a time, up to DataEnd
// (0x0F) or the Footer (0x02). The summary section (found through the Footer) gives the channel
// list and the Statistics record (0x0B) the per-channel counts.
#include <map>
#include <optional>

#include "internal.hpp"

namespace lidartag::driver::bag::detail {
namespace {

constexpr std::string_view kMagic = "\x89MCAP0\r\n";
constexpr uint64_t kMagicSize = 8;
constexpr uint8_t kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
                  kStatistics = 0x0B, kDataEnd = 0x0F;
constexpr uint64_t kFooterSize = 1 + 8 + 20;  // opcode, length, summary_start, offset, crc
constexpr uint32_t kNoChannel = UINT32_MAX;

class McapReader final : public MessageReader {
 public:
  McapReader(const std::string& path, const ReaderOptions& options) : path_(path), file_(path) {
    options_ = options;
    if (!file_.is_open()) throw BagError(path + ": cannot open");
    std::vector<uint8_t> magic;
    if (!file_.read(0, kMagicSize, magic) ||
        !std::equal(kMagic.begin(), kMagic.end(), magic.begin(),
                    [](char a, uint8_t b) { return static_cast<uint8_t>(a) == b; }))
      throw BagError(path + ": not an MCAP file (no magic)");
    pos_ = kMagicSize;
    read_summary();
  }

  BagFormat format() const override { return BagFormat::kMcap; }

  bool next(BagMessage& out) override {
    for (;;) {
      while (chunk_pos_ < chunk_view_.size()) {
        Cursor c(chunk_view_.subspan(chunk_pos_));
        const auto op = c.get<uint8_t>();
        const auto length = c.get<uint64_t>();
        const auto body = c.take(length);
        if (!c.ok()) {
          ++stats_.skipped_records;
          note(at(chunk_start_) + "chunk ends inside a record; rest of the chunk skipped");
          chunk_pos_ = chunk_view_.size();
          break;
        }
        chunk_pos_ += c.pos();
        if (handle(op, body, out)) return true;
      }
      if (done_) return false;
      if (pos_ >= file_.size()) {
        ++stats_.truncated;
        note(at(pos_) + "the file ends without a footer (an unfinished recording?)");
        done_ = true;
        return false;
      }
      std::array<uint8_t, 9> head{};
      if (!file_.read(pos_, head)) {
        // The closing magic alone may follow the last record when there is no footer.
        ++stats_.truncated;
        note(at(pos_) + "the file ends inside a record; the rest is not read");
        done_ = true;
        return false;
      }
      const uint8_t op = head[0];
      uint64_t length = 0;
      std::memcpy(&length, head.data() + 1, 8);
      if (length > file_.size() - pos_ - 9) {
        ++stats_.truncated;
        note(at(pos_) + "a record of " + std::to_string(length) +
             " bytes that the file does not hold; the rest is not read");
        done_ = true;
        return false;
      }
      const uint64_t here = pos_;
      pos_ += 9 + length;
      if (op == kFooter || op == kDataEnd) {
        done_ = true;
        return false;
      }
      if (op != kChunk && op != kSchema && op != kChannel && op != kMessage) continue;
      if (length > options_.max_chunk_bytes) {
        // Read into memory only up to the bound: larger records are skipped (attachments,
        // which are never read, may be as large as the file).
        ++(op == kChunk ? stats_.skipped_chunks : stats_.skipped_records);
        note(at(here) + "a record of " + std::to_string(length) + " bytes, over the " +
             std::to_string(options_.max_chunk_bytes) + "-byte bound, skipped");
        continue;
      }
      if (!file_.read(here + 9, length, record_)) {
        ++stats_.read_errors;
        done_ = true;
        return false;
      }
      if (op == kChunk) {
        read_chunk(here);
        continue;
      }
      if (handle(op, record_, out)) return true;
    }
  }

 private:
  void read_chunk(uint64_t here) {
    ++stats_.chunks;
    chunk_view_ = {};
    chunk_pos_ = 0;
    chunk_start_ = here;
    Cursor c(record_);
    c.get<uint64_t>();  // message_start_time
    c.get<uint64_t>();  // message_end_time
    const auto size = c.get<uint64_t>();
    const auto crc = c.get<uint32_t>();
    const auto compression = c.string();
    const auto records_len = c.get<uint64_t>();
    const auto records = c.take(records_len);
    std::string problem;
    if (!c.ok()) {
      problem = "corrupt chunk header";
    } else if (size > options_.max_chunk_bytes) {
      problem = "chunk of " + std::to_string(size) + " bytes declared (corrupt)";
    } else {
      // Stored records are read where they lie in record_ (untouched until the chunk is read);
      // compressed ones are decompressed into chunk_ (kept at its size: no zero-filling).
      const bool stored = compression.empty() || compression == "none";
      if (stored && records.size() == size) {
        chunk_view_ = records;
      } else {
        problem = decompressor_.run(compression, records, size, chunk_);
        chunk_view_ = std::span<const uint8_t>(chunk_).first(problem.empty() ? size : 0);
      }
      if (problem.empty() && crc != 0 && crc32(chunk_view_) != crc) problem = "CRC mismatch";
    }
    if (!problem.empty()) {
      ++stats_.skipped_chunks;
      note(at(here) + "chunk skipped: " + problem);
      chunk_view_ = {};
    }
  }

  // A record (top level or from a chunk); true when it is a message to deliver.
  bool handle(uint8_t op, std::span<const uint8_t> body, BagMessage& out) {
    if (op == kSchema) {
      add_schema(body);
    } else if (op == kChannel) {
      add_channel(body);
    } else if (op == kMessage) {
      Cursor c(body);
      const auto channel = c.get<uint16_t>();
      c.get<uint32_t>();  // sequence
      const auto log_time = c.get<uint64_t>();
      c.get<uint64_t>();  // publish_time
      const uint32_t index =
          c.ok() && channel < channel_index_.size() ? channel_index_[channel] : kNoChannel;
      if (index == kNoChannel) {
        ++stats_.skipped_records;
        note(c.ok() ? "a message of an unknown channel skipped" : "a corrupt message skipped");
        return false;
      }
      if (!counted_) ++connections_[index].count;
      const bool inside = in_window(static_cast<int64_t>(log_time));
      if (!wanted_[index]) return false;
      if (!inside) {
        ++stats_.outside_window;
        return false;
      }
      out.connection = index;
      out.time_ns = static_cast<int64_t>(log_time);
      out.data = body.subspan(c.pos());
      ++stats_.messages;
      stats_.bytes += out.data.size();
      return true;
    }
    return false;
  }

  void add_schema(std::span<const uint8_t> body) {
    Cursor c(body);
    const auto id = c.get<uint16_t>();
    const auto name = c.string();
    if (c.ok()) schemas_[id] = std::string(name);
  }

  void add_channel(std::span<const uint8_t> body) {
    Cursor c(body);
    const auto id = c.get<uint16_t>();
    const auto schema = c.get<uint16_t>();
    const auto topic = c.string();
    const auto encoding = c.string();
    if (!c.ok()) {
      ++stats_.skipped_records;
      note("a corrupt channel record skipped");
      return;
    }
    if (id < channel_index_.size() && channel_index_[id] != kNoChannel) return;
    Connection conn;
    conn.topic = std::string(topic);
    const auto s = schemas_.find(schema);
    conn.type = s == schemas_.end() ? std::string() : s->second;
    conn.encoding = encoding == "cdr"    ? Encoding::kCdr
                    : encoding == "ros1" ? Encoding::kRos1
                                         : Encoding::kOther;
    if (id >= channel_index_.size()) channel_index_.resize(size_t{id} + 1, kNoChannel);
    channel_index_[id] = static_cast<uint32_t>(connections_.size());
    wanted_.push_back(wanted(conn.topic));
    connections_.push_back(std::move(conn));
  }

  // The summary section: schemas, channels and statistics, when the footer points at one.
  void read_summary() {
    if (file_.size() < kMagicSize * 2 + kFooterSize) return;
    std::vector<uint8_t> footer;
    const uint64_t at_footer = file_.size() - kMagicSize - kFooterSize;
    if (!file_.read(at_footer, kFooterSize, footer) || footer[0] != kFooter) return;
    Cursor c(std::span<const uint8_t>(footer).subspan(9));
    const auto summary_start = c.get<uint64_t>();
    if (summary_start == 0 || summary_start < kMagicSize || summary_start >= at_footer) return;
    std::vector<uint8_t> summary;
    if (!file_.read(summary_start, at_footer - summary_start, summary)) return;
    Cursor s(summary);
    std::map<uint16_t, uint64_t> counts;
    bool have_statistics = false;
    std::optional<int64_t> statistics_start;
    while (s.left() > 0) {
      const auto op = s.get<uint8_t>();
      const auto length = s.get<uint64_t>();
      const auto body = s.take(length);
      if (!s.ok()) break;
      if (op == kSchema) add_schema(body);
      if (op == kChannel) add_channel(body);
      if (op == kStatistics) {
        Cursor t(body);
        t.get<uint64_t>();                     // message_count
        t.get<uint16_t>();                     // schema_count
        t.take(4 * 4);                         // channel, attachment, metadata, chunk counts
        const auto start = t.get<uint64_t>();  // message_start_time
        t.get<uint64_t>();                     // message_end_time
        const auto map_len = t.get<uint32_t>();
        Cursor m(t.take(map_len));
        while (t.ok() && m.ok() && m.left() > 0) {  // a short entry ends it
          const auto id = m.get<uint16_t>();
          counts[id] = m.get<uint64_t>();
        }
        have_statistics = t.ok() && m.ok();
        if (have_statistics && t.ok()) statistics_start = static_cast<int64_t>(start);
      }
    }
    if (!have_statistics) return;
    for (auto& conn : connections_) conn.count = 0;
    for (const auto& [id, n] : counts) {
      if (id < channel_index_.size() && channel_index_[id] != kNoChannel)
        connections_[channel_index_[id]].count = n;
    }
    counted_ = true;
    // The earliest message's log time (a file without messages declares 0: left unknown).
    if (statistics_start && connections_.size() > 0 && *statistics_start > 0)
      start_ns_ = statistics_start;
  }

  std::string path_;
  File file_;
  uint64_t pos_ = 0;
  bool done_ = false, counted_ = false;
  std::map<uint16_t, std::string> schemas_;
  // Per channel id (a u16), its connection's index, kNoChannel if none: looked up per message.
  std::vector<uint32_t> channel_index_;
  std::vector<uint8_t> wanted_;  // per connection: its topic is read
  Decompressor decompressor_;
  std::vector<uint8_t> record_, chunk_;
  std::span<const uint8_t> chunk_view_;  // the chunk's records: in record_ or chunk_
  size_t chunk_pos_ = 0;
  uint64_t chunk_start_ = 0;
};

}  // namespace

std::unique_ptr<MessageReader> open_mcap(const std::string& path, const ReaderOptions& options) {
  return std::make_unique<McapReader>(path, options);
}

}  // namespace lidartag::driver::bag::detail
