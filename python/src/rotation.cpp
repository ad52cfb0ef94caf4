// Rotations as numpy arrays; the Reader that yields them lazily from a pcap/pcapng capture (the
// driver's CaptureReader) or a PCD file (detector/cloud_scan); PCD files read and written.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "bindings.hpp"
#include "lidartag/bag_cloud_reader.hpp"
#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/cloud_fields.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/sources/model_name.hpp"
#include "lidartag/driver/sources/open_reader.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/pcd_scan.hpp"

namespace lidartag::python {
namespace {

// One point of Rotation.points (a numpy structured array).
struct PointRecord {
  float x, y, z;        // metres, sensor frame
  float range;          // metres
  float azimuth;        // degrees [0, 360)
  float time;           // seconds from the rotation start
  uint32_t column;      // firing sequence in the rotation
  uint16_t ring;        // 0 = lowest beam
  uint8_t intensity;    // 0..255
  uint8_t return_type;  // lidartag::ReturnType
};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// A model of either vendor (driver::model_from_name); ValueError listing the names otherwise.
std::optional<driver::ModelName> model_option(const std::optional<std::string>& name) {
  if (!name || name->empty()) return std::nullopt;
  const auto model = driver::model_from_name(*name);
  if (!model)
    throw py::value_error("unknown model '" + *name + "' (" + driver::model_names() + ")");
  return model;
}

bool is_pcd(const std::string& path) {
  return lower(std::filesystem::path(path).extension().string()) == ".pcd";
}

// x (returns, rings, columns) arrays of one cell field.
template <typename Out, typename Field>
py::array_t<Out> grid(const Scan& s, const Field& field) {
  py::array_t<Out> out({s.returns, s.rings, s.columns});
  auto r = out.template mutable_unchecked<3>();
  for (int ret = 0; ret < s.returns; ++ret)
    for (int ring = 0; ring < s.rings; ++ring)
      for (int col = 0; col < s.columns; ++col)
        r(ret, ring, col) = static_cast<Out>(field[s.at(ret, ring, col)]);
  return out;
}

py::array_t<PointRecord> points_of(const Scan& s) {
  py::array_t<PointRecord> out(static_cast<py::ssize_t>(s.point_count()));
  PointRecord* p = out.mutable_data();
  for (int ret = 0; ret < s.returns; ++ret)
    for (int ring = 0; ring < s.rings; ++ring)
      for (int col = 0; col < s.columns; ++col) {
        const size_t i = s.at(ret, ring, col);
        if (!s.valid(i)) continue;
        *p++ = {s.x[i],
                s.y[i],
                s.z[i],
                s.range[i],
                s.azimuth_deg[i],
                s.time_s[i],
                static_cast<uint32_t>(col),
                static_cast<uint16_t>(ring),
                s.intensity[i],
                static_cast<uint8_t>(s.return_type[i])};
      }
  return out;
}

py::dict arrays_of(const Scan& s) {
  py::dict d;
  d["x"] = grid<float>(s, s.x);
  d["y"] = grid<float>(s, s.y);
  d["z"] = grid<float>(s, s.z);
  d["range"] = grid<float>(s, s.range);
  d["intensity"] = grid<uint8_t>(s, s.intensity);
  d["azimuth"] = grid<float>(s, s.azimuth_deg);
  d["time"] = grid<float>(s, s.time_s);
  std::vector<uint8_t> types(s.return_type.size());
  for (size_t i = 0; i < types.size(); ++i) types[i] = static_cast<uint8_t>(s.return_type[i]);
  d["return_type"] = grid<uint8_t>(s, types);
  std::vector<bool> valid(s.range.size());
  for (size_t i = 0; i < valid.size(); ++i) valid[i] = s.valid(i);
  d["valid"] = grid<bool>(s, valid);
  d["column_azimuth"] = py::array_t<float>(s.columns, s.column_azimuth_deg.data());
  d["column_time"] = py::array_t<double>(s.columns, s.column_time_s.data());
  d["laser_id"] = py::array_t<uint8_t>(s.rings, s.laser_id.data());
  return d;
}

// A PCD file as one rotation (what `lidartag detect` does with one).
Rotation rotation_of_pcd(const std::string& path, const std::optional<driver::ModelName>& model,
                         int rings, double resolution_deg) {
  Rotation r;
  clouds::read_pcd_scan(path, model, rings, resolution_deg, r.scan);
  return r;
}

}  // namespace

Rotation Rotation::from_points(const py::object& points, int rings,
                               const std::optional<std::string>& model, double resolution_deg,
                               int64_t stamp_ns, uint64_t sequence) {
  std::vector<std::string> names;
  if (py::isinstance<py::dict>(points)) {
    for (const auto& kv : points.cast<py::dict>()) names.push_back(py::str(kv.first));
  } else if (py::hasattr(points, "dtype") && !points.attr("dtype").attr("names").is_none()) {
    for (const auto& n : points.attr("dtype").attr("names")) names.push_back(py::str(n));
  } else {
    throw py::type_error(
        "from_points takes a numpy structured array (fields x, y, z, intensity, optionally ring, "
        "azimuth, time, return_type) or a dict of such arrays");
  }
  // The fields the detector reads, named as another driver's PointCloud2 or PCD names them (the
  // one vocabulary, driver/cloud_fields.hpp: `timestamp`, `t` or `offset_time` as the time, in
  // seconds by its rule; `channel`, `laser_id` or `line` as the ring), each copied as float64;
  // other fields are left alone.
  std::vector<driver::CloudSourceField> sources;
  for (const std::string& name : names) {
    const py::object column = points[py::str(name)];
    bool integer = false;
    if (py::hasattr(column, "dtype")) {
      const auto kind = py::str(column.attr("dtype").attr("kind")).cast<std::string>();
      integer = kind == "i" || kind == "u";
    }
    sources.push_back({name, integer});
  }
  driver::CloudColumns found;
  driver::cloud_columns_of(
      sources,
      [&](size_t k, std::vector<double>& values) {
        const auto column = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
            points[py::str(names[k])]);
        if (!column || column.ndim() != 1)
          throw detector::CloudError("field " + names[k] + " is not a 1-D array of numbers");
        values.assign(column.data(), column.data() + column.size());
      },
      found);
  for (const char* required : {"x", "y", "z", "intensity"}) {
    if (std::find(found.names.begin(), found.names.end(), required) == found.names.end())
      throw detector::CloudError(std::string("the points have no ") + required +
                                 " field (the detector reads tags from x, y, z and intensity)");
  }
  for (size_t c = 1; c < found.columns.size(); ++c) {
    if (found.columns[c].size() != found.columns.front().size())
      throw detector::CloudError("field " + found.source[c] + " has " +
                                 std::to_string(found.columns[c].size()) + " values, field " +
                                 found.source.front() + " " +
                                 std::to_string(found.columns.front().size()));
  }
  const detector::CloudFields fields =
      detector::cloud_fields_by_name(found.names, found.columns, found.columns.front().size(), 1);
  const std::optional<driver::ModelName> m = model_option(model);
  const driver::RingSource ring_source = driver::ring_source(m, rings);
  const detector::CloudScanOptions options = detector::cloud_scan_options(
      fields, ring_source.elevations_deg, ring_source.rings, resolution_deg);
  Rotation r;
  detector::cloud_to_scan(fields, options, r.scan);
  r.scan.stamp_ns = stamp_ns;
  r.scan.sequence = sequence;
  r.scan.complete = true;  // a whole cloud, as the caller's driver assembled it
  if (m && m->velodyne) r.scan.model = static_cast<uint8_t>(*m->velodyne);
  return r;
}

