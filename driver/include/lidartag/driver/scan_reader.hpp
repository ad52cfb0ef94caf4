// The seam between a vendor's capture reader and whoever wants rotations (the daemon): packets from
// any PacketSource -> a vendor's decoder -> the shared assembly -> the caller's scan. Each vendor's
// reader (velodyne::CaptureReader, driver::ouster::CaptureReader) implements it; what opens one
// for a file, a bag or a live source by content is driver/sources (open_scan_reader). Nothing here
// names a vendor: the counters and the sensor's description are the same for every one.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

#include "lidartag/driver/assembly/batcher_options.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::driver {

// What read() did.
enum class ReadResult : uint8_t {
  kRotation,  // `scan` holds a whole rotation (complete or not); pass another scan next time
  kTimeout,   // no rotation ended within the timeout: the one in progress stays in `scan`, call
              // again with the same scan
  kEnd,       // the source ended (or failed) and everything was delivered: nothing more
};

// A reader's counters, each only ever growing. Every packet the reader took from its source on the
// data port is decoded, refused as malformed, or refused as contradicting the sensor's description
// (for the vendors whose packets are refused for it): data_packets = decoded + refused +
// refused_mismatch, once the model is decided (packets held back while it is being decided count
// in data_packets only).
struct ReaderCounts {
  uint64_t data_packets = 0;  // payloads on the data (lidar) port
  uint64_t decoded = 0;       // data packets decoded into columns
  // Data packets refused as malformed (bad size, bad header, nothing to decode, no model to decode
  // them with), and auxiliary packets that did not parse.
  uint64_t refused = 0;
  // Data packets that contradict the model in use or the sensor's description. A vendor that
  // decodes them anyway (Velodyne: as the model configured) counts them in `decoded` too; one
  // that refuses them (Ouster: another size, init id, serial number or lidar mode than the
  // metadata's) in refused_mismatch as well.
  uint64_t model_mismatch = 0;
  uint64_t refused_mismatch = 0;
  // The auxiliary port: Velodyne's position packets, Ouster's IMU packets (never decoded as data).
  uint64_t aux_packets = 0;
  uint64_t gprmc_valid = 0;  // Velodyne position packets with a valid GPRMC fix
  int pps = 0;               // Velodyne: the last position packet's PPS status (PpsStatus)
  int time_source = 0;       // 0: the host's clock (or the sensor's own), 1: GPS
};

// What the reader decodes as: names for the status and health (empty until the model is decided).
// The views stay valid, unchanged, as long as the reader lives (static tables, or the reader's
// own description of its metadata).
struct SensorDescription {
  std::string_view vendor;       // "velodyne", "ouster"
  std::string_view model;        // "vlp32c", "os1-128"
  std::string_view return_mode;  // "strongest", "RNG19_RFL8_SIG16_NIR16", ...
  // When the decided model contradicts the packets' own evidence (Velodyne: the packets' timing
  // is that of another model), the model the evidence fits; empty otherwise.
  std::string_view evidence_fits;
};

class ScanReader {
 public:
  virtual ~ScanReader() = default;

  // Assembles the next rotation straight into `scan`: kRotation as soon as one ends, kTimeout once
  // `timeout` has passed (also while packets keep coming without ending one), kEnd once the source
  // ended and everything was delivered. A scan whose shape does not fit is reserved for it, so the
  // caller's scans may start empty. The rotation in progress is delivered, incomplete, when the
  // source has been silent for BatcherOptions::flush_timeout_s (host time). May throw a setup
  // error once (a calibration file that does not fit the model decided from the packets).
  [[nodiscard]] virtual ReadResult read(Scan& scan, std::chrono::milliseconds timeout) = 0;

  virtual ReaderCounts reader_counts() const = 0;
  virtual SensorDescription description() const = 0;
  // Empty while the packets fit the model or sensor description in use; else what contradicts
  // it (allocates: call it when ReaderCounts::model_mismatch changed, not per rotation).
  virtual std::string mismatch_text() const = 0;
  virtual SourceStats source_stats() const = 0;
  // Why the source ended before its end; empty if it did not.
  virtual std::string source_error() const = 0;
  virtual BatcherStats batcher_stats() const = 0;
};

}  // namespace lidartag::driver
