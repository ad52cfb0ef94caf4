// `lidartag info CAPTURE`: what a capture holds: sensor, return mode, rate, packets by kind,
// rotations, losses, GPS state. An Ouster capture (--metadata FILE.json, or NAME.json beside
// NAME.pcap when that is an Ouster sensor's metadata): profile, frames, packets, refusals. A bag's
// PointCloud2 topic: clouds, points, stamps. A PCD file: its header, fields and the scan it makes.
#include <fmt/format.h>

#include <algorithm>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "lidartag/bag_clouds.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/ouster/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/pcd_scan.hpp"

namespace lidartag::cli {
namespace {

using velodyne::DecodeStatus;

struct InfoArgs {
  CaptureArgs capture;
  bool json = false;
  OusterArgs ouster;            // --metadata only
  int rings = 0;                // a PCD file without a ring field: beams to estimate (or --model)
  double resolution_deg = 0.0;  // a PCD file's unorganised cloud: column width (0: its own)
};

// A PCD file: its header, its fields and the scan the detector would get from it (the same
// conversion as detect and render; a cloud that cannot become one is described, not an error).
int run_info_pcd(const InfoArgs& args) {
  Scan scan;
  std::optional<clouds::PcdScan> pcd;
  std::string problem;
  try {
    pcd = load_pcd_scan(args.capture, args.rings, args.resolution_deg, scan);
  } catch (const PcdWithoutRings& e) {
    // Unreadable files are errors; a readable cloud without rings is described.
    problem = e.what();
    pcd = clouds::describe_pcd(velodyne::read_pcd_points(args.capture.capture));
  }
  const velodyne::PcdRotation& r = pcd->rotation;
  const detector::CloudScanReport& rep = pcd->report;
  std::string fields;
  for (const std::string& f : pcd->fields) fields += (fields.empty() ? "" : " ") + f;
  const std::string model =
      r.model ? std::string(velodyne::model_spec(*r.model).name)
              : (!args.capture.model.empty() ? args.capture.model + " (--model)" : "");
  // The header's return mode by name; empty when absent (or a byte of no mode).
  std::string mode;
  if (r.return_mode)
    if (const auto m = velodyne::return_mode_from_byte(*r.return_mode))
      mode = velodyne::return_mode_name(*m);
  const std::string rings_from = !problem.empty()          ? ""
                                 : rep.regressed           ? "regressed from elevations"
                                 : pcd->ring_field.empty() ? ""
                                                           : "field '" + pcd->ring_field + "'";
  if (args.json) {
    nlohmann::json j = {{"capture", args.capture.capture},
                        {"container", "pcd"},
                        {"format", std::string(velodyne::pcd_format_name(pcd->format))},
                        {"width", pcd->width},
                        {"height", pcd->height},
                        {"points", pcd->file_points},
                        {"fields", fields}};
    nlohmann::json rot = nlohmann::json::object();
    if (r.sequence) rot["sequence"] = *r.sequence;
    if (r.stamp_ns) rot["stamp_ns"] = *r.stamp_ns;
    if (r.model) rot["model"] = std::string(velodyne::model_spec(*r.model).name);
    if (!mode.empty()) rot["return_mode"] = mode;
    if (r.complete) rot["complete"] = *r.complete;
    if (r.rpm) rot["rpm"] = *r.rpm;
    j["rotation"] = rot;
    if (problem.empty()) {
      j["scan"] = {{"rings", scan.rings},
                   {"rings_from", rings_from},
                   {"columns", scan.columns},
                   {"points", scan.point_count()},
                   {"organised", rep.grid},
                   {"column_deg", rep.grid ? 0.0 : rep.resolution_deg},
                   {"merged", rep.merged},
                   {"echoes", rep.echoes},
                   {"width_from_points", pcd->width_from_points},
                   {"skipped_coordinates", rep.skipped_coordinates},
                   {"skipped_rings", rep.skipped_rings},
                   {"rings_not_level", rep.rings_not_level},
                   {"intensity_scaled", rep.intensity_scaled}};
    } else {
      j["scan"] = {{"error", problem}};
    }
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  fmt::print("capture:        {}\n", args.capture.capture);
  fmt::print(
      "container:      PCD ({}), {}\n", velodyne::pcd_format_name(pcd->format),
      pcd->height > 1 ? fmt::format("{} x {} organised", pcd->width, pcd->height) : "unorganised");
  fmt::print("points:         {}\n", pcd->file_points);
  fmt::print("fields:         {}\n", fields);
  std::string rot;
  const auto add = [&rot](const std::string& item) { rot += (rot.empty() ? "" : ", ") + item; };
  if (r.sequence) add(fmt::format("number {}", *r.sequence));
  if (r.stamp_ns) add(fmt::format("stamp {} ns", *r.stamp_ns));
  if (!model.empty()) add(model);
  if (!mode.empty()) add(mode);
  if (r.complete) add(*r.complete ? "complete" : "incomplete");
  if (r.rpm) add(fmt::format("{:.1f} rpm", *r.rpm));
  fmt::print("rotation:       {}\n", rot.empty() ? "(no lidartag header comments)" : rot);
  if (!problem.empty()) {
    fmt::print("scan:           none: {}\n", problem);
    return 0;
  }
  const char* width_from = args.resolution_deg > 0 ? "--resolution"
                           : rep.column_from_cloud ? "0.95 x its step"
                                                   : "the default";
  const std::string columns_of =
      rep.grid ? " (the file's grid)"
               : fmt::format(" of {:.4g} degrees ({})", rep.resolution_deg, width_from);
  fmt::print("scan:           {} rings ({}), {} columns{}, {} points\n", scan.rings, rings_from,
             scan.columns, columns_of, scan.point_count());
  fmt::print(
      "dropped:        {} sharing a cell ({} second echoes), {} bad coordinates, {} bad rings\n",
      rep.merged, rep.echoes, rep.skipped_coordinates, rep.skipped_rings);
  return 0;
}

int run_info_ouster(const InfoArgs& args, OpenedCapture& opened) {
  namespace ou = driver::ouster;
  ou::CaptureReader& reader = *opened.ouster;
  const ou::SensorInfo& info = reader.info();
  uint64_t frames = 0, complete = 0, points = 0;
  int max_columns = 0;
  while (const Scan* s = reader.next()) {
    ++frames;
    complete += s->complete ? 1 : 0;
    points += s->point_count();
    max_columns = std::max(max_columns, s->columns);
  }
  const auto& counts = reader.counts();
  const auto& st = reader.decoder_stats();
  const auto bs = reader.batcher_stats();
  const auto src = reader.source_stats();
  const std::string& metadata = opened.opened.metadata;
  const double duration_s = static_cast<double>(counts.last_time_ns - counts.first_time_ns) * 1e-9;
  const std::string mode = fmt::format("{}x{}", info.mode_columns, info.mode_rate_hz);
  if (args.json) {
    nlohmann::json j;
    j["capture"] = args.capture.capture;
    j["metadata"] = metadata;
    j["vendor"] = "ouster";
    j["product"] = info.prod_line;
    j["serial_number"] = info.serial_number;
    j["firmware"] = info.firmware;
    j["lidar_mode"] = mode;
    j["profile"] = std::string(ou::profile_name(info.profile));
    j["beams"] = info.pixels_per_column;
    j["duration_s"] = duration_s;
    j["packets"] = {{"lidar", counts.lidar_packets}, {"imu", counts.imu_packets},
                    {"other", counts.other_packets}, {"ignored", src.ignored},
                    {"truncated", src.truncated},    {"malformed", src.malformed}};
    if (args.capture.windowed()) j["outside_window"] = src.outside_window;
    nlohmann::json refused = nlohmann::json::object();
    for (int i = 1; i < ou::kDecodeStatusCount; ++i)
      refused[std::string(ou::decode_status_name(ou::DecodeStatus(i)))] = st.by_status[size_t(i)];
    j["refused"] = refused;
    j["invalid_columns"] = st.invalid_columns;
    j["frames"] = {{"total", frames},
                   {"complete", complete},
                   {"incomplete", frames - complete},
                   {"most_columns", max_columns},
                   {"points", points}};
    j["missing_packets"] = bs.missing_packets;
    j["frame_jumps"] = bs.azimuth_jumps;
    fmt::print("{}\n", j.dump(2));
    return 0;
  }
  fmt::print("capture:        {}\n", args.capture.capture);
  fmt::print("metadata:       {}\n", metadata);
  fmt::print("sensor:         Ouster {} serial {} firmware {}\n",
             info.prod_line.empty() ? "(unnamed)" : info.prod_line, info.serial_number,
             info.firmware.empty() ? "unknown" : info.firmware);
  fmt::print("lidar mode:     {}, {} beams, profile {}\n", mode, info.pixels_per_column,
             ou::profile_name(info.profile));
  fmt::print("duration:       {:.3f} s{}\n", duration_s, window_note(opened, args.capture));
  fmt::print("packets:        lidar {}, imu {}, other {}, ignored {}, truncated {}, malformed {}\n",
             counts.lidar_packets, counts.imu_packets, counts.other_packets, src.ignored,
             src.truncated, src.malformed);
  std::string refused;
  for (int i = 1; i < ou::kDecodeStatusCount; ++i)
    refused += fmt::format("{}{} {}", refused.empty() ? "" : ", ",
                           ou::decode_status_name(ou::DecodeStatus(i)), st.by_status[size_t(i)]);
  fmt::print("refused:        {}\n", refused);
  fmt::print("frames:         total {}, complete {}, incomplete {} (most columns {} of {})\n",
             frames, complete, frames - complete, max_columns, info.columns_per_frame);
  fmt::print("points:         {}\n", points);
  fmt::print("missing:        {} packets, {} frame jumps, {} invalid columns\n", bs.missing_packets,
             bs.azimuth_jumps, st.invalid_columns);
  return 0;
}

constexpr DecodeStatus kDecodeErrors[] = {DecodeStatus::kWrongSize, DecodeStatus::kBadBlockFlag,
                                          DecodeStatus::kBadAzimuth, DecodeStatus::kBadReturnMode};

int run_info(const InfoArgs& args) {
  if (is_pcd(args.capture.capture)) return run_info_pcd(args);
  if (is_point_cloud_bag(args.capture)) return info_bag_clouds(args.capture, args.json);
  OpenedCapture opened = open_capture(args.capture, args.ouster);
  if (opened.ouster != nullptr) return run_info_ouster(args, opened);
  velodyne::CaptureReader& reader = *opened.velodyne;
  uint64_t rotations = 0, complete = 0, points = 0, rated = 0;
  double rpm_complete = 0, rpm_any = 0;
  while (const Scan* scan = reader.next()) {
    ++rotations;
    points += scan->point_count();
    if (scan->rpm > 0) {
      ++rated;
      rpm_any += scan->rpm;
    }
    if (scan->complete) {
      ++complete;
      rpm_complete += scan->rpm;
    }
  }
  const auto& counts = reader.counts();
  const auto source = reader.source_stats();
  const auto batcher = reader.batcher_stats();
  const auto& check = reader.model_check();
  const std::string model =
      reader.model() ? std::string(velodyne::model_spec(*reader.model()).name) : "unknown";
  const std::string model_from = !args.capture.model.empty() ? "--model"
                                 : check.product_model()     ? "product byte"
                                 : reader.model()            ? "packet timing"
                                                             : "none";
  const std::string product = check.product_model()
                                  ? std::string(velodyne::model_spec(*check.product_model()).name)
                                  : "unknown";
  const std::string timing = check.timing_model()
                                 ? std::string(velodyne::model_spec(*check.timing_model()).name)
                                 : "undecided";
  const std::string mode = reader.return_mode()
                               ? std::string(velodyne::return_mode_name(*reader.return_mode()))
                               : "unknown";
  // Complete rotations measure the rate best; short captures may have none.
  const double rpm = complete > 0 ? rpm_complete / static_cast<double>(complete)
                     : rated > 0  ? rpm_any / static_cast<double>(rated)
                                  : 0.0;
  const double duration_s = static_cast<double>(counts.last_time_ns - counts.first_time_ns) * 1e-9;
  const std::string pps = std::string(velodyne::pps_status_name(counts.pps));
  const std::string clock = reader.clock().source() == velodyne::TimeSource::kGps ? "gps" : "host";

  if (args.json) {
    nlohmann::json j;
    j["capture"] = args.capture.capture;
    j["model"] = model;
    j["model_from"] = model_from;
    j["product_model"] = product;
    j["timing_model"] = timing;
    j["model_mismatch"] = reader.model_mismatch();
    j["packet_period_us"] = check.packet_period_us();
    j["return_mode"] = mode;
    j["rpm"] = rpm;
    j["duration_s"] = duration_s;
    j["packets"] = {{"data", counts.data_packets},  {"position", counts.position_packets},
                    {"decoded", counts.decoded},    {"undecodable", counts.undecodable},
                    {"ignored", source.ignored},    {"truncated", source.truncated},
                    {"malformed", source.malformed}};
    nlohmann::json errors = nlohmann::json::object();
    for (DecodeStatus s : kDecodeErrors) {
      errors[std::string(velodyne::decode_status_name(s))] =
          counts.decode_errors[static_cast<size_t>(s)];
    }
    j["decode_errors"] = errors;
    j["rotations"] = {{"total", rotations},
                      {"complete", complete},
                      {"incomplete", rotations - complete},
                      {"points", points}};
    j["missing_packets"] = batcher.missing_packets;
    j["azimuth_jumps"] = batcher.azimuth_jumps;
    j["fov_gaps"] = batcher.fov_gaps;
    j["mode_changes"] = batcher.mode_changes;
    if (args.capture.windowed()) j["outside_window"] = source.outside_window;
    j["gps"] = {{"position_ok", counts.position_ok},
                {"position_errors", counts.position_errors},
                {"gprmc_valid", counts.gprmc_valid},
                {"pps", pps},
                {"clock", clock},
                {"last_nmea", counts.last_nmea}};
    fmt::print("{}\n", j.dump(2));
    return 0;
  }

  fmt::print("capture:        {}\n", args.capture.capture);
  fmt::print("model:          {} (from {})\n", model, model_from);
  fmt::print("model check:    product byte {}, packet timing {} ({:.1f} us per packet)\n", product,
             timing, check.packet_period_us());
  // The reader reports a product byte the timing contradicts, a configured model the packets
  // contradict, and a model change mid-stream.
  if (!reader.model_mismatch().empty()) fmt::print("  MISMATCH:     {}\n", reader.model_mismatch());
  fmt::print("return mode:    {}\n", mode);
  fmt::print("rotation rate:  {:.1f} rpm (mean of {} rotations)\n", rpm,
             complete > 0 ? "complete" : "partial");
  fmt::print("duration:       {:.3f} s{}\n", duration_s, window_note(opened, args.capture));
  fmt::print("packets:        data {}, position {}, ignored {}, truncated {}, malformed {}\n",
             counts.data_packets, counts.position_packets, source.ignored, source.truncated,
             source.malformed);
  std::string errors;
  for (DecodeStatus s : kDecodeErrors) {
    errors += fmt::format("{}{} {}", errors.empty() ? "" : ", ", velodyne::decode_status_name(s),
                          counts.decode_errors[static_cast<size_t>(s)]);
  }
  fmt::print("decode errors:  {}{}\n", errors,
             counts.undecodable > 0 ? fmt::format(", no model {}", counts.undecodable) : "");
  fmt::print("rotations:      total {}, complete {}, incomplete {}\n", rotations, complete,
             rotations - complete);
  fmt::print("points:         {}\n", points);
  fmt::print("missing:        {} packets, {} azimuth jumps\n", batcher.missing_packets,
             batcher.azimuth_jumps);
  fmt::print("fov gaps:       {}\n", batcher.fov_gaps);
  if (batcher.mode_changes > 0) fmt::print("mode changes:   {}\n", batcher.mode_changes);
  fmt::print("gps:            {} position packets ({} bad), PPS {}, valid GPRMC {}, clock {}\n",
             counts.position_packets, counts.position_errors, pps, counts.gprmc_valid, clock);
  fmt::print("last nmea:      {}\n", counts.last_nmea.empty() ? "(none)" : counts.last_nmea);
  return 0;
}

const Registrar kInfo("info", "Summarise a capture: sensor, mode, rotations, losses, GPS",
                      [](CLI::App& app) -> RunFunction {
                        auto args = std::make_shared<InfoArgs>();
                        add_capture_options(app, args->capture);
                        app.add_flag("--json", args->json, "Print JSON instead of text");
                        add_ouster_options(app, args->ouster, false);
                        app.add_option("--rings", args->rings,
                                       "PCD without a ring field: beams to estimate (or --model)");
                        app.add_option("--resolution", args->resolution_deg, kResolutionHelp)
                            ->check(CLI::Range(0.01, 5.0));
                        return [args] { return run_info(*args); };
                      });

}  // namespace
}  // namespace lidartag::cli
