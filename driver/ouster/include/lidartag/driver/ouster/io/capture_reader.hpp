// An Ouster capture read whole, for `lidartag dump/detect/render`: pcap (as fast as possible or at
// capture timing) -> lidar packets (port 7502) through Decoder -> ScanBatcher (the sensor's frames,
// RotationDelimiter::kFrameId) -> destaggered frames; IMU packets (port 7503) counted apart.
// Refused packets are counted by reason (DecoderStats); metadata the packets contradict is named by
// metadata_mismatch() (wrong packet size: another profile, pixel count or columns per packet;
// another init id or serial number: another sensor or configuration).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/scan_reader.hpp"

namespace lidartag::driver::ouster {

// Metadata that the capture's lidar packets contradict (a setup error: the user must give the
// sensor's own metadata). Thrown by CaptureReader::require_frames().
class MetadataMismatch : public MetadataError {
 public:
  using MetadataError::MetadataError;
};

struct CaptureReaderOptions {
  // Ports and pacing; the defaults here are the sensor's ports (lidar 7502, IMU 7503), packets as
  // fast as possible (ReplayPacing::kCaptureTime replays at the capture's timing).
  PcapSourceOptions source = [] {
    PcapSourceOptions o;
    o.data_port = kLidarPort;
    o.position_port = kImuPort;
    return o;
  }();
  DecoderOptions decoder;  // intensity source, identity checks
  BatcherOptions batcher;  // cut_azimuth_deg is not used: frames end where the frame id changes
  // Whole frames are destaggered (Decoder::destagger) before they are handed out: a column's
  // cells point the same way, as in Ouster's destaggered image. false: the firing order.
  bool destagger = true;
};

// What the reader saw.
struct CaptureCounts {
  uint64_t lidar_packets = 0;  // payloads on the lidar port
  uint64_t imu_packets = 0;    // payloads on the IMU port of the IMU packet's size
  uint64_t other_packets = 0;  // payloads on the IMU port of another size
  uint64_t frames = 0;         // frames handed out
  uint64_t whole_frames = 0;   // of those, whole (Scan::complete, see CaptureReader::next())
  uint64_t destaggered = 0;    // frames destaggered
  int64_t first_time_ns = 0, last_time_ns = 0;  // receive times of the first and last packet
};

// Ouster's side of the vendor seam (driver::ScanReader).
class CaptureReader final : public ScanReader {
 public:
  // Opens the capture (IoError) for a sensor described by `info` (load_metadata()); throws
  // std::invalid_argument for decoder options the profile cannot honour (SIGNAL in RNG15).
  CaptureReader(const std::string& path, const SensorInfo& info, CaptureReaderOptions options = {});
  // Reads from any source (live UDP, a bag's packets): lidar packets are those to
  // options.source.data_port, IMU packets those to options.source.position_port.
  CaptureReader(std::unique_ptr<PacketSource> source, const SensorInfo& info,
                CaptureReaderOptions options = {});
  ~CaptureReader() override;
  CaptureReader(const CaptureReader&) = delete;
  CaptureReader& operator=(const CaptureReader&) = delete;

  // The next frame in one of the reader's own two scans, valid until the next call; nullptr once
  // the capture has ended and everything was flushed. Never throws. Scan::complete is set when the
  // frame is whole: every packet of the frame (columns_per_frame / columns_per_packet, of the
  // column window) arrived, none missing. Ouster frames begin at measurement id 0 whatever the
  // capture's start, so a capture's first and last frames are whole when nothing of them was cut
  // off (the shared assembly alone cannot know that: it marks them incomplete).
  // read() underneath, waiting through timeouts; do not mix the two on one reader.
  const Scan* next();

  // ScanReader::read: the next frame straight into `scan` (destaggered and marked complete as
  // next() does). Never throws.
  [[nodiscard]] ReadResult read(Scan& scan, std::chrono::milliseconds timeout) override;
  // The seam's view: lidar packets are the data packets; those refused for contradicting the
  // metadata (another size, init id, serial number or lidar mode) count as model_mismatch and
  // refused_mismatch, the other refusals (and IMU-port packets of another size) as refused; IMU
  // packets are the auxiliary ones. The model is the metadata's ("os1-128"), the return mode its
  // profile; metadata_mismatch() is the mismatch text.
  ReaderCounts reader_counts() const override;
  SensorDescription description() const override;
  std::string mismatch_text() const override { return metadata_mismatch(); }
  const SensorInfo& info() const { return decoder_.info(); }
  const Decoder& decoder() const { return decoder_; }
  const DecoderStats& decoder_stats() const { return decoder_.stats(); }
  const CaptureCounts& counts() const { return counts_; }
  BatcherStats batcher_stats() const override { return batcher_->stats(); }
  SourceStats source_stats() const override { return source_->stats(); }
  // Why the source ended before its end (PcapSource::error()); empty if it did not.
  std::string source_error() const override { return source_->error(); }
  const CaptureReaderOptions& options() const { return options_; }
  // Packets of a whole frame (the column window's columns over columns_per_packet).
  int frame_packets() const { return frame_packets_; }

  // Empty while the lidar packets fit the metadata. Otherwise what they contradict, with what they
  // would fit: "N of M lidar packets are 3392 bytes, not the 24832 of the metadata's profile
  // RNG19_RFL8_SIG16_NIR16 (128 pixels, 16 columns per packet); they fit ..." or "N lidar packets
  // carry serial number X / init id Y, not the metadata's ...".
  std::string metadata_mismatch() const;

  // Throws MetadataMismatch when no packet was accepted and metadata_mismatch() names why (the
  // metadata of another sensor or configuration), else std::runtime_error when no frame was
  // handed out at all. `path` names the capture in the message.
  void require_frames(const std::string& path) const;

 private:
  bool whole(const Scan& scan) const;
  void deliver(Scan& scan);
  void note_refusal(DecodeStatus status, std::span<const uint8_t> payload);
  // One packet of the source; true when it ended a frame in `scan`.
  bool take(const RawPacket& raw, Scan& scan);

  CaptureReaderOptions options_;
  std::unique_ptr<PacketSource> source_;
  Decoder decoder_;
  std::unique_ptr<ScanBatcher> batcher_;
  std::unique_ptr<PacketColumns> parsed_;
  std::array<Scan, 2> own_;
  size_t own_next_ = 0;
  bool ended_ = false;
  bool finished_ = false;
  std::chrono::steady_clock::time_point last_data_;  // host time of the last lidar packet
  std::string model_name_;                           // "os1-128" (description())
  int frame_packets_ = 0;
  // The first refused packet's size (kWrongSize) and identity (kWrongInitId, kWrongSerial).
  size_t refused_size_ = 0;
  uint64_t refused_serial_ = 0;
  uint32_t refused_init_id_ = 0;
  CaptureCounts counts_;
};

// The profiles, pixel counts and columns per packet (8, 16, 32, 64) whose lidar packets are
// `bytes` long, as "RNG15_RFL8_NIR8 with 128 pixels and 16 columns per packet, ..."; empty when
// none is.
std::string formats_of_size(size_t bytes);

}  // namespace lidartag::driver::ouster
