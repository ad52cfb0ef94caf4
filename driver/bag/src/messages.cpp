#include "lidartag/driver/bag/messages.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "internal.hpp"

namespace lidartag::driver::bag {
namespace {

// Reads a message in ROS 1 serialization (packed little endian, strings u32 length + bytes) or
// little-endian CDR (XCDR1 as ROS 2 writes it: a 4-byte encapsulation header, each primitive
// aligned to its size from the end of that header, strings u32 length counting a final NUL).
class MessageCursor {
 public:
  MessageCursor(std::span<const uint8_t> bytes, Encoding encoding) : c_(bytes) {
    if (encoding == Encoding::kCdr) {
      cdr_ = true;
      const auto header = c_.take(4);
      // 0x00 0x01: CDR, little endian. Big endian and XCDR2 are not what ROS 2 records.
      bad_encoding_ = !c_.ok() || header[0] != 0 || header[1] != 1;
    } else {
      bad_encoding_ = encoding != Encoding::kRos1;
    }
  }
  void align(size_t n) {
    if (!cdr_) return;
    const size_t offset = (c_.pos() - 4) % n;
    if (offset != 0) c_.take(n - offset);
  }
  template <class T>
  T get() {
    align(sizeof(T));
    return c_.get<T>();
  }
  std::span<const uint8_t> take(size_t n) { return c_.take(n); }
  std::string_view string() {
    const auto n = get<uint32_t>();
    const auto s = c_.take(n);
    std::string_view text(reinterpret_cast<const char*>(s.data()), s.size());
    if (cdr_ && !text.empty() && text.back() == '\0') text.remove_suffix(1);
    return text;
  }
  // std_msgs/Header: its stamp (ns) and frame_id.
  int64_t header(std::string_view* frame_id = nullptr) {
    if (!cdr_) get<uint32_t>();  // ROS 1's seq
    const int64_t stamp = time();
    const auto frame = string();
    if (frame_id) *frame_id = frame;
    return stamp;
  }
  int64_t time() {
    const auto sec = get<int32_t>();
    const auto nsec = get<uint32_t>();
    // ROS 1 time's seconds are unsigned.
    const int64_t s = cdr_ ? int64_t{sec} : int64_t{static_cast<uint32_t>(sec)};
    return s * 1'000'000'000 + nsec;
  }
  size_t left() const { return c_.left(); }
  bool ok() const { return c_.ok(); }
  bool bad_encoding() const { return bad_encoding_; }
  bool cdr() const { return cdr_; }

