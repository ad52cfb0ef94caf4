#include "lidartag/driver/assembly/stream_screen.hpp"

#include <algorithm>
#include <cmath>

#include "lidartag/driver/angles.hpp"

namespace lidartag::driver {
namespace {

// The azimuth a packet must have, predicted from the stream's newest packet, within this many
// degrees, plus this fraction of the predicted travel (rate uncertainty over a gap). (In-packet
// rates are good to about 0.5 %, packet times to 1 us: a stream's own packets land within a few
// hundredths of a degree; a stray packet fits by chance once in several hundred.)
constexpr double kAzimuthToleranceDeg = 0.3;
constexpr double kTravelTolerance = 0.02;
// Packets later than this many packet periods are not reordered ones but foreign.
constexpr double kMaxLatePackets = 16;

// Signed difference of two azimuths, (-180, 180].
double azimuth_diff(double a, double b) {
  const double d = wrap360(a - b);
  return d > 180.0 ? d - 360.0 : d;
}

}  // namespace

StreamScreen::StreamScreen(const SensorLayout& layout, double flush_timeout_s)
    : layout_(layout),
      flush_timeout_s_(flush_timeout_s),
      candidates_(kNewStreamPackets, layout.max_payload_bytes) {}

StreamScreen::Ref StreamScreen::ref_of(const ColumnPacket& pk) {
  const auto last = static_cast<size_t>(std::max(pk.columns - 1, 0));
  // The rate across the whole packet: one column's step (0.2 deg on a VLP-32C, in 0.01 deg
  // steps) is off by up to 5 %, which across a gap of several lost packets misplaces the next
  // packet by more than the tolerance (a lost run would make a good packet look stray).
  float rate = pk.rate_deg[last];
  const double span_us = pk.column_time_us[last] - pk.column_time_us[0];
  if (last > 0 && span_us > 0) {
    const double turned = wrap360(pk.column_azimuth_deg[last] - pk.column_azimuth_deg[0]);
    if (turned < 90.0) rate = static_cast<float>(turned / span_us);
  }
  return {pk.stamp_ns, pk.column_azimuth_deg[0], pk.column_azimuth_deg[last], rate};
}

bool StreamScreen::fits(const Ref& ref, const ColumnPacket& pk) const {
  if (pk.columns <= 0) return false;
  const double dt_us = static_cast<double>(pk.stamp_ns - ref.stamp_ns) * 1e-3;
  const double period_us = layout_.packet_period_us(pk.returns);
  if (dt_us < -kMaxLatePackets * period_us || dt_us > flush_timeout_s_ * 1e6) return false;
  // Where the sensor pointed at that time, by the rate measured inside the newest packet.
  const double travel = ref.rate_deg_per_us * dt_us;
  const double az = pk.column_azimuth_deg[0];
  if (std::abs(azimuth_diff(az, ref.first_azimuth_deg + travel)) <=
      kAzimuthToleranceDeg + kTravelTolerance * std::abs(travel))
    return true;
  // A restricted field of view: the sensor paused (longer than a packet period), then goes on
  // from where it stopped.
  const double step = ref.rate_deg_per_us * layout_.column_period_us;
  return dt_us > 1.5 * period_us &&
         std::abs(azimuth_diff(az, ref.last_azimuth_deg + step)) <= kAzimuthToleranceDeg + step;
}

StreamScreen::Verdict StreamScreen::screen(const ColumnPacket& pk, const ReorderWindow& window,
                                           std::optional<int64_t> last_written_ns) const {
  if (!have_head_) return Verdict::kAccept;
  const float az = pk.column_azimuth_deg[0];
  // Seen before: in the window, or released not long ago.
  if (window.holds(pk.stamp_ns, az)) return Verdict::kDuplicate;
  const int remembered = std::min(released_count_, kHistory);
  for (int i = 0; i < remembered; ++i)
    if (released_stamp_[static_cast<size_t>(i)] == pk.stamp_ns &&
        released_azimuth_[static_cast<size_t>(i)] == az)
      return Verdict::kDuplicate;
  if (!fits(head_, pk)) {
    // The newest packet taken may itself have been a stray one that fitted by chance.
    if (have_previous_head_ && pk.stamp_ns > previous_head_.stamp_ns && fits(previous_head_, pk))
      return Verdict::kAcceptHeadWasStray;
    return Verdict::kSuspect;
  }
  // Older than what was already written into the rotation: too late to be put in place.
  if (last_written_ns && pk.stamp_ns <= *last_written_ns) return Verdict::kTooLate;
  // A sensor's packets never overlap in time: one that does is stray, however well it fits.
  if (window.overlaps(pk.stamp_ns, last_stamp(pk))) return Verdict::kSuspect;
  return Verdict::kAccept;
}

void StreamScreen::taken(const ColumnPacket& pk) {
  if (!have_head_ || pk.stamp_ns > head_.stamp_ns) {
    previous_head_ = head_;
    have_previous_head_ = have_head_;
    head_ = ref_of(pk);
  }
  have_head_ = true;
}

void StreamScreen::released(const ColumnPacket& pk) {
  const auto h = static_cast<size_t>(released_count_++ % kHistory);
  released_stamp_[h] = pk.stamp_ns;
  released_azimuth_[h] = pk.column_azimuth_deg[0];
}

void StreamScreen::drop_head() {
  head_ = previous_head_;
  have_previous_head_ = false;
}

StreamScreen::Candidate StreamScreen::add_candidate(const ColumnPacket& pk) {
  auto& c = candidates_;
  if (candidate_count_ == kNewStreamPackets) return Candidate::kDropped;  // adopted before this
  if (candidate_count_ == 0 || fits(ref_of(c[candidate_count_ - 1].columns()), pk)) {
    c[candidate_count_++].hold(pk);
    return Candidate::kHeld;
  }
  if (candidate_count_ == 1) {
    // One odd packet then another that disagrees with it: the first was the stray one.
    c[0].hold(pk);
    return Candidate::kReplacedStray;
  }
  return Candidate::kDropped;
}

void StreamScreen::start_candidates(const ColumnPacket& pk) {
  candidates_[0].hold(pk);
  candidate_count_ = 1;
}

int StreamScreen::clear_candidates() {
  const int n = candidate_count_;
  candidate_count_ = 0;
  return n;
}

}  // namespace lidartag::driver
