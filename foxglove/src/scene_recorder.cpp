#include "lidartag/foxglove/scene_recorder.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <iterator>
#include <utility>

namespace lidartag::foxglove {
namespace {

using driver::bag::McapWriteError;

constexpr uint32_t kPointStride = 18;     // x, y, z, intensity float32; ring uint16
constexpr int kUint16 = 3, kFloat32 = 7;  // foxglove.NumericType

void append_time(std::string& out, int64_t ns) {
  const int64_t t = std::max<int64_t>(ns, 0);
  fmt::format_to(std::back_inserter(out), R"({{"sec":{},"nsec":{}}})", t / 1000000000,
                 t % 1000000000);
}

// A JSON number (null where JSON has none).
void append_number(std::string& out, double v) {
  if (std::isfinite(v)) {
    fmt::format_to(std::back_inserter(out), "{}", v);
  } else {
    out += "null";
  }
}

// A JSON string of `s` (quotes, backslashes and control characters escaped).
void append_string(std::string& out, std::string_view s) {
  out += '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      fmt::format_to(std::back_inserter(out), "\\u{:04x}", static_cast<unsigned>(c));
    } else {
      out += c;
    }
  }
  out += '"';
}

// {"x":..,"y":..,...}: one JSON object of named numbers (Foxglove's Vector3 and Quaternion).
void append_fields(std::string& out, std::initializer_list<std::pair<char, double>> fields) {
  char sep = '{';
  for (const auto& [name, value] : fields) {
    out += sep;
    out += '"';
    out += name;
    out += "\":";
    append_number(out, value);
    sep = ',';
  }
  out += '}';
}

void append_vector3(std::string& out, const Eigen::Vector3d& v) {
  append_fields(out, {{'x', v.x()}, {'y', v.y()}, {'z', v.z()}});
}

void append_quaternion(std::string& out, const Eigen::Quaterniond& q) {
  append_fields(out, {{'x', q.x()}, {'y', q.y()}, {'z', q.z()}, {'w', q.w()}});
}

void append_pose(std::string& out, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  out += R"({"position":)";
  append_vector3(out, p);
  out += R"(,"orientation":)";
  append_quaternion(out, q);
  out += '}';
}

// tag_<family>_<id>: the tag's frame in the transforms and its entity's id.
void append_tag_frame(std::string& out, const detector::Detection& d) {
  fmt::format_to(std::back_inserter(out), "tag_{}_{}", d.family, d.id);
}

template <class T>
void pack(uint8_t*& p, T v) {
  std::memcpy(p, &v, sizeof(T));
  p += sizeof(T);
}

}  // namespace

void CloudPoints::clear() {
  x.clear();
  y.clear();
  z.clear();
  intensity.clear();
  ring.clear();
}

void CloudPoints::push(float px, float py, float pz, float i, uint16_t r) {
  x.push_back(px);
  y.push_back(py);
  z.push_back(pz);
  intensity.push_back(i);
  ring.push_back(r);
}

void scan_points(const Scan& scan, CloudPoints& out) {
  out.clear();
  for (int col = 0; col < scan.columns; ++col) {
    for (int ret = 0; ret < scan.returns; ++ret) {
      for (int ring = 0; ring < scan.rings; ++ring) {
        const size_t i = scan.at(ret, ring, col);
        if (!(scan.range[i] > 0.0f)) continue;
        out.push(scan.x[i], scan.y[i], scan.z[i], static_cast<float>(scan.intensity[i]),
                 static_cast<uint16_t>(ring));
      }
    }
  }
}

void append_base64(std::span<const uint8_t> bytes, std::string& out) {
  static constexpr char kDigits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const size_t start = out.size();
  out.resize(start + (bytes.size() + 2) / 3 * 4);
  char* o = out.data() + start;
  size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const uint32_t v = (uint32_t{bytes[i]} << 16) | (uint32_t{bytes[i + 1]} << 8) | bytes[i + 2];
    *o++ = kDigits[(v >> 18) & 63];
    *o++ = kDigits[(v >> 12) & 63];
    *o++ = kDigits[(v >> 6) & 63];
    *o++ = kDigits[v & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const uint32_t v = (uint32_t{bytes[i]} << 16) | (two ? uint32_t{bytes[i + 1]} << 8 : 0u);
    *o++ = kDigits[(v >> 18) & 63];
    *o++ = kDigits[(v >> 12) & 63];
    *o++ = two ? kDigits[(v >> 6) & 63] : '=';
    *o++ = '=';
  }
}

