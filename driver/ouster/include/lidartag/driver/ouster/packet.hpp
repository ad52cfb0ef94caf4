// Ouster lidar packet layouts (docs/ouster.md; Ouster's "Lidar Data Format"): the profiles as
// data, the packet's size from the metadata, and pure readers of its headers and pixel fields.
// Little-endian on the wire. Nothing here throws, allocates or reads outside the payload given.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "lidartag/driver/ouster/metadata.hpp"

namespace lidartag::driver::ouster {

inline constexpr uint16_t kLidarPort = 7502;  // the sensor's default UDP ports
inline constexpr uint16_t kImuPort = 7503;
inline constexpr size_t kImuPacketSize = 48;  // LEGACY IMU profile
inline constexpr uint16_t kLidarPacketType = 0x1;

// A channel field of a pixel.
enum class Field : uint8_t {
  kRange,         // mm
  kFlags,         // per-return flags (profile-specific bits)
  kReflectivity,  // calibrated reflectivity, 0..255
  kSignal,        // signal photons
  kNearIr,        // ambient (near-infrared) photons
  kRange2,        // second return
  kFlags2,
  kReflectivity2,
  kSignal2,
  kRaw32Word1,  // the pixel's raw 32-bit words
  kRaw32Word2,
  kRaw32Word3,
  kRaw32Word4,
};
inline constexpr int kFieldCount = 13;
std::string_view field_name(Field f);  // Ouster's name: "RANGE", "NEAR_IR", "RAW32_WORD1", ...

// Bytes of an integer field (u8, u16, u32): the type the field is kept in.
enum class FieldType : uint8_t { kU8 = 1, kU16 = 2, kU32 = 4 };

// Where a field lies in a pixel: `bits` bits from bit `bit` (little-endian bit numbering across the
// pixel's bytes), then shifted up by `upshift` (RNG15's range counts 8 mm units: upshift 3).
struct FieldSpec {
  Field field;
  uint16_t bit;
  uint8_t bits;
  uint8_t upshift;
  FieldType type;
};

struct ProfileSpec {
  Profile profile;
  int pixel_bytes;   // channel data block of one pixel
  int returns;       // 2 for the dual profiles
  bool fusa_header;  // the FUSA packet header (8-bit type, 32-bit frame id)
  std::span<const FieldSpec> fields;
};
const ProfileSpec& profile_spec(Profile p);
// The field's spec in this profile; nullptr when the profile has no such field.
const FieldSpec* find_field(const ProfileSpec& spec, Field f);

// The byte layout of one sensor's lidar packets, from its metadata.
struct PacketFormat {
  Profile profile = Profile::kLegacy;
  const ProfileSpec* spec = nullptr;
  int pixels = 0;           // pixels (beams) per column
  int columns = 0;          // columns per packet
  size_t header_bytes = 0;  // packet header (0 in LEGACY)
  size_t column_header_bytes = 0;
  size_t column_footer_bytes = 0;  // LEGACY: the column's status word
  size_t footer_bytes = 0;         // packet footer (0 in LEGACY)
  size_t column_bytes = 0;
  size_t packet_bytes = 0;
  int frame_id_bits = 16;  // FUSA: 32

  static PacketFormat of(const SensorInfo& info);
  const uint8_t* column(const uint8_t* payload, int c) const {
    return payload + header_bytes + static_cast<size_t>(c) * column_bytes;
  }
  const uint8_t* pixel(const uint8_t* payload, int c, int row) const {
    return column(payload, c) + column_header_bytes +
           static_cast<size_t>(row) * static_cast<size_t>(spec->pixel_bytes);
  }
};

// The packet header (LEGACY has none: its frame id is the first column's, the rest 0).
struct PacketHeader {
  uint16_t packet_type = 0;
  uint32_t frame_id = 0;
  uint32_t init_id = 0;
  uint64_t serial_number = 0;
};

// A column header (LEGACY: its frame id and encoder count too, its status at the column's end).
struct ColumnHeader {
  uint64_t timestamp_ns = 0;
  uint16_t measurement_id = 0;
  uint32_t status = 0;         // bit 0: the column is valid
  uint16_t frame_id = 0;       // LEGACY only, else 0
  uint32_t encoder_count = 0;  // LEGACY only, else 0
  bool valid() const { return (status & 1u) != 0; }
};

// Little-endian integer of `n` bytes.
inline uint64_t read_le(const uint8_t* p, size_t n) {
  uint64_t v = 0;
  for (size_t i = 0; i < n; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

// The field's value in the pixel at `pixel` (reads only the bytes the field spans).
inline uint32_t field_value(const uint8_t* pixel, const FieldSpec& f) {
  const size_t first = f.bit / 8u;
  const unsigned shift = f.bit % 8u;
  const size_t bytes = (shift + f.bits + 7u) / 8u;
  const uint64_t word = read_le(pixel + first, bytes) >> shift;
  const uint64_t mask = f.bits >= 64 ? ~0ull : (1ull << f.bits) - 1ull;
  return static_cast<uint32_t>((word & mask) << f.upshift);
}

// Reads the packet header; the payload must be format.packet_bytes long (the caller checks).
PacketHeader read_packet_header(const uint8_t* payload, const PacketFormat& format);
ColumnHeader read_column_header(const uint8_t* payload, const PacketFormat& format, int c);

}  // namespace lidartag::driver::ouster
