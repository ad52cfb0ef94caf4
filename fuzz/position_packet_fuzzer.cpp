// Fuzz target: one position (telemetry) packet: parse_position_packet, the GPRMC time parser and
// the sensor clock fed with it. Checks: the sentence is NUL-terminated within the packet's NMEA
// field, a valid fix gives a time the clock can use without overflow.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "fuzz_util.hpp"
#include "lidartag/driver/packet.hpp"
#include "lidartag/driver/sensor_clock.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> payload(data, size);
  velodyne::PositionPacket position;
  const velodyne::PositionStatus status = velodyne::parse_position_packet(payload, position);
  if (status == velodyne::PositionStatus::kOk) {
    fuzz::check(std::memchr(position.nmea.data(), 0, position.nmea.size()) != nullptr,
                "NMEA sentence not terminated");
    fuzz::check(position.sentence().size() <= velodyne::kNmeaMaxLength, "NMEA sentence too long");
    velodyne::SensorClock clock;
    clock.update(position);
    // Joined with any counter, the time stays where a capture's times can be.
    const int64_t t = clock.join(position.usec_since_hour, 1'700'000'000'000'000'000);
    fuzz::check(t > 0, "joined time not positive");
  } else {
    fuzz::check(
        size != velodyne::kPositionPacketSize || status == velodyne::PositionStatus::kBadPps,
        "a packet of the right size refused for its size");
  }
  // The GPRMC parser on any text (it is also given sentences cut anywhere).
  int64_t utc_ns = 0;
  bool valid = false;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (velodyne::parse_gprmc_time(text, utc_ns, valid)) fuzz::check(utc_ns >= 0, "GPRMC time < 0");
  return 0;
}