SceneRecorder::SceneRecorder(const std::string& path, SceneRecorderOptions options)
    : options_(std::move(options)), writer_(path, options_.mcap) {
  auto schema = [&](std::string_view name) {
    return writer_.add_schema(name, "jsonschema", json_schema(name));
  };
  point_cloud_schema_ = schema("foxglove.PointCloud");
  scene_schema_ = schema("foxglove.SceneUpdate");
  transforms_schema_ = schema("foxglove.FrameTransforms");
  detections_schema_ = schema("lidartag.Detections");
  status_schema_ = schema("lidartag.Status");
  tf_channel_ = writer_.add_channel(options_.tf_topic, transforms_schema_, "json");
}

SceneRecorder::Channels& SceneRecorder::channels(std::string_view sensor) {
  for (auto& c : channels_) {
    if (c.sensor == sensor) return c;
  }
  // First rotation of this sensor: its channels (allocates, once per sensor).
  Channels c;
  c.sensor = std::string(sensor);
  std::string base = options_.topic_prefix;
  if (!sensor.empty()) {
    base += '/';
    base.append(sensor);
  }
  c.cloud = writer_.add_channel(base + "/cloud", point_cloud_schema_, "json");
  c.tags = writer_.add_channel(base + "/tags", scene_schema_, "json");
  c.detections = writer_.add_channel(base + "/detections", detections_schema_, "json");
  c.status = writer_.add_channel(base + "/status", status_schema_, "json");
  channels_.push_back(std::move(c));
  return channels_.back();
}