namespace {

// The model a capture is decoded as: a Velodyne model, or an Ouster model name the metadata must
// describe ("os1-128"); ValueError naming both vendors' names otherwise.
void capture_model(const std::optional<std::string>& name, driver::ScanSourceOptions& o) {
  if (const auto model = model_option(name)) {
    o.velodyne_model = model->velodyne;
    o.ouster_model = model->ouster;
  }
}

driver::ouster::IntensitySource intensity_source(const std::string& name) {
  const std::string n = lower(name);
  if (n == "reflectivity") return driver::ouster::IntensitySource::kReflectivity;
  if (n == "signal") return driver::ouster::IntensitySource::kSignal;
  throw py::value_error("intensity '" + name + "': reflectivity or signal");
}

// Reads rotations lazily; the GIL is released while packets are read and decoded. Packet captures
// (pcap/pcapng of Velodyne or Ouster packets, bags of VelodyneScan or Ouster packet messages) are
// opened by the driver's source seam (driver::open_capture) as the daemon opens them.
class Reader {
 public:
  struct Options {
    std::optional<std::string> model, calibration, sensor;
    double cut_deg = driver::BatcherOptions{}.cut_azimuth_deg;
    bool partial = false;
    // Unset: the vendor's ports (Velodyne 2368/8308, Ouster lidar 7502 / IMU 7503).
    std::optional<uint16_t> data_port, position_port;
    int rings = 0;
    double resolution_deg = 0.0;
    std::optional<std::string> topic;  // a bag's LiDAR topic; None: its one LiDAR topic
    double start_s = 0;                // a bag's time window, seconds from its first message
    double duration_s = std::numeric_limits<double>::infinity();
    // Ouster: the sensor's metadata JSON; None: NAME.json beside NAME.pcap, or a bag's metadata
    // topic.
    std::optional<std::string> metadata;
    std::string intensity = "reflectivity";  // Ouster: "reflectivity" or "signal"
  };

