// Recorded ROS messages, whatever the container: ROS 1 bags (format 2.0), ROS 2 bags with sqlite3
// storage (metadata.yaml + .db3) and MCAP files, each read as one stream of serialized messages
// (topic, type, receive time, bytes). The containers are recognised by content, not by name.
// Containers only: decoding a message's bytes is messages.hpp's job.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::driver::bag {

// A file that cannot be opened as a bag at all (not a bag, unreadable, a missing table, a topic
// that is not there): setup errors, thrown by open_bag() and the sources' constructors. An IoError:
// whatever opens captures catches it as it catches a pcap that cannot be opened.
class BagError : public IoError {
 public:
  using IoError::IoError;
};

enum class BagFormat : uint8_t {
  kNone,     // not a container read here
  kRos1,     // ROS 1 bag, format 2.0 ("#ROSBAG V2.0")
  kRosbag2,  // ROS 2 bag, sqlite3 storage: a folder with metadata.yaml and .db3 files, or a .db3
  kMcap,     // MCAP (ROS 2's default storage since Iron, Foxglove)
};

// How a message's bytes are serialized.
enum class Encoding : uint8_t {
  kRos1,   // ROS 1 serialization: little endian, no alignment
  kCdr,    // ROS 2: OMG CDR with a 4-byte encapsulation header, aligned
  kOther,  // anything else (JSON, protobuf, ...): carried, not decoded here
};

// One topic of the container (a ROS 1 connection, a ROS 2 topic, an MCAP channel).
struct Connection {
  std::string topic;
  std::string type;  // as recorded: "velodyne_msgs/VelodyneScan", "sensor_msgs/msg/PointCloud2"
  Encoding encoding = Encoding::kOther;
  // Messages the container's index or summary declares for this topic, or, where the container
  // has none (an unindexed ROS 1 bag, an MCAP without summary), the messages read so far.
  uint64_t count = 0;
};

struct BagMessage {
  uint32_t connection = 0;        // index into MessageReader::connections()
  int64_t time_ns = 0;            // receive (log) time as recorded, ns since epoch
  std::span<const uint8_t> data;  // serialized message; valid until the next call to next()
};

// What a reader read and what it could not. Nothing here is ever thrown: damage is counted and
// reading goes on where the container allows it (the next chunk), else it ends.
struct ReadStats {
  uint64_t messages = 0;         // messages delivered
  uint64_t bytes = 0;            // of delivered messages
  uint64_t chunks = 0;           // chunks read (ROS 1, MCAP)
  uint64_t skipped_chunks = 0;   // chunks that could not be decompressed or failed their CRC
  uint64_t skipped_records = 0;  // records with corrupt headers or unknown connections, skipped
  uint64_t truncated = 0;        // 1 when the file ends inside a record
  uint64_t read_errors = 0;      // storage errors (sqlite)
  uint64_t outside_window = 0;   // messages of the wanted topics outside the time window
};

struct ReaderOptions {
  // Only messages of these topics are delivered (others are skipped without copying); empty: all.
  std::vector<std::string> topics;
  // Largest chunk or record read into memory, compressed or not, bytes: one claiming more is
  // skipped as corrupt (skipped_chunks, skipped_records). Bounds the memory a reader holds (one
  // chunk at a time). Default 256 MiB: ROS 1 writes chunks of 768 KiB, rosbag2's MCAP of 4 MiB.
  uint64_t max_chunk_bytes = uint64_t{256} << 20;
  // Time window, seconds from the bag's start (MessageReader::start_time_ns(): its earliest
  // message): only messages received in [start_s, start_s + duration_s) are delivered, with their
  // own recorded times. Defaults: the whole bag. Negative or NaN values are the caller's error
  // (window_problem() says so); the readers treat them as 0 and as no limit.
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();

  // Every topic, the default chunk bound, the window [start_s, start_s + duration_s).
  static ReaderOptions window(double start, double duration) {
    ReaderOptions r;
    r.start_s = start;
    r.duration_s = duration;
    return r;
  }
};

// Empty when `start_s` and `duration_s` make a window (start >= 0, duration > 0, neither NaN),
// else what is wrong with them ("--start -1: ...").
std::string window_problem(double start_s, double duration_s);

class MessageReader {
 public:
  virtual ~MessageReader() = default;
  // The next message in the container's order (file order for ROS 1 and MCAP, time order for
  // sqlite3 storage); false at the end, or when damage stops the reading (see error()).
  virtual bool next(BagMessage& out) = 0;
  const std::vector<Connection>& connections() const { return connections_; }
  const ReadStats& stats() const { return stats_; }
  // What was lost: each problem met (first few, with file offsets); empty while nothing was.
  const std::string& error() const { return error_; }
  virtual BagFormat format() const = 0;
  // Receive time of the bag's earliest message, ns since epoch, as the container declares it at
  // the open (ROS 1: the index's chunk infos; MCAP: the summary's Statistics; sqlite3: the
  // smallest message timestamp, not metadata.yaml's starting_time). Without an index or summary:
  // the first message read (file order), once one was. The time window counts from it.
  std::optional<int64_t> start_time_ns() const { return start_ns_; }

 protected:
  void note(const std::string& problem);
  bool wanted(std::string_view topic) const;
  // Whether a message received at `time_ns` lies in the time window (options_.start_s,
  // duration_s); the first message seen anchors the window when the start is not known.
  bool in_window(int64_t time_ns);

  std::vector<Connection> connections_;
  ReadStats stats_;
  ReaderOptions options_;
  std::string error_;
  int notes_ = 0;
  std::optional<int64_t> start_ns_;
};

// The container at `path` by its content: a file's first bytes (ROS 1 magic, MCAP magic, SQLite
// header), or a folder holding metadata.yaml or .db3 files. kNone for anything else (also when
// the path cannot be read).
BagFormat detect_bag_format(const std::string& path);
std::string_view format_name(BagFormat format);

// Opens the container at `path` (any of BagFormat's). Throws BagError naming the file when it is
// not a container read here, cannot be read, or its own structure (magic, tables) is broken.
std::unique_ptr<MessageReader> open_bag(const std::string& path, ReaderOptions options = {});

// The type name without ROS 2's "/msg/": "sensor_msgs/msg/PointCloud2" ->
// "sensor_msgs/PointCloud2".
std::string normalized_type(std::string_view type);

}  // namespace lidartag::driver::bag
