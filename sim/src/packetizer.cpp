#include "lidartag/sim/packetizer.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

namespace lidartag::sim {

uint32_t usec_since_hour(int64_t time_ns) {
  constexpr int64_t kHourUs = 3'600'000'000LL;
  const int64_t us = time_ns / 1000;
  return static_cast<uint32_t>(((us % kHourUs) + kHourUs) % kHourUs);
}

std::string gprmc_sentence(int64_t time_ns) {
  using namespace std::chrono;
  const sys_seconds secs{seconds{time_ns / 1'000'000'000LL}};
  const sys_days day = floor<days>(secs);
  const year_month_day ymd{day};
  const hh_mm_ss hms{secs - day};
  // A fixed position (Ann Arbor, MI), standing still; NMEA 2.3 mode indicator 'A'.
  char body[128];
  std::snprintf(body, sizeof(body),
                "GPRMC,%02d%02d%02d,A,4217.6160,N,08342.9960,W,000.0,000.0,%02u%02u%02d,,,A",
                static_cast<int>(hms.hours().count()), static_cast<int>(hms.minutes().count()),
                static_cast<int>(hms.seconds().count()), static_cast<unsigned>(ymd.day()),
                static_cast<unsigned>(ymd.month()), static_cast<int>(ymd.year()) % 100);
  uint8_t checksum = 0;
  for (const char* c = body; *c; ++c)
    checksum = static_cast<uint8_t>(checksum ^ static_cast<uint8_t>(*c));
  char out[160];
  std::snprintf(out, sizeof(out), "$%s*%02X", body, static_cast<unsigned>(checksum));
  return out;
}

Packetizer::Packetizer(const velodyne::ModelSpec& spec, velodyne::ReturnMode mode, int64_t start_ns,
                       double position_rate_hz, PacketCallback emit)
    : spec_(spec),
      mode_(mode),
      start_ns_(start_ns),
      position_rate_hz_(position_rate_hz),
      emit_(std::move(emit)),
      columns_per_packet_(spec.columns_per_packet(mode)),
      column_period_ns_(std::llround(spec.firing_period_us * 1000.0)) {}

void Packetizer::emit_position_until(int64_t time_ns) {
  if (position_rate_hz_ <= 0.0) return;
  for (;;) {
    const int64_t t =
        start_ns_ + std::llround(static_cast<double>(position_packets_) * 1e9 / position_rate_hz_);
    if (t > time_ns) return;
    velodyne::encode_position_packet(usec_since_hour(t), velodyne::PpsStatus::kLocked,
                                     gprmc_sentence(t), position_buffer_);
    emit_(position_buffer_, t, velodyne::kDefaultPositionPort);
    ++position_packets_;
  }
}

void Packetizer::add(const velodyne::FiringColumn& column, int64_t first_firing_ns) {
  if (pending_ == 0) packet_start_ns_ = first_firing_ns;
  columns_[static_cast<size_t>(pending_++)] = column;
  if (pending_ < columns_per_packet_) return;
  velodyne::encode_data_packet(spec_, mode_,
                               std::span<const velodyne::FiringColumn>(
                                   columns_.data(), static_cast<size_t>(columns_per_packet_)),
                               usec_since_hour(packet_start_ns_), data_buffer_);
  const int64_t capture_ns = packet_start_ns_ + columns_per_packet_ * column_period_ns_;
  emit_position_until(capture_ns);
  emit_(data_buffer_, capture_ns, velodyne::kDefaultDataPort);
  ++data_packets_;
  pending_ = 0;
}

}  // namespace lidartag::sim