  Reader(const std::string& path, const Options& o) : path_(path), partial_(o.partial) {
    std::error_code ec;
    // A file, or a folder (a ROS 2 bag): the capture reader tells them apart by content.
    if (!std::filesystem::exists(path, ec)) throw driver::IoError("no such file: '" + path + "'");
    const bool is_bag = driver::bag::detect_bag_format(path) != driver::bag::BagFormat::kNone;
    const bool ouster_options =
        (o.metadata && !o.metadata->empty()) ||
        intensity_source(o.intensity) != driver::ouster::IntensitySource::kReflectivity;
    if (is_pcd(path)) {
      if (ouster_options)
        throw py::value_error("metadata and intensity are for Ouster captures; '" + path +
                              "' is a PCD file");
      if (o.start_s != 0 || o.duration_s != std::numeric_limits<double>::infinity())
        throw py::value_error("start and duration are for recordings; '" + path +
                              "' is a PCD file (one rotation)");
      pcd_ = rotation_of_pcd(path, model_option(o.model), o.rings, o.resolution_deg);
      return;
    }
    const std::string topic = o.topic.value_or("");
    if (!is_bag && o.topic)
      throw py::value_error("topic is for ROS bags and MCAP files; '" + path + "' is not one");
    if (const std::string problem = driver::bag::window_problem(o.start_s, o.duration_s);
        !problem.empty())
      throw py::value_error(problem);
    if (is_bag && !ouster_options && clouds::holds_point_clouds(path, topic)) {
      // A PointCloud2 topic: each cloud a Rotation, as Rotation.from_points makes one.
      const auto model = model_option(o.model);
      clouds::BagCloudOptions c;
      c.topic = topic;
      c.start_s = o.start_s;
      c.duration_s = o.duration_s;
      driver::RingSource ring_source = driver::ring_source(model, o.rings);
      c.elevations_deg = std::move(ring_source.elevations_deg);
      c.rings = ring_source.rings;
      c.resolution_deg = o.resolution_deg;
      clouds_ = std::make_unique<clouds::BagCloudReader>(path, c);
      if (model) cloud_model_ = model->velodyne;
      return;
    }
    driver::ScanSourceOptions so;
    vendor_ports_ = !o.data_port && !o.position_port;
    capture_model(o.model, so);
    so.topic = topic;
    so.metadata = o.metadata.value_or("");
    so.data_port = o.data_port;
    so.aux_port = o.position_port;
    if (o.sensor && !o.sensor->empty()) {
      uint32_t address = 0;
      if (!driver::parse_ipv4_address(*o.sensor, address))
        throw py::value_error("not an IPv4 address: '" + *o.sensor + "'");
      so.replay.sensor_ipv4 = address;
    }
    if (o.calibration) so.calibration_file = *o.calibration;
    so.batcher.cut_azimuth_deg = o.cut_deg;
    so.ouster_decoder.intensity = intensity_source(o.intensity);
    // A time window: a bag's from its first message, a pcap's from its first packet.
    so.start_s = o.start_s;
    so.duration_s = o.duration_s;
    opened_ = driver::open_capture(path, so);
    if (opened_.vendor == driver::Vendor::kVelodyne && ouster_options)
      throw py::value_error("metadata and intensity are for Ouster captures; '" + path +
                            "' holds Velodyne packets");
    velodyne_ = dynamic_cast<velodyne::CaptureReader*>(opened_.reader.get());
    ouster_ = dynamic_cast<driver::ouster::CaptureReader*>(opened_.reader.get());
    if (ouster_) sensor_model_ = std::string(ouster_->description().model);
  }