bool SceneRecorder::write_rotation(const RotationRecord& r) {
  Channels* ch = nullptr;
  try {
    ch = &channels(r.sensor);
  } catch (const McapWriteError&) {
    return false;  // closed, or out of channel ids
  }
  const auto log_time = static_cast<uint64_t>(std::max<int64_t>(r.stamp_ns, 0));
  bool ok = true;
  std::string& out = buffer_;

  // The cloud: foxglove.PointCloud, its points packed little endian.
  if (r.cloud != nullptr) {
    const CloudPoints& c = *r.cloud;
    packed_.resize(c.size() * kPointStride);
    uint8_t* p = packed_.data();
    for (size_t i = 0; i < c.size(); ++i) {
      pack(p, c.x[i]);
      pack(p, c.y[i]);
      pack(p, c.z[i]);
      pack(p, c.intensity[i]);
      pack(p, c.ring[i]);
    }
    out.clear();
    out += R"({"timestamp":)";
    append_time(out, r.stamp_ns);
    out += R"(,"frame_id":)";
    append_string(out, r.frame_id);
    out += R"(,"pose":{"position":{"x":0,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}})";
    fmt::format_to(std::back_inserter(out),
                   R"(,"point_stride":{},"fields":[{{"name":"x","offset":0,"type":{}}},)"
                   R"({{"name":"y","offset":4,"type":{}}},{{"name":"z","offset":8,"type":{}}},)"
                   R"({{"name":"intensity","offset":12,"type":{}}},)"
                   R"({{"name":"ring","offset":16,"type":{}}}],"data":")",
                   kPointStride, kFloat32, kFloat32, kFloat32, kFloat32, kUint16);
    append_base64(packed_, out);
    out += "\"}";
    ok = writer_.write(ch->cloud, log_time, out) && ok;
    ++counts_.clouds;
  }
  if (!r.detected) return ok;

  // The tags: every earlier entity deleted, then a cube and a label per tag.
  out.clear();
  out += R"({"deletions":[{"timestamp":)";
  append_time(out, r.stamp_ns);
  out += R"(,"type":1,"id":""}],"entities":[)";
  for (size_t i = 0; i < r.detections.size(); ++i) {
    const detector::Detection& d = r.detections[i];
    if (i > 0) out += ',';
    out += R"({"timestamp":)";
    append_time(out, r.stamp_ns);
    out += R"(,"frame_id":)";
    append_string(out, r.frame_id);
    out += R"(,"id":")";
    append_tag_frame(out, d);
    out += R"(","lifetime":{"sec":0,"nsec":0},"frame_locked":false,"metadata":[)";
    out += R"({"key":"family","value":)";
    append_string(out, d.family);
    fmt::format_to(std::back_inserter(out), R"(}},{{"key":"id","value":"{}"}},)", d.id);
    fmt::format_to(std::back_inserter(out), R"({{"key":"score","value":"{:.4f}"}}],)", d.score);
    out += R"("arrows":[],"cubes":[{"pose":)";
    append_pose(out, d.position, d.orientation);
    out += R"(,"size":{"x":)";
    append_number(out, options_.tag_thickness_m);
    out += R"(,"y":)";
    append_number(out, d.size_m);
    out += R"(,"z":)";
    append_number(out, d.size_m);
    out += R"(},"color":{"r":0.1,"g":0.8,"b":0.2,"a":0.6}}],)";
    out += R"("spheres":[],"cylinders":[],"lines":[],"triangles":[],"texts":[{"pose":)";
    // The label just above the tag (sensor frame z up), facing the viewer (billboard).
    const Eigen::Vector3d above = d.position + Eigen::Vector3d(0, 0, 0.6 * d.size_m + 0.05);
    append_pose(out, above, Eigen::Quaterniond::Identity());
    out += R"(,"billboard":true,"font_size":14,"scale_invariant":true,)";
    out += R"("color":{"r":1,"g":1,"b":1,"a":1},"text":)";
    buffer_label_.clear();
    fmt::format_to(std::back_inserter(buffer_label_), "{} {}", d.family, d.id);
    append_string(out, buffer_label_);
    out += R"(}],"models":[]})";
  }
  out += "]}";
  ok = writer_.write(ch->tags, log_time, out) && ok;
  ++counts_.scenes;

  // A frame per tag.
  if (!r.detections.empty()) {
    out.clear();
    out += R"({"transforms":[)";
    for (size_t i = 0; i < r.detections.size(); ++i) {
      const detector::Detection& d = r.detections[i];
      if (i > 0) out += ',';
      out += R"({"timestamp":)";
      append_time(out, r.stamp_ns);
      out += R"(,"parent_frame_id":)";
      append_string(out, r.frame_id);
      out += R"(,"child_frame_id":")";
      append_tag_frame(out, d);
      out += R"(","translation":)";
      append_vector3(out, d.position);
      out += R"(,"rotation":)";
      append_quaternion(out, d.orientation);
      out += '}';
    }
    out += "]}";
    ok = writer_.write(tf_channel_, log_time, out) && ok;
    ++counts_.transforms;
  }

  // The detections, as the caller reports them or in the recorder's own form.
  if (!r.detections_json.empty()) {
    ok = writer_.write(ch->detections, log_time, r.detections_json) && ok;
  } else {
    out.clear();
    out += R"({"sensor":)";
    append_string(out, r.sensor);
    fmt::format_to(std::back_inserter(out), R"(,"sequence":{},"stamp":)", r.sequence);
    append_number(out, static_cast<double>(r.stamp_ns) * 1e-9);
    out += R"(,"detections":[)";
    for (size_t i = 0; i < r.detections.size(); ++i) {
      const detector::Detection& d = r.detections[i];
      if (i > 0) out += ',';
      out += R"({"family":)";
      append_string(out, d.family);
      fmt::format_to(std::back_inserter(out), R"(,"id":{},"size_m":)", d.id);
      append_number(out, d.size_m);
      out += R"(,"position":[)";
      append_number(out, d.position.x());
      out += ',';
      append_number(out, d.position.y());
      out += ',';
      append_number(out, d.position.z());
      out += R"(],"orientation":[)";
      append_number(out, d.orientation.w());
      out += ',';
      append_number(out, d.orientation.x());
      out += ',';
      append_number(out, d.orientation.y());
      out += ',';
      append_number(out, d.orientation.z());
      out += R"(],"score":)";
      append_number(out, d.score);
      out += R"(,"margin":)";
      append_number(out, d.margin);
      fmt::format_to(std::back_inserter(out), R"(,"points":{}}})", d.points);
    }
    out += "]}";
    ok = writer_.write(ch->detections, log_time, out) && ok;
  }
  ++counts_.detections;
  return ok;
}

bool SceneRecorder::write_status(std::string_view sensor, int64_t stamp_ns, std::string_view json) {
  Channels* ch = nullptr;
  try {
    ch = &channels(sensor);
  } catch (const McapWriteError&) {
    return false;
  }
  ++counts_.statuses;
  return writer_.write(ch->status, static_cast<uint64_t>(std::max<int64_t>(stamp_ns, 0)), json);
}

}  // namespace lidartag::foxglove
