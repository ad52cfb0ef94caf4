// An Ouster sensor's metadata (the JSON it reports, docs/ouster.md) in one plain struct: beam
// intrinsics, lidar mode, the packets' data format and the identity the packets carry. Both layouts
// are read: the flat one of firmware <= 2.x (`beam_altitude_angles`, `data_format`, ... at the top)
// and the nested one of newer firmware (`sensor_info`, `beam_intrinsics`, `config_params`,
// `lidar_data_format`, `calibration_status`, ...). Setup code: a file that cannot describe a
// sensor is refused with MetadataError naming the key.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::driver::ouster {

// The lidar packets' layout (metadata `udp_profile_lidar`; absent: kLegacy).
enum class Profile : uint8_t {
  kLegacy = 0,
  kRng19Rfl8Sig16Nir16 = 1,
  kRng19Rfl8Sig16Nir16Dual = 2,
  kRng15Rfl8Nir8 = 3,
  kFusaRng15Rfl8Nir8Dual = 4,
};
std::string_view profile_name(Profile p);
std::optional<Profile> profile_from_name(std::string_view name);

// A metadata file that cannot describe a sensor; what() names the file's key at fault.
class MetadataError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SensorInfo {
  // Identity. serial_number and init_id: 0 when the file does not say (then not checked against
  // the packets).
  std::string prod_line;       // e.g. "OS-1-128"
  std::string firmware;        // build_rev, e.g. "v2.3.0"
  uint64_t serial_number = 0;  // prod_sn
  uint32_t init_id = 0;        // initialization_id (24 bits on the wire)
  bool nested_layout = false;  // the file's layout: nested (newer firmware) or flat

  // Beam intrinsics, per beam (pixel row) in the sensor's order: degrees; altitude + up, azimuth
  // the beam's offset from the encoder angle, + clockwise seen from above (the published
  // formula's theta_azimuth is minus it).
  std::vector<double> beam_altitude_deg;
  std::vector<double> beam_azimuth_deg;
  double lidar_origin_to_beam_origin_mm = 0;  // n of the published range-to-xyz formula
  // Row-major 4x4, translation in mm: lidar frame -> sensor frame.
  std::array<double, 16> lidar_to_sensor_transform{};

  // Lidar mode: columns per rotation x rotations per second ("1024x10").
  int mode_columns = 0;
  int mode_rate_hz = 0;

  // Data format.
  int pixels_per_column = 0;            // beams in a packet's column (16, 32, 64, 128)
  int columns_per_packet = 0;           // 16 by default
  int columns_per_frame = 0;            // = mode_columns
  std::array<int, 2> column_window{};   // first and last measurement id sent (inclusive)
  std::vector<int> pixel_shift_by_row;  // per row: destaggered column = column + shift
  Profile profile = Profile::kLegacy;
  bool data_format_reported = false;  // false: firmware 1.x, the defaults of that firmware

  int returns() const {
    return profile == Profile::kRng19Rfl8Sig16Nir16Dual ||
                   profile == Profile::kFusaRng15Rfl8Nir8Dual
               ? 2
               : 1;
  }
  // Time of one column (a measurement id), microseconds.
  double column_period_us() const { return 1e6 / (double(mode_rate_hz) * mode_columns); }
};

// Parses metadata JSON text; `origin` names it in messages (a file name). Throws MetadataError.
SensorInfo parse_metadata(std::string_view json_text, std::string_view origin = "metadata");
// Reads and parses a metadata file. Throws MetadataError (also when it cannot be read).
SensorInfo load_metadata(const std::string& path);

// The JSON a sensor reports for `info`, in the layout info.nested_layout names (nested: the keys
// of newer firmware; flat: those of firmware <= 2.x with `data_format`): what parse_metadata()
// reads back to the same SensorInfo. Identity keys left 0 or empty are left out.
std::string metadata_to_json(const SensorInfo& info);
// Writes metadata_to_json() to `path` (2-space indent). Throws MetadataError when it cannot.
void write_metadata(const SensorInfo& info, const std::string& path);

}  // namespace lidartag::driver::ouster
