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
#include "lidartag/detector/ego_motion.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::daemon {

// A configuration that cannot be used: the key (dotted path, e.g. "sensors[0].source.kind"), the
// offending value as written, and why. what() is one line: "KEY: 'VALUE': REASON", or "KEY: REASON"
// for an error without a value (a duplicate key, a file that is not a regular file's text). Long
// or multi-line parts are shortened there (clip_text); key(), value() and reason() keep them whole.
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string key, std::string value, std::string reason);
  ConfigError(std::string key, std::string reason);
  const std::string& key() const { return key_; }
  const std::string& value() const { return value_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string key_, value_, reason_;
};

// A configuration file must be a regular file of at most this many bytes (1 MiB; the shipped file
// is about 10 kB).
inline constexpr size_t kMaxConfigBytes = size_t{1} << 20;

// `text` as one short line for a message: control characters escaped (\n, \t, \xNN), and when
// longer than `max` characters, its first `max` characters then "... (N bytes)".
std::string clip_text(std::string_view text, size_t max = 80);

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
  // udp: local address to bind (0.0.0.0: every interface; sensors broadcast). A multicast group
  // (224.0.0.0/4) is joined, and its ports are shared (see share_port).
  std::string bind_address = "0.0.0.0";
  // udp: share the ports with other programs (SO_REUSEADDR) instead of binding them exclusively.
  // Only for broadcast or multicast sensor traffic, which every sharer receives; a unicast
  // datagram reaches one of them. A multicast bind_address always shares.
  bool share_port = false;
  // udp, interface: kernel receive buffer, bytes. 8 MiB holds about 1 s of VLS-128 data.
  int receive_buffer_bytes = 8 * 1024 * 1024;
  std::string interface;     // interface: e.g. "eth0"
  bool promiscuous = false;  // interface: needed only on a shared segment
  // pcap: the capture (pcap, pcapng, or a ROS 1 bag, ROS 2 bag folder or MCAP file, recognised
  // by content); lcm: the LCM log
  std::string file;
  // pcap (a bag): the LiDAR topic; empty: the bag's one LiDAR topic (an error lists them when
  // there are several).
  std::string topic;
  // pcap, lcm: replay speed, 1 = the recorded pace, 2 = twice as fast; 0 = as fast as possible.
  double rate = 1.0;
  bool loop = false;  // pcap, lcm: start again at the end
  // pcap (a capture or a bag): the time window replayed, seconds from the capture's first packet
  // (a bag: its earliest message); what lies outside is read, counted and passed over
  // (driver::ScanSourceOptions::start_s, duration_s). duration 0: to the end. Not with `loop`.
  double start = 0;
  double duration = 0;
  // lcm: channel of the raw packets in the log; empty: the sensor's raw channel
  // (channel_prefix + lcm.channels.raw).
  std::string channel;
};

// A LiDAR's pose on the robot's body whose motion ego_motion's messages give (sensor frame ->
// body frame): metres, and degrees R = Rz(yaw) Ry(pitch) Rx(roll). Default: the LiDAR is the body.
struct BodyMount {
  double x = 0, y = 0, z = 0, roll_deg = 0, pitch_deg = 0, yaw_deg = 0;
};

struct SensorOptions {
  std::string name = "lidar";         // in messages, status and logs; unique
  std::string frame_id = "velodyne";  // coordinate frame of the published positions
  std::string channel_prefix;         // prepended to every channel of this sensor; unique
  // Model to decode as; empty ("auto"): the product byte, checked against the packets' timing.
  std::optional<velodyne::Model> model;
  // An Ouster model name of the same `model` key ("os1-128", "os0-32"): the metadata must describe
  // such a sensor. Empty: none configured (then `model` may name a Velodyne model).
  std::string ouster_model;
  // An Ouster sensor's metadata JSON (what the sensor reports; docs/ouster.md). Given, the sensor
  // is an Ouster and its ports default to 7502 (lidar) and 7503 (IMU). Empty: a Velodyne, or for
  // a replay whatever the file holds (NAME.json beside NAME.pcap, a bag's metadata topic).
  std::string metadata;
  // Calibration file (ros-drivers YAML or VeloView XML); empty: the model's built-in table.
  std::string calibration;
  driver::BatcherOptions batcher;    // cut azimuth, flush timeout, jump threshold
  velodyne::DecoderOptions decoder;  // range limits
  SourceOptions source;
  // This LiDAR's own mount on the body (sensors[].sensor_in_body); absent: the global
  // ego_motion.sensor_in_body (mount_of()). Read only with an ego-motion channel.
  std::optional<BodyMount> sensor_in_body;
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
  // Detected rotations per sensor that may wait for an earlier one to be published (in order)
  // while workers go on. Each rotation in the pipeline holds a slot of the scan buffer (a whole
  // rotation: 1.7 MB for a VLP-16 to 13 MB for a VLS-128, twice in dual mode) and a detector, so
  // the buffer has queue_depth + worker_threads + publish_queue + 1 slots.
  int publish_queue = 2;
  // Replay sources (pcap, lcm) wait for the detector instead of dropping rotations, so that a
  // replay at any speed processes every rotation. Live sources always drop the oldest.
  bool lossless_replay = true;
};

struct StatusOptions {
  double period_s = 1.0;  // status_t and systemd STATUS= every period, seconds
};

