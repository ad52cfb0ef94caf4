// ROS 1 bag, format 2.0 (wiki.ros.org/Bags/Format/2.0): after the magic line, records of
// <header_len u32><header: fields <len u32><name>=<value>><data_len u32><data>. Ops: 0x03 bag
// header (index_pos, conn_count, chunk_count), 0x05 chunk (compression, size) holding connection
// (0x07) and message data (0x02: conn, time) records, 0x04 index data after each chunk, and at
// index_pos the connections (0x07) and chunk infos (0x06: per-connection counts). The file is read
// front to back, one chunk in memory at a time; the index only gives the connection list and
// counts.
#include <algorithm>
#include <map>
#include <optional>

#include "internal.hpp"

namespace lidartag::driver::bag::detail {
namespace {

constexpr uint64_t kMagicSize = 13;
constexpr uint8_t kOpMessage = 0x02, kOpBagHeader = 0x03, kOpChunk = 0x05, kOpChunkInfo = 0x06,
                  kOpConnection = 0x07;
// A record header larger than this is corrupt (real ones are tens of bytes; connection records
// keep their message definitions in the data part).
constexpr uint32_t kMaxHeader = 1u << 20;

struct Fields {
  std::optional<uint8_t> op;
  std::map<std::string_view, std::span<const uint8_t>, std::less<>> values;
  bool ok = true;
  std::span<const uint8_t> get(std::string_view name) const {
    const auto it = values.find(name);
    return it == values.end() ? std::span<const uint8_t>{} : it->second;
  }
  template <class T>
  std::optional<T> number(std::string_view name) const {
    const auto v = get(name);
    if (v.size() != sizeof(T)) return std::nullopt;
    T value{};
    std::memcpy(&value, v.data(), sizeof(T));
    return value;
  }
  std::string text(std::string_view name) const {
    const auto v = get(name);
    return {reinterpret_cast<const char*>(v.data()), v.size()};
  }
};

Fields parse_fields(std::span<const uint8_t> header) {
  Fields f;
  Cursor c(header);
  while (c.left() > 0) {
    const auto len = c.get<uint32_t>();
    const auto field = c.take(len);
    if (!c.ok()) {
      f.ok = false;
      break;
    }
    const auto* begin = reinterpret_cast<const char*>(field.data());
    const std::string_view text(begin, field.size());
    const auto eq = text.find('=');
    if (eq == std::string_view::npos) {
      f.ok = false;
      break;
    }
    f.values[text.substr(0, eq)] = field.subspan(eq + 1);
  }
  if (const auto v = f.get("op"); v.size() == 1) f.op = v[0];
  return f;
}

int64_t ros_time(std::span<const uint8_t> v) {
  if (v.size() != 8) return 0;
  uint32_t sec = 0, nsec = 0;
  std::memcpy(&sec, v.data(), 4);
  std::memcpy(&nsec, v.data() + 4, 4);
  return int64_t{sec} * 1'000'000'000 + nsec;
}

class Ros1Reader final : public MessageReader {
 public:
  Ros1Reader(const std::string& path, const ReaderOptions& options) : path_(path), file_(path) {
    options_ = options;
    if (!file_.is_open()) throw BagError(path + ": cannot open");
    std::vector<uint8_t> magic;
    if (!file_.read(0, kMagicSize, magic) ||
        std::string_view(reinterpret_cast<const char*>(magic.data()), magic.size()) !=
            "#ROSBAG V2.0\n")
      throw BagError(path + ": not a ROS 1 bag of format 2.0");
    // The bag header record: where the index is.
    Record header;
    uint64_t after = 0;
    if (!read_record(kMagicSize, header, after) || header.fields.op != kOpBagHeader)
      throw BagError(path + ": " + at(kMagicSize) + "no bag header record (" +
                     (problem_.empty() ? "wrong op" : problem_) + ")");
    pos_ = after;
    const uint64_t index_pos = header.fields.number<uint64_t>("index_pos").value_or(0);
    if (index_pos >= after && index_pos < file_.size()) read_index(index_pos);
    if (!indexed_) {
      note((index_pos == 0 ? std::string("no index (index_pos 0)")
                           : at(index_pos) + "no usable index") +
           " (an unfinished recording?): the connections and counts are those read");
      connections_.clear();
      ids_.clear();
    }
  }

