#include "lidartag/driver/sources/open_reader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <system_error>
#include <utility>

#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/bag/messages.hpp"
#include "lidartag/driver/bag/ouster_packet_source.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/ouster/packet.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::driver {
namespace {

// A bag's packets at their recorded pace (ReplaySchedule, as PcapSource paces a pcap): each packet
// is held until it is due.
class PacedSource final : public PacketSource {
 public:
  PacedSource(std::unique_ptr<PacketSource> inner, double rate)
      : inner_(std::move(inner)), schedule_(rate) {}

  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override {
    if (!pending_) {
      // The inner source (a bag) never waits: its packet's payload stays valid until its next
      // call, which comes only once this one was handed out.
      const ReadStatus status = inner_->next(held_, timeout);
      if (status != ReadStatus::kPacket) return status;
      pending_ = true;
    }
    if (!schedule_.wait(held_.receive_time_ns, timeout)) return ReadStatus::kTimeout;
    pending_ = false;
    out = held_;
    return ReadStatus::kPacket;
  }
  SourceStats stats() const override { return inner_->stats(); }
  std::string error() const override { return inner_->error(); }

 private:
  std::unique_ptr<PacketSource> inner_;
  ReplaySchedule schedule_;
  RawPacket held_;
  bool pending_ = false;
};

// A pcap's packets in a time window (ScanSourceOptions::start_s, duration_s) from its first
// packet: those outside it are read and counted (SourceStats::outside_window), never delivered.
// Under the pacing (PacedSource), so that packets before the window are not waited for.
class WindowSource final : public PacketSource {
 public:
  WindowSource(std::unique_ptr<PacketSource> inner, double start_s, double duration_s)
      : inner_(std::move(inner)), start_s_(start_s), duration_s_(duration_s) {}

  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override {
    for (;;) {
      const ReadStatus status = inner_->next(out, timeout);
      if (status != ReadStatus::kPacket) return status;
      if (!anchored_) {
        anchored_ = true;
        begin_ns_ = out.receive_time_ns + to_ns(start_s_);
        end_ns_ = std::isfinite(duration_s_) ? begin_ns_ + to_ns(duration_s_)
                                             : std::numeric_limits<int64_t>::max();
      }
      if (out.receive_time_ns >= begin_ns_ && out.receive_time_ns < end_ns_)
        return ReadStatus::kPacket;
      ++outside_;
    }
  }
  SourceStats stats() const override {
    SourceStats s = inner_->stats();
    s.packets -= std::min(s.packets, outside_);
    s.outside_window += outside_;
    return s;
  }
  std::string error() const override { return inner_->error(); }

 private:
  static int64_t to_ns(double s) {
    return static_cast<int64_t>(std::min(s * 1e9, 9.0e18));  // a window beyond any capture
  }

