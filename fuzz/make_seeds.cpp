// Writes the fuzz targets' seed corpora and the generated dictionaries. Every seed is cut from the
// project's simulator: its committed captures (pcaps/) and, for the other models and return
// modes, scenes simulated here; configuration, scene and family seeds from the shipped files and
// built-in tables; bag and MCAP seeds are written from the formats' specifications
// (test/bag/synthetic_bags.hpp). Deterministic: the same sources give the same files.
//
//   fuzz_make_seeds committed OUT_DIR      test/fuzz/corpus/<target>/ and fuzz/dict/*.dict
//   (generated
//                                          part); run by hand when a format changes
//   fuzz_make_seeds shared CAPTURES OUT    windows of real captures (../shared/captures) and its
//                                          bags as extra seeds at run time; never committed
#include <bzlib.h>
#include <lz4frame.h>
#include <sqlite3.h>
#include <yaml-cpp/yaml.h>
#include <zstd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bag/synthetic_bags.hpp"
#include "io/pcap_builder.hpp"
#include "io/veloview_xml.hpp"
#include "lidartag/daemon/config.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/velodyne/calibration.hpp"
#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::fuzz {
namespace {

namespace fs = std::filesystem;
using test::Bytes;

const std::string kSource = LIDARTAG_SOURCE_DIR;

struct Packet {
  Bytes payload;
  int64_t time_ns = 0;
  uint16_t port = 0;
};

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_file(const fs::path& path, const Bytes& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}
void write_file(const fs::path& path, const std::string& text) {
  write_file(path, Bytes(text.begin(), text.end()));
}

std::vector<Packet> read_capture(const std::string& path) {
  driver::PcapSource source(path);
  std::vector<Packet> packets;
  driver::RawPacket p;
  while (source.next(p, std::chrono::milliseconds(0)) == driver::ReadStatus::kPacket)
    packets.push_back(
        {{p.payload.begin(), p.payload.end()}, p.receive_time_ns, p.destination_port});
  return packets;
}

// One rotation of a small scene (a room, a tag) for a model and mode, with position packets.
std::vector<Packet> simulate(std::string_view model, std::string_view mode) {
  const std::string yaml = "rotations: 1\nseed: 1\nsensor:\n  model: " + std::string(model) +
                           "\n  rpm: 600\n  return_mode: " + std::string(mode) +
                           "\n  position: [0, 0]\n  height: 1.0\n  position_packets: true\n"
                           "world:\n  room: {center: [2, 0], size: [14, 10], height: 3.2}\n"
                           "tags:\n  - {family: tag16h5, id: 3, size: 0.8, center: [4.0, 0.9, 1.1],"
                           " rotation: diamond}\n";
  sim::Simulator simulator(sim::parse_scene(yaml, "seed scene"));
  std::vector<Packet> packets;
  (void)simulator.run(1, 1, [&](std::span<const uint8_t> payload, int64_t t, uint16_t port) {
    packets.push_back({{payload.begin(), payload.end()}, t, port});
  });
  return packets;
}

// fuzz_util.hpp's record form: kind, time step (us), length, payload.
Bytes records(const std::vector<Packet>& packets, size_t first, size_t count) {
  Bytes b;
  int64_t previous = first < packets.size() ? packets[first].time_ns : 0;
  for (size_t i = first; i < std::min(packets.size(), first + count); ++i) {
    const Packet& p = packets[i];
    b.push_back(p.port == velodyne::kDefaultPositionPort ? 1 : 0);
    test::put_le32(b, static_cast<uint32_t>(std::max<int64_t>(0, p.time_ns - previous) / 1000));
    test::put_le16(b, static_cast<uint16_t>(p.payload.size()));
    test::append(b, p.payload);
    previous = p.time_ns;
  }
  return b;
}

std::vector<test::Record> frames(const std::vector<Packet>& packets, size_t first, size_t count,
                                 const std::function<Bytes(const Bytes&)>& link) {
  std::vector<test::Record> out;
  for (size_t i = first; i < std::min(packets.size(), first + count); ++i) {
    const Bytes ip = test::ipv4_udp(packets[i].payload, packets[i].port);
    out.push_back({link(ip), packets[i].time_ns, 0});
  }
  return out;
}

// Windows of a packet stream: the lead-in and first cut, the last cut, a middle run, one packet.
std::vector<std::pair<size_t, size_t>> windows(size_t n, std::mt19937& rng) {
  std::vector<std::pair<size_t, size_t>> w = {{0, 8}, {n > 8 ? n - 8 : 0, 8}};
  if (n > 20) w.emplace_back(rng() % (n - 12), 12);
  if (n > 0) w.emplace_back(rng() % n, 1);
  return w;
}

// ---- Packets, positions, captures. ----

// The packet corpus of a model (targets decode_<model> and stream_<model>): packets_<name with
// '_' for '-'>.
std::string packet_target(velodyne::Model m) {
  std::string name(velodyne::model_spec(m).name);
  std::replace(name.begin(), name.end(), '-', '_');
  return "packets_" + name;
}

void packet_seeds(const fs::path& out) {
  std::mt19937 rng(1);
  for (velodyne::Model m : velodyne::all_models()) {
    const std::string name(velodyne::model_spec(m).name);
    for (std::string_view mode : {"strongest", "last", "dual"}) {
      const std::vector<Packet> packets = simulate(name, mode);
      int k = 0;
      for (const auto& [first, count] : windows(packets.size(), rng)) {
        const std::string file = std::string(mode) + "_" + std::to_string(k++);
        write_file(out / packet_target(m) / file, records(packets, first, count));
      }
      write_file(out / "packets_auto" / (name + "_" + std::string(mode)), records(packets, 0, 12));
      // Position packets of the simulator (PPS locked, $GPRMC).
      for (const Packet& p : packets)
        if (p.port == velodyne::kDefaultPositionPort) {
          write_file(out / "position_packet" / ("sim_" + name + "_" + std::string(mode)),
                     p.payload);
          break;
        }
    }
  }
  // The bundled outdoor capture's GPS stream.
  const std::vector<Packet> outdoor = read_capture(kSource + "/pcaps/outdoor.pcap");
  int k = 0;
  for (const Packet& p : outdoor)
    if (p.port == velodyne::kDefaultPositionPort && k < 2)
      write_file(out / "position_packet" / ("outdoor_" + std::to_string(k++)), p.payload);
  std::array<uint8_t, velodyne::kPositionPacketSize> position{};
  const std::vector<std::pair<velodyne::PpsStatus, std::string>> sentences = {
      {velodyne::PpsStatus::kAbsent, ""},
      {velodyne::PpsStatus::kSynchronizing,
       "$GPRMC,235959.50,V,4217.6210,N,08342.8190,W,0.0,0.0,311299,,,N*5A"},
      {velodyne::PpsStatus::kLocked,
       "$GPRMC,000000.00,A,4217.6210,N,08342.8190,W,0.0,0.0,010180,,,A"},
      {velodyne::PpsStatus::kError,
       "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"},
  };
  k = 0;
  for (const auto& [pps, nmea] : sentences) {
    velodyne::encode_position_packet(3'599'999'999u, pps, nmea, position);
    write_file(out / "position_packet" / ("encoded_" + std::to_string(k++)),
               Bytes(position.begin(), position.end()));
  }
}

void capture_seeds(const fs::path& out) {
  std::mt19937 rng(2);
  const fs::path dir = out / "pcap";
  for (const char* name : {"demo", "outdoor"}) {
    const std::vector<Packet> p = read_capture(kSource + "/pcaps/" + name + ".pcap");
    const auto eth = [](const Bytes& ip) { return test::ethernet(ip); };
    int k = 0;
    for (const auto& [first, count] : windows(p.size(), rng)) {
      const std::string base = std::string(name) + "_" + std::to_string(k++);
      write_file(dir / (base + ".pcap"), test::classic_pcap(1, frames(p, first, count, eth)));
      write_file(dir / (base + ".pcapng"), test::pcapng(1, frames(p, first, count, eth)));
    }
    // Other link layers, time resolutions, byte order, a VLAN tag.
    const size_t first = p.size() > 8 ? p.size() - 8 : 0;
    write_file(dir / (std::string(name) + "_ns.pcap"),
               test::classic_pcap(1, frames(p, first, 4, eth), true));
    write_file(dir / (std::string(name) + "_vlan.pcap"),
               test::classic_pcap(1, frames(p, first, 4, [](const Bytes& ip) {
                                    return test::ethernet(ip, 0x0800, {0x8100});
                                  })));
    write_file(dir / (std::string(name) + "_sll.pcap"),
               test::classic_pcap(
                   113, frames(p, first, 4, [](const Bytes& ip) { return test::linux_sll(ip); })));
    write_file(dir / (std::string(name) + "_sll2.pcapng"),
               test::pcapng(
                   276, frames(p, first, 4, [](const Bytes& ip) { return test::linux_sll2(ip); })));
    write_file(dir / (std::string(name) + "_raw.pcap"),
               test::classic_pcap(101, frames(p, first, 4, [](const Bytes& ip) { return ip; })));
    write_file(dir / (std::string(name) + "_ipv4_ns.pcapng"),
               test::pcapng(228, frames(p, first, 4, [](const Bytes& ip) { return ip; }), 9));
    Bytes swapped = test::classic_pcap(1, frames(p, first, 3, eth));
    // Big-endian file: every header field byte-swapped (global header, then each record's).
    auto swap32 = [&](size_t at) {
      std::reverse(swapped.begin() + static_cast<long>(at),
                   swapped.begin() + static_cast<long>(at) + 4);
    };
    auto swap16 = [&](size_t at) { std::swap(swapped[at], swapped[at + 1]); };
    swap32(0), swap16(4), swap16(6), swap32(8), swap32(12), swap32(16), swap32(20);
    for (size_t at = 24; at + 16 <= swapped.size();) {
      const uint32_t caplen = velodyne::read_u32(swapped.data() + at + 8);
      for (size_t f = 0; f < 4; ++f) swap32(at + 4 * f);
      at += 16 + caplen;
    }
    write_file(dir / (std::string(name) + "_be.pcap"), swapped);
  }
}

// ---- PCD. ----

// The first `columns` columns of a rotation of the demo.
Scan small_scan(int columns) {
  velodyne::CaptureReader reader(kSource + "/pcaps/demo.pcap", {});
  const Scan* scan = nullptr;
  for (int i = 0; i < 2; ++i) scan = reader.next();  // the first whole rotation
  Scan s = *scan;
  s.columns = std::min(columns, s.columns);
  return s;
}

std::string ascii_pcd(const velodyne::PcdCloud& c, const std::vector<std::string>& types,
                      const std::vector<int>& sizes, size_t height) {
  std::ostringstream out;
  out << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS";
  for (const auto& f : c.fields) out << ' ' << f;
  out << "\nSIZE";
  for (int s : sizes) out << ' ' << s;
  out << "\nTYPE";
  for (const auto& t : types) out << ' ' << t;
  out << "\nCOUNT";
  for (size_t i = 0; i < c.fields.size(); ++i) out << " 1";
  out << "\nWIDTH " << c.size() / height << "\nHEIGHT " << height
      << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << c.size() << "\nDATA ascii\n";
  for (size_t i = 0; i < c.size(); ++i) {
    for (size_t f = 0; f < c.fields.size(); ++f)
      out << (f ? " " : "") << (types[f] == "F" ? c.columns[f][i] : std::round(c.columns[f][i]));
    out << '\n';
  }
  return out.str();
}

void pcd_seeds(const fs::path& out) {
  const fs::path dir = out / "pcd";
  fs::create_directories(dir);
  const fs::path binary = dir / "demo_2_columns.pcd";
  velodyne::write_pcd(binary.string(), small_scan(2));
  (void)velodyne::write_pcd((dir / "demo_1_column.pcd").string(), small_scan(1));
  // LZF-compressed (the sizes and the decompression are an attack surface of their own), and
  // organised with NaN cells.
  (void)velodyne::write_pcd((dir / "demo_2_columns_compressed.pcd").string(), small_scan(2),
                            {.format = velodyne::PcdFormat::kBinaryCompressed});
  (void)velodyne::write_pcd((dir / "demo_1_column_organised_compressed.pcd").string(),
                            small_scan(1),
                            {.format = velodyne::PcdFormat::kBinaryCompressed, .organized = true});
  (void)velodyne::write_pcd((dir / "demo_1_column_organised.pcd").string(), small_scan(1),
                            {.organized = true});
  const velodyne::PcdCloud cloud = velodyne::read_pcd(binary.string());
  std::vector<std::string> types;
  std::vector<int> sizes;
  for (const auto& f : cloud.fields) {
    const bool integer = f == "ring" || f == "return_type";
    types.push_back(integer ? "U" : "F");
    sizes.push_back(f == "ring" ? 2 : f == "return_type" ? 1 : 4);
  }
  write_file(dir / "demo_2_columns_ascii.pcd", ascii_pcd(cloud, types, sizes, 1));
  // Organised (HEIGHT 2), and other types: doubles, signed integers.
  velodyne::PcdCloud even = cloud;
  const size_t n = cloud.size() / 2 * 2;
  for (auto& col : even.columns) col.resize(n);
  even.width = n;
  write_file(dir / "demo_organised_ascii.pcd", ascii_pcd(even, types, sizes, 2));
  std::vector<std::string> other_types = types;
  std::vector<int> other_sizes = sizes;
  for (size_t f = 0; f < types.size(); ++f) {
    if (types[f] == "F") other_sizes[f] = 8;
    if (types[f] == "U") types[f] = "I", other_types[f] = "I", other_sizes[f] = 4;
  }
  write_file(dir / "demo_double_ascii.pcd", ascii_pcd(cloud, other_types, other_sizes, 1));
}

// ---- Calibration files (ros-drivers YAML, VeloView db.xml) of the built-in tables. ----

void calibration_seeds(const fs::path& out) {
  const auto models = velodyne::all_models();
  for (size_t m = 0; m < models.size(); ++m) {
    const velodyne::Calibration c = velodyne::Calibration::builtin(models[m]);
    for (int style = 0; style < 2; ++style) {
      std::ostringstream y;
      y.precision(17);
      y << "num_lasers: " << c.lasers.size() << "\ndistance_resolution: " << c.distance_unit_m
        << "\nlasers:\n";
      for (size_t i = 0; i < c.lasers.size(); ++i) {
        const velodyne::LaserCorrection& l = c.lasers[i];
        const double rad = 3.14159265358979323846 / 180.0;
        if (style == 0) {
          y << "- {dist_correction: " << l.distance_offset_m
            << ", dist_correction_x: 0.0, dist_correction_y: 0.0, focal_distance: 0.0,"
               " focal_slope: 0.0, horiz_offset_correction: "
            << l.horizontal_offset_m << ", laser_id: " << i
            << ", max_intensity: 255, min_intensity: 0, rot_correction: "
            << l.azimuth_offset_deg * rad
            << ", two_pt_correction_available: false, vert_correction: " << l.elevation_deg * rad
            << ", vert_offset_correction: " << l.vertical_offset_m << "}\n";
        } else {
          y << "  - laser_id: " << i << "\n    rot_correction: " << l.azimuth_offset_deg * rad
            << "\n    vert_correction: " << l.elevation_deg * rad
            << "\n    vert_offset_correction: " << l.vertical_offset_m << "\n";
        }
      }
      std::string text = y.str();
      text.insert(text.begin(), static_cast<char>(m));  // the target's model byte
      write_file(out / "calibration" /
                     (std::string(velodyne::model_spec(models[m]).name) +
                      (style == 0 ? "_flow.yaml" : "_block.yaml")),
                 text);
    }
    // The same calibration as VeloView's db.xml (the loader tells the formats apart by content).
    std::string xml = test::veloview_xml(c);
    xml.insert(xml.begin(), static_cast<char>(m));
    write_file(out / "calibration" / (std::string(velodyne::model_spec(models[m]).name) + ".xml"),
               xml);
  }
}

// ---- Configuration, --set, scenes, families. ----

// Every value of a printed configuration as a --set line ("a.b[0].c=value"), in its order; a list
// of scalars is one value ("detector.families=[tag16h5]").
void set_lines(const YAML::Node& node, const std::string& path, std::vector<std::string>& lines) {
  const auto scalar = [](const YAML::Node& n) { return n.IsScalar(); };
  if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string key = kv.first.Scalar();
      set_lines(kv.second, path.empty() ? key : path + "." + key, lines);
    }
  } else if (node.IsSequence() && !std::all_of(node.begin(), node.end(), scalar)) {
    for (size_t i = 0; i < node.size(); ++i)
      set_lines(node[i], path + "[" + std::to_string(i) + "]", lines);
  } else {
    YAML::Emitter value;
    if (node.IsSequence()) value << YAML::Flow;
    value << node;
    lines.push_back(path + "=" + value.c_str());
  }
}