  BagFormat format() const override { return BagFormat::kRos1; }

  bool next(BagMessage& out) override {
    for (;;) {
      // Messages of the chunk in hand first.
      while (chunk_pos_ < chunk_.size()) {
        Cursor c(std::span<const uint8_t>(chunk_).subspan(chunk_pos_));
        const auto header_len = c.get<uint32_t>();
        const auto header = c.take(header_len);
        const auto data_len = c.get<uint32_t>();
        const auto data = c.take(data_len);
        if (!c.ok() || header_len > kMaxHeader) {
          ++stats_.skipped_records;
          note(at(chunk_start_) + "chunk ends inside a record; rest of the chunk skipped");
          chunk_pos_ = chunk_.size();
          break;
        }
        chunk_pos_ += c.pos();
        if (deliver(parse_fields(header), data, out)) return true;
      }
      if (done_) return false;
      // The next top-level record.
      Record r;
      uint64_t after = 0;
      if (pos_ >= file_.size()) {
        done_ = true;
        return false;
      }
      if (!read_record(pos_, r, after)) {
        ++stats_.truncated;
        note(at(pos_) + problem_ + "; the rest of the file is not read");
        done_ = true;
        return false;
      }
      const uint64_t here = pos_;
      pos_ = after;
      if (r.fields.op == kOpChunk) {
        ++stats_.chunks;
        const std::string compression = r.fields.text("compression");
        const auto size = r.fields.number<uint32_t>("size");
        std::string problem;
        if (!size || *size > options_.max_chunk_bytes) {
          problem = "chunk header without a plausible size";
        } else {
          problem = decompressor_.run(compression, r.data, *size, chunk_);
        }
        if (!problem.empty()) {
          ++stats_.skipped_chunks;
          note(at(here) + "chunk skipped: " + problem);
          chunk_.clear();
        }
        chunk_pos_ = 0;
        chunk_start_ = here;
        continue;
      }
      if (deliver(r.fields, r.data, out)) return true;  // unchunked messages, connections
    }
  }

 private:
  struct Record {
    Fields fields;
    std::span<const uint8_t> data;
  };

  // Reads the record at `offset` into buffers of this reader (valid until the next call);
  // false with problem_ set when it does not fit in the file or its header is corrupt.
  bool read_record(uint64_t offset, Record& r, uint64_t& after) {
    uint32_t header_len = 0, data_len = 0;
    std::array<uint8_t, 4> len{};
    if (!file_.read(offset, len)) return fail("file ends inside a record's length");
    std::memcpy(&header_len, len.data(), 4);
    if (header_len > kMaxHeader)
      return fail("record header of " + std::to_string(header_len) + " bytes (corrupt)");
    if (!file_.read(offset + 4, header_len, header_buf_))
      return fail("file ends inside a record header");
    if (!file_.read(offset + 4 + header_len, len)) return fail("file ends inside a record");
    std::memcpy(&data_len, len.data(), 4);
    if (data_len > options_.max_chunk_bytes)
      return fail("record of " + std::to_string(data_len) + " bytes (corrupt)");
    if (!file_.read(offset + 8 + header_len, data_len, data_buf_))
      return fail("file ends inside a record of " + std::to_string(data_len) + " bytes");
    r.fields = parse_fields(header_buf_);
    if (!r.fields.ok || !r.fields.op) return fail("corrupt record header");
    r.data = data_buf_;
    after = offset + 8 + header_len + data_len;
    return true;
  }

