// Small ROS 1 bags and MCAP files written byte by byte from the formats' specifications
// (wiki.ros.org/Bags/Format/2.0, mcap.dev/spec), for the tests and the fuzzers' seeds: chunks in
// any order, with or without index or summary, uncompressed. Test-side only: the library reads
// these formats, it does not write them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::driver::bag::synthetic {

using Bytes = std::vector<uint8_t>;

struct Message {
  std::string topic;
  int64_t time_ns = 0;
  Bytes data;
};
// Chunks in file order, each its messages in file order.
using Chunks = std::vector<std::vector<Message>>;

struct Topic {
  std::string name, type;
};

// How chunks are compressed: the name the container records and the compressor (none: stored).
struct Compression {
  std::string name = "none";
  std::function<Bytes(const Bytes&)> compress;
};

inline void put(Bytes& b, const void* p, size_t n) {
  const auto* c = static_cast<const uint8_t*>(p);
  b.insert(b.end(), c, c + n);
}
template <class T>
void put(Bytes& b, T v) {
  put(b, &v, sizeof v);
}
inline void put(Bytes& b, std::string_view s) {
  put(b, s.data(), s.size());
}

// ---- ROS 1 bag 2.0
inline void ros1_field(Bytes& h, std::string_view name, const Bytes& value) {
  put(h, static_cast<uint32_t>(name.size() + 1 + value.size()));
  put(h, name);
  put(h, std::string_view("="));
  put(h, value.data(), value.size());
}
template <class T>
Bytes le(T v) {
  Bytes b;
  put(b, v);
  return b;
}
inline Bytes text(std::string_view s) {
  return Bytes(s.begin(), s.end());
}
inline Bytes ros_time(int64_t ns) {
  Bytes b;
  put(b, static_cast<uint32_t>(ns / 1'000'000'000));
  put(b, static_cast<uint32_t>(ns % 1'000'000'000));
  return b;
}
inline void ros1_record(Bytes& out, const Bytes& header, const Bytes& data) {
  put(out, static_cast<uint32_t>(header.size()));
  put(out, header.data(), header.size());
  put(out, static_cast<uint32_t>(data.size()));
  put(out, data.data(), data.size());
}
inline Bytes ros1_connection(uint32_t conn, const Topic& t) {
  Bytes h, d, out;
  ros1_field(h, "op", {0x07});
  ros1_field(h, "conn", le(conn));
  ros1_field(h, "topic", text(t.name));
  ros1_field(d, "topic", text(t.name));
  ros1_field(d, "type", text(t.type));
  ros1_field(d, "md5sum", text("*"));
  ros1_field(d, "message_definition", text(""));
  ros1_record(out, h, d);
  return out;
}

// A ROS 1 bag of `chunks` (uncompressed) with the topics' connections in the first chunk that
// uses them; `indexed`: connection and chunk info records at index_pos, else index_pos 0.
inline Bytes ros1_bag(const std::vector<Topic>& topics, const Chunks& chunks, bool indexed = true,
                      const Compression& compression = {}) {
  std::map<std::string, uint32_t> ids;
  for (const Topic& t : topics) ids.emplace(t.name, static_cast<uint32_t>(ids.size()));
  Bytes body;  // after the bag header record
  struct Info {
    uint64_t pos;
    int64_t start, end;
    std::map<uint32_t, uint32_t> counts;
  };
  std::vector<Info> infos;
  std::vector<bool> written(topics.size(), false);
  const std::string magic = "#ROSBAG V2.0\n";
  // The bag header's size is fixed: its fields' sizes do not depend on their values.
  auto bag_header = [&](uint64_t index_pos) {
    Bytes h, out;
    ros1_field(h, "op", {0x03});
    ros1_field(h, "index_pos", le(index_pos));
    ros1_field(h, "conn_count", le(static_cast<uint32_t>(topics.size())));
    ros1_field(h, "chunk_count", le(static_cast<uint32_t>(chunks.size())));
    ros1_record(out, h, {});
    return out;
  };
  const uint64_t start = magic.size() + bag_header(0).size();
  for (const auto& chunk : chunks) {
    Bytes inner;
    Info info{start + body.size(), INT64_MAX, INT64_MIN, {}};
    for (const Message& m : chunk) {
      const uint32_t conn = ids.at(m.topic);
      if (!written[conn]) {
        const Bytes c = ros1_connection(conn, topics[conn]);
        inner.insert(inner.end(), c.begin(), c.end());
        written[conn] = true;
      }
      Bytes h;
      ros1_field(h, "op", {0x02});
      ros1_field(h, "conn", le(conn));
      ros1_field(h, "time", ros_time(m.time_ns));
      ros1_record(inner, h, m.data);
      info.start = std::min(info.start, m.time_ns);
      info.end = std::max(info.end, m.time_ns);
      ++info.counts[conn];
    }
    Bytes h;
    ros1_field(h, "op", {0x05});
    ros1_field(h, "compression", text(compression.name));
    ros1_field(h, "size", le(static_cast<uint32_t>(inner.size())));
    ros1_record(body, h, compression.compress ? compression.compress(inner) : inner);
    infos.push_back(info);
  }
  const uint64_t index_pos = start + body.size();
  if (indexed) {
    for (size_t i = 0; i < topics.size(); ++i) {
      const Bytes c = ros1_connection(static_cast<uint32_t>(i), topics[i]);
      body.insert(body.end(), c.begin(), c.end());
    }
    for (const Info& info : infos) {
      Bytes h, d;
      ros1_field(h, "op", {0x06});
      ros1_field(h, "ver", le(uint32_t{1}));
      ros1_field(h, "chunk_pos", le(info.pos));
      ros1_field(h, "start_time", ros_time(info.counts.empty() ? 0 : info.start));
      ros1_field(h, "end_time", ros_time(info.counts.empty() ? 0 : info.end));
      ros1_field(h, "count", le(static_cast<uint32_t>(info.counts.size())));
      for (const auto& [conn, n] : info.counts) {
        put(d, conn);
        put(d, n);
      }
      ros1_record(body, h, d);
    }
  }
  Bytes out(magic.begin(), magic.end());
  const Bytes header = bag_header(indexed ? index_pos : 0);
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), body.begin(), body.end());
  return out;
}

// ---- MCAP
inline void mcap_string(Bytes& b, std::string_view s) {
  put(b, static_cast<uint32_t>(s.size()));
  put(b, s);
}
inline void mcap_record(Bytes& out, uint8_t op, const Bytes& body) {
  put(out, op);
  put(out, static_cast<uint64_t>(body.size()));
  put(out, body.data(), body.size());
}
inline uint32_t mcap_crc(const Bytes& b) {
  uint32_t c = ~0u;
  for (const uint8_t x : b) {
    c ^= x;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
  }
  return ~c;
}

// An MCAP file of `chunks` (uncompressed, CRC set), each topic's schema and channel in the first
// chunk that uses it ("ros1" encoding when `ros1`, else "cdr"); `summary`: schemas, channels and
// a Statistics record in a summary section the footer points at.
inline Bytes mcap_file(const std::vector<Topic>& topics, const Chunks& chunks, bool summary = true,
                       bool ros1 = false, const Compression& compression = {}) {
  std::map<std::string, uint16_t> ids;
  for (const Topic& t : topics) ids.emplace(t.name, static_cast<uint16_t>(ids.size() + 1));
  auto schema = [&](uint16_t id) {
    Bytes b;
    put(b, id);
    mcap_string(b, topics[id - 1u].type);
    mcap_string(b, ros1 ? "ros1msg" : "ros2msg");
    mcap_string(b, "");
    return b;
  };
  auto channel = [&](uint16_t id) {
    Bytes b;
    put(b, id);
    put(b, id);  // schema id
    mcap_string(b, topics[id - 1u].name);
    mcap_string(b, ros1 ? "ros1" : "cdr");
    put(b, uint32_t{0});  // metadata map
    return b;
  };
  const std::string_view magic("\x89MCAP0\r\n", 8);
  Bytes out;
  put(out, magic);
  Bytes header;
  mcap_string(header, "ros2");
  mcap_string(header, "lidartag tests");
  mcap_record(out, 0x01, header);
  std::vector<bool> written(topics.size() + 1, false);
  std::map<uint16_t, uint64_t> counts;
  uint64_t total = 0;
  int64_t first = INT64_MAX, last = 0;
  for (const auto& chunk : chunks) {
    Bytes records;
    int64_t start = INT64_MAX, end = 0;
    for (const Message& m : chunk) {
      const uint16_t id = ids.at(m.topic);
      if (!written[id]) {
        mcap_record(records, 0x03, schema(id));
        mcap_record(records, 0x04, channel(id));
        written[id] = true;
      }
      Bytes b;
      put(b, id);
      put(b, static_cast<uint32_t>(counts[id]));
      put(b, static_cast<uint64_t>(m.time_ns));
      put(b, static_cast<uint64_t>(m.time_ns));
      put(b, m.data.data(), m.data.size());
      mcap_record(records, 0x05, b);
      ++counts[id];
      ++total;
      start = std::min(start, m.time_ns);
      end = std::max(end, m.time_ns);
    }
    if (chunk.empty()) start = end = 0;
    first = std::min(first, start);
    last = std::max(last, end);
    Bytes c;
    put(c, static_cast<uint64_t>(start));
    put(c, static_cast<uint64_t>(end));
    put(c, static_cast<uint64_t>(records.size()));
    put(c, mcap_crc(records));
    const Bytes stored = compression.compress ? compression.compress(records) : records;
    mcap_string(c, compression.compress ? compression.name : "");
    put(c, static_cast<uint64_t>(stored.size()));
    put(c, stored.data(), stored.size());
    mcap_record(out, 0x06, c);
  }
  mcap_record(out, 0x0F, le(uint32_t{0}));  // DataEnd
  uint64_t summary_start = 0;
  if (summary) {
    summary_start = out.size();
    for (uint16_t id = 1; id <= topics.size(); ++id) {
      mcap_record(out, 0x03, schema(id));
      mcap_record(out, 0x04, channel(id));
    }
    Bytes s;
    put(s, total);
    put(s, static_cast<uint16_t>(topics.size()));
    put(s, static_cast<uint32_t>(topics.size()));
    put(s, uint32_t{0});
    put(s, uint32_t{0});
    put(s, static_cast<uint32_t>(chunks.size()));
    put(s, static_cast<uint64_t>(total ? first : 0));
    put(s, static_cast<uint64_t>(last));
    put(s, static_cast<uint32_t>(counts.size() * 10));
    for (const auto& [id, n] : counts) {
      put(s, id);
      put(s, n);
    }
    mcap_record(out, 0x0B, s);
  }
  Bytes footer;
  put(footer, summary_start);
  put(footer, uint64_t{0});
  put(footer, uint32_t{0});
  mcap_record(out, 0x02, footer);
  put(out, magic);
  return out;
}

// ---- Messages, ROS 1 serialization (little endian, no alignment)
inline void ros1_header(Bytes& b, int64_t stamp_ns, std::string_view frame) {
  put(b, uint32_t{0});  // seq
  const Bytes t = ros_time(stamp_ns);
  put(b, t.data(), t.size());
  put(b, static_cast<uint32_t>(frame.size()));
  put(b, frame);
}

// velodyne_msgs/VelodyneScan: `packets` packets of 1206 bytes filled with `fill`, 1 ms apart.
inline Bytes velodyne_scan_ros1(int64_t stamp_ns, uint32_t packets, uint8_t fill) {
  Bytes b;
  ros1_header(b, stamp_ns, "velodyne");
  put(b, packets);
  for (uint32_t i = 0; i < packets; ++i) {
    const Bytes t = ros_time(stamp_ns + int64_t{i} * 1'000'000);
    put(b, t.data(), t.size());
    b.insert(b.end(), 1206, fill);
  }
  return b;
}

// sensor_msgs/PointCloud2 of `n` points: float32 x y z intensity, uint16 ring (point_step 18).
inline Bytes point_cloud_ros1(int64_t stamp_ns, uint32_t n) {
  Bytes b;
  ros1_header(b, stamp_ns, "lidar");
  put(b, uint32_t{1});  // height
  put(b, n);            // width
  const std::pair<std::string_view, uint8_t> fields[] = {
      {"x", 7}, {"y", 7}, {"z", 7}, {"intensity", 7}, {"ring", 4}};
  put(b, static_cast<uint32_t>(std::size(fields)));
  uint32_t offset = 0;
  for (const auto& [name, type] : fields) {
    put(b, static_cast<uint32_t>(name.size()));
    put(b, name);
    put(b, offset);
    put(b, type);
    put(b, uint32_t{1});
    offset += type == 7 ? 4 : 2;
  }
  put(b, uint8_t{0});  // is_bigendian
  put(b, offset);      // point_step
  put(b, offset * n);  // row_step
  put(b, offset * n);  // data length
  for (uint32_t i = 0; i < n; ++i) {
    const float v[4] = {5.0f, static_cast<float>(i % 8) * 0.1f, static_cast<float>(i / 8) * 0.1f,
                        static_cast<float>(i * 37 % 256)};
    for (const float f : v) put(b, f);
    put(b, static_cast<uint16_t>(i / 8));
  }
  put(b, uint8_t{1});  // is_dense
  return b;
}

}  // namespace lidartag::driver::bag::synthetic
