// Per-model sensor tables: the one source of truth for decoder, simulator and tests.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::velodyne {

enum class Model : uint8_t { kVLP16 = 1, kPuckHiRes = 2, kVLP32C = 3, kHDL32E = 4, kVLS128 = 5 };

// Byte 1204 of a data packet.
enum class ReturnMode : uint8_t { kStrongest = 0x37, kLast = 0x38, kDual = 0x39 };

// Factory table of one laser, in the sensor's own laser (channel) order.
struct LaserSpec {
  double elevation_deg;  // vertical angle, + up
  double
      azimuth_offset_deg;    // point azimuth = firing azimuth - offset (ros-drivers rot_correction)
  double vertical_offset_m;  // ros-drivers vert_offset_correction
};

struct ModelSpec {
  Model model;
  std::string_view name;          // the name used in configs and on the command line
  std::string_view display_name;  // what a human calls it
  uint8_t product_id;             // byte 1205 of a data packet
  int lasers;
  int firings_per_block;  // firing sequences of all lasers in one 32-channel block (VLP-16: 2)
  int blocks_per_firing;  // blocks that one firing sequence spans (VLS-128: 4 banks)
  double distance_unit_m;
  double min_range_m;
  double max_range_m;
  double firing_period_us;  // one firing sequence of every laser, recharge included: a column
  std::span<const LaserSpec> laser_table;

  // Time of laser `laser` from the start of its firing sequence, microseconds.
  double laser_time_us(int laser) const;
  // Columns (firing sequences) carried by one data packet in this return mode.
  int columns_per_packet(ReturnMode mode) const;
  // Nominal data packets per second (independent of rpm).
  double packet_rate_hz(ReturnMode mode) const {
    return 1e6 / (firing_period_us * columns_per_packet(mode));
  }
  double packet_period_us(ReturnMode mode) const { return 1e6 / packet_rate_hz(mode); }
  // Ring (0 = lowest beam) of each laser: the rank of its elevation.
  int ring_of_laser(int laser) const;
  int laser_of_ring(int ring) const;
};

const ModelSpec& model_spec(Model model);
// The elevation of each of `model`'s lasers, degrees, in laser order; empty without a model.
std::vector<double> beam_elevations_deg(std::optional<Model> model);
std::span<const Model> all_models();
// The model of a name, case-insensitive and ignoring '-', '_', '.' and spaces ("VLP-32C",
// "vlp_32c", "Puck Hi-Res"); Velodyne's product names puck, puck-lite (VLP-16), ultra-puck
// (VLP-32C) and alpha-prime (VLS-128) too.
std::optional<Model> model_from_name(std::string_view name);
std::optional<Model> model_from_product_id(uint8_t id);
std::string_view return_mode_name(ReturnMode mode);
std::optional<ReturnMode> return_mode_from_byte(uint8_t b);
// Comma-separated list of model names, for error messages and --help.
std::string model_names();

}  // namespace lidartag::velodyne
