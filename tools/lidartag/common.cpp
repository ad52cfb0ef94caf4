#include "lidartag/common.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>

#include "lidartag/driver/io/udp_frame.hpp"

namespace lidartag::cli {

void add_capture_options(CLI::App& app, CaptureArgs& args) {
  app.add_option("capture", args.capture, "pcap or pcapng file")
      ->required()
      ->check(CLI::ExistingFile);
  const std::string names = velodyne::model_names();
  std::string set = names;
  set.erase(std::remove(set.begin(), set.end(), ' '), set.end());
  app.add_option("--model", args.model,
                 "Decode as this model (any case, '-' optional: VLP-32C; ultra-puck, "
                 "alpha-prime, puck are names too)")
      ->check(CLI::Validator(
          [names](std::string& name) -> std::string {
            return velodyne::model_from_name(name) ? std::string()
                                                   : "unknown model '" + name + "' (" + names + ")";
          },
          "{" + set + "}"));
  app.add_option("--calibration", args.calibration, "ros-drivers calibration file (YAML)")
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
            return velodyne::parse_ipv4_address(text, address)
                       ? std::string()
                       : "not an IPv4 address: '" + text + "'";
          },
          "IPV4"));
}

velodyne::CaptureReaderOptions reader_options(const CaptureArgs& args) {
  velodyne::CaptureReaderOptions options;
  options.source.data_port = args.data_port;
  options.source.position_port = args.position_port;
  if (!args.sensor.empty()) {
    uint32_t address = 0;
    if (velodyne::parse_ipv4_address(args.sensor, address)) options.source.sensor_ipv4 = address;
  }
  if (!args.model.empty()) options.model = velodyne::model_from_name(args.model);
  options.calibration_file = args.calibration;
  options.batcher.cut_azimuth_deg = args.cut_deg;
  return options;
}

uint64_t capture_bytes_read(const velodyne::CaptureReader& reader) {
  // Pcap records: 16 bytes of record header and 42 of Ethernet/IPv4/UDP per packet.
  const auto s = reader.source_stats();
  return s.bytes + 58 * (s.packets + s.ignored);
}

void warn_model_mismatch(const velodyne::CaptureReader& reader, const CaptureArgs& args) {
  const std::string mismatch = reader.model_mismatch();
  const auto decoded_as = reader.model();
  const std::string_view decoded_name =
      decoded_as ? velodyne::model_spec(*decoded_as).name : std::string_view("nothing");
  if (args.model.empty()) {
    if (!mismatch.empty())
      spdlog::warn("{} (decoding as {}, the product byte's model; use --model to override)",
                   mismatch, decoded_name);
    return;
  }
  if (!mismatch.empty()) {
    spdlog::warn("--model {}: {}", args.model, mismatch);
    return;
  }
  // An explicit model the packets' timing contradicts (when ModelCheck does not report it).
  const auto timing = reader.model_check().timing_model();
  if (timing && decoded_as && *timing != *decoded_as)
    spdlog::warn(
        "--model {} but the packet timing ({:.0f} us per packet) fits {}: points are probably "
        "garbage; leave --model out or name the right model",
        args.model, reader.model_check().median_packet_period_us(),
        velodyne::model_spec(*timing).name);
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
      "{}: no rotation: {} data packets on port {}, {} decoded, {} other packets ignored (check "
      "--data-port, --sensor, --model)",
      args.capture, reader.counts().data_packets, args.data_port, reader.counts().decoded,
      s.ignored));
}

}  // namespace lidartag::cli
