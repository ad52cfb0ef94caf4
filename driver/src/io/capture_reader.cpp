#include "lidartag/driver/io/capture_reader.hpp"

#include <algorithm>

#include "lidartag/driver/io/calibration_file.hpp"

namespace lidartag::velodyne {

using namespace std::chrono_literals;

namespace {
// Packets held back while probing: this many, or 4 x probe_packets when that is more.
constexpr size_t kMinHeld = 1024;
}  // namespace

// A fixed set of scans: the batcher fills one at a time and publishes it into a queue that
// next() drains. Scans are sized for the current return mode when handed to the batcher.
class CaptureReader::Pool final : public ScanSink {
 public:
  Pool(size_t size, int rings, int columns) : rings_(rings), columns_(columns) {
    for (size_t i = 0; i < size; ++i) {
      scans_.push_back(std::make_unique<Scan>());
      free_.push_back(scans_.back().get());
    }
  }
  void set_returns(int returns) { returns_ = returns; }
  Scan* acquire() override {
    if (free_.empty()) return nullptr;
    Scan* s = free_.back();
    free_.pop_back();
    if (s->rings != rings_ || s->returns != returns_ || s->column_capacity != columns_) {
      s->reserve(rings_, returns_, columns_);  // first use, or the return mode changed
    }
    return s;
  }
  void publish(Scan* scan) override { ready_.push_back(scan); }
  void release(Scan* scan) { free_.push_back(scan); }
  Scan* pop() {
    if (ready_.empty()) return nullptr;
    Scan* s = ready_.front();
    ready_.pop_front();
    return s;
  }

 private:
  std::vector<std::unique_ptr<Scan>> scans_;
  std::vector<Scan*> free_;
  std::deque<Scan*> ready_;
  int rings_, columns_, returns_ = 1;
};

CaptureReader::CaptureReader(const std::string& path, CaptureReaderOptions options)
    : CaptureReader(std::make_unique<PcapSource>(path, options.source), options) {}

CaptureReader::CaptureReader(std::unique_ptr<PacketSource> source, CaptureReaderOptions options)
    : source_(std::move(source)),
      options_(std::move(options)),
      packet_(std::make_unique<DecodedPacket>()) {
  if (options_.scan_pool < 2) options_.scan_pool = 2;
  if (options_.model) decide();  // loads the calibration now: errors surface at setup
}

CaptureReader::~CaptureReader() = default;

const Calibration* CaptureReader::calibration() const {
  return decoder_ ? &decoder_->calibration() : nullptr;
}

BatcherStats CaptureReader::batcher_stats() const {
  return batcher_ ? batcher_->stats() : BatcherStats{};
}

void CaptureReader::decide() {
  decided_ = true;
  model_ = options_.model;
  if (!model_) model_ = check_.product_model();
  if (!model_) model_ = check_.timing_model();
  if (model_) {
    Calibration calibration = options_.calibration_file.empty()
                                  ? Calibration::builtin(*model_)
                                  : load_calibration_file(options_.calibration_file, *model_);
    decoder_ = std::make_unique<Decoder>(std::move(calibration), options_.decoder);
    const ModelSpec& spec = model_spec(*model_);
    pool_ =
        std::make_unique<Pool>(options_.scan_pool, spec.lasers, ScanBatcher::column_capacity(spec));
  }
  // Decode what was held back while probing, in arrival order.
  std::vector<Held> held = std::move(held_);
  held_.clear();
  for (const Held& h : held) handle(h.payload, h.time_ns, h.port);
}

void CaptureReader::take(const RawPacket& p) {
  if (counts_.first_time_ns == 0) counts_.first_time_ns = p.receive_time_ns;
  counts_.last_time_ns = p.receive_time_ns;
  if (p.destination_port == options_.source.data_port) check_.add(p.payload);
  if (decided_) {
    handle(p.payload, p.receive_time_ns, p.destination_port);
    return;
  }
  // Traffic that never completes the probe (position packets only, datagrams of another size on
  // the data port) must not be held without bound: past the limit the oldest goes on undecoded
  // (position packets as usual, data packets counted as undecodable), its buffer reused.
  if (held_.size() >= std::max<size_t>(kMinHeld, 4 * options_.probe_packets)) {
    Held oldest = std::move(held_.front());
    held_.erase(held_.begin());
    handle(oldest.payload, oldest.time_ns, oldest.port);
    oldest.payload.assign(p.payload.begin(), p.payload.end());
    oldest.time_ns = p.receive_time_ns;
    oldest.port = p.destination_port;
    held_.push_back(std::move(oldest));
  } else {
    held_.push_back({{p.payload.begin(), p.payload.end()}, p.receive_time_ns, p.destination_port});
  }
  if (check_.packets() >= options_.probe_packets) decide();
}

void CaptureReader::handle(std::span<const uint8_t> payload, int64_t time_ns, uint16_t port) {
  if (port == options_.source.position_port) {
    ++counts_.position_packets;
    PositionPacket position;
    if (parse_position_packet(payload, position) != PositionStatus::kOk) {
      ++counts_.position_errors;
      return;
    }
    ++counts_.position_ok;
    counts_.pps = position.pps;
    counts_.last_nmea = std::string(position.sentence());
    if (position.has_gprmc) ++counts_.gprmc_valid;
    clock_.update(position);
    return;
  }
  if (port != options_.source.data_port) return;
  ++counts_.data_packets;
  if (!decoder_) {
    ++counts_.undecodable;
    return;
  }
  const DecodeStatus status = decoder_->decode(payload, clock_, time_ns, *packet_);
  if (status != DecodeStatus::kOk) {
    const auto index = static_cast<size_t>(status);
    if (index < counts_.decode_errors.size()) ++counts_.decode_errors[index];
    return;
  }
  ++counts_.decoded;
  if (!batcher_) {
    mode_ = packet_->mode;
    batcher_ =
        std::make_unique<ScanBatcher>(decoder_->spec(), packet_->mode, options_.batcher, *pool_);
  }
  mode_ = packet_->mode;
  pool_->set_returns(packet_->returns);
  batcher_->poll(packet_->stamp_ns);
  batcher_->add(*packet_);
}

const Scan* CaptureReader::next() {
  if (out_ != nullptr) {
    pool_->release(out_);
    out_ = nullptr;
  }
  for (;;) {
    if (pool_) {
      out_ = pool_->pop();
      if (out_ != nullptr) return out_;
    }
    if (finished_) return nullptr;
    RawPacket packet;
    const ReadStatus status = source_->next(packet, 1000ms);
    if (status == ReadStatus::kPacket) {
      take(packet);
    } else if (status == ReadStatus::kEnd || status == ReadStatus::kError) {
      if (!decided_) decide();
      if (batcher_) batcher_->flush();
      finished_ = true;
    }
  }
}

}  // namespace lidartag::velodyne
