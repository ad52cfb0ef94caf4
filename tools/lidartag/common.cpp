#include "lidartag/common.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <span>
#include <stdexcept>

#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/draw/units.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/sources/open_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/exit_codes.hpp"

namespace lidartag::cli {

std::string other_family_note(std::string_view family) {
  return family.empty() ? std::string() : fmt::format(" ({} fits better)", family);
}

CLI::Validator length_in_metres() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        try {
          text = fmt::format("{:.17g}", draw::parse_length_mm(text) / 1000.0);
          return {};
        } catch (const std::invalid_argument& e) {
          return e.what();
        }
      },
      "LENGTH");
}

CLI::Validator model_validator() {
  std::string set = velodyne::model_names();
  set.erase(std::remove(set.begin(), set.end(), ' '), set.end());
  return CLI::Validator(
      [](std::string& name) -> std::string {
        return driver::model_from_name(name)
                   ? std::string()
                   : "unknown model '" + name + "' (" + driver::model_names() + ")";
      },
      "{" + set + ",os0-32,os1-64,os1-128,...}");
}

void add_capture_options(CLI::App& app, CaptureArgs& args) {
  app.add_option("capture", args.capture,
                 "pcap or pcapng file of Velodyne or Ouster packets, or a ROS 1 bag, ROS 2 bag "
                 "folder or MCAP file of VelodyneScan or Ouster packets or PointCloud2 clouds "
                 "(recognised by content)")
      ->required()
      ->check(CLI::ExistingPath);
  app.add_option("--model", args.model,
                 "Sensor model (any case): a Velodyne model to decode as ('-' optional: "
                 "VLP-32C; ultra-puck, alpha-prime, puck are names too), or an Ouster model that "
                 "the metadata must describe (os1-128, os0-32, ...); for clouds without a ring "
                 "field, its beam elevations")
      ->check(model_validator());
  app.add_option("--calibration", args.calibration,
                 "Calibration file (ros-drivers YAML or VeloView XML)")
      ->check(CLI::ExistingFile);
  app.add_option("--cut", args.cut_deg, "Azimuth where rotations are cut, degrees")
      ->check(CLI::Range(0.0, 360.0));
  app.add_option("--data-port", args.data_port, "UDP port of data packets")->capture_default_str();
  app.add_option("--position-port", args.position_port, "UDP port of position packets")
      ->capture_default_str();
  app.add_option("--sensor", args.sensor, "Only packets from this IPv4 address")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            uint32_t address = 0;
            return driver::parse_ipv4_address(text, address)
                       ? std::string()
                       : "not an IPv4 address: '" + text + "'";
          },
          "IPV4"));
  app.add_option("--topic", args.topic,
                 "ROS bag / MCAP: the LiDAR topic (default: the bag's one LiDAR topic)");
  app.add_option("--start", args.start_s,
                 "Skip the first SECONDS (from a bag's first message or a pcap's first packet)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration", args.duration_s,
                 "Read what was received in SECONDS from --start only")
      ->check(CLI::PositiveNumber);
}

uint64_t capture_bytes_read(const driver::ScanReader& reader) {
  // Pcap records: 16 bytes of record header and 42 of Ethernet/IPv4/UDP per packet.
  const auto s = reader.source_stats();
  return s.bytes + 58 * (s.packets + s.ignored + s.outside_window);
}

void warn_model_mismatch(const velodyne::CaptureReader& reader, const CaptureArgs& args) {
  // Empty when the packets fit the model (a --model that the timing fits included).
  const std::string mismatch = reader.model_mismatch();
  if (mismatch.empty()) return;
  if (!args.model.empty()) {
    spdlog::warn("{} (decoded as --model {} as told)", mismatch, args.model);
    return;
  }
  spdlog::warn("{} (decoded as {}; use --model to override)", mismatch,
               reader.model() ? velodyne::model_spec(*reader.model()).name : "nothing");
}

void require_rotations(const velodyne::CaptureReader& reader, const CaptureArgs& args, size_t used,
                       size_t skipped, const char* partial_effect) {
  if (used > 0) return;
  if (skipped > 0)
    throw std::runtime_error(fmt::format(
        "{}: no complete rotation, only {} incomplete one{} (a truncated or very short capture?); "
        "--partial {}",
        args.capture, skipped, skipped == 1 ? "" : "s", partial_effect));
  const auto s = reader.source_stats();
  throw std::runtime_error(fmt::format(
      "{}: no rotation: {} data packets on port {}, {} decoded, {} other packets ignored{} (check "
      "--data-port, --sensor, --model{})",
      args.capture, reader.counts().data_packets, args.data_port, reader.counts().decoded,
      s.ignored,
      args.windowed() ? fmt::format(", {} outside --start/--duration", s.outside_window) : "",
      args.windowed() ? ", --start/--duration" : ""));
}