  std::unique_ptr<PacketSource> inner_;
  double start_s_, duration_s_;
  bool anchored_ = false;
  int64_t begin_ns_ = 0, end_ns_ = 0;
  uint64_t outside_ = 0;
};

bool windowed(const ScanSourceOptions& o) {
  return o.start_s != 0 || o.duration_s != std::numeric_limits<double>::infinity();
}

// The window's checks (std::invalid_argument naming the option).
void check_window(const ScanSourceOptions& o) {
  if (!windowed(o)) return;
  const std::string problem = bag::window_problem(o.start_s, o.duration_s);
  if (!problem.empty()) throw std::invalid_argument(problem);
  if (o.replay.loop)
    throw std::invalid_argument(
        "a time window (start, duration) and a looped replay cannot go together");
}

// A pcap's packet source: windowed when asked, then paced (PcapSource paces itself otherwise).
std::unique_ptr<PacketSource> pcap_source(const std::string& path, PcapSourceOptions po,
                                          const ScanSourceOptions& o) {
  if (!windowed(o)) return std::make_unique<PcapSource>(path, po);
  const ReplayPacing pacing = po.pacing;
  po.pacing = ReplayPacing::kAsFastAsPossible;
  std::unique_ptr<PacketSource> source = std::make_unique<WindowSource>(
      std::make_unique<PcapSource>(path, po), o.start_s, o.duration_s);
  if (pacing != ReplayPacing::kCaptureTime) return source;
  return std::make_unique<PacedSource>(std::move(source), o.replay.rate);
}

// A bag's packet source at the replay's pace (a pcap paces itself).
std::unique_ptr<PacketSource> paced(std::unique_ptr<PacketSource> source,
                                    const ScanSourceOptions& o) {
  if (o.replay.pacing != ReplayPacing::kCaptureTime) return source;
  return std::make_unique<PacedSource>(std::move(source), o.replay.rate);
}

std::unique_ptr<PacketSource> wrapped(std::unique_ptr<PacketSource> source,
                                      const SourceWrap& wrap) {
  return wrap ? wrap(std::move(source)) : std::move(source);
}

velodyne::CaptureReaderOptions velodyne_options(const ScanSourceOptions& o) {
  velodyne::CaptureReaderOptions r;
  r.source = o.replay;
  r.source.data_port = data_port_of(Vendor::kVelodyne, o);
  r.source.position_port = aux_port_of(Vendor::kVelodyne, o);
  r.topic = o.topic;
  r.model = o.velodyne_model;
  r.calibration_file = o.calibration_file;
  r.decoder = o.velodyne_decoder;
  r.batcher = o.batcher;
  return r;
}

ouster::CaptureReaderOptions ouster_options(const ScanSourceOptions& o) {
  ouster::CaptureReaderOptions r;
  r.source = o.replay;
  r.source.data_port = data_port_of(Vendor::kOuster, o);
  r.source.position_port = aux_port_of(Vendor::kOuster, o);
  r.decoder = o.ouster_decoder;
  r.batcher = o.batcher;
  return r;
}

void refuse_velodyne_options(const ScanSourceOptions& o, const std::string& what) {
  const char* key = o.velodyne_model              ? "a Velodyne model"
                    : !o.calibration_file.empty() ? "a Velodyne calibration file"
                                                  : nullptr;
  if (key != nullptr)
    throw std::invalid_argument(std::string(key) + " is configured but " + what +
                                " holds Ouster packets (the metadata describes the sensor)");
}

// The metadata against a configured Ouster model name.
void check_model(const ouster::SensorInfo& info, const ScanSourceOptions& o,
                 const std::string& origin) {
  if (o.ouster_model.empty()) return;
  const std::string described = ouster::model_name(info);
  const bool fits = ouster::describes_model(info, o.ouster_model);
  if (!fits)
    throw ouster::MetadataError("model " + o.ouster_model + " is configured but the metadata " +
                                origin + " describes an " + described + " (" + info.prod_line +
                                ", " + std::to_string(info.pixels_per_column) + " beams)");
}

OpenedReader ouster_reader(std::unique_ptr<PacketSource> source, const ouster::SensorInfo& info,
                           const ScanSourceOptions& o, std::string what) {
  OpenedReader r;
  r.vendor = Vendor::kOuster;
  r.what = std::move(what);
  r.data_port = data_port_of(Vendor::kOuster, o);
  r.aux_port = aux_port_of(Vendor::kOuster, o);
  r.reader = std::make_unique<ouster::CaptureReader>(std::move(source), info, ouster_options(o));
  return r;
}

OpenedReader velodyne_reader(std::unique_ptr<PacketSource> source, const ScanSourceOptions& o,
                             std::string what) {
  OpenedReader r;
  r.vendor = Vendor::kVelodyne;
  r.what = std::move(what);
  r.data_port = data_port_of(Vendor::kVelodyne, o);
  r.aux_port = aux_port_of(Vendor::kVelodyne, o);
  r.reader = std::make_unique<velodyne::CaptureReader>(std::move(source), velodyne_options(o));
  return r;
}

OpenedReader open_bag_capture(const std::string& path, bag::BagFormat format,
                              const ScanSourceOptions& o, const SourceWrap& wrap) {
  std::string topic, type;
  bag::MessageKind kind = bag::MessageKind::kOther;
  {
    const auto probe = bag::open_bag(path);
    topic = bag::choose_lidar_topic(probe->connections(), o.topic, path);
    for (const bag::Connection& c : probe->connections()) {
      if (c.topic != topic) continue;
      kind = bag::message_kind(c.type);
      type = c.type;
    }
  }
  const std::string what = std::string(bag::format_name(format)) + ", topic " + topic;
  if (kind == bag::MessageKind::kVelodyneScan) {
    if (!o.metadata.empty() || !o.ouster_model.empty())
      throw std::invalid_argument("Ouster metadata or model is configured but " + path +
                                  "'s topic " + topic + " holds Velodyne packets");
    auto source = std::make_unique<bag::BagPacketSource>(
        path, bag::BagPacketSourceOptions{topic, data_port_of(Vendor::kVelodyne, o), o.start_s,
                                          o.duration_s});
    return velodyne_reader(wrapped(paced(std::move(source), o), wrap), o, what);
  }
  if (kind == bag::MessageKind::kOusterPacket) {
    refuse_velodyne_options(o, path);
    ouster::SensorInfo info;
    std::string origin;
    if (!o.metadata.empty()) {
      info = ouster::load_metadata(o.metadata);
      origin = o.metadata;
    } else {
      origin = path + " (its metadata topic)";
      info = ouster::parse_metadata(bag::read_ouster_metadata(path, topic), origin);
    }
    check_model(info, o, origin);
    bag::OusterPacketSourceOptions so;
    so.topic = topic;
    so.lidar_port = data_port_of(Vendor::kOuster, o);
    so.imu_port = aux_port_of(Vendor::kOuster, o);
    so.start_s = o.start_s;
    so.duration_s = o.duration_s;
    auto source = std::make_unique<bag::OusterPacketSource>(path, so);
    OpenedReader r = ouster_reader(wrapped(paced(std::move(source), o), wrap), info, o,
                                   what + ", metadata " + origin);
    r.metadata = origin;
    return r;
  }
  if (kind == bag::MessageKind::kPointCloud2)
    throw bag::BagError(path + ": topic " + topic +
                        " holds point clouds, not packets: lidartag detect reads them");
  throw bag::BagError(path + ": topic " + topic + " holds " + type +
                      ", not velodyne_msgs/VelodyneScan or ouster_ros/PacketMsg packets");
}

}  // namespace

