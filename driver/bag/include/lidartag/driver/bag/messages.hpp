// The LiDAR messages of ROS bags, decoded from their serialized bytes (ROS 1 serialization or CDR):
// velodyne_msgs/VelodyneScan (packets, the exact bytes a pcap holds), ouster_ros/PacketMsg and the
// Ouster metadata (std_msgs/String), sensor_msgs/PointCloud2 (fields by name). Pure functions over
// bytes: nothing here throws or allocates beyond the caller's reused vectors.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/cloud_fields.hpp"

namespace lidartag::driver::bag {

enum class MessageKind : uint8_t {
  kVelodyneScan,  // velodyne_msgs/VelodyneScan
  kOusterPacket,  // ouster_ros/PacketMsg (lidar or IMU packets; told apart by the topic)
  kPointCloud2,   // sensor_msgs/PointCloud2
  kString,        // std_msgs/String (Ouster's metadata topic)
  kOther,
};
MessageKind message_kind(std::string_view type);

enum class DecodeResult : uint8_t {
  kOk,
  kTruncated,  // the bytes end before the message does
  kCorrupt,    // sizes or values the message type does not allow
  kEncoding,   // neither ROS 1 nor CDR (or a CDR encapsulation not read here)
};
std::string_view decode_result_name(DecodeResult result);

// A Velodyne data packet's payload size: VelodynePacket's uint8[1206].
inline constexpr size_t kVelodynePacketBytes = 1206;

struct StampedPacket {
  int64_t stamp_ns = 0;              // VelodynePacket.stamp (the receive time nodes record)
  std::span<const uint8_t> payload;  // views the message's bytes
};

// velodyne_msgs/VelodyneScan: its packets, in order, into `out` (cleared first). A message cut
// short gives kTruncated with the whole packets before the cut in `out`.
[[nodiscard]] DecodeResult decode_velodyne_scan(std::span<const uint8_t> message, Encoding encoding,
                                                int64_t& header_stamp_ns,
                                                std::vector<StampedPacket>& out);

// ouster_ros/PacketMsg (uint8[] buf): the packet's bytes, viewing the message's.
[[nodiscard]] DecodeResult decode_ouster_packet(std::span<const uint8_t> message, Encoding encoding,
                                                std::span<const uint8_t>& out);

// std_msgs/String: the text, viewing the message's bytes.
[[nodiscard]] DecodeResult decode_string(std::span<const uint8_t> message, Encoding encoding,
                                         std::string_view& out);

// sensor_msgs/PointField datatypes.
enum class PointFieldType : uint8_t {
  kInt8 = 1,
  kUint8 = 2,
  kInt16 = 3,
  kUint16 = 4,
  kInt32 = 5,
  kUint32 = 6,
  kFloat32 = 7,
  kFloat64 = 8,
};

struct PointField {
  std::string_view name;  // views the message's bytes
  uint32_t offset = 0;    // bytes into the point
  PointFieldType type = PointFieldType::kFloat32;
  uint32_t count = 1;
};

// sensor_msgs/PointCloud2 as read: its layout, fields and data, viewing the message's bytes.
// decode_point_cloud checks that every field fits in point_step and the data holds
// width x height points of point_step bytes.
struct PointCloudView {
  int64_t stamp_ns = 0;  // header.stamp
  std::string_view frame_id;
  uint32_t height = 0, width = 0;
  std::vector<PointField> fields;
  bool big_endian = false;
  uint32_t point_step = 0, row_step = 0;
  std::span<const uint8_t> data;
  bool dense = false;
  size_t points() const { return size_t{height} * width; }
};

[[nodiscard]] DecodeResult decode_point_cloud(std::span<const uint8_t> message, Encoding encoding,
                                              PointCloudView& out);

// A cloud's points as the detector's columns, its fields named by the one vocabulary that PCD
// files share (driver/cloud_fields.hpp: x y z intensity azimuth return_type; the ring under ring,
// channel, laser_id or line; the time under time, t, time_offset, timestamp, time_stamp,
// offset_time or time_sec + time_nsec, in seconds by time_to_seconds's rule).
using driver::CloudColumns;
void cloud_columns(const PointCloudView& cloud, CloudColumns& out);

// The topics that carry LiDAR data: VelodyneScan, PointCloud2 and Ouster packet topics (not those
// named like IMU packets).
std::vector<std::string> lidar_topics(const std::vector<Connection>& connections);

// `requested` when the bag has that topic (BagError listing the bag's topics otherwise); with
// nothing requested, the bag's one LiDAR topic (BagError listing the candidates when there are
// several, or the topics and their types when there is none).
std::string choose_lidar_topic(const std::vector<Connection>& connections,
                               const std::string& requested, const std::string& path);

}  // namespace lidartag::driver::bag
