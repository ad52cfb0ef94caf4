#include "lidartag/daemon/tap_source.hpp"

#include <algorithm>

namespace lidartag::daemon {

using namespace std::chrono_literals;

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

PcapRecorder::PcapRecorder(const std::string& path) : writer_(path) {}

void PcapRecorder::write(const velodyne::RawPacket& packet) noexcept {
  std::lock_guard lock(mutex_);
  if (!writer_.is_open()) return;
  try {
    const uint32_t source =
        packet.source_ipv4 != 0 ? packet.source_ipv4 : velodyne::PcapWriter::kDefaultSourceIpv4;
    writer_.write_udp(packet.payload, packet.receive_time_ns, packet.destination_port, source);
  } catch (const std::exception& e) {
    error_ = e.what();
    try {
      writer_.close();
    } catch (const std::exception&) {
      // Already failing: the first error is the one reported.
    }
  }
}

void PcapRecorder::close() noexcept {
  std::lock_guard lock(mutex_);
  try {
    writer_.close();
  } catch (const std::exception& e) {
    if (error_.empty()) error_ = e.what();
  }
}

uint64_t PcapRecorder::records() const {
  std::lock_guard lock(mutex_);
  return writer_.records();
}

std::string PcapRecorder::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

TapSource::TapSource(std::unique_ptr<velodyne::PacketSource> inner, PcapRecorder* recorder,
                     RawTap raw_tap)
    : inner_(std::move(inner)), recorder_(recorder), raw_tap_(std::move(raw_tap)) {}

velodyne::ReadStatus TapSource::next(velodyne::RawPacket& out, std::chrono::milliseconds timeout) {
  if (stop_.load(std::memory_order_relaxed)) return velodyne::ReadStatus::kEnd;
  const auto status = inner_->next(out, std::min<std::chrono::milliseconds>(timeout, 100ms));
  if (status != velodyne::ReadStatus::kPacket) return status;
  packets_.fetch_add(1, std::memory_order_relaxed);
  if (recorder_ != nullptr) recorder_->write(out);
  if (raw_tap_) raw_tap_(out);
  return status;
}

velodyne::SourceStats TapSource::stats() const {
  return inner_->stats();
}

}  // namespace lidartag::daemon
