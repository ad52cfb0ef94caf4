// Columns -> the UDP payloads a sensor sends: data packets of exactly columns_per_packet columns
// stamped with the first firing's microseconds since the hour, and optional position packets
// ($GPRMC, PPS locked) at their own rate, all in capture-time order.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>

#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::sim {

// Receives each payload with its capture time (ns since the epoch) and UDP destination port.
using PacketCallback =
    std::function<void(std::span<const uint8_t> payload, int64_t time_ns, uint16_t port)>;

// Microseconds since the top of the hour of an absolute time.
uint32_t usec_since_hour(int64_t time_ns);
// "$GPRMC,hhmmss,A,...,ddmmyy,,,A*CS" for the whole second at or before `time_ns`.
std::string gprmc_sentence(int64_t time_ns);

class Packetizer {
 public:
  // position_rate_hz <= 0: no position packets.
  Packetizer(const velodyne::ModelSpec& spec, velodyne::ReturnMode mode, int64_t start_ns,
             double position_rate_hz, PacketCallback emit);

  // Adds the next column, fired at `first_firing_ns`; a full packet is emitted at once, stamped
  // with its first column's time and captured when its last firing sequence ends.
  void add(const velodyne::FiringColumn& column, int64_t first_firing_ns);

  uint64_t data_packets() const { return data_packets_; }
  uint64_t position_packets() const { return position_packets_; }
  int columns_per_packet() const { return columns_per_packet_; }

 private:
  void emit_position_until(int64_t time_ns);

  const velodyne::ModelSpec& spec_;
  velodyne::ReturnMode mode_;
  int64_t start_ns_;
  double position_rate_hz_;
  PacketCallback emit_;
  int columns_per_packet_;
  int64_t column_period_ns_;
  std::array<velodyne::FiringColumn, 24> columns_{};
  int pending_ = 0;
  int64_t packet_start_ns_ = 0;
  uint64_t data_packets_ = 0;
  uint64_t position_packets_ = 0;
  std::array<uint8_t, velodyne::kDataPacketSize> data_buffer_{};
  std::array<uint8_t, velodyne::kPositionPacketSize> position_buffer_{};
};

}  // namespace lidartag::sim