  bool fail(std::string problem) {
    problem_ = std::move(problem);
    return false;
  }

  // The index: connections and chunk infos, from index_pos to the end.
  void read_index(uint64_t offset) {
    std::map<uint32_t, uint64_t> counts;
    std::optional<int64_t> first;  // the earliest chunk's start_time
    while (offset < file_.size()) {
      Record r;
      uint64_t after = 0;
      if (!read_record(offset, r, after)) return;  // a damaged index: counts from the reading
      if (r.fields.op == kOpConnection) {
        if (!add_connection(r.fields, r.data)) return;
      } else if (r.fields.op == kOpChunkInfo) {
        if (const auto t = r.fields.get("start_time"); t.size() == 8)
          first = std::min(first.value_or(ros_time(t)), ros_time(t));
        Cursor c(r.data);
        const auto n = r.fields.number<uint32_t>("count").value_or(0);
        for (uint32_t i = 0; i < n && c.ok(); ++i) {
          const auto conn = c.get<uint32_t>();
          counts[conn] += c.get<uint32_t>();
        }
        if (!c.ok()) return;
      } else {
        return;  // not an index record
      }
      offset = after;
    }
    for (const auto& [conn, n] : counts) {
      const auto it = ids_.find(conn);
      if (it == ids_.end()) return;
      connections_[it->second].count = n;
    }
    indexed_ = true;
    start_ns_ = first;
  }

  // A connection record (in a chunk or the index): false when it is corrupt.
  bool add_connection(const Fields& f, std::span<const uint8_t> data) {
    const auto conn = f.number<uint32_t>("conn");
    const Fields inner = parse_fields(data);
    if (!conn || !inner.ok) return false;
    if (ids_.count(*conn)) return true;
    Connection c;
    c.topic = f.text("topic");
    if (c.topic.empty()) c.topic = inner.text("topic");
    c.type = inner.text("type");
    c.encoding = Encoding::kRos1;
    ids_[*conn] = static_cast<uint32_t>(connections_.size());
    connections_.push_back(std::move(c));
    return true;
  }

  bool deliver(const Fields& f, std::span<const uint8_t> data, BagMessage& out) {
    if (!f.ok || !f.op) {
      ++stats_.skipped_records;
      return false;
    }
    if (*f.op == kOpConnection) {
      if (!add_connection(f, data)) {
        ++stats_.skipped_records;
        note("corrupt connection record skipped");
      }
      return false;
    }
    if (*f.op != kOpMessage) return false;  // index data, chunk info: not messages
    const auto conn = f.number<uint32_t>("conn");
    const auto it = conn ? ids_.find(*conn) : ids_.end();
    if (it == ids_.end()) {
      ++stats_.skipped_records;
      note("message of an unknown connection skipped");
      return false;
    }
    Connection& c = connections_[it->second];
    if (!indexed_) ++c.count;
    const int64_t time = ros_time(f.get("time"));
    const bool inside = in_window(time);
    if (!wanted(c.topic)) return false;
    if (!inside) {
      ++stats_.outside_window;
      return false;
    }
    out.connection = it->second;
    out.time_ns = time;
    out.data = data;
    ++stats_.messages;
    stats_.bytes += data.size();
    return true;
  }

  std::string path_;
  File file_;
  uint64_t pos_ = 0;
  bool done_ = false, indexed_ = false;
  std::map<uint32_t, uint32_t> ids_;  // conn id -> index in connections_
  std::vector<uint8_t> header_buf_, data_buf_, chunk_;
  Decompressor decompressor_;
  size_t chunk_pos_ = 0;
  uint64_t chunk_start_ = 0;
  std::string problem_;
};

}  // namespace

std::unique_ptr<MessageReader> open_ros1(const std::string& path, const ReaderOptions& options) {
  return std::make_unique<Ros1Reader>(path, options);
}

}  // namespace lidartag::driver::bag::detail
