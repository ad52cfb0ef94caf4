#include "lidartag/driver/velodyne/sensor_model.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace lidartag::velodyne {
namespace {

// VLP-16: velodyne.md table; vertical offsets from the VLP-16 manual (mm).
constexpr std::array<LaserSpec, 16> kVlp16 = {{
    {-15, 0, 0.0112},
    {1, 0, -0.0007},
    {-13, 0, 0.0097},
    {3, 0, -0.0022},
    {-11, 0, 0.0081},
    {5, 0, -0.0037},
    {-9, 0, 0.0066},
    {7, 0, -0.0051},
    {-7, 0, 0.0051},
    {9, 0, -0.0066},
    {-5, 0, 0.0037},
    {11, 0, -0.0081},
    {-3, 0, 0.0022},
    {13, 0, -0.0097},
    {-1, 0, 0.0007},
    {15, 0, -0.0112},
}};

// Puck Hi-Res: the VLP-16 layout with elevations scaled to -10..+10 deg (1.333 deg steps).
constexpr std::array<LaserSpec, 16> kPuckHiRes = {{
    {-10.0, 0, 0},
    {0.667, 0, 0},
    {-8.667, 0, 0},
    {2.0, 0, 0},
    {-7.333, 0, 0},
    {3.333, 0, 0},
    {-6.0, 0, 0},
    {4.667, 0, 0},
    {-4.667, 0, 0},
    {6.0, 0, 0},
    {-3.333, 0, 0},
    {7.333, 0, 0},
    {-2.0, 0, 0},
    {8.667, 0, 0},
    {-0.667, 0, 0},
    {10.0, 0, 0},
}};

// VLP-32C: velodyne.md table (elevation, azimuth offset); no published vertical offsets.
constexpr std::array<LaserSpec, 32> kVlp32c = {{
    {-25, -1.4, 0},    {-1, 4.2, 0},      {-1.667, -1.4, 0}, {-15.639, 1.4, 0}, {-11.31, -1.4, 0},
    {0, 1.4, 0},       {-0.667, -4.2, 0}, {-8.843, 1.4, 0},  {-7.254, -1.4, 0}, {0.333, 4.2, 0},
    {-0.333, -1.4, 0}, {-6.148, 1.4, 0},  {-5.333, -4.2, 0}, {1.333, 1.4, 0},   {0.667, -4.2, 0},
    {-4, 1.4, 0},      {-4.667, -1.4, 0}, {1.667, 4.2, 0},   {1, -1.4, 0},      {-3.667, 4.2, 0},
    {-3.333, -4.2, 0}, {3.333, 1.4, 0},   {2.333, -1.4, 0},  {-2.667, 1.4, 0},  {-3, -1.4, 0},
    {7, 1.4, 0},       {4.667, -1.4, 0},  {-2.333, 4.2, 0},  {-2, -4.2, 0},     {15, 1.4, 0},
    {10.333, -1.4, 0}, {-1.333, 1.4, 0},
}};

// HDL-32E: velodyne.md table (elevation, vertical offset in mm).
constexpr std::array<LaserSpec, 32> kHdl32e = {{
    {-30.67, 0, 0.01717}, {-9.33, 0, 0.00476}, {-29.33, 0, 0.01627}, {-8.00, 0, 0.00407},
    {-28.00, 0, 0.01540}, {-6.67, 0, 0.00338}, {-26.67, 0, 0.01454}, {-5.33, 0, 0.00270},
    {-25.33, 0, 0.01371}, {-4.00, 0, 0.00202}, {-24.00, 0, 0.01289}, {-2.67, 0, 0.00135},
    {-22.67, 0, 0.01209}, {-1.33, 0, 0.00067}, {-21.33, 0, 0.01131}, {0.00, 0, 0.0},
    {-20.00, 0, 0.01054}, {1.33, 0, -0.00067}, {-18.67, 0, 0.00978}, {2.67, 0, -0.00135},
    {-17.33, 0, 0.00904}, {4.00, 0, -0.00202}, {-16.00, 0, 0.00830}, {5.33, 0, -0.00270},
    {-14.67, 0, 0.00758}, {6.67, 0, -0.00338}, {-13.33, 0, 0.00686}, {8.00, 0, -0.00407},
    {-12.00, 0, 0.00615}, {9.33, 0, -0.00476}, {-10.67, 0, 0.00545}, {10.67, 0, -0.00545},
}};

// VLS-128: elevations of the public ros-drivers/velodyne VLS128.yaml (vert_correction, radians,
// converted to degrees and rounded to 0.001 deg). Azimuth offsets repeat every 8 lasers
// (rot_correction: -6.354, -4.548, -2.732, -0.911, +0.911, +2.732, +4.548, +6.354 deg).
constexpr std::array<double, 128> kVls128Elevation = {
    -11.742, -1.990, 3.400,  -5.290,  -0.780, 4.610,  -4.080, 1.310,  -6.500, -1.110,  4.280,
    -4.410,  0.100,  6.480,  -3.200,  2.190,  -3.860, 1.530,  -9.244, -1.770, 2.740,   -5.950,
    -0.560,  4.830,  -2.980, 2.410,   -6.280, -0.890, 3.620,  -5.070, 0.320,  7.580,   -0.340,
    5.180,   -3.640, 1.750,  -25.000, -2.430, 2.960,  -5.730, 0.540,  9.700,  -2.760,  2.630,
    -7.650,  -1.550, 3.840,  -4.850,  3.180,  -5.510, -0.120, 5.730,  -4.300, 1.090,   -16.042,
    -2.210,  4.060,  -4.630, 0.760,   15.000, -3.420, 1.970,  -6.850, -1.330, -5.620,  -0.230,
    5.430,   -3.530, 0.980,  -19.582, -2.320, 3.070,  -4.740, 0.650,  11.750, -2.650,  1.860,
    -7.150,  -1.440, 3.950,  -2.100,  3.290,  -5.400, -0.010, 4.500,  -4.190, 1.200,   -13.565,
    -1.220,  4.170,  -4.520, 0.870,   6.080,  -3.310, 2.080,  -6.650, 1.420,  -10.346, -1.880,
    3.510,   -6.060, -0.670, 4.720,   -3.970, 2.300,  -6.390, -1.000, 4.390,  -5.180,  0.210,
    6.980,   -3.090, 4.980,  -3.750,  1.640,  -8.352, -2.540, 2.850,  -5.840, -0.450,  8.430,
    -2.870,  2.520,  -6.170, -1.660,  3.730,  -4.960, 0.430,
};
constexpr std::array<double, 8> kVls128AzimuthOffset = {-6.354, -4.548, -2.732, -0.911,
                                                        0.911,  2.732,  4.548,  6.354};

constexpr std::array<LaserSpec, 128> make_vls128() {
  std::array<LaserSpec, 128> t{};
  for (size_t i = 0; i < t.size(); ++i)
    t[i] = {kVls128Elevation[i], kVls128AzimuthOffset[i % 8], 0};
  return t;
}
constexpr std::array<LaserSpec, 128> kVls128 = make_vls128();

// Firing sequences: VLP-16 16 x 2.304 + 18.432 us; VLP-32C 16 pairs x 2.304 + 18.432 us;
// HDL-32E 32 x 1.152 + 9.216 us; VLS-128 measured on the real capture as 165.83 us per packet of
// 3 sequences, which matches the 55.296 us cycle within 0.04 %.
constexpr std::array<ModelSpec, 5> kModels = {{
    {Model::kVLP16, "vlp16", "VLP-16", 0x22, 16, 2, 1, 0.002, 0.3, 100.0, 55.296, kVlp16},
    {Model::kPuckHiRes, "puck-hires", "Puck Hi-Res", 0x24, 16, 2, 1, 0.002, 0.3, 100.0, 55.296,
     kPuckHiRes},
    {Model::kVLP32C, "vlp32c", "VLP-32C (Ultra Puck)", 0x28, 32, 1, 1, 0.004, 0.5, 200.0, 55.296,
     kVlp32c},
    {Model::kHDL32E, "hdl32e", "HDL-32E", 0x21, 32, 1, 1, 0.002, 1.0, 100.0, 46.08, kHdl32e},
    {Model::kVLS128, "vls128", "VLS-128 (Alpha Prime)", 0xA1, 128, 1, 4, 0.004, 0.5, 245.0, 55.296,
     kVls128},
}};

constexpr std::array<Model, 5> kAllModels = {Model::kVLP16, Model::kPuckHiRes, Model::kVLP32C,
                                             Model::kHDL32E, Model::kVLS128};

// Rank of elevation, computed once per model.
struct RingTables {
  std::array<std::array<int, 128>, 6> ring_of{};
  std::array<std::array<int, 128>, 6> laser_of{};
  RingTables() {
    for (const auto& spec : kModels) {
      const auto m = static_cast<size_t>(spec.model);
      std::array<int, 128> order{};
      for (int i = 0; i < spec.lasers; ++i) order[static_cast<size_t>(i)] = i;
      std::stable_sort(order.begin(), order.begin() + spec.lasers, [&](int a, int b) {
        return spec.laser_table[static_cast<size_t>(a)].elevation_deg <
               spec.laser_table[static_cast<size_t>(b)].elevation_deg;
      });
      for (int r = 0; r < spec.lasers; ++r) {
        laser_of[m][static_cast<size_t>(r)] = order[static_cast<size_t>(r)];
        ring_of[m][static_cast<size_t>(order[static_cast<size_t>(r)])] = r;
      }
    }
  }
};
const RingTables& ring_tables() {
  static const RingTables t;
  return t;
}

}  // namespace

