#include "lidartag/driver/ouster/io/capture_reader.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <string>
#include <utility>

#include "lidartag/driver/ouster/models.hpp"

namespace lidartag::driver::ouster {

std::string formats_of_size(size_t bytes) {
  std::string out;
  for (int p = 0; p <= static_cast<int>(Profile::kFusaRng15Rfl8Nir8Dual); ++p) {
    for (int pixels : {16, 32, 64, 128}) {
      for (int columns : {8, 16, 32, 64}) {
        SensorInfo info;
        info.profile = static_cast<Profile>(p);
        info.pixels_per_column = pixels;
        info.columns_per_packet = columns;
        if (PacketFormat::of(info).packet_bytes != bytes) continue;
        out += (out.empty() ? "" : ", ") + std::string(profile_name(info.profile)) + " with " +
               std::to_string(pixels) + " pixels and " + std::to_string(columns) +
               " columns per packet";
      }
    }
  }
  return out;
}

CaptureReader::CaptureReader(const std::string& path, const SensorInfo& info,
                             CaptureReaderOptions options)
    : CaptureReader(std::make_unique<PcapSource>(path, options.source), info, options) {}

CaptureReader::CaptureReader(std::unique_ptr<PacketSource> source, const SensorInfo& info,
                             CaptureReaderOptions options)
    : options_(std::move(options)),
      source_(std::move(source)),
      decoder_(info, options_.decoder),
      batcher_(std::make_unique<ScanBatcher>(
          decoder_.layout(), static_cast<uint8_t>(kReturnModeBase + uint8_t(info.profile)),
          info.returns(), options_.batcher)),
      parsed_(std::make_unique<PacketColumns>()),
      model_name_(model_name(info)) {
  // The column window's columns (inclusive ids; a window across the frame's end wraps).
  const int w = info.columns_per_frame;
  const int first = info.column_window[0], last = info.column_window[1];
  const int window = w > 0 ? ((last - first) % w + w) % w + 1 : 0;
  frame_packets_ = info.columns_per_packet > 0
                       ? (window + info.columns_per_packet - 1) / info.columns_per_packet
                       : 0;
}

CaptureReader::~CaptureReader() = default;

bool CaptureReader::whole(const Scan& scan) const {
  return frame_packets_ > 0 && scan.packets == static_cast<uint32_t>(frame_packets_) &&
         scan.missing_packets == 0 && scan.azimuth_jumps == 0;
}

void CaptureReader::deliver(Scan& scan) {
  scan.complete = whole(scan);
  ++counts_.frames;
  if (scan.complete) ++counts_.whole_frames;
  if (options_.destagger && decoder_.destagger(scan)) ++counts_.destaggered;
}

void CaptureReader::note_refusal(DecodeStatus status, std::span<const uint8_t> payload) {
  const auto& st = decoder_.stats().by_status;
  if (st[static_cast<size_t>(status)] != 1) return;  // keep the first of each kind
  if (status == DecodeStatus::kWrongSize) {
    refused_size_ = payload.size();
  } else if (status == DecodeStatus::kWrongInitId || status == DecodeStatus::kWrongSerial) {
    // The size fitted: the header can be read.
    const PacketHeader h = read_packet_header(payload.data(), decoder_.format());
    refused_init_id_ = h.init_id;
    refused_serial_ = h.serial_number;
  }
}

bool CaptureReader::take(const RawPacket& raw, Scan& scan) {
  if (counts_.lidar_packets + counts_.imu_packets + counts_.other_packets == 0)
    counts_.first_time_ns = raw.receive_time_ns;
  counts_.last_time_ns = raw.receive_time_ns;
  if (raw.destination_port != options_.source.data_port) {
    // The IMU port (the sources deliver no other): never lidar data.
    ++(raw.payload.size() == kImuPacketSize ? counts_.imu_packets : counts_.other_packets);
    return false;
  }
  ++counts_.lidar_packets;
  last_data_ = std::chrono::steady_clock::now();
  const DecodeStatus s = decoder_.parse(raw.payload, *parsed_);
  if (s != DecodeStatus::kOk) {
    note_refusal(s, raw.payload);
    return false;
  }
  return batcher_->add(*parsed_, scan);
}

ReadResult CaptureReader::read(Scan& scan, std::chrono::milliseconds timeout) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    if (finished_) return ReadResult::kEnd;
    if (ended_) {
      // The reorder window may still hold the start of another frame: one per call.
      if (batcher_->flush(scan)) {
        deliver(scan);
        return ReadResult::kRotation;
      }
      finished_ = true;
      return ReadResult::kEnd;
    }
    // Rounded up: a source that waits the whole timeout returns after the deadline.
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now());
    RawPacket raw;
    const ReadStatus status = source_->next(raw, std::max(left, std::chrono::milliseconds::zero()));
    if (status == ReadStatus::kPacket) {
      if (take(raw, scan)) {
        deliver(scan);
        return ReadResult::kRotation;
      }
    } else if (status == ReadStatus::kEnd || status == ReadStatus::kError) {
      ended_ = true;
      continue;
    } else if (counts_.lidar_packets > 0) {
      // A pause or silence of the source: the window releases, or flushes, by itself.
      const double silent_s = std::chrono::duration<double>(Clock::now() - last_data_).count();
      if (batcher_->idle(silent_s, scan)) {
        deliver(scan);
        return ReadResult::kRotation;
      }
    }
    if (Clock::now() >= deadline) return ReadResult::kTimeout;
  }
}

