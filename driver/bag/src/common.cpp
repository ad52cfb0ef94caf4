#include <bzlib.h>
#include <isa-l/crc.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <span>

#include "internal.hpp"
#include "lidartag/driver/bag/message_reader.hpp"

namespace lidartag::driver::bag {

namespace detail {

std::string at(uint64_t offset) {
  return "at byte " + std::to_string(offset) + ": ";
}

uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc) {
  return crc32_gzip_refl(crc, bytes.data(), bytes.size());
}

struct Decompressor::Contexts {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
  ~Contexts() {
    ZSTD_freeDCtx(zstd);  // both accept null
    LZ4F_freeDecompressionContext(lz4);
  }
};

Decompressor::Decompressor() : contexts_(std::make_unique<Contexts>()) {}
Decompressor::~Decompressor() = default;

std::string Decompressor::run(std::string_view compression, std::span<const uint8_t> in,
                              uint64_t size, std::vector<uint8_t>& out) {
  out.resize(size);
  if (compression.empty() || compression == "none") {
    if (in.size() != size)
      return "uncompressed chunk of " + std::to_string(in.size()) + " bytes, " +
             std::to_string(size) + " declared";
    std::copy(in.begin(), in.end(), out.begin());
    return {};
  }
  if (compression == "zstd") {
    // Created on the first zstd chunk, then reused (one allocation per reader, not per chunk).
    if (contexts_->zstd == nullptr) contexts_->zstd = ZSTD_createDCtx();
    if (contexts_->zstd == nullptr) return "zstd: no decompression context";
    const size_t n =
        ZSTD_decompressDCtx(contexts_->zstd, out.data(), out.size(), in.data(), in.size());
    if (ZSTD_isError(n)) return std::string("zstd: ") + ZSTD_getErrorName(n);
    if (n != size)
      return "zstd: " + std::to_string(n) + " bytes, " + std::to_string(size) + " declared";
    return {};
  }
  if (compression == "lz4") {
    if (contexts_->lz4 == nullptr &&
        LZ4F_isError(LZ4F_createDecompressionContext(&contexts_->lz4, LZ4F_VERSION))) {
      contexts_->lz4 = nullptr;
      return "lz4: no decompression context";
    }
    LZ4F_dctx* ctx = contexts_->lz4;
    size_t in_pos = 0, out_pos = 0, status = 1;
    while (in_pos < in.size() && status != 0) {
      size_t in_left = in.size() - in_pos, out_left = out.size() - out_pos;
      status = LZ4F_decompress(ctx, out.data() + out_pos, &out_left, in.data() + in_pos, &in_left,
                               nullptr);
      if (LZ4F_isError(status)) {
        LZ4F_resetDecompressionContext(ctx);  // ready for the next frame
        return std::string("lz4: ") + LZ4F_getErrorName(status);
      }
      in_pos += in_left;
      out_pos += out_left;
      if (in_left == 0 && out_left == 0) break;  // no progress: output full or input stuck
    }
    if (status != 0) LZ4F_resetDecompressionContext(ctx);  // a frame left unfinished
    if (status != 0 || out_pos != size)
      return "lz4: " + std::to_string(out_pos) + " bytes, " + std::to_string(size) + " declared" +
             (status != 0 ? " (frame incomplete)" : "");
    return {};
  }
  if (compression == "bz2") {
    if (size > std::numeric_limits<unsigned>::max() ||
        in.size() > std::numeric_limits<unsigned>::max())
      return "bz2: chunk too large";
    auto out_size = static_cast<unsigned>(size);
    // libbz2 takes non-const input; it does not write to it.
    const int rc =
        BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(out.data()), &out_size,
                                   const_cast<char*>(reinterpret_cast<const char*>(in.data())),
                                   static_cast<unsigned>(in.size()), 0, 0);
    if (rc != BZ_OK) return "bz2: error " + std::to_string(rc);
    if (out_size != size)
      return "bz2: " + std::to_string(out_size) + " bytes, " + std::to_string(size) + " declared";
    return {};
  }
  return "unknown compression '" + std::string(compression) + "'";
}

File::File(const std::string& path) : owner_(std::fopen(path.c_str(), "rb")), file_(owner_.get()) {
  if (!file_) return;
  if (std::fseek(file_, 0, SEEK_END) == 0) {
    const long end = std::ftell(file_);
    if (end > 0) size_ = static_cast<uint64_t>(end);
  }
}

bool File::read(uint64_t offset, std::span<uint8_t> out) {
  if (!file_ || offset > size_ || out.size() > size_ - offset) return false;
  if (std::fseek(file_, static_cast<long>(offset), SEEK_SET) != 0) return false;
  return std::fread(out.data(), 1, out.size(), file_) == out.size();
}

bool File::read(uint64_t offset, uint64_t n, std::vector<uint8_t>& out) {
  if (!file_ || offset > size_ || n > size_ - offset) return false;
  out.resize(n);
  return read(offset, std::span<uint8_t>(out));
}

}  // namespace detail

