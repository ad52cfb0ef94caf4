// Test-only packet streams: a sensor spinning at a given rpm, encoded with the project's encoder.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::velodyne::testing {

struct StreamPacket {
  std::vector<uint8_t> bytes;
  int64_t time_ns;  // capture time = firing time of the first column
};

// Distance (in units) and intensity of the synthetic world, a function of laser and column so
// tests can predict every cell. Distance 0 (no return) for some cells.
inline uint16_t synthetic_distance(int laser, long column) {
  if ((laser * 7 + column) % 53 == 0) return 0;
  return static_cast<uint16_t>(1000 + (laser * 131 + column * 17) % 4000);
}
inline uint8_t synthetic_intensity(int laser, long column) {
  return static_cast<uint8_t>((laser * 7 + column * 3) % 256);
}

struct StreamOptions {
  double rpm = 600.0;
  double start_azimuth_deg = 10.0;
  int64_t start_ns = 1'700'000'000'000'000'000LL;  // an absolute time, ns since epoch
  bool dual_differs = true;  // dual mode: second echo differs from the last (else identical)
};

// Packets covering `packets` consecutive packets of the stream. Column k fires at
// start + k * firing period, at azimuth start + rate * t (wrapped), quantised to 0.01 deg.
inline std::vector<StreamPacket> make_stream(const ModelSpec& spec, ReturnMode mode, int packets,
                                             const StreamOptions& o = {}) {
  const int per_packet = spec.columns_per_packet(mode);
  const double rate = o.rpm * 360.0 / 60e6;  // deg per us
  std::vector<StreamPacket> out;
  std::vector<FiringColumn> cols(static_cast<size_t>(per_packet));
  for (int p = 0; p < packets; ++p) {
    for (int c = 0; c < per_packet; ++c) {
      const long k = static_cast<long>(p) * per_packet + c;
      const double t_us = static_cast<double>(k) * spec.firing_period_us;
      double az = std::fmod(o.start_azimuth_deg + rate * t_us, 360.0);
      auto& col = cols[static_cast<size_t>(c)];
      col.azimuth_centideg = static_cast<uint16_t>(std::lround(az * 100.0) % 36000);
      for (int l = 0; l < spec.lasers; ++l) {
        const auto ul = static_cast<size_t>(l);
        col.echo[0].distance[ul] = synthetic_distance(l, k);
        col.echo[0].intensity[ul] = synthetic_intensity(l, k);
        if (o.dual_differs) {
          col.echo[1].distance[ul] = static_cast<uint16_t>(synthetic_distance(l, k) / 2);
          col.echo[1].intensity[ul] = static_cast<uint8_t>(synthetic_intensity(l, k) ^ 0x55);
        } else {
          col.echo[1] = col.echo[0];
        }
      }
    }
    StreamPacket sp;
    sp.bytes.resize(kDataPacketSize);
    const double t0_us = static_cast<double>(p) * per_packet * spec.firing_period_us;
    sp.time_ns = o.start_ns + static_cast<int64_t>(std::llround(t0_us * 1e3));
    const auto usec = static_cast<uint32_t>((sp.time_ns / 1000) % 3'600'000'000LL);
    encode_data_packet(spec, mode, cols, usec, std::span<uint8_t, kDataPacketSize>(sp.bytes));
    out.push_back(std::move(sp));
  }
  return out;
}

}  // namespace lidartag::velodyne::testing
