#include "lidartag/driver/ouster/metadata.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <sstream>

namespace lidartag::driver::ouster {
namespace {

using json = nlohmann::json;

constexpr std::array<std::string_view, 5> kProfileNames = {
    "LEGACY", "RNG19_RFL8_SIG16_NIR16", "RNG19_RFL8_SIG16_NIR16_DUAL", "RNG15_RFL8_NIR8",
    "FUSA_RNG15_RFL8_NIR8_DUAL"};

// Keys only the nested layout has at its top, and keys only the flat one has.
constexpr std::array<std::string_view, 7> kNestedKeys = {
    "sensor_info",      "beam_intrinsics", "config_params",     "lidar_data_format",
    "lidar_intrinsics", "imu_intrinsics",  "calibration_status"};
constexpr std::array<std::string_view, 6> kFlatKeys = {
    "beam_altitude_angles", "beam_azimuth_angles",       "data_format",
    "lidar_mode",           "lidar_to_sensor_transform", "lidar_origin_to_beam_origin_mm"};

// Firmware 1.x reported no data format: its gen-1 OS-1 defaults (16 columns a packet, the whole
// rotation, per 4 beams the pixel shifts 3, 2, 1, 0 times 3 columns at 512 columns a rotation).
constexpr int kDefaultColumnsPerPacket = 16;
// lidar_to_sensor_transform when absent (Ouster's documented default: 180 deg about z, 36.18 mm
// up).
constexpr std::array<double, 16> kDefaultLidarToSensor = {-1, 0, 0, 0,     0, -1, 0, 0,
                                                          0,  0, 1, 36.18, 0, 0,  0, 1};

class Reader {
 public:
  explicit Reader(std::string_view origin) : origin_(origin) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw MetadataError(origin_ + ": " + key + ": " + what);
  }

