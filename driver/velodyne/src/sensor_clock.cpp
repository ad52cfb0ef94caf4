#include "lidartag/driver/velodyne/sensor_clock.hpp"

#include <cstdlib>

namespace lidartag::velodyne {
namespace {
constexpr int64_t kHourNs = 3'600'000'000'000LL;
constexpr int64_t kHalfHourNs = kHourNs / 2;
constexpr int64_t kDayNs = 24 * kHourNs;
constexpr int64_t kGpsEraNs = 1024 * 7 * kDayNs;  // the week counter's rollover
// Receive times before 2020 are no reference for the GPS era (a host clock without RTC or NTP).
constexpr int64_t kPlausibleHostNs = 1'577'836'800LL * 1'000'000'000LL;
}  // namespace

int64_t join_hour(uint32_t usec_since_hour, int64_t reference_ns) {
  const int64_t hour = reference_ns - ((reference_ns % kHourNs) + kHourNs) % kHourNs;
  int64_t t = hour + static_cast<int64_t>(usec_since_hour) * 1000;
  if (t - reference_ns > kHalfHourNs) t -= kHourNs;
  if (reference_ns - t > kHalfHourNs) t += kHourNs;
  return t;
}

int64_t SensorClock::join(uint32_t usec_since_hour, int64_t reference_ns) const {
  // With GPS, the reference is the fix time (position packets come many times a second, so it
  // is always within half an hour of the data packet).
  return join_hour(usec_since_hour, source_ == TimeSource::kGps ? gps_reference_ns_ : reference_ns);
}

void SensorClock::update(const PositionPacket& position, int64_t receive_ns) {
  pps_ = position.pps;
  if (!position.has_gprmc || position.pps != PpsStatus::kLocked) return;
  int64_t fix = join_hour(position.usec_since_hour, position.gps_fix_ns);
  if (receive_ns >= kPlausibleHostNs) {
    // Off by whole GPS eras (to within a day) from the receive time: the receiver's week rolled
    // over (a fix in 2004 for 2023). Another offset (a capture replayed years later) is kept.
    const int64_t off = receive_ns - fix;
    const int64_t eras = (off + (off >= 0 ? kGpsEraNs / 2 : -kGpsEraNs / 2)) / kGpsEraNs;
    if (eras != 0 && std::abs(off - eras * kGpsEraNs) < kDayNs) {
      fix += eras * kGpsEraNs;
      ++eras_;
    }
  }
  if (have_gps_) {
    const int64_t carried = gps_reference_ns_ + (receive_ns - gps_host_ns_);
    if (std::abs(fix - carried) > kMaxJumpNs) {
      // Adopted only once kConfirmFixes fixes in a row agree on the new time.
      const int64_t offset = fix - receive_ns;
      pending_ =
          pending_ > 0 && std::abs(offset - pending_offset_ns_) <= kMaxJumpNs ? pending_ + 1 : 1;
      pending_offset_ns_ = offset;
      if (pending_ < kConfirmFixes) {
        ++rejected_;
        return;
      }
    }
  }
  pending_ = 0;
  have_gps_ = true;
  source_ = TimeSource::kGps;
  gps_reference_ns_ = fix;
  gps_host_ns_ = receive_ns;
}

}  // namespace lidartag::velodyne