Vendor live_vendor(const ScanSourceOptions& o) {
  return o.metadata.empty() ? Vendor::kVelodyne : Vendor::kOuster;
}

uint16_t data_port_of(Vendor vendor, const ScanSourceOptions& o) {
  if (o.data_port) return *o.data_port;
  return vendor == Vendor::kOuster ? ouster::kLidarPort : kDefaultDataPort;
}

uint16_t aux_port_of(Vendor vendor, const ScanSourceOptions& o) {
  if (o.aux_port) return *o.aux_port;
  return vendor == Vendor::kOuster ? ouster::kImuPort : kDefaultPositionPort;
}

std::optional<std::string> ouster_metadata_beside(const std::string& capture) {
  std::filesystem::path beside = capture;
  beside.replace_extension(".json");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(beside, ec)) return std::nullopt;
  std::ifstream in(beside);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_object() && (j.contains("beam_intrinsics") || j.contains("beam_altitude_angles")))
    return beside.string();
  return std::nullopt;
}

OpenedReader open_capture(const std::string& path, const ScanSourceOptions& o,
                          const SourceWrap& wrap) {
  check_window(o);
  const bag::BagFormat format = bag::detect_bag_format(path);
  if (format != bag::BagFormat::kNone) return open_bag_capture(path, format, o, wrap);
  std::string metadata = o.metadata;
  std::string what = "pcap";
  if (metadata.empty() && !o.velodyne_model && o.calibration_file.empty()) {
    if (auto beside = ouster_metadata_beside(path)) metadata = *beside;
  }
  if (metadata.empty() && !o.ouster_model.empty())
    throw std::invalid_argument(
        "model " + o.ouster_model + " is an Ouster sensor but " + path +
        " has no Ouster metadata (give its JSON file, or put NAME.json beside NAME.pcap)");
  if (metadata.empty()) {
    PcapSourceOptions po = o.replay;
    po.data_port = data_port_of(Vendor::kVelodyne, o);
    po.position_port = aux_port_of(Vendor::kVelodyne, o);
    return velodyne_reader(wrapped(pcap_source(path, po, o), wrap), o, what);
  }
  refuse_velodyne_options(o, path);
  const ouster::SensorInfo info = ouster::load_metadata(metadata);
  check_model(info, o, metadata);
  PcapSourceOptions po = o.replay;
  po.data_port = data_port_of(Vendor::kOuster, o);
  po.position_port = aux_port_of(Vendor::kOuster, o);
  OpenedReader r = ouster_reader(wrapped(pcap_source(path, po, o), wrap), info, o,
                                 what + ", metadata " + metadata);
  r.metadata = metadata;
  return r;
}

OpenedReader open_live(std::unique_ptr<PacketSource> source, const ScanSourceOptions& o) {
  if (live_vendor(o) == Vendor::kVelodyne) return velodyne_reader(std::move(source), o, "live");
  refuse_velodyne_options(o, "the sensor");
  const ouster::SensorInfo info = ouster::load_metadata(o.metadata);
  check_model(info, o, o.metadata);
  OpenedReader r = ouster_reader(std::move(source), info, o, "live, metadata " + o.metadata);
  r.metadata = o.metadata;
  return r;
}

}  // namespace lidartag::driver