bool is_pcd(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".pcd";
}

// A PCD file as one scan (detector/cloud_scan.hpp): organised dumps keep their cells, other clouds
// are binned by azimuth, rings come from a `ring` field or are regressed from the elevations (the
// --model's beam table, or --rings beams estimated from the cloud). The stamp and the rotation's
// other fields come from the header comments `lidartag dump` writes.
clouds::PcdScan load_pcd_scan(const CaptureArgs& args, int rings, double resolution_deg,
                              Scan& scan) {
  if (args.windowed())
    throw UsageError(fmt::format(
        "--start/--duration take a capture or a bag; {} is a PCD file (one cloud)", args.capture));
  const std::string& path = args.capture;
  const auto model = args.model.empty() ? std::nullopt : driver::model_from_name(args.model);
  clouds::PcdScan pcd;
  try {
    pcd = clouds::read_pcd_scan(path, model, rings, resolution_deg, scan);
  } catch (const detector::NoRingFieldError& e) {
    // The tool's options that give a cloud without a ring field its rings.
    throw PcdWithoutRings(std::string(e.what()) + " (--model or --rings N)");
  } catch (const detector::CloudError& e) {
    throw driver::IoError(e.what());
  }
  const detector::CloudScanReport& report = pcd.report;
  if (pcd.width_from_points)
    spdlog::warn("{}: the header says WIDTH 0 with POINTS {}: read as {} unorganised points", path,
                 pcd.file_points, pcd.file_points);
  if (report.skipped_coordinates > 0)
    spdlog::warn("{}: {} points with infinite or out-of-range coordinates skipped", path,
                 report.skipped_coordinates);
  if (report.skipped_rings > 0)
    spdlog::warn("{}: {} points with a ring that is not a whole number in 0..{} skipped", path,
                 report.skipped_rings, scan.rings - 1);
  if (report.merged > 0)
    spdlog::warn("{}: {}", path, merged_points_note(report, report.merged + report.points));
  if (report.rings_not_level) {
    const std::string& field = pcd.ring_field;
    if (report.regressed)
      spdlog::info(
          "{}: the rings of field '{}' are not level (points of one ring at many "
          "elevations): set aside, rings regressed from elevations",
          path, field);
    else
      spdlog::warn(
          "{}: the rings of field '{}' are not level (points of one ring at many "
          "elevations, as Livox's line numbers): --model or --rings N regresses rings "
          "from elevations instead",
          path, field);
  }
  if (report.intensity_scaled)
    spdlog::warn("{}: every intensity is within [0, 1]: read as 0..1 and scaled to 0..255", path);
  return pcd;
}

std::string merged_points_note(const detector::CloudScanReport& report, size_t points) {
  const size_t echoes = std::min(report.echoes, report.merged);
  std::string note = fmt::format("{} of {} points dropped:", report.merged, points);
  if (echoes > 0)
    note += fmt::format(
        " {} the farther echo of a firing whose nearer echo was kept (a dual-return cloud){}",
        echoes, echoes < report.merged ? ";" : "");
  if (echoes < report.merged)
    note += fmt::format(
        " {} in a ring's column (of {:.4g} degrees) that a nearer point took (--resolution sets "
        "the "
        "column width)",
        report.merged - echoes, report.resolution_deg);
  return note;
}

bool worth_explaining(const detector::ClusterDiagnostic& c, std::span<const double> tag_sizes_m) {
  if (c.rejection != detector::Rejection::kFewFeatures) return true;
  if (tag_sizes_m.empty()) return false;
  const double span = std::hypot(c.max_x - c.min_x, c.max_y - c.min_y);
  const auto [lo, hi] = std::minmax_element(tag_sizes_m.begin(), tag_sizes_m.end());
  return c.features >= 2 && span >= 0.5 * *lo && span <= 1.5 * *hi;
}

void add_ouster_options(CLI::App& app, OusterArgs& args, bool intensity) {
  app.add_option("--metadata", args.metadata,
                 "Ouster sensor metadata JSON (default: NAME.json beside NAME.pcap when it is an "
                 "Ouster sensor's)")
      ->check(CLI::ExistingFile);
  if (intensity) {
    app.add_option("--intensity", args.intensity,
                   "Ouster: the points' intensity, calibrated reflectivity or signal photons "
                   "(clamped to 255; RNG19 profiles only)")
        ->check(CLI::IsMember({"reflectivity", "signal"}))
        ->capture_default_str();
  }
}

