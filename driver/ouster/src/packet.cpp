#include "lidartag/driver/ouster/packet.hpp"

namespace lidartag::driver::ouster {
namespace {

using F = Field;
using T = FieldType;

// The profiles' pixels (Ouster's "Lidar Data Format"): bit offset and width of each field, the
// upshift of truncated ones, and the integer type the field is kept in.
// LEGACY, 12 bytes: range 20 bits, flags in the word's top 4 bits, reflectivity (8 bits of a
// 16-bit slot), signal, near-IR, 2 bytes unused.
constexpr std::array<FieldSpec, 8> kLegacyFields = {{
    {F::kRange, 0, 20, 0, T::kU32},
    {F::kFlags, 28, 4, 0, T::kU8},
    {F::kReflectivity, 32, 8, 0, T::kU8},
    {F::kSignal, 48, 16, 0, T::kU16},
    {F::kNearIr, 64, 16, 0, T::kU16},
    {F::kRaw32Word1, 0, 32, 0, T::kU32},
    {F::kRaw32Word2, 32, 32, 0, T::kU32},
    {F::kRaw32Word3, 64, 32, 0, T::kU32},
}};
// RNG19_RFL8_SIG16_NIR16, 12 bytes.
constexpr std::array<FieldSpec, 8> kSingleFields = {{
    {F::kRange, 0, 19, 0, T::kU32},
    {F::kFlags, 19, 5, 0, T::kU8},
    {F::kReflectivity, 32, 8, 0, T::kU8},
    {F::kSignal, 48, 16, 0, T::kU16},
    {F::kNearIr, 64, 16, 0, T::kU16},
    {F::kRaw32Word1, 0, 32, 0, T::kU32},
    {F::kRaw32Word2, 32, 32, 0, T::kU32},
    {F::kRaw32Word3, 64, 32, 0, T::kU32},
}};
// RNG19_RFL8_SIG16_NIR16_DUAL, 16 bytes.
constexpr std::array<FieldSpec, 13> kDualFields = {{
    {F::kRange, 0, 19, 0, T::kU32},
    {F::kFlags, 19, 5, 0, T::kU8},
    {F::kReflectivity, 24, 8, 0, T::kU8},
    {F::kRange2, 32, 19, 0, T::kU32},
    {F::kFlags2, 51, 5, 0, T::kU8},
    {F::kReflectivity2, 56, 8, 0, T::kU8},
    {F::kSignal, 64, 16, 0, T::kU16},
    {F::kSignal2, 80, 16, 0, T::kU16},
    {F::kNearIr, 96, 16, 0, T::kU16},
    {F::kRaw32Word1, 0, 32, 0, T::kU32},
    {F::kRaw32Word2, 32, 32, 0, T::kU32},
    {F::kRaw32Word3, 64, 32, 0, T::kU32},
    {F::kRaw32Word4, 96, 32, 0, T::kU32},
}};
// RNG15_RFL8_NIR8 (low bandwidth), 4 bytes: range in 8 mm units, near-IR in units of 16.
constexpr std::array<FieldSpec, 5> kLowBandwidthFields = {{
    {F::kRange, 0, 15, 3, T::kU32},
    {F::kFlags, 15, 1, 0, T::kU8},
    {F::kReflectivity, 16, 8, 0, T::kU8},
    {F::kNearIr, 24, 8, 4, T::kU16},
    {F::kRaw32Word1, 0, 32, 0, T::kU32},
}};
// FUSA_RNG15_RFL8_NIR8_DUAL, 8 bytes (the last byte: the window field, not decoded).
constexpr std::array<FieldSpec, 9> kFusaDualFields = {{
    {F::kRange, 0, 15, 3, T::kU32},
    {F::kFlags, 15, 1, 0, T::kU8},
    {F::kReflectivity, 16, 8, 0, T::kU8},
    {F::kNearIr, 24, 8, 4, T::kU16},
    {F::kRange2, 32, 15, 3, T::kU32},
    {F::kFlags2, 47, 1, 0, T::kU8},
    {F::kReflectivity2, 48, 8, 0, T::kU8},
    {F::kRaw32Word1, 0, 32, 0, T::kU32},
    {F::kRaw32Word2, 32, 32, 0, T::kU32},
}};

// Indexed by Profile.
const std::array<ProfileSpec, 5> kProfiles = {{
    {Profile::kLegacy, 12, 1, false, kLegacyFields},
    {Profile::kRng19Rfl8Sig16Nir16, 12, 1, false, kSingleFields},
    {Profile::kRng19Rfl8Sig16Nir16Dual, 16, 2, false, kDualFields},
    {Profile::kRng15Rfl8Nir8, 4, 1, false, kLowBandwidthFields},
    {Profile::kFusaRng15Rfl8Nir8Dual, 8, 2, true, kFusaDualFields},
}};

constexpr std::array<std::string_view, kFieldCount> kFieldNames = {
    "RANGE",       "FLAGS",       "REFLECTIVITY",  "SIGNAL",  "NEAR_IR",
    "RANGE2",      "FLAGS2",      "REFLECTIVITY2", "SIGNAL2", "RAW32_WORD1",
    "RAW32_WORD2", "RAW32_WORD3", "RAW32_WORD4"};

}  // namespace

std::string_view field_name(Field f) {
  return kFieldNames[static_cast<size_t>(f)];
}

const ProfileSpec& profile_spec(Profile p) {
  return kProfiles[static_cast<size_t>(p)];
}

const FieldSpec* find_field(const ProfileSpec& spec, Field f) {
  for (const FieldSpec& s : spec.fields)
    if (s.field == f) return &s;
  return nullptr;
}

PacketFormat PacketFormat::of(const SensorInfo& info) {
  PacketFormat f;
  f.profile = info.profile;
  f.spec = &profile_spec(info.profile);
  f.pixels = info.pixels_per_column;
  f.columns = info.columns_per_packet;
  const bool legacy = info.profile == Profile::kLegacy;
  // LEGACY: per column timestamp(8) measurement id(2) frame id(2) encoder count(4), the pixels,
  // status(4). Others: a 32-byte packet header, per column timestamp(8) measurement id(2)
  // status(2), the pixels, a 32-byte packet footer.
  f.header_bytes = legacy ? 0 : 32;
  f.column_header_bytes = legacy ? 16 : 12;
  f.column_footer_bytes = legacy ? 4 : 0;
  f.footer_bytes = legacy ? 0 : 32;
  f.column_bytes = f.column_header_bytes +
                   static_cast<size_t>(f.pixels) * static_cast<size_t>(f.spec->pixel_bytes) +
                   f.column_footer_bytes;
  f.packet_bytes =
      f.header_bytes + static_cast<size_t>(f.columns) * f.column_bytes + f.footer_bytes;
  f.frame_id_bits = f.spec->fusa_header ? 32 : 16;
  return f;
}

PacketHeader read_packet_header(const uint8_t* payload, const PacketFormat& format) {
  PacketHeader h;
  if (format.profile == Profile::kLegacy) {
    h.frame_id = static_cast<uint32_t>(read_le(payload + 10, 2));
  } else if (format.spec->fusa_header) {
    // type(1) init id(3) frame id(4) alert flags(1) reserved(2) serial number(5)
    h.packet_type = static_cast<uint16_t>(payload[0]);
    h.init_id = static_cast<uint32_t>(read_le(payload + 1, 3));
    h.frame_id = static_cast<uint32_t>(read_le(payload + 4, 4));
    h.serial_number = read_le(payload + 11, 5);
  } else {
    // type(2) frame id(2) init id(3) serial number(5)
    h.packet_type = static_cast<uint16_t>(read_le(payload, 2));
    h.frame_id = static_cast<uint32_t>(read_le(payload + 2, 2));
    h.init_id = static_cast<uint32_t>(read_le(payload + 4, 3));
    h.serial_number = read_le(payload + 7, 5);
  }
  return h;
}

ColumnHeader read_column_header(const uint8_t* payload, const PacketFormat& format, int c) {
  const uint8_t* col = format.column(payload, c);
  ColumnHeader h;
  h.timestamp_ns = read_le(col, 8);
  h.measurement_id = static_cast<uint16_t>(read_le(col + 8, 2));
  if (format.profile == Profile::kLegacy) {
    h.frame_id = static_cast<uint16_t>(read_le(col + 10, 2));
    h.encoder_count = static_cast<uint32_t>(read_le(col + 12, 4));
    h.status = static_cast<uint32_t>(read_le(col + format.column_bytes - 4, 4));
  } else {
    h.status = static_cast<uint32_t>(read_le(col + 10, 2));
  }
  return h;
}

}  // namespace lidartag::driver::ouster
