#include "lidartag/driver/ouster/models.hpp"

#include <array>
#include <cmath>
#include <stdexcept>

namespace lidartag::driver::ouster {
namespace {

// OS0 and OS2: the beam tables real units report (firmware 2.x; the Ouster SDK's test data,
// ../shared/captures/ouster/pcaps/NAME.json): their altitudes are not evenly spaced (an OS0-128's
// 92 deg field of view, beams closer near the horizon; an OS2-128's 22 deg) and their azimuth
// offsets vary from beam to beam. The 32-beam units are "uniform" ones (U0, U1): every 4th beam
// of a 128-beam field of view.
// OS-0-32-U1_v2.2.0_1024x10.json, beam_altitude_angles
constexpr std::array<double, 32> kOs0_32Altitude = {
    43.88,  40.9,   37.94,  34.98,  32.06,  29.16,  26.25,  23.37,  20.51,  17.66,  14.81,
    11.99,  9.17,   6.35,   3.55,   0.72,   -2.09,  -4.9,   -7.72,  -10.55, -13.38, -16.22,
    -19.06, -21.92, -24.79, -27.68, -30.58, -33.49, -36.43, -39.39, -42.38, -45.4};
// OS-0-32-U1_v2.2.0_1024x10.json, beam_azimuth_angles
constexpr std::array<double, 32> kOs0_32Azimuth = {
    -2.9,  -2.83, -2.78, -2.73, -2.7,  -2.67, -2.65, -2.64, -2.65, -2.65, -2.65,
    -2.67, -2.69, -2.71, -2.74, -2.78, -2.81, -2.85, -2.89, -2.95, -3.01, -3.08,
    -3.17, -3.25, -3.35, -3.46, -3.58, -3.72, -3.87, -4.05, -4.25, -4.48};
// OS-0-128-U1_v2.3.0_1024x10.json, beam_altitude_angles
constexpr std::array<double, 128> kOs0_128Altitude = {
    45.75,  44.7,   43.93,  43.47,  42.72,  41.68,  40.94,  40.46,  39.7,   38.69,  37.95,  37.47,
    36.71,  35.72,  35.0,   34.51,  33.74,  32.78,  32.06,  31.56,  30.8,   29.85,  29.13,  28.62,
    27.86,  26.93,  26.23,  25.7,   24.93,  24.03,  23.33,  22.79,  22.03,  21.16,  20.46,  19.91,
    19.13,  18.3,   17.6,   17.04,  16.27,  15.45,  14.76,  14.19,  13.41,  12.62,  11.94,  11.34,
    10.55,  9.81,   9.13,   8.51,   7.71,   6.99,   6.31,   5.68,   4.87,   4.17,   3.5,    2.86,
    2.06,   1.37,   0.71,   0.04,   -0.77,  -1.43,  -2.09,  -2.77,  -3.6,   -4.23,  -4.9,   -5.6,
    -6.43,  -7.05,  -7.71,  -8.43,  -9.24,  -9.85,  -10.51, -11.28, -12.07, -12.65, -13.34, -14.1,
    -14.91, -15.48, -16.16, -16.95, -17.77, -18.32, -18.99, -19.8,  -20.62, -21.17, -21.84, -22.68,
    -23.5,  -24.02, -24.7,  -25.56, -26.39, -26.9,  -27.57, -28.46, -29.29, -29.78, -30.47, -31.36,
    -32.21, -32.68, -33.37, -34.29, -35.14, -35.6,  -36.29, -37.24, -38.11, -38.55, -39.24, -40.21,
    -41.08, -41.51, -42.23, -43.22, -44.09, -44.52, -45.24, -46.26};
// OS-0-128-U1_v2.3.0_1024x10.json, beam_azimuth_angles
constexpr std::array<double, 128> kOs0_128Azimuth = {
    11.24, 3.93,  -3.29,  -10.34, 10.81, 3.75,  -3.18,  -10.0, 10.41, 3.61,  -3.1,  -9.7,   10.09,
    3.49,  -3.02, -9.45,  9.81,   3.39,  -2.96, -9.23,  9.56,  3.3,   -2.91, -9.05, 9.35,   3.21,
    -2.87, -8.88, 9.15,   3.14,   -2.83, -8.76, 8.99,   3.06,  -2.8,  -8.63, 8.85,  3.02,   -2.79,
    -8.55, 8.73,  2.96,   -2.77,  -8.49, 8.64,  2.93,   -2.77, -8.41, 8.55,  2.89,  -2.76,  -8.38,
    8.5,   2.86,  -2.77,  -8.37,  8.45,  2.83,  -2.77,  -8.35, 8.41,  2.82,  -2.77, -8.35,  8.39,
    2.8,   -2.8,  -8.39,  8.39,   2.79,  -2.82, -8.43,  8.4,   2.8,   -2.83, -8.47, 8.42,   2.79,
    -2.87, -8.55, 8.46,   2.79,   -2.92, -8.63, 8.51,   2.78,  -2.96, -8.73, 8.58,  2.8,    -3.01,
    -8.86, 8.66,  2.83,   -3.07,  -9.01, 8.78,  2.85,   -3.14, -9.17, 8.9,   2.88,  -3.22,  -9.35,
    9.05,  2.91,  -3.31,  -9.57,  9.23,  2.95,  -3.41,  -9.83, 9.44,  3.01,  -3.51, -10.12, 9.7,
    3.08,  -3.64, -10.47, 9.99,   3.15,  -3.8,  -10.88, 10.34, 3.24,  -3.98, -11.35};
// OS-2-32-U0_v2.0.0_1024x10.json, beam_altitude_angles
constexpr std::array<double, 32> kOs2_32Altitude = {
    10.87, 10.24, 9.56, 8.88, 8.2,   7.52,  6.83,  6.14,  5.44,  4.76,  4.06,
    3.35,  2.66,  1.96, 1.27, 0.56,  -0.12, -0.83, -1.51, -2.22, -2.92, -3.61,
    -4.32, -5.02, -5.7, -6.4, -7.08, -7.77, -8.47, -9.14, -9.82, -10.48};
// OS-2-32-U0_v2.0.0_1024x10.json, beam_azimuth_angles
constexpr std::array<double, 32> kOs2_32Azimuth = {
    -2.08, -2.06, -2.07, -2.07, -2.07, -2.07, -2.07, -2.06, -2.07, -2.06, -2.07,
    -2.08, -2.07, -2.08, -2.07, -2.09, -2.07, -2.09, -2.08, -2.09, -2.1,  -2.08,
    -2.1,  -2.1,  -2.09, -2.1,  -2.09, -2.1,  -2.11, -2.1,  -2.11, -2.1};
// OS-2-128-U1_v2.3.0_1024x10.json, beam_altitude_angles
constexpr std::array<double, 128> kOs2_128Altitude = {
    10.76, 10.58, 10.42, 10.24, 10.1,   9.93,   9.76,   9.57,   9.41,   9.24,   9.09,  8.91,  8.75,
    8.57,  8.41,  8.23,  8.08,  7.9,    7.74,   7.55,   7.39,   7.21,   7.03,   6.86,  6.7,   6.53,
    6.35,  6.18,  6.02,  5.83,  5.67,   5.5,    5.32,   5.14,   4.97,   4.81,   4.63,  4.46,  4.28,
    4.11,  3.95,  3.76,  3.58,  3.43,   3.24,   3.07,   2.9,    2.72,   2.55,   2.37,  2.21,  2.03,
    1.87,  1.69,  1.51,  1.32,  1.16,   0.98,   0.81,   0.63,   0.46,   0.29,   0.11,  -0.05, -0.25,
    -0.42, -0.58, -0.76, -0.93, -1.11,  -1.28,  -1.45,  -1.63,  -1.81,  -1.97,  -2.16, -2.32, -2.5,
    -2.68, -2.85, -3.02, -3.19, -3.37,  -3.55,  -3.73,  -3.9,   -4.07,  -4.25,  -4.4,  -4.58, -4.75,
    -4.94, -5.11, -5.28, -5.46, -5.64,  -5.8,   -5.96,  -6.15,  -6.32,  -6.49,  -6.66, -6.84, -7.0,
    -7.17, -7.35, -7.51, -7.69, -7.86,  -8.04,  -8.22,  -8.38,  -8.55,  -8.72,  -8.89, -9.06, -9.23,
    -9.4,  -9.57, -9.74, -9.91, -10.07, -10.24, -10.41, -10.58, -10.75, -10.92, -11.09};
// OS-2-128-U1_v2.3.0_1024x10.json, beam_azimuth_angles
constexpr std::array<double, 128> kOs2_128Azimuth = {
    2.07,  0.66,  -0.71, -2.08, 2.07,  0.69,  -0.7,  -2.09, 2.06,  0.67,  -0.71, -2.06, 2.06,
    0.69,  -0.71, -2.07, 2.07,  0.69,  -0.71, -2.07, 2.07,  0.69,  -0.7,  -2.08, 2.05,  0.68,
    -0.69, -2.06, 2.06,  0.69,  -0.69, -2.07, 2.08,  0.69,  -0.69, -2.06, 2.08,  0.69,  -0.69,
    -2.07, 2.08,  0.69,  -0.69, -2.05, 2.08,  0.7,   -0.68, -2.06, 2.09,  0.7,   -0.67, -2.05,
    2.08,  0.7,   -0.68, -2.05, 2.08,  0.71,  -0.67, -2.06, 2.08,  0.71,  -0.68, -2.05, 2.07,
    0.71,  -0.67, -2.05, 2.08,  0.7,   -0.68, -2.05, 2.09,  0.71,  -0.66, -2.05, 2.09,  0.71,
    -0.67, -2.05, 2.09,  0.71,  -0.66, -2.05, 2.1,   0.71,  -0.66, -2.05, 2.09,  0.73,  -0.67,
    -2.05, 2.1,   0.72,  -0.66, -2.05, 2.09,  0.72,  -0.66, -2.05, 2.11,  0.73,  -0.69, -2.03,
    2.1,   0.72,  -0.65, -2.04, 2.11,  0.72,  -0.67, -2.05, 2.1,   0.72,  -0.66, -2.04, 2.11,
    0.72,  -0.66, -2.04, 2.1,   0.72,  -0.65, -2.03, 2.11,  0.73,  -0.66, -2.04};

// OS1 (gen 2 and later): 45 deg vertical field of view (+-22.5 deg, Ouster's OS1 datasheet), the
// beams evenly spaced; azimuth offsets +-4.23 and +-1.41 deg repeating every 4 beams and
// lidar_origin_to_beam_origin_mm 15.806, as OS1 sensors of firmware 2.x report them. Range
// 0.5 m (the minimum range the datasheet gives, rounded up) to 120 m. OS0 and OS2: the units'
// lidar_origin_to_beam_origin_mm (27.67, 13.762) and lidar_to_sensor_transform heights (36.18;
// 74.296 and 78.296 mm), ranges representative of the datasheets (OS0 0.5 to 50 m, OS2 1 to
// 240 m at 80 % reflectivity).
constexpr std::array<double, 4> kOs1Pattern = {4.23, 1.41, -1.41, -4.23};
constexpr std::array<double, 4> kNoPattern = {0.0, 0.0, 0.0, 0.0};
constexpr std::array<ModelSpec, 6> kModels = {{
    {Model::kOs1_64,
     "os1-64",
     "OS-1-64",
     64,
     22.5,
     -22.5,
     kOs1Pattern,
     {},
     {},
     15.806,
     36.18,
     0.5,
     120.0},
    {Model::kOs1_128,
     "os1-128",
     "OS-1-128",
     128,
     22.5,
     -22.5,
     kOs1Pattern,
     {},
     {},
     15.806,
     36.18,
     0.5,
     120.0},
    {Model::kOs0_32, "os0-32", "OS-0-32-U1", 32, 0.0, 0.0, kNoPattern, kOs0_32Altitude,
     kOs0_32Azimuth, 27.67, 36.18, 0.5, 50.0},
    {Model::kOs0_128, "os0-128", "OS-0-128", 128, 0.0, 0.0, kNoPattern, kOs0_128Altitude,
     kOs0_128Azimuth, 27.67, 36.18, 0.5, 50.0},
    {Model::kOs2_32, "os2-32", "OS-2-32-U0", 32, 0.0, 0.0, kNoPattern, kOs2_32Altitude,
     kOs2_32Azimuth, 13.762, 74.296, 1.0, 240.0},
    {Model::kOs2_128, "os2-128", "OS-2-128", 128, 0.0, 0.0, kNoPattern, kOs2_128Altitude,
     kOs2_128Azimuth, 13.762, 78.296, 1.0, 240.0},
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

std::vector<double> nominal_beam_altitudes_deg(Model m) {
  const ModelSpec& spec = model_spec(m);
  const auto n = static_cast<size_t>(spec.beams);
  std::vector<double> altitudes(n);
  for (size_t i = 0; i < n; ++i) {
    const double f = double(i) / double(n - 1);
    // Rounded to 1e-4 deg, as sensors report them.
    altitudes[i] = spec.altitude_table_deg.empty()
                       ? std::round((spec.altitude_top_deg +
                                     f * (spec.altitude_bottom_deg - spec.altitude_top_deg)) *
                                    1e4) /
                             1e4
                       : spec.altitude_table_deg[i];
  }
  return altitudes;
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
  s.beam_altitude_deg = nominal_beam_altitudes_deg(m);
  s.beam_azimuth_deg.resize(n);
  s.pixel_shift_by_row.resize(n);
  for (size_t i = 0; i < n; ++i) {
    s.beam_azimuth_deg[i] = spec.azimuth_table_deg.empty() ? spec.azimuth_pattern_deg[i % 4]
                                                           : spec.azimuth_table_deg[i];
    // A beam pointing `az` degrees clockwise of its column's encoder angle looks where the column
    // `az / (360 / columns)` later does (firmware >= 2.4's convention, centred on zero).
    s.pixel_shift_by_row[i] =
        static_cast<int>(std::lround(s.beam_azimuth_deg[i] * columns / 360.0));
  }
  s.lidar_origin_to_beam_origin_mm = spec.lidar_origin_to_beam_origin_mm;
  s.lidar_to_sensor_transform = {-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, spec.lidar_to_sensor_z_mm,
                                 0,  0, 0, 1};
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