std::vector<std::string> default_set_lines() {
  std::vector<std::string> lines;
  set_lines(YAML::Load(daemon::print_config(daemon::DaemonOptions{})), "", lines);
  return lines;
}

void config_seeds(const fs::path& out) {
  write_file(out / "config" / "lidartagd.yaml", read_text(kSource + "/config/lidartagd.yaml"));
  write_file(out / "config" / "demo.yaml", read_text(kSource + "/config/demo.yaml"));
  write_file(out / "config" / "defaults_printed.yaml",
             daemon::print_config(daemon::DaemonOptions{}));
  write_file(out / "config" / "two_sensors.yaml",
             "sensors:\n  - name: front\n    channel_prefix: FRONT_\n    model: vlp32c\n"
             "    source: {kind: udp, bind_address: 127.0.0.1, data_port: 2368, position_port: "
             "8308}\n  - name: rear\n    channel_prefix: REAR_\n    model: vls128\n"
             "    calibration: /etc/lidartag/vls128.yaml\n"
             "    source: {kind: interface, interface: eth0, data_port: 2369, promiscuous: true}\n"
             "lcm: {url: \"memq://\", publish_raw: true, cloud_decimation: 10}\n"
             "pipeline: {worker_threads: 2, queue_depth: 2}\n");
  write_file(out / "config" / "replays.yaml",
             "sensors:\n  - name: a\n    source: {kind: pcap, file: /tmp/a.pcap, rate: 0, loop: "
             "true}\n  - name: b\n    channel_prefix: B_\n    source: {kind: lcm, file: "
             "/tmp/b.lcmlog, channel: RAW, rate: 2.5}\n"
             "logging: {level: debug, file: /var/log/lidartag.log, journald: never}\n"
             "record_pcap: /tmp/record.pcap\nstatus: {period_s: 0.5}\n"
             "watchdog: {stall_timeout_s: 2}\n");
  write_file(out / "config" / "detector.yaml",
             "detector:\n  tag_sizes_m: [0.8, 0.6]\n  families: [tag16h5, tag36h11]\n"
             "  plane: {iterations: 200}\n  decode: {reject_other_families: false}\n");
  const std::vector<std::vector<std::string>> sets = {
      {"sensors[0].source.kind=udp", "sensors[0].source.bind_address=127.0.0.1",
       "sensors[0].source.data_port=2370", "sensors[0].source.position_port=8310"},
      {"sensors[0].channel_prefix=FRONT_", "sensors[1].name=rear",
       "sensors[1].frame_id=velodyne_rear", "sensors[1].channel_prefix=REAR_",
       "sensors[1].model=vlp32c"},
      {"pipeline.queue_depth=1", "pipeline.publish_queue=1", "pipeline.lossless_replay=false",
       "detector.plane.iterations=20000"},
      {"lcm.publish_tag_points=true", "lcm.cloud_decimation=10", "status.period_s=0.2"},
      {"detector.families=[tag16h5, tag25h9]", "detector.tag_sizes_m=[1.2]"},
      {"sensors[0].source.kind=interface", "sensors[0].source.interface=lo"},
      {"sensors[0].source.kind=pcap", "sensors[0].source.file=/tmp/x.pcap",
       "sensors[0].source.loop=true", "logging.level=warn"},
  };
  int k = 0;
  for (const auto& s : sets) {
    std::string text;
    for (const auto& line : s) text += line + "\n";
    text.pop_back();
    write_file(out / "config_set" / ("set_" + std::to_string(k++)), text);
  }
  // Each section's every value set to its default: every key's --set path, accepted.
  std::map<std::string, std::string> sections;
  for (const std::string& line : default_set_lines()) {
    const std::string section = line.substr(0, line.find_first_of(".[="));
    sections[section] += line + "\n";
  }
  for (const auto& [section, text] : sections)
    write_file(out / "config_set" / ("defaults_" + section), text);
}

