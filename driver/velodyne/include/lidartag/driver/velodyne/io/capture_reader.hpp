// Capture -> rotations: the plumbing shared by `lidartag info/dump/detect` and the daemon's replay.
// PacketSource -> (data: ModelCheck, Decoder with a SensorClock; position: parse_position_packet,
// SensorClock::update) -> ScanBatcher -> the caller's scan (read()), or the reader's own scan
// (next()).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/scan_reader.hpp"
#include "lidartag/driver/velodyne/calibration.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"

namespace lidartag::velodyne {

struct CaptureReaderOptions {
  // Ports tell data from position packets; the file constructor also opens the capture with these
  // options (as fast as possible unless pacing is set).
  driver::PcapSourceOptions source;
  // A ROS bag or MCAP file (driver/bag): the VelodyneScan topic to read; empty: the bag's one
  // LiDAR topic. Unused for pcaps.
  std::string topic;
  // A ROS bag or MCAP file: the time window, seconds from the bag's first message
  // (driver::bag::ReaderOptions::start_s, duration_s). Defaults: the whole bag. Unused for pcaps.
  double bag_start_s = 0;
  double bag_duration_s = std::numeric_limits<double>::infinity();
  // Model to decode as. Empty: the product byte of the data packets, checked against their timing
  // by ModelCheck (see model_mismatch()); the timing's model when the byte names none.
  std::optional<Model> model;
  // Calibration file (ros-drivers YAML or VeloView XML); empty: the model's built-in table.
  std::string calibration_file;
  // Range limits.
  DecoderOptions decoder;
  driver::BatcherOptions batcher;
  // Data packets examined before the model is decided when it is not given (held back, then
  // decoded in order). Only payloads laid out as data packets count (see ModelCheck); ModelCheck
  // needs about ten for the timing. At most max(1024, 4 x this) packets are held; traffic that
  // never completes the probe goes on undecoded past that. A probe that no model fits lets its
  // packets go on undecoded and starts over: nothing before the sensor decides its model.
  size_t probe_packets = 32;
};

// What the reader saw, by kind.
struct CaptureCounts {
  uint64_t data_packets = 0;                // payloads on the data port
  uint64_t position_packets = 0;            // payloads on the position port
  uint64_t decoded = 0;                     // data packets decoded into columns
  std::array<uint64_t, 8> decode_errors{};  // indexed by DecodeStatus (kOk unused)
  uint64_t undecodable = 0;  // data packets with no model to decode them (unknown sensor)
  // Data packets whose product byte and timing contradict the model in use (another model
  // mid-stream, or an explicitly configured wrong model), judged per 64 packets.
  uint64_t model_mismatch = 0;
  uint64_t model_changes = 0;  // models switched to mid-stream (model detected, not configured)
  // Probes after which no model fitted the packets held (their packets went on undecoded and
  // the probe started over).
  uint64_t failed_probes = 0;
  uint64_t position_ok = 0;        // position packets parsed
  uint64_t position_errors = 0;    // wrong size or bad PPS byte
  uint64_t position_checksum = 0;  // of position_ok: NMEA checksum missing or wrong (time unused)
  uint64_t gprmc_valid = 0;        // position packets with a valid GPRMC fix
  PpsStatus pps = PpsStatus::kAbsent;           // of the last parsed position packet
  std::string last_nmea;                        // the last NMEA sentence seen
  int64_t first_time_ns = 0, last_time_ns = 0;  // receive times of the first and last packet
};

// Velodyne's side of the vendor seam (driver::ScanReader).
class CaptureReader final : public driver::ScanReader {
 public:
  // Opens the capture file (IoError) and, with a model given, the calibration (CalibrationError).
  // The file is recognised by content: a ROS 1 bag, ROS 2 bag folder or MCAP file is read through
  // driver::bag::BagPacketSource (its VelodyneScan packets on `options.topic`; packet stamps as
  // receive times), anything else as a pcap or pcapng.
  CaptureReader(const std::string& path, CaptureReaderOptions options);
  // Reads from any source (live or replay); ends when the source reports kEnd or kError.
  CaptureReader(std::unique_ptr<driver::PacketSource> source, CaptureReaderOptions options);
  ~CaptureReader() override;
  CaptureReader(const CaptureReader&) = delete;
  CaptureReader& operator=(const CaptureReader&) = delete;

