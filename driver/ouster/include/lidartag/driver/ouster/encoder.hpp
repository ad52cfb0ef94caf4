// The inverse of the decoder: columns of pixel values -> the bytes of an Ouster lidar packet, for
// every profile of packet.hpp (the simulator's captures and the round-trip tests). Pure: no I/O;
// encode_lidar_packet() never throws or allocates.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/ouster/packet.hpp"

namespace lidartag::driver::ouster {

inline constexpr int kMaxPixels = 128;
// LEGACY column headers carry the encoder count: 90112 counts per turn.
inline constexpr uint32_t kEncoderCountsPerTurn = 90112;

// One column to encode. Per pixel row (the sensor's beam order, not rings). Fields the profile
// lacks are ignored; values wider than a field are truncated to it (range: after its upshift,
// RNG15 keeps range / 8 mm).
struct ColumnPixels {
  uint64_t timestamp_ns = 0;
  uint16_t measurement_id = 0;
  bool valid = true;  // the status bit; an invalid column's pixels are written as zeros
  std::array<uint32_t, kMaxPixels> range_mm{};  // 0: no return
  std::array<uint8_t, kMaxPixels> reflectivity{};
  std::array<uint16_t, kMaxPixels> signal{};
  std::array<uint16_t, kMaxPixels> near_ir{};
  // The second return of the dual profiles.
  std::array<uint32_t, kMaxPixels> range2_mm{};
  std::array<uint8_t, kMaxPixels> reflectivity2{};
  std::array<uint16_t, kMaxPixels> signal2{};
};

// Writes `value` into the field's bits of the pixel at `pixel` (the inverse of field_value()).
void put_field(uint8_t* pixel, const FieldSpec& f, uint32_t value);

// Encodes one packet of format.columns columns into `out` (format.packet_bytes long): the packet
// header from `header` (its packet type, frame id, init id, serial number; LEGACY: the frame id
// goes to every column header), the columns, a zero footer. False, `out` untouched, when `out` or
// `columns` has the wrong size.
[[nodiscard]] bool encode_lidar_packet(const PacketFormat& format, const PacketHeader& header,
                                       int columns_per_frame, std::span<const ColumnPixels> columns,
                                       std::span<uint8_t> out);

}  // namespace lidartag::driver::ouster