const Scan* CaptureReader::next() {
  Scan& scan = own_[own_next_];
  for (;;) {
    switch (read(scan, std::chrono::milliseconds(1000))) {
      case ReadResult::kRotation:
        own_next_ ^= 1;
        return &scan;
      case ReadResult::kTimeout:
        continue;  // capture timing: the next packet is not due yet
      case ReadResult::kEnd:
        return nullptr;
    }
  }
}

ReaderCounts CaptureReader::reader_counts() const {
  const auto& st = decoder_.stats().by_status;
  const auto at = [&st](DecodeStatus s) { return st[static_cast<size_t>(s)]; };
  ReaderCounts r;
  r.data_packets = counts_.lidar_packets;
  r.decoded = at(DecodeStatus::kOk);
  r.refused_mismatch = at(DecodeStatus::kWrongSize) + at(DecodeStatus::kWrongInitId) +
                       at(DecodeStatus::kWrongSerial) + at(DecodeStatus::kBadMeasurementId);
  r.model_mismatch = r.refused_mismatch;
  r.refused = decoder_.stats().rejected() - r.refused_mismatch + counts_.other_packets;
  r.aux_packets = counts_.imu_packets;
  return r;
}

SensorDescription CaptureReader::description() const {
  SensorDescription d;
  d.vendor = "ouster";
  d.model = model_name_;
  d.return_mode = profile_name(decoder_.info().profile);
  return d;
}

std::string CaptureReader::metadata_mismatch() const {
  const auto& st = decoder_.stats().by_status;
  const SensorInfo& info = decoder_.info();
  const PacketFormat& f = decoder_.format();
  std::string out;
  auto add = [&out](const std::string& s) { out += (out.empty() ? "" : "; ") + s; };
  if (const uint64_t n = st[static_cast<size_t>(DecodeStatus::kWrongSize)]; n > 0) {
    const std::string fits = formats_of_size(refused_size_);
    add(std::to_string(n) + " of " + std::to_string(counts_.lidar_packets) +
        " lidar packets are not " + std::to_string(f.packet_bytes) +
        " bytes long, the size of the metadata's profile " +
        std::string(profile_name(info.profile)) + " with " + std::to_string(f.pixels) +
        " pixels and " + std::to_string(f.columns) + " columns per packet (the first is " +
        std::to_string(refused_size_) + " bytes" +
        (fits.empty() ? ", no Ouster format's size" : ": " + fits) + ")");
  }
  // The init id is checked first: a packet of another sensor is refused for it too, its serial
  // number then tells the two cases apart.
  const uint64_t ids = st[static_cast<size_t>(DecodeStatus::kWrongInitId)] +
                       st[static_cast<size_t>(DecodeStatus::kWrongSerial)];
  if (ids > 0) {
    const bool other_sensor = info.serial_number != 0 && refused_serial_ != info.serial_number;
    add(std::to_string(ids) + " lidar packets carry init id " + std::to_string(refused_init_id_) +
        " and serial number " + std::to_string(refused_serial_) + ", not the metadata's " +
        std::to_string(info.init_id) + " and " + std::to_string(info.serial_number) +
        (other_sensor ? " (another sensor)" : " (another configuration of the sensor)"));
  }
  if (const uint64_t n = st[static_cast<size_t>(DecodeStatus::kBadMeasurementId)]; n > 0) {
    add(std::to_string(n) + " lidar packets have measurement ids beyond the metadata's " +
        std::to_string(info.columns_per_frame) + " columns per frame (another lidar mode)");
  }
  return out;
}

void CaptureReader::require_frames(const std::string& path) const {
  const auto& st = decoder_.stats();
  const uint64_t accepted = st.by_status[static_cast<size_t>(DecodeStatus::kOk)];
  const std::string mismatch = metadata_mismatch();
  if (accepted == 0 && !mismatch.empty()) {
    throw MetadataMismatch(path +
                           ": the metadata does not describe this capture's sensor: " + mismatch +
                           " (give the metadata this sensor reported in this configuration: "
                           "--metadata FILE.json)");
  }
  if (counts_.frames > 0) return;
  const auto src = source_->stats();
  throw std::runtime_error(
      path + ": no frame: " + std::to_string(counts_.lidar_packets) + " lidar packets on port " +
      std::to_string(options_.source.data_port) + " (" + std::to_string(accepted) + " accepted, " +
      std::to_string(st.rejected()) + " refused), " + std::to_string(counts_.imu_packets) +
      " IMU packets on port " + std::to_string(options_.source.position_port) + ", " +
      std::to_string(src.ignored) + " other packets ignored (check --data-port, --sensor)");
}

}  // namespace lidartag::driver::ouster