struct WatchdogOptions {
  // The systemd watchdog (WATCHDOG=1) is fed only while every sensor progresses: its receiving
  // loop ran, the rotations it took were published, and a rotation was assembled, each within
  // this many seconds (or it waits for its first packets within health.startup_grace_s).
  double stall_timeout_s = 3.0;
  // Feed the watchdog while a sensor is silent (its receiving loop runs, nothing arrives), for
  // robots that switch the sensor off on purpose. Off: a silent sensor stops the pings, so that
  // WatchdogSec restarts the daemon (which reopens its sockets).
  bool while_silent = false;
};

// Thresholds of the health states (status_t.state and .reason, systemd STATUS=; docs/daemon.md).
struct HealthOptions {
  // Waiting this long after the start for the first data packet is normal (a sensor powered up
  // with the robot takes 10-20 s to spin up): state "waiting", watchdog fed. Later: "silent".
  double startup_grace_s = 30.0;
  // No data packet for this long: the sensor is silent (a Velodyne sends one every 0.1-1.3 ms).
  double silence_s = 0.5;
  // Rates (loss, rotations per second, drops, publish failures) are judged over windows of this
  // many seconds; a verdict holds until the next window closes.
  double window_s = 2.0;
  // Data packets missing from the stream (sequence gaps), as a fraction of a window's data
  // packets, above which the state is "packet loss".
  double max_loss = 0.01;
  // The rotation rate measured must lie in [min_rpm, max_rpm] (Velodyne: 300-1200 rpm).
  double min_rpm = 270.0;
  double max_rpm = 1320.0;
  // Rotations assembled per second above this many times rpm / 60 (plus one per window, for a
  // partial rotation): stray or spoofed packets are cutting the stream.
  double max_rotation_ratio = 1.5;
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

// The robot's own motion for the trackers (issue 33; docs/tracking.md, "Ego-motion"): poses or
// twists of a body frame in an odometry frame, lidartag.ego_motion_t on an LCM channel. Each tag
// candidate is placed in the odometry frame at its own time; without messages (none yet, gaps,
// stale) the trackers follow tags with their own motion model.
struct EgoMotionConfig {
  // The channel (not prefixed per sensor). Default empty: no ego-motion input.
  std::string channel;
  // LCM URL to receive it on. Default empty: lcm.url.
  std::string url;
  // The samples kept and interpolated (capacity, max_gap_s, max_extrapolation_s).
  detector::EgoMotionOptions buffer;
  // No message for longer than this (host time): the input is stale (a health note, logged).
  // Seconds, default 0.5.
  double stale_s = 0.5;
  // The LiDAR's pose on the body frame the messages move: every sensor's, unless its entry gives
  // its own (SensorOptions::sensor_in_body). Default: the LiDAR is the body.
  BodyMount sensor_in_body;
};

struct DaemonOptions {
  std::vector<SensorOptions> sensors = {SensorOptions{}};
  detector::DetectorOptions detector = daemon_detector_defaults();
  // Evidence over rotations (one tracker per sensor, fed in rotation order).
  detector::TrackerOptions tracker;
  EgoMotionConfig ego_motion;
  LcmOptions lcm;
  PipelineOptions pipeline;
  StatusOptions status;
  WatchdogOptions watchdog;
  HealthOptions health;
  LoggingOptions logging;
  // Every raw packet received by the sources is also written to this pcap; empty: none.
  std::string record_pcap;
  // lidartagd --mcap: what is published, also written to this MCAP file (mcap_recorder.hpp);
  // empty: none. The command line only (not a configuration key).
  std::string mcap;
};

// Parses a YAML document (`origin` names it in messages). `overrides` are "dotted.key=value" (a
// YAML value; sensors[N] indexes the sensor list) applied to the document before mapping. Every
// key is checked: unknown keys and bad values throw ConfigError. Cross-field rules too (unique
// sensor names and prefixes, a file for replay sources, detector families that exist).
DaemonOptions parse_config(std::string_view yaml, const std::vector<std::string>& overrides = {});
// Reads `path` (ConfigError with key "config" when it cannot be read, is not a regular file, is
// larger than kMaxConfigBytes or is not YAML). In files and --set values alike, a key given twice
// in one mapping and a second YAML document are errors.
DaemonOptions load_config(const std::string& path, const std::vector<std::string>& overrides = {});

// The `detector:` section of a config file alone (for `lidartag detect --config`); other sections
// are not checked. Throws ConfigError.
detector::DetectorOptions load_detector_config(const std::string& path);
// The same from a YAML document (`origin` names it in messages), e.g. for the Python module.
detector::DetectorOptions parse_detector_config(std::string_view yaml,
                                                const std::string& origin = "config");

// Re-checks options built in code (what parse_config checks after mapping). Throws ConfigError.
void validate(const DaemonOptions& options);

// The effective configuration as YAML, every key, in the order of config/lidartagd.yaml; parsing
// it gives the same options back.
std::string print_config(const DaemonOptions& options);

// Channel names of a sensor: prefix + the configured channel.
std::string channel_of(const SensorOptions& sensor, const std::string& channel);

// The mount of a sensor on the body that ego_motion's messages move: its own
// (sensors[].sensor_in_body) when its entry gives one, else ego_motion.sensor_in_body.
const BodyMount& mount_of(const DaemonOptions& options, const SensorOptions& sensor);

}  // namespace lidartag::daemon