  const json& need(const json& obj, const std::string& path, const char* key) const {
    const auto it = obj.find(key);
    if (it == obj.end() || it->is_null()) fail(path + key, "missing");
    return *it;
  }
  const json* find(const json& obj, const char* key) const {
    const auto it = obj.find(key);
    return it == obj.end() || it->is_null() ? nullptr : &*it;
  }
  double number(const json& v, const std::string& key) const {
    if (!v.is_number()) fail(key, "not a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(key, "not finite");
    return d;
  }
  int integer(const json& v, const std::string& key, int lo, int hi) const {
    if (!v.is_number_integer() && !v.is_number_unsigned()) fail(key, "not an integer");
    const auto i = v.get<int64_t>();
    if (i < lo || i > hi) {
      fail(key,
           std::to_string(i) + " outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return static_cast<int>(i);
  }
  std::vector<double> numbers(const json& v, const std::string& key) const {
    if (!v.is_array()) fail(key, "not an array");
    std::vector<double> out;
    out.reserve(v.size());
    for (const json& e : v) out.push_back(number(e, key));
    return out;
  }
  std::string text(const json* v) const { return v && v->is_string() ? v->get<std::string>() : ""; }

 private:
  std::string origin_;
};

void parse_lidar_mode(const Reader& r, const json& v, const std::string& key, SensorInfo& s) {
  if (!v.is_string()) r.fail(key, "not a string");
  const auto m = v.get<std::string>();
  int cols = 0, rate = 0;
  char x = 0;
  std::istringstream in(m);
  if (!(in >> cols >> x >> rate) || x != 'x' || !in.eof())
    r.fail(key, "\"" + m + "\" is not COLUMNSxRATE");
  if (cols != 512 && cols != 1024 && cols != 2048 && cols != 4096)
    r.fail(key, "\"" + m + "\": columns not 512, 1024, 2048 or 4096");
  if (rate != 5 && rate != 10 && rate != 20) r.fail(key, "\"" + m + "\": rate not 5, 10 or 20");
  s.mode_columns = cols;
  s.mode_rate_hz = rate;
}

void parse_data_format(const Reader& r, const json& f, const std::string& p, SensorInfo& s) {
  s.data_format_reported = true;
  s.pixels_per_column =
      r.integer(r.need(f, p, "pixels_per_column"), p + "pixels_per_column", 1, 128);
  s.columns_per_packet =
      r.integer(r.need(f, p, "columns_per_packet"), p + "columns_per_packet", 1, 16);
  s.columns_per_frame =
      r.integer(r.need(f, p, "columns_per_frame"), p + "columns_per_frame", 1, 4096);
  if (const json* w = r.find(f, "column_window")) {
    if (!w->is_array() || w->size() != 2) r.fail(p + "column_window", "not [first, last]");
    for (size_t i = 0; i < 2; ++i)
      s.column_window[i] = r.integer((*w)[i], p + "column_window", 0, s.columns_per_frame - 1);
  } else {
    s.column_window = {0, s.columns_per_frame - 1};
  }
  const json& shift = r.need(f, p, "pixel_shift_by_row");
  if (!shift.is_array()) r.fail(p + "pixel_shift_by_row", "not an array");
  s.pixel_shift_by_row.clear();
  for (const json& e : shift)
    s.pixel_shift_by_row.push_back(
        r.integer(e, p + "pixel_shift_by_row", -s.columns_per_frame, s.columns_per_frame));
  if (const json* prof = r.find(f, "udp_profile_lidar")) {
    const auto name = r.text(prof);
    const auto known = profile_from_name(name);
    if (!known) r.fail(p + "udp_profile_lidar", "\"" + name + "\" is not a supported profile");
    s.profile = *known;
  }
}

// Firmware 1.x: no data format reported.
void default_data_format(SensorInfo& s) {
  s.data_format_reported = false;
  s.pixels_per_column = static_cast<int>(s.beam_altitude_deg.size());
  s.columns_per_packet = kDefaultColumnsPerPacket;
  s.columns_per_frame = s.mode_columns;
  s.column_window = {0, s.mode_columns - 1};
  s.pixel_shift_by_row.resize(static_cast<size_t>(s.pixels_per_column));
  const int step = 3 * s.mode_columns / 512;
  for (size_t i = 0; i < s.pixel_shift_by_row.size(); ++i)
    s.pixel_shift_by_row[i] = step * (3 - static_cast<int>(i % 4));
}

double default_origin_to_beam_mm(const std::string& prod_line) {
  // Ouster's documented defaults per product line (gen 1 otherwise).
  if (prod_line.rfind("OS-0-", 0) == 0) return 27.67;
  if (prod_line.rfind("OS-1-", 0) == 0) return 15.806;
  if (prod_line.rfind("OS-2-", 0) == 0) return 13.762;
  return 12.163;
}

void parse_beams(const Reader& r, const json& b, const std::string& p, SensorInfo& s) {
  s.beam_altitude_deg = r.numbers(r.need(b, p, "beam_altitude_angles"), p + "beam_altitude_angles");
  s.beam_azimuth_deg = r.numbers(r.need(b, p, "beam_azimuth_angles"), p + "beam_azimuth_angles");
  if (const json* n = r.find(b, "lidar_origin_to_beam_origin_mm")) {
    s.lidar_origin_to_beam_origin_mm = r.number(*n, p + "lidar_origin_to_beam_origin_mm");
  } else {
    s.lidar_origin_to_beam_origin_mm = default_origin_to_beam_mm(s.prod_line);
  }
}

void parse_transform(const Reader& r, const json* t, const std::string& key, SensorInfo& s) {
  if (!t) {
    s.lidar_to_sensor_transform = kDefaultLidarToSensor;
    return;
  }
  const auto v = r.numbers(*t, key);
  if (v.size() != 16) r.fail(key, std::to_string(v.size()) + " numbers, not 16");
  std::copy(v.begin(), v.end(), s.lidar_to_sensor_transform.begin());
}

void parse_identity(const Reader& r, const json& o, const std::string& p, SensorInfo& s) {
  s.prod_line = r.text(r.find(o, "prod_line"));
  s.firmware = r.text(r.find(o, "build_rev"));
  if (const json* sn = r.find(o, "prod_sn")) {
    const std::string t = sn->is_string() ? sn->get<std::string>() : sn->dump();
    if (!t.empty() && t.find_first_not_of("0123456789") == std::string::npos && t.size() <= 19) {
      s.serial_number = std::stoull(t);
    } else if (!t.empty()) {
      r.fail(p + "prod_sn", "\"" + t + "\" is not a serial number");
    }
  }
  if (const json* id = r.find(o, "initialization_id"))
    s.init_id = static_cast<uint32_t>(r.integer(*id, p + "initialization_id", 0, (1 << 24) - 1));
}

// Everything that must hold whatever the layout.
void validate(const Reader& r, SensorInfo& s, const std::string& beams, const std::string& fmt) {
  const size_t n = s.beam_altitude_deg.size();
  if (s.beam_azimuth_deg.size() != n) {
    r.fail(beams + "beam_azimuth_angles", std::to_string(s.beam_azimuth_deg.size()) +
                                              " entries for " + std::to_string(n) +
                                              " beam_altitude_angles");
  }
  if (n != 16 && n != 32 && n != 64 && n != 128)
    r.fail(beams + "beam_altitude_angles", std::to_string(n) + " beams, not 16, 32, 64 or 128");
  if (std::all_of(s.beam_altitude_deg.begin(), s.beam_altitude_deg.end(),
                  [](double a) { return a == 0.0; }))
    r.fail(beams + "beam_altitude_angles", "all zero: the sensor reported no calibration");
  for (double a : s.beam_altitude_deg)
    if (std::abs(a) > 90.0) r.fail(beams + "beam_altitude_angles", "an angle beyond +-90 deg");
  if (!s.data_format_reported) default_data_format(s);
  if (static_cast<size_t>(s.pixels_per_column) != n) {
    r.fail(fmt + "pixels_per_column",
           std::to_string(s.pixels_per_column) + " for " + std::to_string(n) + " beam angles");
  }
  if (s.pixel_shift_by_row.size() != n) {
    r.fail(fmt + "pixel_shift_by_row", std::to_string(s.pixel_shift_by_row.size()) +
                                           " entries for " + std::to_string(n) + " beams");
  }
  if (s.columns_per_frame != s.mode_columns) {
    r.fail(fmt + "columns_per_frame", std::to_string(s.columns_per_frame) +
                                          " contradicts the lidar mode's " +
                                          std::to_string(s.mode_columns));
  }
  if (s.columns_per_frame % s.columns_per_packet != 0) {
    r.fail(fmt + "columns_per_packet",
           std::to_string(s.columns_per_packet) + " does not divide columns_per_frame");
  }
  if (s.lidar_to_sensor_transform[15] != 1.0)
    r.fail("lidar_to_sensor_transform", "last element not 1: not a homogeneous transform");
}

SensorInfo parse_flat(const Reader& r, const json& root) {
  for (auto key : kNestedKeys)
    if (root.contains(key)) {
      r.fail(std::string(key),
             "a key of the nested layout in a flat (firmware <= 2.x) file: "
             "layouts mixed");
    }
  SensorInfo s;
  s.nested_layout = false;
  parse_identity(r, root, "", s);
  parse_beams(r, root, "", s);
  parse_lidar_mode(r, r.need(root, "", "lidar_mode"), "lidar_mode", s);
  parse_transform(r, r.find(root, "lidar_to_sensor_transform"), "lidar_to_sensor_transform", s);
  if (const json* f = r.find(root, "data_format")) {
    if (!f->is_object()) r.fail("data_format", "not an object");
    parse_data_format(r, *f, "data_format.", s);
  }
  validate(r, s, "", "data_format.");
  return s;
}

SensorInfo parse_nested(const Reader& r, const json& root) {
  for (auto key : kFlatKeys)
    if (root.contains(key)) {
      r.fail(std::string(key),
             "a key of the flat (firmware <= 2.x) layout in a nested file: "
             "layouts mixed");
    }
  SensorInfo s;
  s.nested_layout = true;
  const json& info = r.need(root, "", "sensor_info");
  if (!info.is_object()) r.fail("sensor_info", "not an object");
  parse_identity(r, info, "sensor_info.", s);
  // The sensor's calibration reference: firmware 1.x answered it with an error string.
  r.need(root, "", "calibration_status");
  const json& beams = r.need(root, "", "beam_intrinsics");
  if (!beams.is_object()) r.fail("beam_intrinsics", "not an object");
  parse_beams(r, beams, "beam_intrinsics.", s);
  const json& config = r.need(root, "", "config_params");
  if (!config.is_object()) r.fail("config_params", "not an object");
  parse_lidar_mode(r, r.need(config, "config_params.", "lidar_mode"), "config_params.lidar_mode",
                   s);
  const json* intr = r.find(root, "lidar_intrinsics");
  parse_transform(r,
                  intr && intr->is_object() ? r.find(*intr, "lidar_to_sensor_transform") : nullptr,
                  "lidar_intrinsics.lidar_to_sensor_transform", s);
  // Firmware 1.x reported the data format as an error string: its defaults then.
  const json& f = r.need(root, "", "lidar_data_format");
  if (f.is_object()) {
    parse_data_format(r, f, "lidar_data_format.", s);
  } else if (!f.is_string()) {
    r.fail("lidar_data_format", "not an object");
  }
  validate(r, s, "beam_intrinsics.", "lidar_data_format.");
  return s;
}

}  // namespace

std::string_view profile_name(Profile p) {
  return kProfileNames[static_cast<size_t>(p)];
}

std::optional<Profile> profile_from_name(std::string_view name) {
  // Firmware spells some profiles with a PROFILE_ prefix in places.
  if (name.rfind("PROFILE_", 0) == 0) name.remove_prefix(8);
  for (size_t i = 0; i < kProfileNames.size(); ++i)
    if (kProfileNames[i] == name) return static_cast<Profile>(i);
  return std::nullopt;
}

SensorInfo parse_metadata(std::string_view json_text, std::string_view origin) {
  const Reader r(origin);
  json root;
  try {
    root = json::parse(json_text.begin(), json_text.end());
  } catch (const json::parse_error& e) {
    throw MetadataError(std::string(origin) + ": not JSON: " + e.what());
  }
  if (!root.is_object()) throw MetadataError(std::string(origin) + ": not a JSON object");
  try {
    if (root.contains("beam_intrinsics")) return parse_nested(r, root);
    if (root.contains("beam_altitude_angles")) return parse_flat(r, root);
  } catch (const json::exception& e) {
    // Only the checks above read the tree; a type they did not expect is still the file's fault.
    throw MetadataError(std::string(origin) + ": " + e.what());
  }
  throw MetadataError(std::string(origin) +
                      ": neither beam_intrinsics (nested layout) nor beam_altitude_angles (flat "
                      "layout): not an Ouster sensor's metadata");
}

SensorInfo load_metadata(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw MetadataError(path + ": cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw MetadataError(path + ": read error");
  return parse_metadata(text.str(), path);
}

}  // namespace lidartag::driver::ouster
