// Writing MCAP files (mcap.dev/spec, major version 0): schemas, channels and messages, chunked
// (zstd, lz4 or uncompressed, each chunk with the CRC-32 of its records), a Message Index per
// channel after each chunk, and on close() the Data End record (the data section's CRC), the
// summary section (schemas, channels, Statistics, Chunk Indexes), the Summary Offset records, the
// Footer (with the summary's CRC) and the closing magic. Bytes and schemas only: what the messages
// mean is the caller's business (lidartag/foxglove/scene_recorder.hpp writes Foxglove's).
//
// Memory is bounded: one chunk's records (McapWriterOptions::chunk_bytes, plus one message) and
// its compressed copy are held; a chunk is written out when it is full, so a recording of any
// length streams to disk. The summary grows by one Chunk Index per chunk.
#pragma once

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::driver::bag {

// The file cannot be created, written or closed, or a schema/channel is refused (a setup error).
class McapWriteError : public IoError {
 public:
  using IoError::IoError;
};

enum class McapCompression : uint8_t {
  kNone,  // records stored as they are (fastest; largest files)
  kZstd,  // "zstd": Foxglove's and rosbag2's default
  kLz4,   // "lz4": the LZ4 frame format
};

// "none", "zstd", "lz4" (as the command line takes them); throws McapWriteError for others.
McapCompression parse_mcap_compression(std::string_view name);

struct McapWriterOptions {
  McapCompression compression = McapCompression::kZstd;
  // A chunk is written out once its uncompressed records reach this many bytes. Larger chunks
  // compress better and index coarser; Foxglove reads any size. Bytes, >= 1.
  size_t chunk_bytes = 4u << 20;
  // zstd's compression level (1 fastest .. 19 smallest; 3 is zstd's default).
  int zstd_level = 3;
  // The Header record's profile ("" none; "ros1", "ros2" for ROS messages) and library fields.
  std::string profile;
  std::string library = "lidartag";
};

// What has been written so far.
struct McapWriterStats {
  uint64_t messages = 0;
  uint64_t chunks = 0;           // chunks written out
  uint64_t bytes = 0;            // file bytes written out (flushed to the stream)
  uint64_t failed_messages = 0;  // write() calls refused after an I/O error or a bad channel
};

class McapWriter {
 public:
  // Creates (truncates) `path`. A path that exists and is not a regular file (a FIFO, a device,
  // a folder) is refused. Throws McapWriteError.
  McapWriter(const std::string& path, McapWriterOptions options = {});
  // Closes the file as close() does; an error there is lost (call close() to see it).
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Registers a schema (ids 1, 2, ...; 0 is MCAP's "no schema") and writes its record into the
  // data section. `encoding` as MCAP names them ("jsonschema", "protobuf", "ros2msg", ...).
  // Throws McapWriteError when closed or out of ids.
  uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  // Registers a channel (ids 0, 1, ...) of a schema added before (or 0). `message_encoding`:
  // "json", "protobuf", "cdr", ... Throws McapWriteError for an unknown schema, when closed or
  // out of ids.
  uint16_t add_channel(std::string_view topic, uint16_t schema, std::string_view message_encoding,
                       const std::map<std::string, std::string>& metadata = {});

  // Appends a message to the current chunk (times in ns; the sequence counts per channel). False
  // (counted in failed_messages, error() says why) for an unknown channel, after close() or after
  // an I/O error; never throws. Allocates only while the chunk buffers grow.
  [[nodiscard]] bool write(uint16_t channel, uint64_t log_time_ns, uint64_t publish_time_ns,
                           std::span<const uint8_t> data);
  [[nodiscard]] bool write(uint16_t channel, uint64_t log_time_ns, std::string_view data) {
    return write(channel, log_time_ns, log_time_ns,
                 {reinterpret_cast<const uint8_t*>(data.data()), data.size()});
  }

  // Writes the last chunk, the Data End record, the summary, the footer and the magic, flushes
  // and syncs the file and closes it. Every message write() accepted is in the file when it
  // returns. Throws McapWriteError when the file could not be completed (or an earlier write
  // failed: the file then holds what was written before the failure). A second call does nothing.
  void close();

  bool closed() const { return file_ == nullptr; }
  const McapWriterStats& stats() const { return stats_; }
  // The first I/O error ("" none).
  const std::string& error() const { return error_; }
  const std::string& path() const { return path_; }

 private:
  struct ChannelInfo {
    uint16_t schema = 0;
    uint32_t sequence = 0;
    uint64_t count = 0;
    std::string record;  // its Channel record, repeated in the summary
    // (log time, offset in the chunk's uncompressed records) of this chunk's messages.
    std::vector<std::pair<uint64_t, uint64_t>> index;
  };
  struct ChunkIndex {
    uint64_t start_time = 0, end_time = 0, offset = 0, length = 0;
    std::vector<std::pair<uint16_t, uint64_t>> message_index_offsets;
    uint64_t message_index_length = 0, compressed_size = 0, uncompressed_size = 0;
  };

  void flush_chunk();
  void emit(std::span<const uint8_t> bytes);
  void emit(const std::string& bytes);
  void fail(const std::string& what);
  void write_summary();

  std::string path_;
  McapWriterOptions options_;
  std::FILE* file_ = nullptr;
  uint64_t offset_ = 0;    // bytes emitted
  uint32_t data_crc_ = 0;  // of every byte before the Data End record
  bool in_data_ = true;    // data_crc_ still counts
  std::string error_;
  McapWriterStats stats_;
  std::vector<std::string> schema_records_;  // schema id - 1 -> its Schema record
  std::vector<ChannelInfo> channels_;        // by channel id
  std::vector<uint8_t> chunk_;               // the open chunk's records, uncompressed
  std::vector<uint8_t> compressed_;
  std::string record_;  // scratch for one record
  uint64_t chunk_start_time_ = 0, chunk_end_time_ = 0;
  bool chunk_has_messages_ = false;
  uint64_t start_time_ = 0, end_time_ = 0;  // over the whole file
  std::vector<ChunkIndex> chunk_indexes_;
  struct Context;  // the compressors' state
  std::unique_ptr<Context> context_;
};

}  // namespace lidartag::driver::bag