  Rotation next() {
    if (pcd_) {
      Rotation r = std::move(*pcd_);
      pcd_.reset();
      ++rotations_;
      return r;
    }
    if (clouds_) return next_cloud();
    if (!opened_.reader) throw py::stop_iteration();
    std::optional<Rotation> out;
    {
      py::gil_scoped_release release;
      for (;;) {
        // Two scans in turn: a rotation handed out, the next one is assembled into the other.
        Scan& scan = scans_[next_scan_];
        const driver::ReadResult result = opened_.reader->read(scan, std::chrono::seconds(1));
        if (result == driver::ReadResult::kTimeout) continue;
        if (result == driver::ReadResult::kEnd) break;
        next_scan_ = 1 - next_scan_;
        if (!scan.complete && !partial_) {
          ++skipped_;
          continue;
        }
        out = Rotation::copy_of(scan);
        out->sensor_model = sensor_model_;
        break;
      }
    }
    if (!out) {
      end_of_capture();
      throw py::stop_iteration();
    }
    ++rotations_;
    return std::move(*out);
  }

  // At the end, as `lidartag` does: a capture that gave no rotation, or that was cut short by a
  // corrupt record, is an IoError (once), not an empty or a quietly shortened iteration; Ouster
  // metadata that the packets contradict is a MetadataError naming what they would fit.
  void end_of_capture() {
    if (ended_) return;
    ended_ = true;
    const std::string cut = opened_.reader->source_error();
    if (!cut.empty()) throw driver::IoError(cut);
    if (rotations_ > 0) return;
    if (skipped_ > 0) {
      throw driver::IoError("'" + path_ + "': no complete rotation, only " +
                            std::to_string(skipped_) + " incomplete one" +
                            (skipped_ == 1 ? "" : "s") +
                            " (a truncated or very short capture?); partial=True reads them");
    }
    const driver::ReaderCounts c = opened_.reader->reader_counts();
    if (ouster_ && c.decoded == 0 && !ouster_->metadata_mismatch().empty())
      throw driver::ouster::MetadataMismatch("'" + path_ +
                                             "': the metadata does not describe this capture's "
                                             "sensor: " +
                                             ouster_->metadata_mismatch());
    const driver::SourceStats s = opened_.reader->source_stats();
    // Nothing on Velodyne's own ports but other traffic: perhaps an Ouster capture whose metadata
    // was not found.
    const std::string hint =
        !ouster_ && vendor_ports_ && c.data_packets == 0 && s.ignored > 0
            ? "; " + std::to_string(s.ignored) +
                  " packets to other ports: an Ouster capture is read with its metadata "
                  "(metadata=FILE.json, or NAME.json beside NAME.pcap)"
            : "";
    throw driver::IoError("'" + path_ + "': no rotation: " + std::to_string(c.data_packets) +
                          " data packets, " + std::to_string(c.decoded) + " decoded, " +
                          std::to_string(s.truncated) + " truncated records (check data_port, " +
                          "sensor, model" + (ouster_ ? ", metadata)" : ")") + hint);
  }

  // The next cloud of a PointCloud2 topic; clouds that cannot become a scan are counted
  // (counts["skipped_clouds"], counts["last_problem"]); a topic that gave none raises IoError.
  Rotation next_cloud() {
    std::optional<Rotation> out;
    {
      py::gil_scoped_release release;
      for (;;) {
        const auto step = clouds_->next(cloud_scan_);
        if (step == clouds::BagCloudReader::Step::kEnd) break;
        if (step == clouds::BagCloudReader::Step::kSkipped) {
          cloud_problem_ = clouds_->problem();
          continue;
        }
        if (cloud_model_) cloud_scan_.model = static_cast<uint8_t>(*cloud_model_);
        out = Rotation::copy_of(cloud_scan_);
        break;
      }
    }
    if (!out) {
      if (!ended_ && rotations_ == 0) {
        ended_ = true;
        throw driver::IoError("'" + path_ + "': no point cloud of " + clouds_->topic() +
                              " became a rotation" +
                              (cloud_problem_.empty() ? std::string(" (none in the window?)")
                                                      : ": " + cloud_problem_));
      }
      throw py::stop_iteration();
    }
    ++rotations_;
    return std::move(*out);
  }

