#include "lidartag/driver/ouster/models.hpp"

#include <cmath>
#include <stdexcept>

namespace lidartag::driver::ouster {
namespace {

// OS1 (gen 2 and later): 45 deg vertical field of view (+-22.5 deg, Ouster's OS1 datasheet), the
// beams evenly spaced; azimuth offsets +-4.23 and +-1.41 deg repeating every 4 beams and
// lidar_origin_to_beam_origin_mm 15.806, as OS1 sensors of firmware 2.x report them. Range
// 0.5 m (the minimum range the datasheet gives, rounded up) to 120 m.
constexpr std::array<ModelSpec, 2> kModels = {{
    {Model::kOs1_64,
     "os1-64",
     "OS-1-64",
     64,
     22.5,
     -22.5,
     {4.23, 1.41, -1.41, -4.23},
     15.806,
     0.5,
     120.0},
    {Model::kOs1_128,
     "os1-128",
     "OS-1-128",
     128,
     22.5,
     -22.5,
     {4.23, 1.41, -1.41, -4.23},
     15.806,
     0.5,
     120.0},
}};

}  // namespace

const ModelSpec& model_spec(Model m) {
  return kModels[static_cast<size_t>(m)];
}

std::optional<Model> model_from_name(std::string_view name) {
  for (const ModelSpec& s : kModels)
    if (s.name == name) return s.model;
  return std::nullopt;
}

std::string model_names() {
  std::string out;
  for (const ModelSpec& s : kModels) out += (out.empty() ? "" : ", ") + std::string(s.name);
  return out;
}

std::string model_name(const SensorInfo& info) {
  // "OS-1-128", "OS1-64", "OS-0-32-U1": the digit after "OS" and an optional '-'.
  std::string line;
  const std::string& p = info.prod_line;
  if (p.size() >= 3 && (p[0] == 'O' || p[0] == 'o') && (p[1] == 'S' || p[1] == 's')) {
    size_t i = 2;
    if (i < p.size() && p[i] == '-') ++i;
    if (i < p.size() && p[i] >= '0' && p[i] <= '9') line = p.substr(i, 1);
  }
  return "os" + line + "-" + std::to_string(info.pixels_per_column);
}

bool is_model_name(std::string_view name) {
  for (const std::string_view line : {"os0-", "os1-", "os2-", "os-"}) {
    if (name.substr(0, line.size()) != line) continue;
    const std::string_view beams = name.substr(line.size());
    return beams == "16" || beams == "32" || beams == "64" || beams == "128";
  }
  return false;
}

bool describes_model(const SensorInfo& info, std::string_view name) {
  const std::string described = model_name(info);
  if (described == name) return true;
  const auto beams = [](std::string_view m) {
    const size_t dash = m.find('-');
    return dash == std::string_view::npos ? std::string_view() : m.substr(dash);
  };
  const bool unnamed = described.rfind("os-", 0) == 0 || name.substr(0, 3) == "os-";
  return unnamed && beams(described) == beams(name);
}

SensorInfo nominal_sensor_info(Model m, int columns, int rate_hz, Profile profile) {
  if ((columns != 512 && columns != 1024 && columns != 2048) || (rate_hz != 10 && rate_hz != 20) ||
      (columns == 2048 && rate_hz != 10))
    throw std::invalid_argument("lidar mode " + std::to_string(columns) + "x" +
                                std::to_string(rate_hz) +
                                " not one of 512x10, 512x20, 1024x10, 1024x20, 2048x10");
  const ModelSpec& spec = model_spec(m);
  SensorInfo s;
  s.prod_line = std::string(spec.prod_line);
  s.firmware = "v2.5.0";
  s.nested_layout = true;
  const auto n = static_cast<size_t>(spec.beams);
  s.beam_altitude_deg.resize(n);
  s.beam_azimuth_deg.resize(n);
  s.pixel_shift_by_row.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const double f = double(i) / double(n - 1);
    // Rounded to 1e-4 deg, as sensors report them.
    s.beam_altitude_deg[i] = std::round((spec.altitude_top_deg +
                                         f * (spec.altitude_bottom_deg - spec.altitude_top_deg)) *
                                        1e4) /
                             1e4;
    s.beam_azimuth_deg[i] = spec.azimuth_pattern_deg[i % 4];
    // A beam pointing `az` degrees clockwise of its column's encoder angle looks where the column
    // `az / (360 / columns)` later does (firmware >= 2.4's convention, centred on zero).
    s.pixel_shift_by_row[i] =
        static_cast<int>(std::lround(s.beam_azimuth_deg[i] * columns / 360.0));
  }
  s.lidar_origin_to_beam_origin_mm = spec.lidar_origin_to_beam_origin_mm;
  s.lidar_to_sensor_transform = {-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1};
  s.mode_columns = columns;
  s.mode_rate_hz = rate_hz;
  s.pixels_per_column = spec.beams;
  s.columns_per_packet = 16;
  s.columns_per_frame = columns;
  s.column_window = {0, columns - 1};
  s.profile = profile;
  s.data_format_reported = true;
  return s;
}

}  // namespace lidartag::driver::ouster
