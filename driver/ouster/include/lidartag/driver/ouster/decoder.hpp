// Ouster lidar packet -> points, the decoder behind the assembly's seam
// (lidartag/driver/columns.hpp): rotations are the sensor's frames (RotationDelimiter::kFrameId).
// Pure: no I/O; parse() and write_batch() never throw or allocate.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>
#include <vector>

#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/ouster/packet.hpp"
#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::driver::ouster {

// Scan::model of Ouster scans (Velodyne's models are 1..5); Scan::return_mode is
// kReturnModeBase + the Profile's number.
inline constexpr uint8_t kScanModel = 0x80;
inline constexpr uint8_t kReturnModeBase = 0x80;

enum class DecodeStatus : uint8_t {
  kOk = 0,
  kWrongSize,         // not the metadata's packet size for its profile and shape
  kWrongPacketType,   // the header's packet type is not lidar data (0x1)
  kWrongInitId,       // the header's init id is not the metadata's (another configuration)
  kWrongSerial,       // the header's serial number is not the metadata's (another sensor)
  kBadMeasurementId,  // a valid column's measurement id beyond the frame's columns
  kNoValidColumn,     // every column's status bit clear: nothing to place in a frame
  kBadTimestamp,      // a valid column's timestamp at or beyond 2^32 s (driver::kMaxReceiveTimeNs)
};
inline constexpr int kDecodeStatusCount = 8;
std::string_view decode_status_name(DecodeStatus s);

// Where the 8-bit intensity of the points comes from.
enum class IntensitySource : uint8_t {
  kReflectivity,  // calibrated reflectivity, 0..255 as sent (REFLECTIVITY / REFLECTIVITY2)
  kSignal,        // signal photons (SIGNAL / SIGNAL2), clamped to 255; RNG19 profiles only
};

struct DecoderOptions {
  // The points' intensity. Default: reflectivity (what the detector's thresholds assume).
  IntensitySource intensity = IntensitySource::kReflectivity;
  // Packets whose init id / serial number differ from the metadata's are refused (counted) when
  // the metadata names them (non-zero). false: accepted whatever they say.
  bool check_init_id = true;
  bool check_serial = true;
};

// What parse() reads of a packet: the assembly's header (columns' azimuths and times, the frame
// id) and, per column, what write_batch() needs later.
struct PacketColumns : ColumnPacket {
  PacketHeader header;
  std::array<uint16_t, kMaxColumns> measurement_id{};
  std::array<uint8_t, kMaxColumns> valid{};  // the column's status bit
};

// Per-packet outcome counters (parse()).
struct DecoderStats {
  std::array<uint64_t, kDecodeStatusCount> by_status{};  // indexed by DecodeStatus
  uint64_t invalid_columns = 0;  // columns of accepted packets with the status bit clear (holes)
  uint64_t rejected() const {
    uint64_t n = 0;
    for (size_t i = 1; i < by_status.size(); ++i) n += by_status[i];
    return n;
  }
};

// The SensorLayout of a sensor: its frames are the rotations.
SensorLayout sensor_layout(const SensorInfo& info);

// A field of a pixel read with one unaligned 32-bit load from its first byte: the value
// field_value() gives (which reads only the bytes the field spans), for fields within 32 bits,
// on a little-endian host, where the load stays inside the packet (the decoder checks).
struct FastField {
  uint32_t byte = 0, shift = 0, mask = 0, upshift = 0;
  uint32_t read(const uint8_t* pixel) const {
    uint32_t word;
    std::memcpy(&word, pixel + byte, sizeof word);
    return ((word >> shift) & mask) << upshift;
  }
};

class Decoder final : public ColumnDecoder {
 public:
  // Throws std::invalid_argument when the options ask for a field the profile lacks (SIGNAL in
  // RNG15 profiles). `info` comes from load_metadata() (validated).
  explicit Decoder(const SensorInfo& info, DecoderOptions options = {});

  // Checks `payload` (size, packet type, init id, serial number) and reads its headers; its points
  // are written later by write_batch(). On an error `out` is left untouched and the status
  // counted. `payload` must outlive the use of `out`.
  [[nodiscard]] DecodeStatus parse(std::span<const uint8_t> payload, PacketColumns& out);

  void write_batch(const ColumnBatch& batch, const PointSink& sink) const override;
  ColumnPacket* copy_packet(const ColumnPacket& packet,
                            std::span<std::byte> storage) const override;

  const SensorInfo& info() const { return info_; }
  const PacketFormat& format() const { return format_; }
  const SensorLayout& layout() const { return layout_; }
  const DecoderStats& stats() const { return stats_; }
  // The beam (pixel row) of each ring; ring 0 is the lowest beam.
  std::span<const uint8_t> beam_of_ring() const {
    return {beam_of_ring_.data(), static_cast<size_t>(format_.pixels)};
  }
  // The sensor frame's clockwise azimuth of measurement id `m`'s encoder angle, degrees.
  double column_azimuth_deg(int m) const;

  // Applies the metadata's pixel_shift_by_row to a whole frame assembled from this decoder's
  // packets (Scan::columns == columns_per_frame, column c = measurement id c): each ring's cells
  // move from column c to (c + shift) mod columns, so that a column's cells point the same way
  // (Ouster's destaggered image; each cell keeps its own azimuth_deg and time_s, the per-column
  // arrays stay those of the firing). False, the scan untouched, for anything else (a partial
  // frame, a restricted column_window). In place: never allocates.
  bool destagger(Scan& scan) const;

 private:
  SensorInfo info_;
  DecoderOptions options_;
  PacketFormat format_;
  SensorLayout layout_;
  DecoderStats stats_;
  double period_us_;
  double yaw_deg_;  // of lidar_to_sensor_transform, about z
  // Per ring (row-major by ring), the fields the kernel reads.
  std::array<uint8_t, ColumnPacket::kMaxRings> beam_of_ring_{};
  std::array<float, ColumnPacket::kMaxRings> cos_alt_, sin_alt_, cos_az_, sin_az_, az_deg_;
  // The lidar-to-sensor transform in metres, row-major 3x4.
  std::array<float, 12> transform_{};
  float n_m_ = 0;  // lidar_origin_to_beam_origin, metres
  const FieldSpec* range_[2] = {nullptr, nullptr};
  const FieldSpec* intensity_[2] = {nullptr, nullptr};
  // The range and intensity fields read with one load each (fast_fields_: possible here).
  FastField fast_range_[2], fast_intensity_[2];
  bool fast_fields_ = false;
  // Every beam azimuth within (-360, 360) degrees: a cell's azimuth wraps without fmod.
  bool near_azimuths_ = false;
  // cos/sin of the encoder angle of every measurement id.
  std::vector<float> cos_enc_, sin_enc_;
};

}  // namespace lidartag::driver::ouster