  py::dict counts() const {
    py::dict d;
    d["rotations"] = rotations_;
    d["skipped_incomplete"] = skipped_;
    if (clouds_) {
      const auto& s = clouds_->reader().stats();
      d["messages"] = s.messages;
      d["skipped_clouds"] = clouds_->skipped();
      d["last_problem"] = cloud_problem_;
      d["outside_window"] = s.outside_window;
      d["skipped_chunks"] = s.skipped_chunks;
      d["skipped_records"] = s.skipped_records;
      d["truncated"] = s.truncated;
      d["bag_error"] = clouds_->reader().error();
      d["topic"] = clouds_->topic();
      return d;
    }
    if (!opened_.reader) return d;
    const driver::ReaderCounts rc = opened_.reader->reader_counts();
    d["data_packets"] = rc.data_packets;
    d["decoded"] = rc.decoded;
    if (velodyne_) {
      const auto& c = velodyne_->counts();
      d["position_packets"] = c.position_packets;
      uint64_t errors = 0;
      for (uint64_t e : c.decode_errors) errors += e;
      d["decode_errors"] = errors;
      d["undecodable"] = c.undecodable;
      d["gprmc_valid"] = c.gprmc_valid;
    }
    if (ouster_) {
      // Lidar packets are the data packets: decoded, or refused (decode_errors; those that
      // contradict the metadata also in refused_mismatch). IMU packets are counted apart.
      d["imu_packets"] = rc.aux_packets;
      d["decode_errors"] = ouster_->decoder_stats().rejected();
      d["refused_mismatch"] = rc.refused_mismatch;
      d["invalid_columns"] = ouster_->decoder_stats().invalid_columns;
    }
    const auto s = opened_.reader->source_stats();
    d["ignored"] = s.ignored;
    d["truncated"] = s.truncated;
    d["malformed"] = s.malformed;
    d["outside_window"] = s.outside_window;
    const auto b = opened_.reader->batcher_stats();
    d["missing_packets"] = b.missing_packets;
    return d;
  }