  using ReadResult = driver::ReadResult;
  // Assembles the next rotation straight into `scan`: returns kRotation as soon as one ends, or
  // kTimeout once `timeout` has passed (also while packets keep coming without ending one). A
  // scan whose shape does not fit the model is reserved for it (a first use, a return-mode
  // change), so the caller's scans may start empty. The rotation in progress is delivered,
  // incomplete, when the source has been silent for BatcherOptions::flush_timeout_s (host time).
  // May throw CalibrationError once, when the model is decided from the data and the calibration
  // file does not fit it.
  [[nodiscard]] ReadResult read(Scan& scan, std::chrono::milliseconds timeout) override;

  // The next rotation (complete or not: see Scan::complete) in the reader's own scan, valid until
  // the next call (which fills the same scan again: the batcher keeps the columns after a cut
  // itself, so one scan is enough, and a reader allocates and zero-fills one, not two: a VLS-128
  // scan is 26 MB); nullptr once the source has ended and everything was flushed.
  // read() underneath, waiting through timeouts; do not mix the two on one reader.
  const Scan* next();

  std::optional<Model> model() const { return model_; }  // empty until decided
  std::optional<ReturnMode> return_mode() const { return mode_; }
  const ModelCheck& model_check() const { return check_; }
  // Empty while the packets fit the model in use. Otherwise what contradicts it: the product byte
  // against the timing of the first packets (ModelCheck), packets of another model mid-stream
  // (with the model detected, the reader then decodes them as that model), or a configured model
  // (or calibration file) that the packets' product byte and timing contradict.
  std::string model_mismatch() const;
  const CaptureCounts& counts() const { return counts_; }
  driver::SourceStats source_stats() const override { return source_->stats(); }
  // Why the source ended before its end (PacketSource::error()); empty if it did not.
  std::string source_error() const override { return source_->error(); }
  driver::BatcherStats batcher_stats() const override;

  // The seam's view (driver::ScanReader): counts() summed by kind; the model decided and, when the
  // packets' timing is that of a model with another timing, that model (evidence_fits);
  // model_mismatch() as the mismatch text.
  driver::ReaderCounts reader_counts() const override;
  driver::SensorDescription description() const override;
  std::string mismatch_text() const override { return model_mismatch(); }
  const SensorClock& clock() const { return clock_; }
  const Calibration* calibration() const;

 private:
  struct Held {
    std::vector<uint8_t> payload;
    int64_t time_ns;
    uint16_t port;
  };

  // Each returns true when `scan` received a finished rotation.
  bool take(const driver::RawPacket& packet, Scan& scan);
  bool handle(std::span<const uint8_t> payload, int64_t time_ns, uint16_t port, Scan& scan);
  void decide();
  // Per data packet after the decision: checks that the packets still fit the model in use.
  // "configured model X but the packets' ... fit Y" (or the calibration file's model).
  std::string configured_mismatch(Model fits, double period_us) const;
  void watch_model(std::span<const uint8_t> payload);
  // Decodes as `model` from now on (what was assembled with the old one is delivered first).
  void switch_model(Model model);

  std::unique_ptr<driver::PacketSource> source_;
  CaptureReaderOptions options_;
  std::unique_ptr<Decoder> decoder_;
  std::unique_ptr<driver::ScanBatcher> batcher_;
  driver::BatcherStats retired_;           // of the batchers of models switched away from
  uint64_t next_sequence_ = 0;             // of a batcher switched away from
  std::unique_ptr<PacketColumns> packet_;  // parsed: the batcher decodes it into the scan
  SensorClock clock_;
  ModelCheck check_;
  CaptureCounts counts_;
  std::optional<Model> model_;
  std::optional<ReturnMode> mode_;
  bool decided_ = false;
  bool draining_ = false;  // the held packets are being handled (after a probe, failed or not)
  bool source_ended_ = false;
  bool finished_ = false;
  // Model watch: a ModelCheck per 64 data packets; two running that contradict the model in use
  // make the reader switch (model detected) or report (model or calibration configured).
  ModelCheck epoch_;
  int mismatched_epochs_ = 0;
  std::optional<Model> switch_to_;
  std::optional<Model> expected_;  // what the configuration or the first packets' timing said
  std::string stream_mismatch_;
  std::vector<Held> held_;  // packets read while probing
  size_t held_next_ = 0;    // the first held packet not handled yet (after the decision)
  std::chrono::steady_clock::time_point last_data_;  // host time of the last data packet
  bool data_unstamped_ = false;  // a data packet came that last_data_ does not stamp yet
  Scan own_;                     // next()'s scan
};

}  // namespace lidartag::velodyne
