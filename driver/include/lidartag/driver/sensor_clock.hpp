// Absolute time of a packet: the sensor's microseconds-since-the-hour counter joined with a wall
// clock (host receive time or capture timestamp) or with GPS time from position packets.
#pragma once

#include <cstdint>

#include "lidartag/driver/packet.hpp"

namespace lidartag::velodyne {

enum class TimeSource : uint8_t { kHost, kGps };

class SensorClock {
 public:
  // Joins `usec_since_hour` with `reference_ns` (ns since the epoch): the hour is taken from the
  // reference, corrected by one hour when the two disagree by more than 30 min (hour boundary).
  // With a GPS hour known (position packets with a valid GPRMC and PPS locked), that hour is used.
  int64_t join(uint32_t usec_since_hour, int64_t reference_ns) const;

  // Feeds a position packet; adopts GPS time when PPS is locked and the GPRMC fix is valid.
  void update(const PositionPacket& position);

  TimeSource source() const { return source_; }
  PpsStatus pps() const { return pps_; }

 private:
  TimeSource source_ = TimeSource::kHost;
  PpsStatus pps_ = PpsStatus::kAbsent;
  int64_t gps_reference_ns_ = 0;  // absolute time of the last position packet, from GPS
};

// Pure form of the join, exposed for tests.
int64_t join_hour(uint32_t usec_since_hour, int64_t reference_ns);

}  // namespace lidartag::velodyne