  std::optional<std::string> model() const {
    if (!opened_.reader) return std::nullopt;
    const std::string_view m = opened_.reader->description().model;
    if (m.empty()) return std::nullopt;
    return std::string(m);
  }
  std::optional<std::string> vendor() const {
    if (!opened_.reader) return std::nullopt;
    return opened_.vendor == driver::Vendor::kOuster ? "ouster" : "velodyne";
  }
  std::string model_mismatch() const {
    return opened_.reader ? opened_.reader->mismatch_text() : "";
  }
  // What the Ouster metadata says of the sensor (None for other sources).
  py::object sensor_info() const {
    if (!ouster_) return py::none();
    const driver::ouster::SensorInfo& i = ouster_->info();
    py::dict d;
    d["model"] = sensor_model_;
    d["prod_line"] = i.prod_line;
    d["serial_number"] = i.serial_number;
    d["firmware"] = i.firmware;
    d["init_id"] = i.init_id;
    d["lidar_mode"] = std::to_string(i.mode_columns) + "x" + std::to_string(i.mode_rate_hz);
    d["profile"] = std::string(driver::ouster::profile_name(i.profile));
    d["pixels_per_column"] = i.pixels_per_column;
    d["columns_per_packet"] = i.columns_per_packet;
    d["columns_per_frame"] = i.columns_per_frame;
    d["column_window"] = py::make_tuple(i.column_window[0], i.column_window[1]);
    d["beam_altitude_deg"] = py::array_t<double>(
        static_cast<py::ssize_t>(i.beam_altitude_deg.size()), i.beam_altitude_deg.data());
    d["beam_azimuth_deg"] = py::array_t<double>(static_cast<py::ssize_t>(i.beam_azimuth_deg.size()),
                                                i.beam_azimuth_deg.data());
    d["pixel_shift_by_row"] = i.pixel_shift_by_row;
    d["lidar_origin_to_beam_origin_mm"] = i.lidar_origin_to_beam_origin_mm;
    py::array_t<double> transform({4, 4});
    std::copy(i.lidar_to_sensor_transform.begin(), i.lidar_to_sensor_transform.end(),
              transform.mutable_data());
    d["lidar_to_sensor_transform"] = transform;
    d["nested_layout"] = i.nested_layout;
    return d;
  }
  const std::string& what() const { return opened_.what; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  bool partial_ = false;
  std::optional<Rotation> pcd_;
  driver::OpenedReader opened_;                      // a packet capture
  velodyne::CaptureReader* velodyne_ = nullptr;      // opened_.reader when Velodyne's
  driver::ouster::CaptureReader* ouster_ = nullptr;  // opened_.reader when Ouster's
  std::string sensor_model_;                         // Ouster: the metadata's model name
  std::array<Scan, 2> scans_;
  size_t next_scan_ = 0;
  bool vendor_ports_ = true;  // data_port and position_port not given: the vendor's
  std::unique_ptr<clouds::BagCloudReader> clouds_;  // a bag's PointCloud2 topic
  std::optional<velodyne::Model> cloud_model_;
  Scan cloud_scan_;
  std::string cloud_problem_;
  uint64_t rotations_ = 0, skipped_ = 0;
  bool ended_ = false;  // end_of_capture() ran
};

velodyne::PcdFormat format_of(const std::string& name) {
  for (auto f : {velodyne::PcdFormat::kAscii, velodyne::PcdFormat::kBinary,
                 velodyne::PcdFormat::kBinaryCompressed})
    if (name == velodyne::pcd_format_name(f)) return f;
  throw py::value_error("PCD format '" + name + "': ascii, binary or binary_compressed");
}

py::dict read_pcd_fields(const std::string& path) {
  const velodyne::PcdCloud pcd = velodyne::read_pcd(path);
  py::dict fields;
  for (size_t f = 0; f < pcd.fields.size(); ++f) {
    py::array_t<double> column(static_cast<py::ssize_t>(pcd.size()), pcd.columns[f].data());
    if (pcd.height > 1)
      column = column.reshape(
          {static_cast<py::ssize_t>(pcd.height), static_cast<py::ssize_t>(pcd.width)});
    fields[py::str(pcd.fields[f])] = column;
  }
  py::dict out;
  out["fields"] = fields;
  out["width"] = pcd.width;
  out["height"] = pcd.height;
  out["format"] = std::string(velodyne::pcd_format_name(pcd.format));
  out["skipped_fields"] = pcd.skipped_fields;
  const auto& r = pcd.rotation;
  out["stamp_ns"] = r.stamp_ns ? py::cast(*r.stamp_ns) : py::none();
  out["sequence"] = r.sequence ? py::cast(*r.sequence) : py::none();
  out["model"] = r.model ? py::cast(std::string(velodyne::model_spec(*r.model).name)) : py::none();
  return out;
}

}  // namespace

Rotation Rotation::copy_of(const Scan& s) {
  Rotation r;
  Scan& d = r.scan;
  d.reserve(s.rings, s.returns, std::max(s.columns, 1));
  d.columns = s.columns;
  for (int ret = 0; ret < s.returns; ++ret)
    for (int ring = 0; ring < s.rings; ++ring) {
      const size_t from = s.at(ret, ring, 0), to = d.at(ret, ring, 0);
      const auto n = static_cast<size_t>(s.columns);
      auto copy = [&](const auto& src, auto& dst) {
        std::copy_n(src.begin() + static_cast<std::ptrdiff_t>(from), n,
                    dst.begin() + static_cast<std::ptrdiff_t>(to));
      };
      copy(s.x, d.x);
      copy(s.y, d.y);
      copy(s.z, d.z);
      copy(s.range, d.range);
      copy(s.azimuth_deg, d.azimuth_deg);
      copy(s.time_s, d.time_s);
      copy(s.intensity, d.intensity);
      copy(s.return_type, d.return_type);
    }
  d.laser_id = s.laser_id;
  std::copy_n(s.column_azimuth_deg.begin(), s.columns, d.column_azimuth_deg.begin());
  std::copy_n(s.column_time_s.begin(), s.columns, d.column_time_s.begin());
  d.sequence = s.sequence;
  d.stamp_ns = s.stamp_ns;
  d.model = s.model;
  d.return_mode = s.return_mode;
  d.complete = s.complete;
  d.starts_at_cut = s.starts_at_cut;
  d.ends_at_cut = s.ends_at_cut;
  d.packets = s.packets;
  d.missing_packets = s.missing_packets;
  d.azimuth_jumps = s.azimuth_jumps;
  d.rpm = s.rpm;
  return r;
}

std::string model_name(const Rotation& r) {
  if (!r.sensor_model.empty()) return r.sensor_model;
  return model_name(r.scan);
}

std::string model_name(const Scan& scan) {
  const auto models = velodyne::all_models();
  const auto m = static_cast<velodyne::Model>(scan.model);
  return std::find(models.begin(), models.end(), m) != models.end()
             ? std::string(velodyne::model_spec(m).name)
             : std::string();
}

std::string return_mode_name(const Scan& scan) {
  if (scan.model == driver::ouster::kScanModel &&
      scan.return_mode >= driver::ouster::kReturnModeBase)
    return std::string(driver::ouster::profile_name(
        static_cast<driver::ouster::Profile>(scan.return_mode - driver::ouster::kReturnModeBase)));
  const auto mode = velodyne::return_mode_from_byte(scan.return_mode);
  return mode ? std::string(velodyne::return_mode_name(*mode)) : std::string();
}

void bind_rotation(py::module_& m) {
  PYBIND11_NUMPY_DTYPE(PointRecord, x, y, z, range, azimuth, time, column, ring, intensity,
                       return_type);

  py::class_<Rotation>(m, "Rotation", R"(One rotation of the sensor.

Cells are (return, ring, column): ring 0 the lowest beam, columns in firing order from the cut.
Units: metres (sensor frame: x forward, y left, z up), degrees of azimuth clockwise from +x seen
from above, seconds from the rotation's first firing.)")
      .def_property_readonly(
          "points", [](const Rotation& r) { return points_of(r.scan); },
          "The points with a return: a numpy structured array with fields x, y, z, range, azimuth, "
          "time (float32), column (uint32), ring (uint16), intensity, return_type (uint8); "
          "return by return, ring by ring, in column order.")
      .def(
          "arrays", [](const Rotation& r) { return arrays_of(r.scan); },
          "Every cell as a dict of numpy arrays shaped (returns, rings, columns): x, y, z, range, "
          "azimuth, time (float32), intensity, return_type (uint8), valid (bool; range 0 where "
          "there is no return); column_azimuth, column_time (columns,), laser_id (rings,).")
      .def_property_readonly(
          "stamp_ns", [](const Rotation& r) { return r.scan.stamp_ns; },
          "Absolute time of the first firing, ns since the epoch.")
      .def_property_readonly(
          "stamp", [](const Rotation& r) { return static_cast<double>(r.scan.stamp_ns) * 1e-9; },
          "Absolute time of the first firing, seconds since the epoch.")
      .def_property_readonly("sequence", [](const Rotation& r) { return r.scan.sequence; })
      .def_property_readonly(
          "complete", [](const Rotation& r) { return r.scan.complete; },
          "Began and ended at the cut with no packet lost.")
      .def_property_readonly("model",
                             [](const Rotation& r) -> py::object {
                               const std::string n = model_name(r);
                               return n.empty() ? py::object(py::none()) : py::str(n);
                             })
      .def_property_readonly("return_mode",
                             [](const Rotation& r) -> py::object {
                               const std::string n = return_mode_name(r.scan);
                               return n.empty() ? py::object(py::none()) : py::str(n);
                             })
      .def_property_readonly("rpm", [](const Rotation& r) { return r.scan.rpm; })
      .def_property_readonly("rings", [](const Rotation& r) { return r.scan.rings; })
      .def_property_readonly("columns", [](const Rotation& r) { return r.scan.columns; })
      .def_property_readonly("returns", [](const Rotation& r) { return r.scan.returns; })
      .def_property_readonly("packets", [](const Rotation& r) { return r.scan.packets; })
      .def_property_readonly("missing_packets",
                             [](const Rotation& r) { return r.scan.missing_packets; })
      .def_static("from_points", &Rotation::from_points, py::arg("points"), py::kw_only(),
                  py::arg("rings") = 0, py::arg("model") = py::none(),
                  py::arg("resolution_deg") = 0.0, py::arg("stamp_ns") = 0, py::arg("sequence") = 0,
                  R"(A rotation made of a point cloud from any source (another driver, a bag).

points: a numpy structured array or a dict of equal-length arrays with fields x, y, z (metres,
sensor frame), intensity (0-255; 0-1 is scaled) and optionally ring (0 = lowest beam), azimuth
(degrees clockwise from +x), time (seconds from the rotation's start), return_type -- the names
Rotation.points uses, so rotation.points round-trips. Without ring, the rings come from the model's
beam elevations (model="vlp32c", "os1-128", ...) or are estimated (rings=N beams). Points are
binned into columns of resolution_deg of azimuth (0: 0.95 x the cloud's own step between a ring's
neighbouring points; 0.2 without level ring numbers). Raises CloudError (no intensity, sizes that
disagree, rings that cannot be told).)")
      .def("__len__", [](const Rotation& r) { return r.scan.point_count(); })
      .def("__repr__", [](const Rotation& r) {
        const std::string model = model_name(r);
        return "<lidartag.Rotation " + std::to_string(r.scan.sequence) + " " +
               (model.empty() ? "?" : model) + " stamp " +
               std::to_string(static_cast<double>(r.scan.stamp_ns) * 1e-9) + " s, " +
               std::to_string(r.scan.point_count()) + " points, " +
               (r.scan.complete ? "complete" : "partial") + ">";
      });

  py::class_<Reader::Options>(m, "_ReaderOptions")
      .def(py::init<>())
      .def_readwrite("model", &Reader::Options::model)
      .def_readwrite("calibration", &Reader::Options::calibration)
      .def_readwrite("sensor", &Reader::Options::sensor)
      .def_readwrite("cut_deg", &Reader::Options::cut_deg)
      .def_readwrite("partial", &Reader::Options::partial)
      .def_readwrite("data_port", &Reader::Options::data_port)
      .def_readwrite("position_port", &Reader::Options::position_port)
      .def_readwrite("rings", &Reader::Options::rings)
      .def_readwrite("resolution_deg", &Reader::Options::resolution_deg)
      .def_readwrite("topic", &Reader::Options::topic)
      .def_readwrite("start_s", &Reader::Options::start_s)
      .def_readwrite("duration_s", &Reader::Options::duration_s)
      .def_readwrite("metadata", &Reader::Options::metadata)
      .def_readwrite("intensity", &Reader::Options::intensity);

  py::class_<Reader>(m, "Reader", "Rotations of a capture, read one at a time (see read()).")
      .def(py::init<const std::string&, const Reader::Options&>())
      .def("__iter__", [](Reader& r) -> Reader& { return r; })
      .def("__next__", &Reader::next)
      .def_property_readonly("counts", &Reader::counts,
                             "What was read so far: rotations, packets, errors, ...")
      .def_property_readonly("model", &Reader::model,
                             "The model decoded as ('vlp32c', 'os1-128'; None until decided, and "
                             "for PCD files and point clouds).")
      .def_property_readonly("vendor", &Reader::vendor,
                             "'velodyne' or 'ouster' for packet captures; None for PCD files and "
                             "point clouds.")
      .def_property_readonly("model_mismatch", &Reader::model_mismatch,
                             "What contradicts the model in use ('' if nothing): Velodyne, the "
                             "product byte against the packets' timing; Ouster, packets the "
                             "metadata does not describe.")
      .def_property_readonly("sensor_info", &Reader::sensor_info,
                             "Ouster: the metadata's description of the sensor (a dict: model, "
                             "prod_line, serial_number, firmware, lidar_mode, profile, beam "
                             "tables, ...); None for other sources.")
      .def_property_readonly("source", &Reader::what,
                             "What was opened ('pcap', 'ROS 1 bag, topic ..., metadata ...'); '' "
                             "for PCD files and point clouds.")
      .def_property_readonly("path", &Reader::path);

  m.def("_read_pcd", &read_pcd_fields, py::arg("path"));
  m.def(
      "_write_pcd",
      [](const Rotation& r, const std::string& path, const std::string& format, bool organized) {
        return velodyne::write_pcd(path, r.scan, {format_of(format), organized});
      },
      py::arg("rotation"), py::arg("path"), py::arg("format"), py::arg("organized"));
}

}  // namespace lidartag::python