void scene_seeds(const fs::path& out) {
  for (const auto& entry : fs::directory_iterator(kSource + "/pcaps"))
    if (entry.path().extension() == ".yaml")
      write_file(out / "scene" / entry.path().filename(), read_text(entry.path().string()));
  write_file(out / "scene" / "bad_scene.yaml", read_text(kSource + "/test/sim/bad_scene.yaml"));
  write_file(out / "scene" / "every_model.yaml",
             "rotations: 2\nseed: 4\nsensor: {model: vls128, rpm: 300, return_mode: dual, "
             "position: [1, 2], height: 1.5, velocity: [0.5, 0, 0], angular_velocity: [0, 0, 5], "
             "position_packets: true, noise: none}\nworld:\n  ground_reflectivity: 20\n"
             "  walls:\n    - {from: [-5, 5], to: [5, 5], height: 3}\n"
             "  boxes:\n    - {center: [3, -3, 1], size: [0.5, 0.5, 2], yaw_deg: 30}\n"
             "tags:\n  - {family: tag36h11, id: 7, size: 0.8, center: [5, -5, 1.2], normal: "
             "[-0.3, 1, 0], rotation: square, retro_reflective: true}\n");
}

std::string family_json(const tags::TagFamily& f, size_t max_codes) {
  std::ostringstream o;
  o << "{\"" << f.name << "\": {\"nbits\": " << f.nbits << ", \"min_hamming\": " << f.min_hamming
    << ", \"total_width\": " << f.total_width << ", \"width_at_border\": " << f.width_at_border
    << ", \"reversed_border\": " << (f.reversed_border ? "true" : "false") << ", \"bit_x\": [";
  for (size_t i = 0; i < f.bit_x.size(); ++i) o << (i ? ", " : "") << f.bit_x[i];
  o << "], \"bit_y\": [";
  for (size_t i = 0; i < f.bit_y.size(); ++i) o << (i ? ", " : "") << f.bit_y[i];
  o << "], \"codes\": [";
  for (size_t i = 0; i < std::min(max_codes, f.codes.size()); ++i) {
    char hex[32];
    std::snprintf(hex, sizeof hex, "\"0x%llx\"", static_cast<unsigned long long>(f.codes[i]));
    o << (i ? ", " : "") << hex;
  }
  o << "]}}\n";
  return o.str();
}

