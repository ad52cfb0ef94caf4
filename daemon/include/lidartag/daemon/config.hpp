// lidartagd's configuration: plain option structs with their defaults, and the one place that maps
// YAML (config/lidartagd.yaml, `--set key=value`) onto them and back (--print-config).
// Knows YAML, the driver's and the detector's option structs; not LCM, not systemd, so that the
// `lidartag` CLI can reuse the detector section.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/decoder.hpp"
#include "lidartag/driver/packet.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/sensor_model.hpp"

namespace lidartag::daemon {

// A configuration that cannot be used: the key (dotted path, e.g. "sensors[0].source.kind"), the
// offending value as written, and why. what() is one line: "KEY: 'VALUE': REASON".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string key, std::string value, std::string reason);
  const std::string& key() const { return key_; }
  const std::string& value() const { return value_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string key_, value_, reason_;
};

enum class SourceKind : uint8_t {
  kUdp,        // live sensor: UDP sockets on the data and position ports
  kInterface,  // live capture of an interface with libpcap (needs CAP_NET_RAW)
  kPcap,       // replay of a pcap/pcapng capture
  kLcm,        // replay of an LCM log of raw_packet_t messages (recorded with lcm-logger)
};
std::string_view source_kind_name(SourceKind kind);

// Where a sensor's packets come from. Keys that do not apply to the kind are ignored.
struct SourceOptions {
  SourceKind kind = SourceKind::kUdp;
  uint16_t data_port = velodyne::kDefaultDataPort;          // UDP port of data packets
  uint16_t position_port = velodyne::kDefaultPositionPort;  // UDP port of position packets
  std::string sensor_address;  // only packets from this IPv4 sender; empty: any
  // udp: local address to bind (0.0.0.0: every interface; sensors broadcast).
  std::string bind_address = "0.0.0.0";
  // udp, interface: kernel receive buffer, bytes. 8 MiB holds about 1 s of VLS-128 data.
  int receive_buffer_bytes = 8 * 1024 * 1024;
  std::string interface;     // interface: e.g. "eth0"
  bool promiscuous = false;  // interface: needed only on a shared segment
  std::string file;          // pcap: the capture; lcm: the LCM log
  // pcap, lcm: replay speed, 1 = the recorded pace, 2 = twice as fast; 0 = as fast as possible.
  double rate = 1.0;
  bool loop = false;  // pcap, lcm: start again at the end
  // lcm: channel of the raw packets in the log; empty: the sensor's raw channel
  // (channel_prefix + lcm.channels.raw).
  std::string channel;
};

struct SensorOptions {
  std::string name = "lidar";         // in messages, status and logs; unique
  std::string frame_id = "velodyne";  // coordinate frame of the published positions
  std::string channel_prefix;         // prepended to every channel of this sensor; unique
  // Model to decode as; empty ("auto"): the product byte, checked against the packets' timing.
  std::optional<velodyne::Model> model;
  std::string calibration;  // ros-drivers calibration file; empty: the model's built-in table
  velodyne::BatcherOptions batcher;  // cut azimuth, flush timeout, jump threshold
  velodyne::DecoderOptions decoder;  // range limits
  SourceOptions source;
};

struct LcmChannels {
  std::string detections = "LIDARTAG_DETECTIONS";  // tag_detections_t, every rotation
  std::string status = "LIDARTAG_STATUS";          // status_t, every status period
  std::string raw = "LIDARTAG_RAW";                // raw_packet_t, when publish_raw
  // tag_points_t, rotations with detections, when lcm.publish_tag_points
  std::string tag_points = "LIDARTAG_TAG_POINTS";
  std::string cloud = "LIDARTAG_CLOUD";  // point_cloud_t, every rotation, when cloud_decimation
};

struct LcmOptions {
  // LCM provider URL; empty: LCM's default (udpm://239.255.76.67:7667?ttl=0, or $LCM_DEFAULT_URL).
  std::string url;
  LcmChannels channels;
  bool publish_raw = false;  // every received packet on the raw channel (for lcm-logger)
  // Every k-th column of each rotation on the cloud channel (for visualisation); 0: none.
  int cloud_decimation = 0;
  // lcm.publish_tag_points (each detection's points on the tag_points channel) is not a field
  // here: it is DaemonOptions::detector.keep_tag_points, so that publishing the points and the
  // detector keeping them cannot disagree.
};

struct PipelineOptions {
  // Detector threads (a oneTBB arena shared by all sensors); 0: one per core.
  int worker_threads = 0;
  // Rotations per sensor waiting for a worker; when full, the oldest is dropped and counted.
  int queue_depth = 4;
  // Finished rotations per sensor waiting for the publisher (in order); workers stop taking
  // rotations when it is full, so the rotation buffer drops instead.
  int publish_queue = 8;
  // Replay sources (pcap, lcm) wait for the detector instead of dropping rotations, so that a
  // replay at any speed processes every rotation. Live sources always drop the oldest.
  bool lossless_replay = true;
};

struct StatusOptions {
  double period_s = 1.0;  // status_t and systemd STATUS= every period, seconds
};

struct WatchdogOptions {
  // The pipeline is unhealthy (no systemd WATCHDOG=1 ping, status healthy=false) when a receiver
  // or publisher loop has not run, or one rotation has been in detection, for this long. Seconds.
  double stall_timeout_s = 3.0;
};

enum class JournalMode : uint8_t { kAuto, kAlways, kNever };

struct LoggingOptions {
  std::string level = "info";  // trace, debug, info, warn, error, critical, off
  // Log file (reopened on SIGHUP, for logrotate); empty: standard error.
  std::string file;
  // Standard error with syslog priority prefixes and no timestamps (what journald wants):
  // auto = when $JOURNAL_STREAM says standard error is the journal.
  JournalMode journald = JournalMode::kAuto;
};

// The detector's defaults, without per-cluster diagnostics (the daemon does not publish them).
inline detector::DetectorOptions daemon_detector_defaults() {
  detector::DetectorOptions options;
  options.cluster_diagnostics = false;
  return options;
}

struct DaemonOptions {
  std::vector<SensorOptions> sensors = {SensorOptions{}};
  detector::DetectorOptions detector = daemon_detector_defaults();
  // Evidence over rotations (one tracker per sensor, fed in rotation order).
  detector::TrackerOptions tracker;
  LcmOptions lcm;
  PipelineOptions pipeline;
  StatusOptions status;
  WatchdogOptions watchdog;
  LoggingOptions logging;
  // Every raw packet received by the sources is also written to this pcap; empty: none.
  std::string record_pcap;
};

// Parses a YAML document (`origin` names it in messages). `overrides` are "dotted.key=value" (a
// YAML value; sensors[N] indexes the sensor list) applied to the document before mapping. Every
// key is checked: unknown keys and bad values throw ConfigError. Cross-field rules too (unique
// sensor names and prefixes, a file for replay sources, detector families that exist).
DaemonOptions parse_config(std::string_view yaml, const std::vector<std::string>& overrides = {});
// Reads `path` (ConfigError with key "config" when it cannot be read or is not YAML).
DaemonOptions load_config(const std::string& path, const std::vector<std::string>& overrides = {});

// The `detector:` section of a config file alone (for `lidartag detect --config`); other sections
// are not checked. Throws ConfigError.
detector::DetectorOptions load_detector_config(const std::string& path);

// Re-checks options built in code (what parse_config checks after mapping). Throws ConfigError.
void validate(const DaemonOptions& options);

// The effective configuration as YAML, every key, in the order of config/lidartagd.yaml; parsing
// it gives the same options back.
std::string print_config(const DaemonOptions& options);

// Channel names of a sensor: prefix + the configured channel.
std::string channel_of(const SensorOptions& sensor, const std::string& channel);

}  // namespace lidartag::daemon
