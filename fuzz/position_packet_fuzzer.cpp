// Fuzz target: one position (telemetry) packet: parse_position_packet, the GPRMC time parser and
// the sensor clock fed with it. Checks: the sentence is NUL-terminated within the packet's NMEA
// field, a fix is trusted only with its NMEA checksum right, a valid fix gives a time the clock
// can use without overflow, and a second fix far from the first (forged, or off by GPS eras) is
// not adopted on its own.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "fuzz_util.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> payload(data, size);
  velodyne::PositionPacket position;
  const velodyne::PositionStatus status = velodyne::parse_position_packet(payload, position);
  if (status == velodyne::PositionStatus::kOk || status == velodyne::PositionStatus::kBadChecksum) {
    fuzz::check(std::memchr(position.nmea.data(), 0, position.nmea.size()) != nullptr,
                "NMEA sentence not terminated");
    fuzz::check(position.sentence().size() <= velodyne::kNmeaMaxLength, "NMEA sentence too long");
    fuzz::check(!position.has_gprmc || velodyne::nmea_checksum_ok(position.sentence()),
                "a fix trusted without its checksum");
    fuzz::check(status == velodyne::PositionStatus::kOk || !position.has_gprmc,
                "a fix trusted from a sentence that failed its checksum");
    constexpr int64_t kReceive = 1'700'000'000'000'000'000;
    velodyne::SensorClock clock;
    clock.update(position, kReceive);
    // Joined with any counter, the time stays where a capture's times can be.
    const int64_t t = clock.join(position.usec_since_hour, kReceive);
    fuzz::check(t > 0, "joined time not positive");
    // The same packet 0.1 s later as the only other fix: if the first was adopted, this one is
    // within kMaxJumpNs of its carried time or not adopted, so the joined time moves by at most
    // that (plus the hour-counter's own step, when the counter jumps).
    if (clock.source() == velodyne::TimeSource::kGps) {
      velodyne::PositionPacket later = position;
      later.gps_fix_ns += 7LL * 24 * 3600 * 1'000'000'000 * 1024;  // one GPS era later
      clock.update(later, kReceive + 100'000'000);
      fuzz::check(clock.join(position.usec_since_hour, kReceive) == t,
                  "a fix one era off adopted on its own");
    }
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
