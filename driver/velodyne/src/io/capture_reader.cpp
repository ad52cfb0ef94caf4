#include "lidartag/driver/velodyne/io/capture_reader.hpp"

#include <algorithm>
#include <cmath>

#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

namespace lidartag::velodyne {

using namespace std::chrono_literals;

namespace {
// Packets held back while probing: this many, or 4 x probe_packets when that is more.
constexpr size_t kMinHeld = 1024;
// Data packets per model check after the decision.
constexpr size_t kModelEpochPackets = 64;

// Models that the packets' timing and layout cannot tell apart (VLP-16 and Puck Hi-Res).
bool same_timing(Model a, Model b, ReturnMode mode) {
  const auto& sa = model_spec(a);
  const auto& sb = model_spec(b);
  return (sa.blocks_per_firing > 1) == (sb.blocks_per_firing > 1) &&
         std::abs(sa.packet_period_us(mode) - sb.packet_period_us(mode)) <
             0.01 * sa.packet_period_us(mode);
}

// A bag (by content) or a pcap.
std::unique_ptr<driver::PacketSource> open_capture(const std::string& path,
                                                   const CaptureReaderOptions& options) {
  if (driver::bag::detect_bag_format(path) == driver::bag::BagFormat::kNone)
    return std::make_unique<driver::PcapSource>(path, options.source);
  return std::make_unique<driver::bag::BagPacketSource>(
      path, driver::bag::BagPacketSourceOptions{options.topic, options.source.data_port,
                                                options.bag_start_s, options.bag_duration_s});
}
}  // namespace

CaptureReader::CaptureReader(const std::string& path, CaptureReaderOptions options)
    : CaptureReader(open_capture(path, options), options) {}

CaptureReader::CaptureReader(std::unique_ptr<driver::PacketSource> source,
                             CaptureReaderOptions options)
    : source_(std::move(source)),
      options_(std::move(options)),
      packet_(std::make_unique<PacketColumns>()) {
  if (options_.model) decide();  // loads the calibration now: errors surface at setup
}

CaptureReader::~CaptureReader() = default;

const Calibration* CaptureReader::calibration() const {
  return decoder_ ? &decoder_->calibration() : nullptr;
}

driver::BatcherStats CaptureReader::batcher_stats() const {
  driver::BatcherStats s = retired_;
  if (batcher_) s += batcher_->stats();
  return s;
}

driver::ReaderCounts CaptureReader::reader_counts() const {
  driver::ReaderCounts r;
  r.data_packets = counts_.data_packets;
  r.decoded = counts_.decoded;
  for (const uint64_t e : counts_.decode_errors) r.refused += e;
  r.refused += counts_.undecodable + counts_.position_errors + counts_.position_checksum;
  r.model_mismatch = counts_.model_mismatch;
  r.aux_packets = counts_.position_packets;
  r.gprmc_valid = counts_.gprmc_valid;
  r.pps = static_cast<int>(counts_.pps);
  r.time_source = static_cast<int>(clock_.source());
  return r;
}

driver::SensorDescription CaptureReader::description() const {
  driver::SensorDescription d;
  d.vendor = "velodyne";
  if (model_) d.model = model_spec(*model_).name;
  if (mode_) d.return_mode = return_mode_name(*mode_);
  // The model decoded against the packets' timing, which follows the latest packets: a wrong
  // configuration or a change mid-stream shows here.
  const std::optional<Model> timing = check_.timing_model();
  if (model_ && timing && !same_timing(*model_, *timing, mode_.value_or(ReturnMode::kStrongest)))
    d.evidence_fits = model_spec(*timing).name;
  return d;
}

std::string CaptureReader::model_mismatch() const {
  if (!stream_mismatch_.empty()) return stream_mismatch_;
  if (options_.model) {
    // A configured model that the timing fits settles a product byte that says otherwise; one the
    // timing contradicts is reported as soon as the timing is known (a short capture never
    // reaches the mid-stream watch).
    const std::optional<Model> fits = check_.timing_model();
    if (!fits || *fits == *options_.model) return {};
    return configured_mismatch(*fits, check_.packet_period_us());
  }
  return check_.mismatch();
}

std::string CaptureReader::configured_mismatch(Model fits, double period_us) const {
  return std::string(options_.model ? "configured model " : "calibration file's model ") +
         std::string(model_spec(model_ ? *model_ : fits).name) +
         " but the packets' product byte and timing (" + std::to_string(std::lround(period_us)) +
         " us per packet) fit " + std::string(model_spec(fits).name);
}

void CaptureReader::watch_model(std::span<const uint8_t> payload) {
  if (!model_ || switch_to_) return;
  epoch_.add(payload);
  if (epoch_.packets() < kModelEpochPackets) return;
  // The product byte's model if the timing fits it, else the model the timing fits.
  const std::optional<Model> fits = epoch_.timing_model();
  const std::optional<Model> product = epoch_.product_model();
  const double period_us = epoch_.packet_period_us();
  epoch_ = ModelCheck{};
  // Compared with what the first packets (or the configuration) said: a capture whose product
  // byte contradicts its timing from the start is ModelCheck's complaint, not a change, as long
  // as the packets still carry the product byte decided on. Packets whose byte and timing both
  // name another model are evidence against the decision, however it was made.
  if (!fits || *fits == *model_ || (fits == expected_ && product == model_)) {
    mismatched_epochs_ = 0;
    return;
  }
  counts_.model_mismatch += kModelEpochPackets;
  if (++mismatched_epochs_ < 2) return;  // sustained, not a burst of stray packets
  const std::string now(model_spec(*model_).name), seen(model_spec(*fits).name);
  if (options_.model || !options_.calibration_file.empty()) {
    // Configured: decode as told, but say so (once; the counter keeps counting).
    if (stream_mismatch_.empty()) stream_mismatch_ = configured_mismatch(*fits, period_us);
    return;
  }
  stream_mismatch_ = "model changed mid-stream: " + now + " -> " + seen +
                     " (product byte and packet timing); decoding as " + seen;
  ++counts_.model_changes;
  switch_to_ = *fits;
  expected_ = *fits;
}

void CaptureReader::switch_model(Model model) {
  model_ = model;
  decoder_ = std::make_unique<Decoder>(Calibration::builtin(model), options_.decoder);
  // The counters go on across the change (a status must never see them fall).
  if (batcher_) {
    retired_ += batcher_->stats();
    next_sequence_ = batcher_->next_sequence();
  }
  batcher_.reset();  // the next packet makes one for the new model; scans are reshaped by it
  mismatched_epochs_ = 0;
}

void CaptureReader::decide() {
  model_ = options_.model;
  if (!model_) model_ = check_.product_model();
  if (!model_) model_ = check_.timing_model();
  // What was held back while probing is handled next, in arrival order (by read()).
  held_next_ = 0;
  draining_ = true;
  if (!model_) {
    // No model fits what was probed (another sensor, or packets that only look like Velodyne
    // data): those packets go on undecoded and the probe starts over on the next ones, so that
    // the sensor is decoded as soon as it speaks, whatever came before it.
    ++counts_.failed_probes;
    check_ = ModelCheck{};
    return;
  }
  decided_ = true;
  expected_ = options_.model ? options_.model : check_.timing_model();
  Calibration calibration = options_.calibration_file.empty()
                                ? Calibration::builtin(*model_)
                                : load_calibration_file(options_.calibration_file, *model_);
  decoder_ = std::make_unique<Decoder>(std::move(calibration), options_.decoder);
}

bool CaptureReader::take(const driver::RawPacket& p, Scan& scan) {
  if (counts_.first_time_ns == 0) counts_.first_time_ns = p.receive_time_ns;
  counts_.last_time_ns = p.receive_time_ns;
  if (p.destination_port == options_.source.data_port) {
    check_.add(p.payload);
    if (decided_) watch_model(p.payload);
    data_unstamped_ = true;  // read() stamps it with its next reading of the clock
  }
  if (decided_) return handle(p.payload, p.receive_time_ns, p.destination_port, scan);
  // Traffic that never completes the probe (position packets only, datagrams of another size on
  // the data port) must not be held without bound: past the limit the oldest goes on undecoded
  // (position packets as usual, data packets counted as undecodable), its buffer reused.
  if (held_.size() >= std::max<size_t>(kMinHeld, 4 * options_.probe_packets)) {
    Held oldest = std::move(held_.front());
    held_.erase(held_.begin());
    (void)handle(oldest.payload, oldest.time_ns, oldest.port, scan);  // no decoder: no rotation
    oldest.payload.assign(p.payload.begin(), p.payload.end());
    oldest.time_ns = p.receive_time_ns;
    oldest.port = p.destination_port;
    held_.push_back(std::move(oldest));
  } else {
    held_.push_back({{p.payload.begin(), p.payload.end()}, p.receive_time_ns, p.destination_port});
  }
  if (check_.packets() >= options_.probe_packets) decide();
  return false;
}

bool CaptureReader::handle(std::span<const uint8_t> payload, int64_t time_ns, uint16_t port,
                           Scan& scan) {
  if (port == options_.source.position_port) {
    ++counts_.position_packets;
    PositionPacket position;
    const PositionStatus parsed = parse_position_packet(payload, position);
    if (parsed == PositionStatus::kBadChecksum) {
      ++counts_.position_checksum;  // parsed, but its time is not trusted
    } else if (parsed != PositionStatus::kOk) {
      ++counts_.position_errors;
      return false;
    }
    ++counts_.position_ok;
    counts_.pps = position.pps;
    counts_.last_nmea = std::string(position.sentence());
    if (position.has_gprmc) ++counts_.gprmc_valid;
    clock_.update(position, time_ns);
    return false;
  }
  if (port != options_.source.data_port) return false;
  ++counts_.data_packets;
  clock_.expire(time_ns);
  if (!decoder_) {
    ++counts_.undecodable;
    return false;
  }
  // Header and column azimuths only: the batcher has the decoder write the points straight into
  // the scan (from `payload`, valid during this call; what the batcher holds back it copies).
  const DecodeStatus status = decoder_->parse(payload, clock_, time_ns, *packet_);
  if (status != DecodeStatus::kOk) {
    const auto index = static_cast<size_t>(status);
    if (index < counts_.decode_errors.size()) ++counts_.decode_errors[index];
    return false;
  }
  ++counts_.decoded;
  if (!batcher_) {
    batcher_ = std::make_unique<driver::ScanBatcher>(
        sensor_layout(decoder_->spec()), packet_->return_mode, packet_->returns, options_.batcher);
    batcher_->continue_sequence(next_sequence_);
  }
  mode_ = packet_->mode();
  // A pause in the packets' own clock longer than flush_timeout_s makes the stream a new one for
  // the batcher (its screening, not this packet's possibly spoofed time, ends the rotation).
  return batcher_->add(*packet_, scan);
}

CaptureReader::ReadResult CaptureReader::read(Scan& scan, std::chrono::milliseconds timeout) {
  using Clock = std::chrono::steady_clock;
  // The clock is read once per packet (after it is handled: that reading also stamps a data
  // packet's host time) and once per rotation; reading it three times a packet cost 60 ns of a
  // packet's 1 to 2 us on a VM.
  auto now = Clock::now();
  const auto deadline = now + timeout;
  auto stamp_data = [this](Clock::time_point t) {
    if (!data_unstamped_) return;
    last_data_ = t;
    data_unstamped_ = false;
  };
  for (;;) {
    if (finished_) return ReadResult::kEnd;
    if (switch_to_) {
      // Deliver what was assembled as the old model, then decode as the new one.
      if (batcher_ && batcher_->flush(scan)) return ReadResult::kRotation;
      switch_model(*switch_to_);
      switch_to_.reset();
    }
    // Packets held back while the model was probed, one at a time: each may end a rotation.
    if (draining_ && held_next_ < held_.size()) {
      const Held& h = held_[held_next_++];
      const bool done = handle(h.payload, h.time_ns, h.port, scan);
      if (held_next_ == held_.size()) {
        held_.clear();
        if (decided_) held_.shrink_to_fit();  // else the next probe reuses the room
        held_next_ = 0;
        draining_ = false;
        now = Clock::now();  // the source's wait is measured from here
      }
      if (done) return ReadResult::kRotation;
      continue;
    }
    if (source_ended_) {
      // The reorder window may still hold the start of another rotation: one per call.
      if (batcher_ && batcher_->flush(scan)) return ReadResult::kRotation;
      finished_ = true;
      return ReadResult::kEnd;
    }
    // Rounded up: a source that waits the whole timeout returns after the deadline, not just
    // before it (which would take another call).
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - now);
    driver::RawPacket packet;
    const driver::ReadStatus status =
        source_->next(packet, std::max(left, std::chrono::milliseconds::zero()));
    if (status == driver::ReadStatus::kPacket) {
      if (take(packet, scan)) {
        stamp_data(Clock::now());
        return ReadResult::kRotation;
      }
    } else if (status == driver::ReadStatus::kEnd || status == driver::ReadStatus::kError) {
      if (!decided_ && !draining_) decide();
      source_ended_ = true;
      continue;
    } else if (batcher_) {
      // A pause or silence of the source: the batcher's window releases, or flushes, by itself.
      const double silent_s = std::chrono::duration<double>(Clock::now() - last_data_).count();
      if (batcher_->idle(silent_s, scan)) return ReadResult::kRotation;
    }
    now = Clock::now();
    stamp_data(now);
    if (now >= deadline) return ReadResult::kTimeout;
  }
}

const Scan* CaptureReader::next() {
  for (;;) {
    switch (read(own_, 1000ms)) {
      case ReadResult::kRotation:
        return &own_;
      case ReadResult::kTimeout:
        continue;
      case ReadResult::kEnd:
        return nullptr;
    }
  }
}

}  // namespace lidartag::velodyne
