// Shared by the container readers: little-endian reads, decompression, CRC-32, file reading.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/bag/message_reader.hpp"

namespace lidartag::driver::bag::detail {

// Reads little-endian values from bytes; a read past the end sets `ok` to false and yields 0.
class Cursor {
 public:
  explicit Cursor(std::span<const uint8_t> bytes) : bytes_(bytes) {}
  template <class T>
  T get() {
    T value{};
    if (!need(sizeof(T))) return value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  std::span<const uint8_t> take(size_t n) {
    if (!need(n)) return {};
    auto s = bytes_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  // A u32-length-prefixed string.
  std::string_view string() {
    const auto n = get<uint32_t>();
    const auto s = take(n);
    return {reinterpret_cast<const char*>(s.data()), s.size()};
  }
  bool need(size_t n) {
    if (!ok_ || n > bytes_.size() - pos_) {
      ok_ = false;
      return false;
    }
    return true;
  }
  size_t pos() const { return pos_; }
  size_t left() const { return bytes_.size() - pos_; }
  bool ok() const { return ok_; }

 private:
  std::span<const uint8_t> bytes_;
  size_t pos_ = 0;
  bool ok_ = true;
};

// Decompresses chunks and messages, keeping zstd's and lz4's contexts from one to the next
// (creating one allocates and clears tens of kilobytes): one per reader.
class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;
  // Decompresses `in` into `out` (resized to `size`; its capacity kept, so that a reused buffer
  // is not allocated again): "", "none", "bz2", "lz4" (LZ4 frame format: what both ROS 1 and
  // MCAP write), "zstd". Empty on success, else what went wrong.
  std::string run(std::string_view compression, std::span<const uint8_t> in, uint64_t size,
                  std::vector<uint8_t>& out);

 private:
  struct Contexts;
  std::unique_ptr<Contexts> contexts_;
};

// CRC-32 (IEEE 802.3, as zlib and MCAP compute it), continuing from `crc`: Intel's ISA-L
// (libisal, carry-less multiplies where the CPU has them), 5-6x zlib's crc32_z on the chunks.
uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

// A file read with explicit offsets (64-bit), no exceptions.
class File {
 public:
  explicit File(const std::string& path);
  bool is_open() const { return file_ != nullptr; }
  uint64_t size() const { return size_; }
  // Reads exactly `n` bytes at `offset` into `out` (resized); false when the file ends first.
  bool read(uint64_t offset, uint64_t n, std::vector<uint8_t>& out);
  bool read(uint64_t offset, std::span<uint8_t> out);

 private:
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, Closer> owner_;
  std::FILE* file_ = nullptr;
  uint64_t size_ = 0;
};

std::unique_ptr<MessageReader> open_ros1(const std::string& path, const ReaderOptions& options);
std::unique_ptr<MessageReader> open_rosbag2(const std::string& path, const ReaderOptions& options);
std::unique_ptr<MessageReader> open_mcap(const std::string& path, const ReaderOptions& options);

// "at byte 1234: " style offsets in messages.
std::string at(uint64_t offset);

}  // namespace lidartag::driver::bag::detail
