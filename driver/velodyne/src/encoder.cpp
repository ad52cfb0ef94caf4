#include "lidartag/driver/velodyne/encoder.hpp"

#include <algorithm>

namespace lidartag::velodyne {

void encode_data_packet(const ModelSpec& spec, ReturnMode mode,
                        std::span<const FiringColumn> columns, uint32_t usec_since_hour,
                        std::span<uint8_t, kDataPacketSize> out) {
  std::fill(out.begin(), out.end(), uint8_t{0});
  uint8_t* p = out.data();
  const bool dual = mode == ReturnMode::kDual;
  const bool banked = spec.blocks_per_firing > 1;
  const int group_blocks = spec.blocks_per_firing * (dual ? 2 : 1);
  const int groups = banked && dual ? 1 : 12 / group_blocks;
  const int fpb = spec.firings_per_block;
  const int lasers_per_firing = 32 / fpb;
  const size_t needed = static_cast<size_t>(groups * fpb);
  if (columns.size() < needed) return;  // caller error: leave an all-zero (invalid) packet

  for (int g = 0; g < groups; ++g) {
    const FiringColumn& first = columns[static_cast<size_t>(g * fpb)];
    for (int i = 0; i < group_blocks; ++i) {
      const int b = g * group_blocks + i;
      // Banked (VLS-128): single = banks 0..3; dual = (bank k last, bank k strongest) pairs.
      const int bank = banked ? (dual ? i / 2 : i) : 0;
      const int echo = dual ? (i & 1) : 0;
      uint8_t* blk = p + static_cast<size_t>(b) * kBlockSize;
      write_u16(blk, kBankFlags[static_cast<size_t>(bank)]);
      write_u16(blk + 2, first.azimuth_centideg);
      for (int f = 0; f < fpb; ++f) {
        const FiringColumn::Echo& e =
            columns[static_cast<size_t>(g * fpb + f)].echo[static_cast<size_t>(echo)];
        for (int j = 0; j < lasers_per_firing; ++j) {
          const auto laser = static_cast<size_t>(bank * 32 + j);
          uint8_t* cell = blk + 4 + static_cast<size_t>(f * lasers_per_firing + j) * 3;
          write_u16(cell, e.distance[laser]);
          cell[2] = e.intensity[laser];
        }
      }
    }
  }
  write_u32(p + kTimestampOffset, usec_since_hour);
  p[kReturnModeOffset] = static_cast<uint8_t>(mode);
  p[kProductIdOffset] = spec.product_id;
}

void encode_position_packet(uint32_t usec_since_hour, PpsStatus pps, std::string_view nmea,
                            std::span<uint8_t, kPositionPacketSize> out) {
  std::fill(out.begin(), out.end(), uint8_t{0});
  write_u32(out.data() + kPositionTimestampOffset, usec_since_hour);
  out[kPpsStatusOffset] = static_cast<uint8_t>(pps);
  const size_t n = std::min(nmea.size(), kNmeaMaxLength);
  std::copy_n(nmea.begin(), n, out.begin() + static_cast<long>(kNmeaOffset));
}

}  // namespace lidartag::velodyne