double ModelSpec::laser_time_us(int laser) const {
  switch (model) {
    case Model::kVLP16:
    case Model::kPuckHiRes:
      return laser * 2.304;
    case Model::kVLP32C:
      return (laser / 2) * 2.304;
    case Model::kHDL32E:
      return laser * 1.152;
    case Model::kVLS128: {
      // 8 lasers fire together; one idle slot after the first 8 groups.
      const int group = laser / 8;
      return (group + (group >= 8 ? 1 : 0)) * 2.665;
    }
  }
  return 0.0;
}

int ModelSpec::columns_per_packet(ReturnMode mode) const {
  const int single = 12 * firings_per_block / blocks_per_firing;
  if (mode != ReturnMode::kDual) return single;
  // Dual: blocks pair up; VLS-128 fills 8 of its 12 blocks (one sequence, two returns).
  return blocks_per_firing > 1 ? 1 : single / 2;
}

int ModelSpec::ring_of_laser(int laser) const {
  return ring_tables().ring_of[static_cast<size_t>(model)][static_cast<size_t>(laser)];
}
int ModelSpec::laser_of_ring(int ring) const {
  return ring_tables().laser_of[static_cast<size_t>(model)][static_cast<size_t>(ring)];
}

const ModelSpec& model_spec(Model model) {
  for (const auto& s : kModels)
    if (s.model == model) return s;
  return kModels[0];
}