void family_seeds(const fs::path& out) {
  for (const auto& name : tags::builtin_family_names()) {
    const tags::TagFamily& f = tags::builtin_family(name);
    write_file(out / "tag_family" / (name + ".json"), family_json(f, 40));
    write_file(out / "tag_family" / (name + "_3_codes.json"), family_json(f, 3));
  }
}

// ---- LCM logs and raw_packet_t messages. ----

raw_packet_t raw_message(const Packet& p) {
  raw_packet_t m;
  m.utime = p.time_ns / 1000;
  m.receive_time_ns = p.time_ns;
  m.sensor = "demo";
  m.source_ipv4 = static_cast<int32_t>(0xC0A801C9u);
  m.port = p.port;
  m.nbytes = static_cast<int32_t>(p.payload.size());
  m.data = p.payload;
  return m;
}

Bytes encode(const raw_packet_t& m) {
  Bytes b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

void lcm_seeds(const fs::path& out) {
  const std::vector<Packet> demo = read_capture(kSource + "/pcaps/demo.pcap");
  const std::vector<Packet> outdoor = read_capture(kSource + "/pcaps/outdoor.pcap");
  const fs::path logs = out / "lcm_log";
  fs::create_directories(logs);
  std::mt19937 rng(3);
  int k = 0;
  for (const std::vector<Packet>* source : {&demo, &outdoor}) {
    for (const auto& [first, count] : windows(source->size(), rng)) {
      const std::string path = (logs / ("raw_" + std::to_string(k++) + ".lcmlog")).string();
      lcm::LogFile log(path, "w");
      int64_t n = 0;
      for (size_t i = first; i < std::min(source->size(), first + count); ++i) {
        const Bytes bytes = encode(raw_message((*source)[i]));
        lcm::LogEvent e{};
        e.eventnum = n++;
        e.timestamp = (*source)[i].time_ns / 1000;
        e.channel = "LIDARTAG_RAW";
        e.datalen = static_cast<int32_t>(bytes.size());
        e.data = const_cast<uint8_t*>(bytes.data());
        log.writeEvent(&e);
        if (i % 5 == 0) {  // another channel in between
          e.channel = "LIDARTAG_STATUS";
          e.datalen = 4;
          log.writeEvent(&e);
        }
      }
    }
  }
  int m = 0;
  for (const Packet* p : {&demo.front(), &outdoor[0], &outdoor[1]})
    write_file(out / "lcm_raw_packet" / ("message_" + std::to_string(m++)),
               encode(raw_message(*p)));
  for (const Packet& p : outdoor)
    if (p.port == velodyne::kDefaultPositionPort) {
      write_file(out / "lcm_raw_packet" / "position", encode(raw_message(p)));
      break;
    }
  raw_packet_t empty = raw_message(demo.front());
  empty.nbytes = 0;
  empty.data.clear();
  empty.port = 0;
  write_file(out / "lcm_raw_packet" / "empty_port_0", encode(empty));
}

// ---- Dictionaries generated from the code (the rest of fuzz/dict/ is written by hand). ----

void add_keys(std::set<std::string>& words, const std::string& yaml) {
  static const std::regex key(R"(([A-Za-z_][A-Za-z0-9_]*):)");
  for (auto it = std::sregex_iterator(yaml.begin(), yaml.end(), key); it != std::sregex_iterator();
       ++it)
    words.insert((*it)[1].str() + ":");
}

void write_dict(const fs::path& path, const std::string& what, const std::set<std::string>& words) {
  std::string text = "# " + what + " (generated by fuzz_make_seeds committed)\n";
  for (const auto& w : words) text += "\"" + w + "\"\n";
  write_file(path, text);
}

void dictionaries(const fs::path& dict_dir) {
  std::set<std::string> config;
  add_keys(config, daemon::print_config(daemon::DaemonOptions{}));
  for (velodyne::Model m : velodyne::all_models())
    config.insert(std::string(velodyne::model_spec(m).name));
  for (const char* w :
       {"udp",       "interface",   "pcap",        "lcm",    "auto",  "true",    "false",
        "strongest", "last",        "dual",        "always", "never", "memq://", "file://",
        "udpm://",   "sensors[0].", "sensors[1].", "=",      "[",     "]",       "{",
        "}",         "- ",          "~",           "null"})
    config.insert(w);
  for (const auto& f : tags::builtin_family_names()) config.insert(f);
  write_dict(dict_dir / "config.dict", "lidartagd configuration keys and values", config);
  // --set lines: every key's path ("health.max_rpm="), and the words of the file's values.
  std::set<std::string> set = config;
  for (const std::string& line : default_set_lines())
    set.insert(line.substr(0, line.find('=') + 1));
  write_dict(dict_dir / "config_set.dict", "lidartagd --set keys and values", set);
  std::set<std::string> scene;
  for (const auto& entry : fs::directory_iterator(kSource + "/pcaps"))
    if (entry.path().extension() == ".yaml") add_keys(scene, read_text(entry.path().string()));
  add_keys(scene, read_text(kSource + "/docs/simulator.md"));
  write_dict(dict_dir / "scene.dict", "scene keys", scene);
}

// ---- ROS bags and MCAP (synthetic_bags.hpp): a VelodyneScan, a PointCloud2 and a string topic,
// indexed or not, chunks in and out of time order, every compression the readers take, a cut
// final chunk; a rosbag2 .db3 (one topic with an empty serialization_format) made with sqlite.
namespace syn = driver::bag::synthetic;

Bytes compress_bz2(const Bytes& in) {
  Bytes out(in.size() + in.size() / 100 + 600);
  auto n = static_cast<unsigned>(out.size());
  if (BZ2_bzBuffToBuffCompress(reinterpret_cast<char*>(out.data()), &n,
                               const_cast<char*>(reinterpret_cast<const char*>(in.data())),
                               static_cast<unsigned>(in.size()), 9, 0, 0) != BZ_OK)
    throw std::runtime_error("bz2 compression failed");
  out.resize(n);
  return out;
}
Bytes compress_lz4(const Bytes& in) {
  Bytes out(LZ4F_compressFrameBound(in.size(), nullptr));
  const size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), nullptr);
  if (LZ4F_isError(n)) throw std::runtime_error("lz4 compression failed");
  out.resize(n);
  return out;
}
Bytes compress_zstd(const Bytes& in) {
  Bytes out(ZSTD_compressBound(in.size()));
  const size_t n = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), 3);
  if (ZSTD_isError(n)) throw std::runtime_error("zstd compression failed");
  out.resize(n);
  return out;
}

