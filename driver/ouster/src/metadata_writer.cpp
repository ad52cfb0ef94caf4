// SensorInfo -> the sensor's metadata JSON (the inverse of metadata.cpp's reader).
#include <fstream>
#include <nlohmann/json.hpp>

#include "lidartag/driver/ouster/metadata.hpp"

namespace lidartag::driver::ouster {
namespace {

using json = nlohmann::ordered_json;

json data_format(const SensorInfo& s) {
  json f;
  f["pixels_per_column"] = s.pixels_per_column;
  f["columns_per_packet"] = s.columns_per_packet;
  f["columns_per_frame"] = s.columns_per_frame;
  f["column_window"] = s.column_window;
  f["pixel_shift_by_row"] = s.pixel_shift_by_row;
  f["udp_profile_lidar"] = std::string(profile_name(s.profile));
  return f;
}

void identity(const SensorInfo& s, json& o) {
  if (!s.prod_line.empty()) o["prod_line"] = s.prod_line;
  if (!s.firmware.empty()) o["build_rev"] = s.firmware;
  if (s.serial_number != 0) o["prod_sn"] = std::to_string(s.serial_number);
  if (s.init_id != 0) o["initialization_id"] = s.init_id;
}

}  // namespace

std::string metadata_to_json(const SensorInfo& s) {
  const std::string mode = std::to_string(s.mode_columns) + "x" + std::to_string(s.mode_rate_hz);
  json root;
  if (s.nested_layout) {
    json info = json::object();
    identity(s, info);
    root["sensor_info"] = info;
    root["calibration_status"] = json::object();
    root["beam_intrinsics"] = {
        {"beam_altitude_angles", s.beam_altitude_deg},
        {"beam_azimuth_angles", s.beam_azimuth_deg},
        {"lidar_origin_to_beam_origin_mm", s.lidar_origin_to_beam_origin_mm}};
    root["config_params"] = {{"lidar_mode", mode},
                             {"udp_profile_lidar", std::string(profile_name(s.profile))}};
    root["lidar_intrinsics"] = {{"lidar_to_sensor_transform", s.lidar_to_sensor_transform}};
    root["lidar_data_format"] = data_format(s);
  } else {
    identity(s, root);
    root["lidar_mode"] = mode;
    root["beam_altitude_angles"] = s.beam_altitude_deg;
    root["beam_azimuth_angles"] = s.beam_azimuth_deg;
    root["lidar_origin_to_beam_origin_mm"] = s.lidar_origin_to_beam_origin_mm;
    root["lidar_to_sensor_transform"] = s.lidar_to_sensor_transform;
    root["data_format"] = data_format(s);
  }
  return root.dump(2) + "\n";
}

void write_metadata(const SensorInfo& info, const std::string& path) {
  const std::string text = metadata_to_json(info);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw MetadataError(path + ": cannot be written");
  out << text;
  out.close();
  if (!out) throw MetadataError(path + ": write error");
}

}  // namespace lidartag::driver::ouster