 private:
  detail::Cursor c_;
  bool cdr_ = false;
  bool bad_encoding_ = false;
};

}  // namespace

MessageKind message_kind(std::string_view type) {
  const std::string t = normalized_type(type);
  if (t == "velodyne_msgs/VelodyneScan") return MessageKind::kVelodyneScan;
  if (t == "ouster_ros/PacketMsg" || t == "ouster_sensor_msgs/PacketMsg")
    return MessageKind::kOusterPacket;
  if (t == "sensor_msgs/PointCloud2") return MessageKind::kPointCloud2;
  if (t == "std_msgs/String") return MessageKind::kString;
  return MessageKind::kOther;
}

std::string_view decode_result_name(DecodeResult result) {
  switch (result) {
    case DecodeResult::kOk:
      return "ok";
    case DecodeResult::kTruncated:
      return "truncated message";
    case DecodeResult::kCorrupt:
      return "corrupt message";
    case DecodeResult::kEncoding:
      return "unsupported serialization";
  }
  return "?";
}

DecodeResult decode_velodyne_scan(std::span<const uint8_t> message, Encoding encoding,
                                  int64_t& header_stamp_ns, std::vector<StampedPacket>& out) {
  out.clear();
  MessageCursor c(message, encoding);
  if (c.bad_encoding()) return DecodeResult::kEncoding;
  header_stamp_ns = c.header();
  const auto count = c.get<uint32_t>();
  if (!c.ok()) return DecodeResult::kTruncated;
  // Packets up to the end of the bytes: a count larger than the message holds (a message cut
  // short, a corrupt count) keeps the whole packets before the end.
  for (uint32_t i = 0; i < count; ++i) {
    StampedPacket p;
    p.stamp_ns = c.time();
    p.payload = c.take(kVelodynePacketBytes);
    if (!c.ok()) return DecodeResult::kTruncated;
    out.push_back(p);
  }
  return DecodeResult::kOk;
}

DecodeResult decode_ouster_packet(std::span<const uint8_t> message, Encoding encoding,
                                  std::span<const uint8_t>& out) {
  MessageCursor c(message, encoding);
  if (c.bad_encoding()) return DecodeResult::kEncoding;
  const auto n = c.get<uint32_t>();
  out = c.take(n);
  return c.ok() ? DecodeResult::kOk : DecodeResult::kTruncated;
}

DecodeResult decode_string(std::span<const uint8_t> message, Encoding encoding,
                           std::string_view& out) {
  MessageCursor c(message, encoding);
  if (c.bad_encoding()) return DecodeResult::kEncoding;
  out = c.string();
  return c.ok() ? DecodeResult::kOk : DecodeResult::kTruncated;
}

namespace {
size_t type_size(PointFieldType t) {
  switch (t) {
    case PointFieldType::kInt8:
    case PointFieldType::kUint8:
      return 1;
    case PointFieldType::kInt16:
    case PointFieldType::kUint16:
      return 2;
    case PointFieldType::kInt32:
    case PointFieldType::kUint32:
    case PointFieldType::kFloat32:
      return 4;
    case PointFieldType::kFloat64:
      return 8;
  }
  return 0;
}
}  // namespace

DecodeResult decode_point_cloud(std::span<const uint8_t> message, Encoding encoding,
                                PointCloudView& out) {
  MessageCursor c(message, encoding);
  if (c.bad_encoding()) return DecodeResult::kEncoding;
  out.stamp_ns = c.header(&out.frame_id);
  out.height = c.get<uint32_t>();
  out.width = c.get<uint32_t>();
  const auto n_fields = c.get<uint32_t>();
  if (!c.ok() || n_fields > c.left() / 9) return DecodeResult::kTruncated;
  out.fields.clear();
  for (uint32_t i = 0; i < n_fields; ++i) {
    PointField f;
    f.name = c.string();
    f.offset = c.get<uint32_t>();
    const auto type = c.get<uint8_t>();
    f.count = c.get<uint32_t>();
    if (!c.ok()) return DecodeResult::kTruncated;
    if (type < 1 || type > 8) return DecodeResult::kCorrupt;
    f.type = static_cast<PointFieldType>(type);
    out.fields.push_back(f);
  }
  out.big_endian = c.get<uint8_t>() != 0;
  out.point_step = c.get<uint32_t>();
  out.row_step = c.get<uint32_t>();
  const auto n_data = c.get<uint32_t>();
  out.data = c.take(n_data);
  out.dense = c.get<uint8_t>() != 0;
  if (!c.ok()) return DecodeResult::kTruncated;
  for (const PointField& f : out.fields) {
    if (uint64_t{f.offset} + type_size(f.type) * uint64_t{std::max(f.count, 1u)} > out.point_step)
      return DecodeResult::kCorrupt;
  }
  const uint64_t needed = uint64_t{out.height} * out.width * out.point_step;
  if (needed > out.data.size()) return DecodeResult::kCorrupt;
  return DecodeResult::kOk;
}

namespace {

double field_value(const uint8_t* p, PointFieldType type, bool big_endian) {
  uint8_t b[8] = {};
  const size_t n = type_size(type);
  if (big_endian) {
    for (size_t i = 0; i < n; ++i) b[i] = p[n - 1 - i];
  } else {
    std::memcpy(b, p, n);
  }
  auto as = [&b]<class T>(T) {
    T v{};
    std::memcpy(&v, b, sizeof(T));
    return static_cast<double>(v);
  };
  switch (type) {
    case PointFieldType::kInt8:
      return as(int8_t{});
    case PointFieldType::kUint8:
      return as(uint8_t{});
    case PointFieldType::kInt16:
      return as(int16_t{});
    case PointFieldType::kUint16:
      return as(uint16_t{});
    case PointFieldType::kInt32:
      return as(int32_t{});
    case PointFieldType::kUint32:
      return as(uint32_t{});
    case PointFieldType::kFloat32:
      return as(float{});
    case PointFieldType::kFloat64:
      return as(double{});
  }
  return 0.0;
}

bool is_integer(PointFieldType t) {
  return t != PointFieldType::kFloat32 && t != PointFieldType::kFloat64;
}

void column(const PointCloudView& cloud, const PointField& f, std::vector<double>& out) {
  const size_t n = cloud.points();
  out.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const size_t row = i / std::max<size_t>(cloud.width, 1),
                 col = i % std::max<size_t>(cloud.width, 1);
    const uint8_t* p = cloud.data.data() + row * cloud.row_step + col * cloud.point_step + f.offset;
    out[i] = field_value(p, f.type, cloud.big_endian);
  }
}

}  // namespace