void bag_seeds(const fs::path& out) {
  const std::vector<syn::Topic> topics = {{"/velodyne_packets", "velodyne_msgs/VelodyneScan"},
                                          {"/points", "sensor_msgs/PointCloud2"},
                                          {"/metadata", "std_msgs/String"}};
  constexpr int64_t t0 = 1'700'000'000'000'000'000, step = 50'000'000;
  Bytes text = {5, 0, 0, 0, '{', '"', 'a', '"', '}'};
  auto chunk = [&](int first) {
    std::vector<syn::Message> c;
    c.push_back({"/velodyne_packets", t0 + first * step, syn::velodyne_scan_ros1(t0, 1, 0xFF)});
    c.push_back({"/points", t0 + (first + 1) * step, syn::point_cloud_ros1(t0, 16)});
    c.push_back({"/metadata", t0 + (first + 2) * step, text});
    return c;
  };
  const syn::Chunks in_order = {chunk(0), chunk(3)}, out_of_order = {chunk(3), chunk(0)};
  const syn::Compression bz2{"bz2", compress_bz2}, lz4{"lz4", compress_lz4},
      zstd{"zstd", compress_zstd};
  const fs::path ros1 = out / "ros1_bag";
  write_file(ros1 / "indexed.bag", syn::ros1_bag(topics, in_order));
  write_file(ros1 / "unindexed.bag", syn::ros1_bag(topics, in_order, false));
  write_file(ros1 / "out_of_order.bag", syn::ros1_bag(topics, out_of_order));
  write_file(ros1 / "bz2.bag", syn::ros1_bag(topics, in_order, true, bz2));
  write_file(ros1 / "lz4.bag", syn::ros1_bag(topics, in_order, true, lz4));
  Bytes cut = syn::ros1_bag(topics, in_order, false);
  cut.resize(cut.size() - 100);
  write_file(ros1 / "cut_final_chunk.bag", cut);
  const fs::path mcap = out / "mcap";
  write_file(mcap / "summary.mcap", syn::mcap_file(topics, in_order, true, true));
  write_file(mcap / "no_summary.mcap", syn::mcap_file(topics, in_order, false, true));
  write_file(mcap / "out_of_order.mcap", syn::mcap_file(topics, out_of_order, true, true));
  write_file(mcap / "zstd.mcap", syn::mcap_file(topics, in_order, true, true, zstd));
  write_file(mcap / "lz4.mcap", syn::mcap_file(topics, in_order, true, true, lz4));
  write_file(
      mcap / "cdr.mcap",
      syn::mcap_file({topics[2]}, {{{"/metadata", t0, {0, 1, 0, 0, 3, 0, 0, 0, 'a', 'b', 0}}}}));
  cut = syn::mcap_file(topics, in_order, false, true);
  cut.resize(cut.size() - 100);
  write_file(mcap / "cut_final_chunk.mcap", cut);
  // A rosbag2 .db3 built in a scratch file, then read back as bytes (sqlite writes the same
  // bytes for the same statements).
  const fs::path db_path = fs::temp_directory_path() / "lidartag_fuzz_seed.db3";
  fs::remove(db_path);
  sqlite3* db = nullptr;
  if (sqlite3_open(db_path.c_str(), &db) != SQLITE_OK) throw std::runtime_error("sqlite open");
  std::string sql =
      "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
      "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp "
      "INTEGER NOT NULL, data BLOB NOT NULL);"
      "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
      "INSERT INTO topics VALUES(1, '/points', 'sensor_msgs/msg/PointCloud2', 'cdr', '');"
      "INSERT INTO topics VALUES(2, '/metadata', 'std_msgs/msg/String', '', '');";
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr);
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO messages(topic_id, timestamp, data) VALUES(?, ?, ?)", -1,
                     &insert, nullptr);
  // The ROS 1 cloud behind a CDR encapsulation header: not a valid CDR cloud (CDR aligns its
  // fields), a start for the fuzzer's mutations of the CDR decoder.
  const Bytes cloud = [&] {
    Bytes b = {0, 1, 0, 0};
    const Bytes r = syn::point_cloud_ros1(t0, 4);
    b.insert(b.end(), r.begin(), r.end());
    return b;
  }();
  const Bytes string_cdr = {0, 1, 0, 0, 3, 0, 0, 0, 'a', 'b', 0};
  for (int k = 0; k < 4; ++k) {
    const Bytes& data = k % 2 == 0 ? cloud : string_cdr;
    sqlite3_bind_int(insert, 1, 1 + k % 2);
    sqlite3_bind_int64(insert, 2, t0 + (3 - k) * step);  // stored out of time order
    sqlite3_bind_blob(insert, 3, data.data(), static_cast<int>(data.size()), SQLITE_STATIC);
    if (sqlite3_step(insert) != SQLITE_DONE) throw std::runtime_error("sqlite insert");
    sqlite3_reset(insert);
  }
  sqlite3_finalize(insert);
  sqlite3_close(db);
  if (rc != SQLITE_OK) throw std::runtime_error("sqlite schema");
  const std::string bytes = read_text(db_path.string());
  fs::remove(db_path);
  write_file(out / "rosbag2" / "bag_0.db3", Bytes(bytes.begin(), bytes.end()));
}

