// Absolute time of a packet: the sensor's microseconds-since-the-hour counter joined with a wall
// clock (host receive time or capture timestamp) or with GPS time from position packets.
#pragma once

#include <cstdint>

#include "lidartag/driver/velodyne/packet.hpp"

namespace lidartag::velodyne {

enum class TimeSource : uint8_t { kHost, kGps };

class SensorClock {
 public:
  // A GPS reference older than this (no valid locked fix since, by the receive clock) is stale:
  // the clock falls back to the host reference until fixes come again.
  static constexpr int64_t kStaleNs = 10'000'000'000LL;
  // A fix that disagrees by more than this with the GPS time carried forward from the last one
  // is not adopted (spoofed, corrupt, or a receiver that lost its week); three in a row that
  // agree with each other are (the GPS time really moved, e.g. after a receiver reset).
  static constexpr int64_t kMaxJumpNs = 2'000'000'000LL;
  static constexpr int kConfirmFixes = 3;

  // Joins `usec_since_hour` with `reference_ns` (ns since the epoch): the hour is taken from the
  // reference, corrected by one hour when the two disagree by more than 30 min (hour boundary).
  // With a GPS hour known (position packets with a valid GPRMC and PPS locked), that hour is used.
  int64_t join(uint32_t usec_since_hour, int64_t reference_ns) const;

  // Feeds a position packet received at `receive_ns` (host or capture time); adopts GPS time
  // when PPS is locked and the GPRMC fix is valid and plausible: within kMaxJumpNs of the time
  // carried forward from the last fix, and moved by whole 1024-week GPS eras to the receive
  // time's era when it is off by such an era (a receiver that lost the week rollover).
  void update(const PositionPacket& position, int64_t receive_ns);
  // Called with each data packet's receive time: a reference older than kStaleNs is dropped.
  void expire(int64_t receive_ns) {
    if (source_ == TimeSource::kGps && receive_ns - gps_host_ns_ > kStaleNs) {
      source_ = TimeSource::kHost;
      ++stale_;
    }
  }

  TimeSource source() const { return source_; }
  PpsStatus pps() const { return pps_; }
  uint64_t rejected_fixes() const { return rejected_; }  // implausible jumps, not adopted
  uint64_t era_corrections() const { return eras_; }     // fixes moved by 1024-week eras
  uint64_t stale() const { return stale_; }              // times the reference went stale

 private:
  TimeSource source_ = TimeSource::kHost;
  PpsStatus pps_ = PpsStatus::kAbsent;
  int64_t gps_reference_ns_ = 0;  // absolute time of the last adopted position packet, from GPS
  int64_t gps_host_ns_ = 0;       // its receive time
  bool have_gps_ = false;         // a fix was adopted once (the jump check has a reference)
  // Fixes not adopted, that agree with each other: the GPS time may really have moved.
  int64_t pending_offset_ns_ = 0;  // their GPS time minus receive time
  int pending_ = 0;
  uint64_t rejected_ = 0, eras_ = 0, stale_ = 0;
};

// Pure form of the join, exposed for tests.
int64_t join_hour(uint32_t usec_since_hour, int64_t reference_ns);

}  // namespace lidartag::velodyne