OpenedCapture open_capture(const CaptureArgs& args, const OusterArgs& ouster) {
  namespace ou = driver::ouster;
  driver::ScanSourceOptions o;
  // Each vendor's own ports unless others were given.
  if (args.data_port != velodyne::kDefaultDataPort) o.data_port = args.data_port;
  if (args.position_port != velodyne::kDefaultPositionPort) o.aux_port = args.position_port;
  uint32_t address = 0;
  if (!args.sensor.empty() && driver::parse_ipv4_address(args.sensor, address))
    o.replay.sensor_ipv4 = address;
  o.topic = args.topic;
  o.start_s = args.start_s;
  o.duration_s = args.duration_s;
  const auto model = args.model.empty() ? std::nullopt : driver::model_from_name(args.model);
  if (model) {
    o.velodyne_model = model->velodyne;
    o.ouster_model = model->ouster;  // the metadata must describe it (open_capture checks)
  }
  o.calibration_file = args.calibration;
  o.batcher.cut_azimuth_deg = args.cut_deg;
  if (ouster.intensity == "signal") o.ouster_decoder.intensity = ou::IntensitySource::kSignal;

  OpenedCapture r;
  r.bag = driver::bag::detect_bag_format(args.capture) != driver::bag::BagFormat::kNone;
  // A pcap's metadata beside it is looked for whatever else was given, so that a Velodyne option
  // for an Ouster capture is refused naming it rather than read as a Velodyne capture.
  o.metadata = ouster.metadata;
  if (o.metadata.empty() && !r.bag)
    o.metadata = driver::ouster_metadata_beside(args.capture).value_or("");
  // Velodyne's options have no meaning for Ouster: the metadata describes the sensor, frames end
  // where the frame id changes.
  const std::string model_option =
      "--model " + args.model + " (a Velodyne model; Ouster models: os1-128, os0-32, ...)";
  const char* velodyne_only = model && model->velodyne    ? model_option.c_str()
                              : !args.calibration.empty() ? "--calibration"
                              : args.cut_deg != driver::BatcherOptions{}.cut_azimuth_deg ? "--cut"
                                                                                         : nullptr;
  auto refuse = [&](const std::string& what) {
    return UsageError(fmt::format(
        "{} is for Velodyne captures; {} is read as an Ouster capture ({}: the sensor and its "
        "frames come from there)",
        velodyne_only, args.capture, what));
  };
  if (velodyne_only != nullptr && !o.metadata.empty() && !r.bag)
    throw refuse("with the metadata " + o.metadata);
  try {
    r.opened = driver::open_capture(args.capture, o);
  } catch (const std::invalid_argument& e) {
    // Options the capture's sensor cannot honour (SIGNAL in RNG15, a Velodyne model for a bag of
    // Ouster packets, Ouster metadata for a bag of Velodyne packets).
    const std::string text = e.what();
    if (ouster.intensity == "signal" && text.find("SIGNAL") != std::string::npos)
      throw UsageError(fmt::format("--intensity {}: {}", ouster.intensity, text));
    throw UsageError(text);
  }
  if (r.opened.vendor == driver::Vendor::kOuster) {
    r.ouster = dynamic_cast<ou::CaptureReader*>(r.opened.reader.get());
    if (velodyne_only != nullptr) throw refuse(r.opened.what);
  } else {
    r.velodyne = dynamic_cast<velodyne::CaptureReader*>(r.opened.reader.get());
  }
  if (r.ouster == nullptr && r.velodyne == nullptr)  // the seam opened another vendor's reader
    throw std::logic_error(args.capture + ": opened as " + r.opened.what +
                           " by a reader the tool does not know");
  return r;
}

std::string window_note(const OpenedCapture& capture, const CaptureArgs& args) {
  if (!args.windowed()) return {};
  return fmt::format(" ({} {} outside --start/--duration)",
                     capture.opened.reader->source_stats().outside_window,
                     capture.bag ? "messages" : "packets");
}

void warn_model_mismatch(const driver::ouster::CaptureReader& reader, const CaptureArgs& args) {
  // Without any packet accepted, require_rotations() says it as an error.
  const std::string mismatch = reader.metadata_mismatch();
  if (!mismatch.empty() && reader.decoder_stats().by_status[0] > 0)
    spdlog::warn("{}: packets refused against the metadata: {}", args.capture, mismatch);
}

void require_rotations(const driver::ouster::CaptureReader& reader, const CaptureArgs& args,
                       size_t used, size_t skipped, const char* partial_effect) {
  if (used > 0) return;
  reader.require_frames(args.capture);  // no frame at all, or metadata of another sensor
  if (skipped > 0)
    throw std::runtime_error(
        fmt::format("{}: no whole frame, only {} partial one{} (a truncated or very short "
                    "capture?); --partial {}",
                    args.capture, skipped, skipped == 1 ? "" : "s", partial_effect));
}

}  // namespace lidartag::cli
