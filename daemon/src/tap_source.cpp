#include "lidartag/daemon/tap_source.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace lidartag::daemon {

using namespace std::chrono_literals;

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

namespace {

// The writer, its setup error naming the setting.
driver::PcapWriter open_record_file(const std::string& path) {
  try {
    return driver::PcapWriter(path, /*follow_links=*/false);
  } catch (const driver::IoError& e) {
    throw driver::IoError(std::string("record_pcap: ") + e.what());
  }
}

}  // namespace

PcapRecorder::PcapRecorder(const std::string& path)
    : path_(path), writer_(open_record_file(path)), next_flush_ns_(steady_ns() + kFlushPeriodNs) {}

void PcapRecorder::write(const driver::RawPacket& packet) noexcept {
  std::lock_guard lock(mutex_);
  ++received_;
  if (writer_.failed()) return;
  const uint32_t source =
      packet.source_ipv4 != 0 ? packet.source_ipv4 : driver::PcapWriter::kDefaultSourceIpv4;
  // kClosed and kTooLarge cannot happen here (closed after the sources stopped; UDP payloads fit):
  // both leave the packet out of the file, which missed() counts.
  (void)writer_.append_udp(packet.payload, packet.receive_time_ns, packet.destination_port, source);
  const int64_t now = steady_ns();
  if (now >= next_flush_ns_) {
    (void)writer_.flush();
    next_flush_ns_ = now + kFlushPeriodNs;
  }
  check_failure();
}

void PcapRecorder::close() noexcept {
  std::lock_guard lock(mutex_);
  try {
    writer_.close();
  } catch (const driver::IoError&) {
    // In writer_.error(), reported below.
  }
  check_failure();
}

void PcapRecorder::check_failure() {
  if (!writer_.failed() || reported_) return;
  reported_ = true;
  spdlog::error("recording {} stopped: {}", path_, error_text());
}

std::string PcapRecorder::error_text() const {
  if (!writer_.failed()) return {};
  return fmt::format("{}; the file holds the first {} packets, {} received later are not in it",
                     writer_.error(), writer_.records(), received_ - writer_.records());
}

uint64_t PcapRecorder::records() const {
  std::lock_guard lock(mutex_);
  return writer_.records();
}

uint64_t PcapRecorder::missed() const {
  std::lock_guard lock(mutex_);
  return received_ - writer_.records();
}

bool PcapRecorder::failed() const {
  std::lock_guard lock(mutex_);
  return writer_.failed();
}

std::string PcapRecorder::error() const {
  std::lock_guard lock(mutex_);
  return error_text();
}

TapSource::TapSource(std::unique_ptr<driver::PacketSource> inner, PcapRecorder* recorder,
                     RawTap raw_tap)
    : inner_(std::move(inner)), recorder_(recorder), raw_tap_(std::move(raw_tap)) {}

driver::ReadStatus TapSource::next(driver::RawPacket& out, std::chrono::milliseconds timeout) {
  if (stop_.load(std::memory_order_relaxed)) return driver::ReadStatus::kEnd;
  const auto status = inner_->next(out, std::min<std::chrono::milliseconds>(timeout, 100ms));
  if (status != driver::ReadStatus::kPacket) return status;
  packets_.fetch_add(1, std::memory_order_relaxed);
  if (recorder_ != nullptr) recorder_->write(out);
  if (raw_tap_) raw_tap_(out);
  return status;
}

driver::SourceStats TapSource::stats() const {
  return inner_->stats();
}

}  // namespace lidartag::daemon
