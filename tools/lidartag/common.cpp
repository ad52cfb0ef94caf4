#include "lidartag/common.hpp"

#include <spdlog/spdlog.h>

#include "lidartag/driver/io/udp_frame.hpp"

namespace lidartag::cli {

void add_capture_options(CLI::App& app, CaptureArgs& args) {
  app.add_option("capture", args.capture, "pcap or pcapng file")
      ->required()
      ->check(CLI::ExistingFile);
  const std::string names = velodyne::model_names();
  app.add_option("--model", args.model, "Decode as this model (" + names + ")")
      ->check(CLI::Validator(
          [names](std::string& name) -> std::string {
            return velodyne::model_from_name(name) ? std::string()
                                                   : "unknown model '" + name + "' (" + names + ")";
          },
          "MODEL"));
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

}  // namespace lidartag::cli
