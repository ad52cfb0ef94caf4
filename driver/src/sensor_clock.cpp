#include "lidartag/driver/sensor_clock.hpp"

namespace lidartag::velodyne {
namespace {
constexpr int64_t kHourNs = 3'600'000'000'000LL;
constexpr int64_t kHalfHourNs = kHourNs / 2;
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

void SensorClock::update(const PositionPacket& position) {
  pps_ = position.pps;
  if (position.has_gprmc && position.pps == PpsStatus::kLocked) {
    source_ = TimeSource::kGps;
    gps_reference_ns_ = join_hour(position.usec_since_hour, position.gps_fix_ns);
  }
}

}  // namespace lidartag::velodyne
