// Opens any source as rotations, by content, behind the vendor seam (driver::ScanReader):
//   - a ROS 1 bag, ROS 2 bag or MCAP file: its LiDAR topic's type decides (VelodyneScan ->
//     velodyne::CaptureReader; ouster_ros/PacketMsg -> ouster::CaptureReader with the metadata
//     given, else the bag's metadata topic);
//   - a pcap or pcapng: Ouster packets when Ouster metadata is given or found as NAME.json beside
//     NAME.pcap, else Velodyne packets (model from the packets or as configured);
//   - a live packet source (UDP sockets, interface capture): Ouster when metadata is given.
// Setup code: errors are typed exceptions (driver::IoError and bag::BagError for sources,
// ouster::MetadataError for metadata, velodyne::CalibrationError, std::invalid_argument for
// options a sensor cannot honour).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/scan_reader.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::driver {

enum class Vendor : uint8_t { kVelodyne, kOuster };

struct ScanSourceOptions {
  // UDP ports of data and auxiliary packets (Velodyne: position packets; Ouster: lidar and IMU
  // packets). Unset: the vendor's (Velodyne 2368/8308, Ouster 7502/7503).
  std::optional<uint16_t> data_port, aux_port;
  // Replays: the sender filter, pacing, rate and loop (PcapSourceOptions; its ports are unused).
  // A bag is paced by its packets' stamps like a pcap; `loop` and `sensor_ipv4` are a pcap's only
  // (a bag's packets carry no sender, and it is read once).
  PcapSourceOptions replay;
  // ROS bag or MCAP: the LiDAR topic; empty: the bag's one LiDAR topic (bag::BagError listing
  // them when there are several or none).
  std::string topic;
  // A capture file's time window, seconds: only what was received in [start_s, start_s +
  // duration_s) is read, counted from a bag's earliest message (bag::ReaderOptions) or a pcap's
  // first packet to the data or auxiliary port (after the `replay.sensor_ipv4` filter). What lies
  // outside is read and passed over, counted in SourceStats::outside_window (a bag: messages; a
  // pcap: packets). Defaults: everything. A window on a looped pcap, a negative start or a
  // duration that is not positive: std::invalid_argument. Live sources have no window.
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();
  // Ouster metadata JSON file; empty: NAME.json beside NAME.pcap, or the bag's metadata topic.
  // Given, the source is read as Ouster packets.
  std::string metadata;
  // Model to decode as: a Velodyne model; or, for Ouster, a model name ("os1-128") that the
  // metadata must describe (ouster::MetadataError otherwise); empty: whatever the packets (or the
  // metadata) say.
  std::optional<velodyne::Model> velodyne_model;
  std::string ouster_model;
  std::string calibration_file;  // Velodyne: calibration file; empty: the built-in table
  velodyne::DecoderOptions velodyne_decoder;
  ouster::DecoderOptions ouster_decoder;
  BatcherOptions batcher;  // cut_azimuth_deg is Velodyne's only (Ouster frames end by frame id)
};

// Wraps the packet source before the reader takes it (the daemon's tap: counting, recording, stop);
// empty: none.
using SourceWrap = std::function<std::unique_ptr<PacketSource>(std::unique_ptr<PacketSource>)>;

struct OpenedReader {
  std::unique_ptr<ScanReader> reader;
  Vendor vendor = Vendor::kVelodyne;
  // What was opened, for a log line: "pcap", "ROS 1 bag, topic /os_node0/lidar_packets", ...,
  // and with Ouster metadata, where it came from.
  std::string what;
  // Ouster: where its metadata came from (the file, or "BAG (its metadata topic)"); else empty.
  std::string metadata;
  uint16_t data_port = 0, aux_port = 0;  // the ports in use
};

// A capture file by content (see above).
OpenedReader open_capture(const std::string& path, const ScanSourceOptions& options,
                          const SourceWrap& wrap = {});

// The vendor and ports a live source must listen on for `options` (Ouster when metadata is given).
Vendor live_vendor(const ScanSourceOptions& options);
uint16_t data_port_of(Vendor vendor, const ScanSourceOptions& options);
uint16_t aux_port_of(Vendor vendor, const ScanSourceOptions& options);

// A live source (already opened on data_port_of / aux_port_of): the reader of live_vendor().
OpenedReader open_live(std::unique_ptr<PacketSource> source, const ScanSourceOptions& options);

// NAME.json beside NAME.pcap when it holds an Ouster sensor's beam intrinsics (a simulator's truth
// JSON there is not taken for one); empty otherwise.
std::optional<std::string> ouster_metadata_beside(const std::string& capture);

}  // namespace lidartag::driver