std::vector<double> beam_elevations_deg(std::optional<Model> model) {
  std::vector<double> elevations;
  if (model)
    for (const auto& laser : model_spec(*model).laser_table)
      elevations.push_back(laser.elevation_deg);
  return elevations;
}

std::span<const Model> all_models() {
  return kAllModels;
}

namespace {
// Lower case without '-', '_', '.' and spaces: "VLP-32C", "vlp_32c" and "vlp32c" are one name.
std::string fold_name(std::string_view name) {
  std::string out;
  for (const char c : name) {
    if (c == '-' || c == '_' || c == '.' || c == ' ') continue;
    out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}
// Velodyne's product names besides the model numbers, folded.
constexpr std::pair<std::string_view, Model> kAliases[] = {{"puck", Model::kVLP16},
                                                           {"pucklite", Model::kVLP16},
                                                           {"ultrapuck", Model::kVLP32C},
                                                           {"alphaprime", Model::kVLS128}};
}  // namespace

std::optional<Model> model_from_name(std::string_view name) {
  const std::string folded = fold_name(name);
  for (const auto& s : kModels)
    if (fold_name(s.name) == folded) return s.model;
  for (const auto& [alias, model] : kAliases)
    if (alias == folded) return model;
  return std::nullopt;
}

std::optional<Model> model_from_product_id(uint8_t id) {
  for (const auto& s : kModels)
    if (s.product_id == id) return s.model;
  return std::nullopt;
}

std::string_view return_mode_name(ReturnMode mode) {
  switch (mode) {
    case ReturnMode::kStrongest:
      return "strongest";
    case ReturnMode::kLast:
      return "last";
    case ReturnMode::kDual:
      return "dual";
  }
  return "unknown";
}

std::optional<ReturnMode> return_mode_from_byte(uint8_t b) {
  if (b == 0x37 || b == 0x38 || b == 0x39) return static_cast<ReturnMode>(b);
  return std::nullopt;
}

std::string model_names() {
  std::string out;
  for (const auto& s : kModels) {
    if (!out.empty()) out += ", ";
    out += s.name;
  }
  return out;
}

}  // namespace lidartag::velodyne