void committed(const fs::path& out, const fs::path& dict_dir) {
  bag_seeds(out);
  packet_seeds(out);
  capture_seeds(out);
  pcd_seeds(out);
  calibration_seeds(out);
  config_seeds(out);
  scene_seeds(out);
  family_seeds(out);
  lcm_seeds(out);
  dictionaries(dict_dir);
}

// Real captures as extra seeds for the packet and capture targets (at run time only).
void shared(const fs::path& captures, const fs::path& out) {
  std::mt19937 rng(4);
  for (const auto& entry : fs::directory_iterator(captures)) {
    if (entry.path().extension() != ".pcap") continue;
    const std::vector<Packet> p = read_capture(entry.path().string());
    std::optional<velodyne::Model> model;
    for (const Packet& q : p)
      if (q.port == velodyne::kDefaultDataPort && q.payload.size() == velodyne::kDataPacketSize) {
        model = velodyne::model_from_product_id(q.payload[velodyne::kProductIdOffset]);
        break;
      }
    const std::string stem = entry.path().stem().string();
    int k = 0;
    for (const auto& [first, count] : windows(p.size(), rng)) {
      const std::string name = stem + "_" + std::to_string(k++);
      const Bytes r = records(p, first, count);
      write_file(out / "packets_auto" / name, r);
      if (model) write_file(out / packet_target(*model) / name, r);
      write_file(out / "pcap" / (name + ".pcap"),
                 test::classic_pcap(1, frames(p, first, count,
                                              [](const Bytes& ip) { return test::ethernet(ip); })));
    }
    for (const Packet& q : p)
      if (q.port == velodyne::kDefaultPositionPort) {
        write_file(out / "position_packet" / stem, q.payload);
        break;
      }
  }
  // The real bags (captures/bags), whole, for the bag targets (those under 1 MB: libFuzzer's
  // default -max_len would cut larger ones anyway).
  const fs::path bags = captures / "bags";
  std::error_code ec;
  if (!fs::is_directory(bags, ec)) return;
  for (const auto& entry : fs::recursive_directory_iterator(bags, ec)) {
    const std::string ext = entry.path().extension().string();
    const char* target = ext == ".bag"    ? "ros1_bag"
                         : ext == ".mcap" ? "mcap"
                         : ext == ".db3"  ? "rosbag2"
                                          : nullptr;
    if (target == nullptr || !entry.is_regular_file(ec) || entry.file_size(ec) > (1u << 20))
      continue;
    const std::string text = read_text(entry.path().string());
    write_file(out / target / entry.path().filename(), Bytes(text.begin(), text.end()));
  }
}

}  // namespace
}  // namespace lidartag::fuzz

int main(int argc, char** argv) {
  using namespace lidartag::fuzz;
  const std::string mode = argc > 1 ? argv[1] : "";
  try {
    if (mode == "committed" && argc == 4) {
      committed(argv[2], argv[3]);
      return 0;
    }
    if (mode == "shared" && argc == 4) {
      shared(argv[2], argv[3]);
      return 0;
    }
  } catch (const std::exception& e) {
    std::cerr << "fuzz_make_seeds: " << e.what() << "\n";
    return 1;
  }
  std::cerr << "usage: fuzz_make_seeds committed CORPUS_DIR DICT_DIR\n"
               "       fuzz_make_seeds shared CAPTURES_DIR OUT_DIR\n";
  return 2;
}
