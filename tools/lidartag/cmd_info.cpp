// `lidartag info CAPTURE`: what a capture holds: sensor, return mode, rate, packets by kind,
// rotations, losses, GPS state.
#include <fmt/format.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "lidartag/commands.hpp"
#include "lidartag/common.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::cli {
namespace {

using velodyne::DecodeStatus;

struct InfoArgs {
  CaptureArgs capture;
  bool json = false;
};

constexpr DecodeStatus kDecodeErrors[] = {DecodeStatus::kWrongSize, DecodeStatus::kBadBlockFlag,
                                          DecodeStatus::kBadAzimuth, DecodeStatus::kBadReturnMode};

int run_info(const InfoArgs& args) {
  velodyne::CaptureReader reader(args.capture.capture, reader_options(args.capture));
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
  fmt::print("duration:       {:.3f} s\n", duration_s);
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
                        return [args] { return run_info(*args); };
                      });

}  // namespace
}  // namespace lidartag::cli
