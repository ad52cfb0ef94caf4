#include "lidartag/driver/ouster/encoder.hpp"

#include <algorithm>
#include <cstring>

namespace lidartag::driver::ouster {
namespace {

void write_le(uint8_t* p, uint64_t v, size_t n) {
  for (size_t i = 0; i < n; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

void put(uint8_t* pixel, const ProfileSpec& spec, Field field, uint32_t value) {
  if (const FieldSpec* f = find_field(spec, field)) put_field(pixel, *f, value);
}

}  // namespace

void put_field(uint8_t* pixel, const FieldSpec& f, uint32_t value) {
  const uint64_t mask = f.bits >= 64 ? ~0ull : (1ull << f.bits) - 1ull;
  const uint64_t v = (static_cast<uint64_t>(value) >> f.upshift) & mask;
  const size_t first = f.bit / 8u;
  const unsigned shift = f.bit % 8u;
  const size_t bytes = (shift + f.bits + 7u) / 8u;
  uint64_t word = read_le(pixel + first, bytes);
  word = (word & ~(mask << shift)) | (v << shift);
  write_le(pixel + first, word, bytes);
}

bool encode_lidar_packet(const PacketFormat& format, const PacketHeader& header,
                         int columns_per_frame, std::span<const ColumnPixels> columns,
                         std::span<uint8_t> out) {
  if (out.size() != format.packet_bytes || columns.size() != static_cast<size_t>(format.columns) ||
      format.pixels > kMaxPixels || columns_per_frame < 1)
    return false;
  uint8_t* p = out.data();
  std::memset(p, 0, out.size());
  const ProfileSpec& spec = *format.spec;
  const bool legacy = format.profile == Profile::kLegacy;
  if (spec.fusa_header) {
    // type(1) init id(3) frame id(4) alert flags(1) reserved(2) serial number(5)
    p[0] = static_cast<uint8_t>(header.packet_type);
    write_le(p + 1, header.init_id, 3);
    write_le(p + 4, header.frame_id, 4);
    write_le(p + 11, header.serial_number, 5);
  } else if (!legacy) {
    // type(2) frame id(2) init id(3) serial number(5)
    write_le(p, header.packet_type, 2);
    write_le(p + 2, header.frame_id, 2);
    write_le(p + 4, header.init_id, 3);
    write_le(p + 7, header.serial_number, 5);
  }
  for (int c = 0; c < format.columns; ++c) {
    const ColumnPixels& in = columns[static_cast<size_t>(c)];
    uint8_t* col = p + format.header_bytes + static_cast<size_t>(c) * format.column_bytes;
    write_le(col, in.timestamp_ns, 8);
    write_le(col + 8, in.measurement_id, 2);
    if (legacy) {
      write_le(col + 10, header.frame_id & 0xffffu, 2);
      const uint64_t counts =
          uint64_t(in.measurement_id) * kEncoderCountsPerTurn / uint64_t(columns_per_frame);
      write_le(col + 12, counts, 4);
      write_le(col + format.column_bytes - 4, in.valid ? 0xffffffffu : 0u, 4);
    } else {
      write_le(col + 10, in.valid ? 1u : 0u, 2);
    }
    if (!in.valid) continue;
    for (int row = 0; row < format.pixels; ++row) {
      const auto r = static_cast<size_t>(row);
      uint8_t* px = col + format.column_header_bytes + r * static_cast<size_t>(spec.pixel_bytes);
      put(px, spec, Field::kRange, in.range_mm[r]);
      put(px, spec, Field::kReflectivity, in.reflectivity[r]);
      put(px, spec, Field::kSignal, in.signal[r]);
      put(px, spec, Field::kNearIr, in.near_ir[r]);
      if (spec.returns == 2) {
        put(px, spec, Field::kRange2, in.range2_mm[r]);
        put(px, spec, Field::kReflectivity2, in.reflectivity2[r]);
        put(px, spec, Field::kSignal2, in.signal2[r]);
      }
    }
  }
  return true;
}

}  // namespace lidartag::driver::ouster
