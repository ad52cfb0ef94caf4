// Options and helpers shared by the capture subcommands (info, dump, detect, render).
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "lidartag/cli11.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/scan_reader.hpp"
#include "lidartag/driver/sources/open_reader.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/pcd_scan.hpp"

namespace lidartag::cli {

// What the capture subcommands accept besides their own options.
struct CaptureArgs {
  std::string capture;
  std::string model;        // empty: from the product byte
  std::string calibration;  // empty: built-in table
  double cut_deg = driver::BatcherOptions{}.cut_azimuth_deg;
  uint16_t data_port = velodyne::kDefaultDataPort;
  uint16_t position_port = velodyne::kDefaultPositionPort;
  std::string sensor;  // sender address filter, dotted quad
  std::string topic;   // ROS bag / MCAP: the LiDAR topic; empty: the bag's one LiDAR topic
  // The time window, seconds from a bag's first message or a pcap's first packet (--start,
  // --duration; driver::ScanSourceOptions::start_s, duration_s).
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();
  bool windowed() const {
    return start_s > 0 || duration_s < std::numeric_limits<double>::infinity();
  }
};

// --model's check: a model of either vendor (driver::model_from_name), the names listed otherwise.
CLI::Validator model_validator();

// Adds CAPTURE, --model, --calibration, --cut, --data-port, --position-port, --sensor, --topic,
// --start, --duration to `app`.
void add_capture_options(CLI::App& app, CaptureArgs& args);

// Bytes of the capture file read so far, for a progress bar (pcap record and UDP/IP headers
// estimated).
uint64_t capture_bytes_read(const driver::ScanReader& reader);

// Warns on stderr when the product byte contradicts the timing, or when the packets' timing
// contradicts an explicit --model.
void warn_model_mismatch(const velodyne::CaptureReader& reader, const CaptureArgs& args);

// Throws (exit 1) when a capture gave nothing to work on: `used` rotations were used and
// `skipped` incomplete ones left out. The message names --partial (`partial_effect`: what it does
// for this command, e.g. "detects in them") or, without any rotation, the packet counts.
void require_rotations(const velodyne::CaptureReader& reader, const CaptureArgs& args, size_t used,
                       size_t skipped, const char* partial_effect);

// Whether `path` names a PCD file (by its extension, any case).
bool is_pcd(const std::string& path);

// --resolution's help, for every command that reads clouds.
inline constexpr const char* kResolutionHelp =
    "PCD or PointCloud2: column width, degrees of azimuth (default: 0.95 x the cloud's own step "
    "between a ring's neighbouring points; 0.2 without level ring numbers)";

// A PCD file (`args.capture`) as one scan, for detect and render (detector/cloud_scan.hpp):
// organised dumps keep their cells, other clouds are binned by azimuth (`resolution_deg`); rings
// come from a `ring` field or are regressed from the elevations (--model's beam table, or `rings`
// beams estimated from the cloud), clouds::read_pcd_scan with the tool's warnings. Throws
// driver::IoError naming the file, PcdWithoutRings when the cloud needs --model or --rings.
class PcdWithoutRings : public driver::IoError {
 public:
  using driver::IoError::IoError;
};
clouds::PcdScan load_pcd_scan(const CaptureArgs& args, int rings, double resolution_deg,
                              Scan& scan);

// What a cloud's binning dropped (report.merged > 0), for a warning after "NAME: ": how many of
// `points`, split into the farther echoes of dual-return firings and those of a column that a
// nearer point took (the column width, report.resolution_deg, is too coarse for them).
std::string merged_points_note(const detector::CloudScanReport& report, size_t points);

// " (tag36h11 fits better)" after a rejection of other_family that names the family
// (Detector::other_family_of); "" when it names none.
std::string other_family_note(std::string_view family);

// Clusters worth explaining (detect --clusters, render): every one that got past clustering, and
// of those dropped there the ones about as wide as a configured tag size (a tag too far or too
// sparse: one or two rings across it); the many smaller ones (edges of clutter) are left out.
bool worth_explaining(const detector::ClusterDiagnostic& c, std::span<const double> tag_sizes_m);

// A length option given in metres, or with its unit as everywhere a length is taken ("0.8",
// "800mm", "80cm", "31.5in"): rewritten to metres before CLI11 converts it; a text that is not a
// length is refused naming it.
CLI::Validator length_in_metres();

// Ouster captures (docs/ouster.md): what info, dump, detect and render take besides CaptureArgs.
struct OusterArgs {
  std::string metadata;                    // --metadata; empty: NAME.json beside NAME.pcap
  std::string intensity = "reflectivity";  // --intensity: reflectivity or signal
};

// Adds --metadata and, with `intensity`, --intensity to `app`.
void add_ouster_options(CLI::App& app, OusterArgs& args, bool intensity);

// A capture (pcap, pcapng, or a bag's or MCAP file's packet topic) opened by content through the
// driver's source seam (driver::open_capture) with the command line's options: a Velodyne or an
// Ouster reader. Ouster: with --metadata, NAME.json beside NAME.pcap when it holds an Ouster
// sensor's beam intrinsics (a simulator's truth JSON there is not taken for one), or a bag's
// metadata topic. UsageError for options the capture's sensor cannot honour (--model,
// --calibration, --cut on an Ouster capture; --intensity signal for a profile without SIGNAL);
// driver::IoError, bag::BagError, MetadataError, CalibrationError as the seam throws them.
struct OpenedCapture {
  driver::OpenedReader opened;
  velodyne::CaptureReader* velodyne = nullptr;  // exactly one of the two is set
  driver::ouster::CaptureReader* ouster = nullptr;
  bool bag = false;  // a ROS bag or MCAP file (its window counts messages, not packets)

  // `f(reader)` with the vendor's reader.
  template <typename F>
  decltype(auto) visit(F&& f) {
    if (ouster != nullptr) return f(*ouster);
    return f(*velodyne);
  }
};
OpenedCapture open_capture(const CaptureArgs& args, const OusterArgs& ouster);

// " (N packets outside --start/--duration)" (a bag: messages) when a window was given, else "".
std::string window_note(const OpenedCapture& capture, const CaptureArgs& args);

// The Velodyne reader's helpers above, for an Ouster reader: a warning when some lidar packets
// contradict the metadata; MetadataMismatch (exit 2) when none fitted it, else as
// require_rotations when no whole frame was used.
void warn_model_mismatch(const driver::ouster::CaptureReader& reader, const CaptureArgs& args);
void require_rotations(const driver::ouster::CaptureReader& reader, const CaptureArgs& args,
                       size_t used, size_t skipped, const char* partial_effect);

}  // namespace lidartag::cli