void cloud_columns(const PointCloudView& cloud, CloudColumns& out) {
  // Rows are row_step apart; a row_step that does not hold a row is corrupt: read as packed.
  PointCloudView packed = cloud;
  if (uint64_t{packed.row_step} < uint64_t{packed.width} * packed.point_step ||
      uint64_t{packed.row_step} * packed.height > packed.data.size())
    packed.row_step = packed.width * packed.point_step;
  std::vector<CloudSourceField> fields;
  fields.reserve(cloud.fields.size());
  for (const PointField& f : cloud.fields) fields.push_back({f.name, is_integer(f.type)});
  cloud_columns_of(
      fields,
      [&](size_t k, std::vector<double>& values) { column(packed, cloud.fields[k], values); }, out);
  out.width = cloud.width;
  out.height = cloud.height;
}

std::vector<std::string> lidar_topics(const std::vector<Connection>& connections) {
  std::vector<std::string> topics;
  for (const Connection& c : connections) {
    const MessageKind kind = message_kind(c.type);
    const bool lidar =
        kind == MessageKind::kVelodyneScan || kind == MessageKind::kPointCloud2 ||
        (kind == MessageKind::kOusterPacket && c.topic.find("imu") == std::string::npos);
    if (lidar && std::find(topics.begin(), topics.end(), c.topic) == topics.end())
      topics.push_back(c.topic);
  }
  return topics;
}

std::string choose_lidar_topic(const std::vector<Connection>& connections,
                               const std::string& requested, const std::string& path) {
  const auto topics = lidar_topics(connections);
  auto list = [&](bool all) {
    std::string text;
    for (const Connection& c : connections) {
      if (!all && std::find(topics.begin(), topics.end(), c.topic) == topics.end()) continue;
      if (!text.empty()) text += ", ";
      text += c.topic + " (" + c.type + ", " + std::to_string(c.count) + " messages)";
    }
    return text.empty() ? std::string("none") : text;
  };
  if (!requested.empty()) {
    for (const Connection& c : connections)
      if (c.topic == requested) return requested;
    throw BagError(path + ": no topic " + requested + "; its topics: " + list(true));
  }
  if (topics.size() == 1) return topics.front();
  if (topics.empty())
    throw BagError(path +
                   ": no LiDAR topic (VelodyneScan, PointCloud2, Ouster packets); its "
                   "topics: " +
                   list(true));
  throw BagError(path + ": several LiDAR topics, choose one with --topic: " + list(false));
}

}  // namespace lidartag::driver::bag
