// Options and helpers shared by the capture subcommands (info, dump, and later detect).
#pragma once

#include <optional>
#include <string>

#include "lidartag/cli11.hpp"
#include "lidartag/driver/io/capture_reader.hpp"
#include "lidartag/driver/sensor_model.hpp"

namespace lidartag::cli {

// What the capture subcommands accept besides their own options.
struct CaptureArgs {
  std::string capture;
  std::string model;        // empty: from the product byte
  std::string calibration;  // empty: built-in table
  double cut_deg = velodyne::BatcherOptions{}.cut_azimuth_deg;
  uint16_t data_port = velodyne::kDefaultDataPort;
  uint16_t position_port = velodyne::kDefaultPositionPort;
  std::string sensor;  // sender address filter, dotted quad
};

// Adds CAPTURE, --model, --calibration, --cut, --data-port, --position-port, --sensor to `app`.
void add_capture_options(CLI::App& app, CaptureArgs& args);

// The reader options for `args` (names already validated by CLI11).
velodyne::CaptureReaderOptions reader_options(const CaptureArgs& args);

// Warns on stderr when the product byte contradicts the timing and no model was given.
void warn_model_mismatch(const velodyne::CaptureReader& reader, const CaptureArgs& args);

}  // namespace lidartag::cli
