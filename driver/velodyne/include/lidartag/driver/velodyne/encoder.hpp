// Points -> Velodyne packets: the inverse of the decoder. Used by the simulator and by the
// round-trip tests; writes exactly the bytes a sensor of that model sends.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::velodyne {

// One firing sequence of all lasers, in laser (channel) order. In dual mode `echo[0]` is the last
// return (written to the even block) and `echo[1]` the strongest or second strongest (odd block);
// in single modes only echo[0] is used. distance is in the model's distance units (0 = none).
struct FiringColumn {
  uint16_t azimuth_centideg = 0;  // azimuth of the firing, 0..35999
  struct Echo {
    std::array<uint16_t, 128> distance{};
    std::array<uint8_t, 128> intensity{};
  };
  std::array<Echo, 2> echo{};
};

// Writes one data packet from exactly spec.columns_per_packet(mode) columns. Where a block holds
// two firings (VLP-16) the block carries the first firing's azimuth, as the sensor does.
void encode_data_packet(const ModelSpec& spec, ReturnMode mode,
                        std::span<const FiringColumn> columns, uint32_t usec_since_hour,
                        std::span<uint8_t, kDataPacketSize> out);

// Writes a position packet with the given counter, PPS state and NMEA sentence (truncated to 128).
void encode_position_packet(uint32_t usec_since_hour, PpsStatus pps, std::string_view nmea,
                            std::span<uint8_t, kPositionPacketSize> out);

}  // namespace lidartag::velodyne
