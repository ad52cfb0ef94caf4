// The seam between a vendor's decoder and the shared assembly (docs/driver.md, "Vendors"): what a
// vendor tells the assembly about its sensor (SensorLayout, with its rotation delimiter), the
// header of every parsed packet (ColumnPacket) and the decoder the assembly calls once per batch
// of columns to write their points into the scan (ColumnDecoder). Nothing here knows a vendor.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "lidartag/driver/scan.hpp"

namespace lidartag::driver {

// Where one rotation ends and the next begins, as the vendor's packets say it.
enum class RotationDelimiter : uint8_t {
  // Between the two columns whose firing azimuths straddle BatcherOptions::cut_azimuth_deg
  // (Velodyne: packets carry azimuths, no rotation number).
  kCutAzimuth,
  // Where the packets' frame id changes (frame-numbered sensors, e.g. Ouster): the rotation is
  // the sensor's own frame, whatever the cut azimuth.
  kFrameId,
};

// What the assembly needs to know of a sensor, filled by its vendor from its model tables
// (velodyne::sensor_layout()). Constant for a stream; a change of model makes a new batcher.
struct SensorLayout {
  uint8_t model = 0;              // the vendor's model number, stored in Scan::model
  int rings = 0;                  // beams, the scan's rows
  double column_period_us = 0;    // one column: a firing of every beam, recharge included
  int packet_columns_single = 0;  // columns of a data packet in a single-return mode
  int packet_columns_dual = 0;    // columns of a data packet in a dual-return mode
  size_t max_payload_bytes = 0;  // the most bytes a packet's decoder reads (held packets copy them)
  RotationDelimiter delimiter = RotationDelimiter::kCutAzimuth;
  // kFrameId: frame ids count modulo 2^frame_id_bits (Ouster: 16); a step forward of less than
  // half of that is the next frame (frames lost between are lost packets), any other a jump.
  int frame_id_bits = 16;
  // Columns of a whole frame when the sensor says so (kFrameId); 0: unknown.
  int frame_columns = 0;

  int packet_columns(int returns) const {
    return returns == 2 ? packet_columns_dual : packet_columns_single;
  }
  // Nominal time between data packets, microseconds (independent of the rotation rate).
  double packet_period_us(int returns) const {
    return 1e6 / (1e6 / (column_period_us * packet_columns(returns)));
  }
};

class ColumnDecoder;

// The header of a parsed data packet, what the assembly reads: its columns' azimuths and times,
// its shape, and who decodes its points. A vendor's parsed packet derives from it and adds what
// its decoder needs (velodyne::PacketColumns); it must be trivially copyable and fit
// ColumnPacket::kMaxObjectBytes (the assembly holds copies of it, made by its decoder).
struct ColumnPacket {
  static constexpr int kMaxColumns = 24;
  static constexpr int kMaxRings = 128;
  static constexpr size_t kMaxObjectBytes = 4096;

  int columns = 0;
  int rings = 0;
  int returns = 1;
  // The vendor's code of the return mode (Velodyne: byte 1204), stored in Scan::return_mode:
  // packets of another code are a new stream (the scan's layout may change).
  uint8_t return_mode = 0;
  bool has_frame_id = false;  // a frame-numbered sensor's packet (RotationDelimiter::kFrameId)
  uint32_t frame_id = 0;      // the rotation (frame) the packet's columns belong to
  int64_t stamp_ns = 0;       // absolute time of the packet's first column
  const uint8_t* laser_of_ring = nullptr;               // rings entries, owned by the decoder
  std::array<float, kMaxColumns> column_azimuth_deg{};  // firing azimuth, [0, 360), clockwise
  std::array<double, kMaxColumns> column_time_us{};     // from the packet's first column
  std::array<float, kMaxColumns> rate_deg{};            // spin rate at the column, deg per us

  const ColumnDecoder* decoder = nullptr;  // the one that parsed it
  const uint8_t* payload = nullptr;        // payload_size bytes, which the decoder reads
  size_t payload_size = 0;
};

// Runs of columns of one or several parsed packets (of one decoder and return mode) bound for
// consecutive columns of one scan: what ColumnDecoder::write_batch() writes at once.
struct ColumnBatch {
  static constexpr int kMaxColumns = 48;
  struct Run {
    const ColumnPacket* packet;
    int first, count;   // the packet's columns [first, first + count)
    float time_offset;  // written times are time_offset + t_us * PointSink::time_scale
  };
  int columns = 0;
  int runs = 0;
  int returns = 1;
  uint8_t return_mode = 0;
  std::array<Run, kMaxColumns> run{};

  void clear() { columns = runs = 0; }
  // Adds `count` columns of `packet` from `first`; false (nothing added) when they do not fit or
  // the packet's return mode differs from the batch's.
  bool append(const ColumnPacket& packet, int first, int count, float time_offset) {
    if (count <= 0 || columns + count > kMaxColumns) return false;
    if (columns == 0) {
      return_mode = packet.return_mode;
      returns = packet.returns;
    } else if (packet.return_mode != return_mode) {
      return false;
    }
    run[static_cast<size_t>(runs++)] = {&packet, first, count, time_offset};
    columns += count;
    return true;
  }
};

// Where a decoder puts a run of columns: pointers to the run's first cell of return 0, ring 0,
// per field; cells of the next ring are `ring_stride` further, of return 1 `return_stride`
// further. Times are written as time_offset + t_us * time_scale, t_us from the packet's first
// column.
struct PointSink {
  float *x, *y, *z, *range, *azimuth_deg, *time;
  uint8_t* intensity;
  ReturnType* return_type;
  size_t ring_stride, return_stride;
  float time_offset, time_scale;
};

// A vendor's decoder as the assembly sees it: called once per packet held and once per batch of
// columns (about 32), never per column or point. Neither call throws or allocates.
class ColumnDecoder {
 public:
  virtual ~ColumnDecoder() = default;
  // A copy of `packet` (parsed by this decoder: of its own derived type) built in `storage`
  // (ColumnPacket::kMaxObjectBytes, aligned for any type); its payload pointer is the caller's
  // to set.
  virtual ColumnPacket* copy_packet(const ColumnPacket& packet,
                                    std::span<std::byte> storage) const = 0;
  // The points of a batch of columns into `sink` (its time_offset unused: each run has one):
  // every field of every cell of the batch's returns, whatever the storage held (a scan's new
  // storage is not zeroed before the decoder writes it: Scan::reserve_lazily).
  virtual void write_batch(const ColumnBatch& batch, const PointSink& sink) const = 0;
};

}  // namespace lidartag::driver
