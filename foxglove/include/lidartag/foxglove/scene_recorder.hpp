// Rotations and their detections as an MCAP file that Foxglove opens without plugins: JSON
// messages whose schemas (JSON Schema, embedded in the file) are Foxglove's own message types.
// Per rotation (log time = the rotation's stamp: the capture's clock, not the wall clock):
//   <prefix>[/<sensor>]/cloud       foxglove.PointCloud: x, y, z, intensity (float32), ring
//                                   (uint16), 18 bytes a point, in the sensor's frame
//   <prefix>[/<sensor>]/tags        foxglove.SceneUpdate: every earlier entity deleted, then one
//                                   entity per tag: a cube at its pose (x its normal; the
//                                   marker's size, tag_thickness_m thick) and its family and ID
//                                   as text
//   /tf                             foxglove.FrameTransforms: sensor frame -> tag_<family>_<id>
//                                   per tag (only rotations with tags)
//   <prefix>[/<sensor>]/detections  lidartag.Detections (JSON): the rotation's detections
// and, when the caller has one, <prefix>[/<sensor>]/status (lidartag.Status, JSON).
// The messages are built in reused buffers: no allocation once they have grown.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/detector/result.hpp"
#include "lidartag/driver/bag/mcap_writer.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::foxglove {

// One cloud's points, one entry per return.
struct CloudPoints {
  std::vector<float> x, y, z, intensity;
  std::vector<uint16_t> ring;
  size_t size() const { return x.size(); }
  void clear();
  void push(float px, float py, float pz, float i, uint16_t r);
};

// The returns of `scan` (cells with a range): column by column, each return, ring by ring.
// Reuses `out`'s storage.
void scan_points(const Scan& scan, CloudPoints& out);

struct SceneRecorderOptions {
  driver::bag::McapWriterOptions mcap;
  // Topics: <topic_prefix>/<kind> without a sensor name, <topic_prefix>/<sensor>/<kind> with one.
  std::string topic_prefix = "/lidartag";
  std::string tf_topic = "/tf";
  double tag_thickness_m = 0.02;  // the cubes' depth along the tag's normal, metres
};

// What one rotation contributes.
struct RotationRecord {
  std::string_view sensor;    // "" for topics without a sensor level (the CLI)
  std::string_view frame_id;  // the sensor's frame: the clouds' and the transforms' parent
  uint64_t sequence = 0;
  int64_t stamp_ns = 0;                // the rotation's first firing (ns since the epoch)
  const CloudPoints* cloud = nullptr;  // null: no cloud message
  // false: the cloud alone (a conversion, nothing detected): no tags, transforms or detections.
  bool detected = true;
  std::span<const detector::Detection> detections;
  // The detections message as the caller has it (lidartag detect: its --json object); "" writes
  // the recorder's own (sensor, sequence, stamp and each tag's family, ID, size, pose, score).
  std::string_view detections_json;
};

class SceneRecorder {
 public:
  // Creates `path` (McapWriter's rules); throws driver::bag::McapWriteError.
  SceneRecorder(const std::string& path, SceneRecorderOptions options = {});

  // Writes the rotation's messages; false when the writer refused one (McapWriter::error()).
  // Never throws past setup (a sensor's channels are added on its first rotation).
  [[nodiscard]] bool write_rotation(const RotationRecord& r);
  // A status message (a JSON object) at `stamp_ns`.
  [[nodiscard]] bool write_status(std::string_view sensor, int64_t stamp_ns, std::string_view json);

  // Completes the file (McapWriter::close()); throws driver::bag::McapWriteError.
  void close() { writer_.close(); }
  const driver::bag::McapWriter& writer() const { return writer_; }

  // Messages written per kind, over all sensors.
  struct Counts {
    uint64_t clouds = 0, scenes = 0, transforms = 0, detections = 0, statuses = 0;
  };
  const Counts& counts() const { return counts_; }

 private:
  struct Channels {
    std::string sensor;
    uint16_t cloud = 0, tags = 0, detections = 0, status = 0;
  };
  Channels& channels(std::string_view sensor);

  SceneRecorderOptions options_;
  driver::bag::McapWriter writer_;
  uint16_t point_cloud_schema_ = 0, scene_schema_ = 0, transforms_schema_ = 0,
           detections_schema_ = 0, status_schema_ = 0, tf_channel_ = 0;
  std::vector<Channels> channels_;
  std::string buffer_, buffer_label_;
  std::vector<uint8_t> packed_;
  Counts counts_;
};

// The schemas embedded in the file (JSON Schema documents), by name: foxglove.PointCloud,
// foxglove.SceneUpdate, foxglove.FrameTransforms, lidartag.Detections, lidartag.Status.
std::string_view json_schema(std::string_view name);

// Standard base64 (RFC 4648, with padding) of `bytes`, appended to `out`.
void append_base64(std::span<const uint8_t> bytes, std::string& out);

}  // namespace lidartag::foxglove