void MessageReader::note(const std::string& problem) {
  // The first few problems in full, then a count: a badly damaged file must not grow the text.
  constexpr int kShown = 4;
  ++notes_;
  if (notes_ <= kShown) {
    if (!error_.empty()) error_ += "; ";
    // One line whatever the file holds: a corrupt compression name is quoted from the file.
    static constexpr char kHex[] = "0123456789abcdef";
    for (const char ch : problem) {
      const auto c = static_cast<unsigned char>(ch);
      if (c >= 0x20 && c != 0x7F) {
        error_ += ch;
      } else {
        error_ += "\\x";
        error_ += kHex[c >> 4];
        error_ += kHex[c & 15];
      }
    }
  } else if (notes_ == kShown + 1) {
    error_ += "; more problems follow (see the counters)";
  }
}

bool MessageReader::wanted(std::string_view topic) const {
  return options_.topics.empty() ||
         std::find(options_.topics.begin(), options_.topics.end(), topic) != options_.topics.end();
}

bool MessageReader::in_window(int64_t time_ns) {
  if (!start_ns_) start_ns_ = time_ns;
  const double start = options_.start_s > 0 ? options_.start_s : 0.0;
  const double duration = options_.duration_s;
  const bool bounded = duration > 0 && duration < std::numeric_limits<double>::infinity();
  if (start == 0 && !bounded) return true;  // the whole bag
  int64_t since = 0;
  // Times of corrupt records may be anything: 292 years or more from the start is outside any
  // window but an open-ended one.
  if (__builtin_sub_overflow(time_ns, *start_ns_, &since)) return time_ns > *start_ns_ && !bounded;
  const double t = static_cast<double>(since) * 1e-9;  // exact to a ns for 104 days
  if (t < start) return false;
  return !bounded || t - start < duration;
}

std::string window_problem(double start_s, double duration_s) {
  if (std::isnan(start_s) || start_s < 0)
    return "--start " + std::to_string(start_s) + ": seconds from the first message, 0 or more";
  if (std::isnan(duration_s) || duration_s <= 0)
    return "--duration " + std::to_string(duration_s) + ": seconds, more than 0";
  return {};
}

std::string_view format_name(BagFormat format) {
  switch (format) {
    case BagFormat::kRos1:
      return "ROS 1 bag";
    case BagFormat::kRosbag2:
      return "ROS 2 bag (sqlite3)";
    case BagFormat::kMcap:
      return "MCAP";
    case BagFormat::kNone:
      break;
  }
  return "not a bag";
}

namespace {
constexpr std::string_view kRos1Magic = "#ROSBAG V2.0\n";
constexpr std::string_view kMcapMagic = "\x89MCAP0\r\n";
constexpr std::string_view kSqliteMagic{"SQLite format 3\0", 16};

// The file's first `n` bytes, or all of it when shorter; empty when it cannot be read. (Read once
// for every format's magic: a capture opened by content was opened three times to tell.)
std::vector<uint8_t> head_of(const std::string& path, size_t n) {
  detail::File f(path);
  std::vector<uint8_t> head;
  if (!f.is_open() || !f.read(0, std::min<uint64_t>(n, f.size()), head)) head.clear();
  return head;
}

bool starts_with(std::span<const uint8_t> head, std::string_view magic) {
  return head.size() >= magic.size() &&
         std::equal(magic.begin(), magic.end(), head.begin(),
                    [](char a, uint8_t b) { return static_cast<uint8_t>(a) == b; });
}

constexpr std::string_view kRos2Metadata = "rosbag2_bagfile_information";
constexpr size_t kHeadBytes =
    std::max({kRos1Magic.size(), kMcapMagic.size(), kSqliteMagic.size(), kRos2Metadata.size()});
}  // namespace

BagFormat detect_bag_format(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path p(path);
  if (std::filesystem::is_directory(p, ec)) {
    if (std::filesystem::is_regular_file(p / "metadata.yaml", ec)) return BagFormat::kRosbag2;
    for (const auto& entry : std::filesystem::directory_iterator(p, ec)) {
      if (entry.is_regular_file(ec) &&
          starts_with(head_of(entry.path().string(), kSqliteMagic.size()), kSqliteMagic))
        return BagFormat::kRosbag2;
    }
    return BagFormat::kNone;
  }
  if (!std::filesystem::is_regular_file(p, ec)) return BagFormat::kNone;
  const std::vector<uint8_t> head = head_of(path, kHeadBytes);
  if (starts_with(head, kRos1Magic)) return BagFormat::kRos1;
  if (starts_with(head, kMcapMagic)) return BagFormat::kMcap;
  if (starts_with(head, kSqliteMagic)) return BagFormat::kRosbag2;
  // A rosbag2 metadata.yaml named directly: its folder.
  if (p.filename() == "metadata.yaml" && starts_with(head, kRos2Metadata))
    return BagFormat::kRosbag2;
  return BagFormat::kNone;
}

std::unique_ptr<MessageReader> open_bag(const std::string& path, ReaderOptions options) {
  switch (detect_bag_format(path)) {
    case BagFormat::kRos1:
      return detail::open_ros1(path, options);
    case BagFormat::kRosbag2:
      return detail::open_rosbag2(path, options);
    case BagFormat::kMcap:
      return detail::open_mcap(path, options);
    case BagFormat::kNone:
      break;
  }
  throw BagError(path +
                 ": not a ROS 1 bag, ROS 2 bag (metadata.yaml + .db3) or MCAP file (by content)");
}

std::string normalized_type(std::string_view type) {
  std::string t(type);
  const auto pos = t.find("/msg/");
  if (pos != std::string::npos) t.erase(pos, 4);
  return t;
}

}  // namespace lidartag::driver::bag
