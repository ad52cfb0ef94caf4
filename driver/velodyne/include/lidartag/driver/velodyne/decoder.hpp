// Velodyne data packet -> points of up to 24 columns, in ring order; the decoder behind the
// assembly's seam (lidartag/driver/columns.hpp). Pure: no I/O, no allocation per packet.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/calibration.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/options/rules.hpp"

namespace lidartag::velodyne {

enum class DecodeStatus : uint8_t {
  kOk = 0,
  kWrongSize,      // payload is not 1206 bytes
  kBadBlockFlag,   // a block does not start with a flag of this model
  kBadAzimuth,     // an azimuth above 35999
  kBadReturnMode,  // byte 1204 is not 0x37/0x38/0x39 (0x00, old firmware, reads as strongest)
};
std::string_view decode_status_name(DecodeStatus s);

using driver::PointSink;

// The SensorLayout of a model (driver/columns.hpp): what the shared assembly knows of it. Rotations
// are delimited by the cut azimuth; Scan::model is the Model's number.
driver::SensorLayout sensor_layout(const ModelSpec& spec);
// Returns per column in this mode: 2 in dual mode, else 1.
constexpr int returns_of(ReturnMode mode) {
  return mode == ReturnMode::kDual ? 2 : 1;
}
// The shared batcher for this model's packets, `mode` expected first.
inline driver::ScanBatcher make_batcher(const ModelSpec& spec, ReturnMode mode,
                                        driver::BatcherOptions options = {}) {
  return driver::ScanBatcher(sensor_layout(spec), static_cast<uint8_t>(mode), returns_of(mode),
                             options);
}

// What Decoder::parse() reads of a data packet: the assembly's header (its columns' azimuths,
// times and spin rates, its shape; return_mode is byte 1204, returns 2 in dual mode) and what
// write_points() needs to decode the points of any run of its columns later, from `payload`
// (which must then still be valid: a copy of this struct may point it at a copy of the bytes).
struct PacketColumns : driver::ColumnPacket {
  uint32_t usec_since_hour = 0;  // packet timestamp field
  // Per column, what every point of the column shares: the firing azimuth's cos/sin, the spin
  // rate in rad per us, the firing time (us, float) and, per echo and bank, the payload offset of
  // the column's channel 0.
  std::array<float, kMaxColumns> cos_az{}, sin_az{}, rate_rad{}, time0_us{};
  std::array<std::array<std::array<uint16_t, 4>, 2>, kMaxColumns> channel_offset{};

  ReturnMode mode() const { return static_cast<ReturnMode>(return_mode); }
};

// A data packet with its points (Decoder::decode()). Cells are indexed [ret][ring][col]
// (ring-major like Scan); ring 0 is the lowest beam.
struct DecodedPacket : PacketColumns {
  static constexpr int kMaxCells = 2 * 384;  // returns x columns x rings, all models

  std::array<float, kMaxCells> x{}, y{}, z{}, range{}, azimuth_deg{}, time_us{};
  std::array<uint8_t, kMaxCells> intensity{};
  std::array<ReturnType, kMaxCells> return_type{};

  int at(int ret, int col, int ring) const { return (ret * rings + ring) * columns + col; }
};

namespace detail {
// The columns of a driver::ColumnBatch gathered for the ring-by-ring kernel (Decoder::write_batch):
// every ring's run is then long, also for packets of few columns (VLS-128: 3, dual 1). The
// packets' bytes must still be valid when the batch is written.
struct BatchColumns {
  static constexpr int kMaxColumns = driver::ColumnBatch::kMaxColumns;
  int columns = 0;
  int returns = 1;
  ReturnMode mode = ReturnMode::kStrongest;
  // Per column: its packet's bytes and channel offsets, and what compute_firing() needs; the time
  // offset of its run (written times are time_offset + t_us * PointSink::time_scale).
  // (Not zeroed: a batch is gathered on the stack per write, and only its `columns` are read.)
  std::array<const uint8_t*, kMaxColumns> payload;
  std::array<std::array<std::array<uint16_t, 4>, 2>, kMaxColumns> channel_offset;
  std::array<float, kMaxColumns> cos_az, sin_az, azimuth_deg, rate_deg, rate_rad, time0_us,
      time_offset;

  // Adds `count` columns of `packet` from `first`; false (nothing added) when they do not fit or
  // the packet's return mode differs from the batch's.
  bool append(const PacketColumns& packet, int first, int count, float time_offset);
};

// Per-laser constants of the per-point loop, a struct of arrays so that it vectorises. Floats:
// 24 bits resolve 15 um at 200 m, well below the 2-4 mm distance unit.
struct LaserTable {
  std::array<float, 128> cos_el, sin_el;    // elevation
  std::array<float, 128> v_sin, v_cos;      // vertical offset times sin/cos of the elevation
  std::array<float, 128> horiz_offset_m;    // perpendicular to the beam
  std::array<double, 128> dist_offset_m;    // double: range = the packet's distance, rounded once
  std::array<float, 128> time_us;           // firing time within the firing sequence
  std::array<float, 128> az_offset_deg;     // subtracted from the firing azimuth
  std::array<float, 128> cos_off, sin_off;  // of the azimuth offset
  std::array<int, 128> ring;
};
}  // namespace detail

// The model decoded is the calibration's: the caller picks it from configuration or from the
// product byte (ModelCheck tells whether that byte fits the packets' timing).
struct DecoderOptions {
  // Returns closer than this or farther than max are dropped. <= 0: the model's own limits.
  double min_range_m = 0.0;
  double max_range_m = 0.0;
};

// The rule table of DecoderOptions (lidartag/options/rules.hpp). Between fields (max above min,
// min below the model's range) the configuration checks, which knows the model.
template <class V>
void visit_decoder_options(V& v, DecoderOptions& o) {
  using namespace rules;
  v.field("min_range_m", o.min_range_m, at_least(0.0), "m");
  v.field("max_range_m", o.max_range_m, at_least(0.0), "m");
}

// Decodes data packets of one sensor. Holds the calibration, per-laser constants and the last
// measured rotation rate (used where a packet's own azimuths cannot give it).
class Decoder final : public driver::ColumnDecoder {
 public:
  // `calibration.model` is the model decoded; the calibration must match it (lasers count).
  explicit Decoder(Calibration calibration, DecoderOptions options = {});

  // Decodes `payload` into `out`; `clock` turns the packet timestamp into absolute time.
  [[nodiscard]] DecodeStatus decode(std::span<const uint8_t> payload, const SensorClock& clock,
                                    int64_t receive_time_ns, DecodedPacket& out);
  // Checks `payload` and reads its header and column azimuths and times, not its points: the
  // batcher then has write_points() put each column straight where it belongs in the scan. On an
  // error `out` is left untouched. `payload` must outlive the use of `out`.
  [[nodiscard]] DecodeStatus parse(std::span<const uint8_t> payload, const SensorClock& clock,
                                   int64_t receive_time_ns, PacketColumns& out);
  // The points of a batch of columns (of packets this decoder parsed) into `sink` (its
  // time_offset unused: each run has one). Never allocates.
  void write_batch(const driver::ColumnBatch& batch, const PointSink& sink) const override;
  driver::ColumnPacket* copy_packet(const driver::ColumnPacket& packet,
                                    std::span<std::byte> storage) const override;
  // The points of `count` columns from `first` of a parsed packet into `sink`. Never allocates.
  void write_points(const PacketColumns& packet, int first, int count, const PointSink& sink) const;

  const Calibration& calibration() const { return calibration_; }
  const ModelSpec& spec() const { return *spec_; }
  // Last rotation rate measured from block azimuths, degrees per microsecond.
  double rate_deg_per_us() const { return rate_deg_per_us_; }

 private:
  Calibration calibration_;
  DecoderOptions options_;
  // The ring-by-ring kernel over gathered columns.
  void write_columns(const detail::BatchColumns& batch, const PointSink& sink) const;

  const ModelSpec* spec_;
  double min_range_m_, max_range_m_;
  detail::LaserTable lasers_{};
  std::array<uint8_t, 128> laser_of_ring_{};
  double rate_deg_per_us_;
  const float* trig_table_;  // cos, sin of the azimuth in 0.01 deg steps, 36002 pairs
  // Previous packet, to measure the rate where a packet holds one azimuth (VLS-128 dual).
  bool have_previous_ = false;
  uint16_t previous_azimuth_ = 0;
  uint32_t previous_usec_ = 0;
};

// Reads the model and return mode bytes of a data packet without decoding it.
struct PacketHeader {
  uint8_t product_id = 0;
  uint8_t return_mode = 0;
  uint32_t usec_since_hour = 0;
};
[[nodiscard]] bool read_header(std::span<const uint8_t> payload, PacketHeader& out);

// Model autodetection checked against structure and timing: accumulates the packets' timestamp
// steps and block flags, and tells which model they fit, so that a capture whose product byte
// contradicts its timing is noticed (the real VLP-16 captures with product byte 0x21 exist).
// Only payloads laid out as data packets count (1206 bytes, the flags of the first 8 blocks, which
// every model fills, among kBankFlags):
// junk of the probe's size (zeros, random bytes) neither votes nor adds timing, and no single
// packet decides: the product byte is the one most packets carry.
class ModelCheck {
 public:
  void add(std::span<const uint8_t> payload);
  // The model named by the product byte of more than half of the packets counted; empty while
  // none is (or the byte names no known model).
  std::optional<Model> product_model() const;
  std::optional<Model> timing_model() const;
  // The packet period on the sensor's clock (microseconds; 0 until known), robust to loss.
  double packet_period_us() const;
  std::optional<ReturnMode> return_mode() const { return mode_; }
  // Human-readable mismatch, empty when the product byte fits the timing.
  std::string mismatch() const;
  size_t packets() const { return packets_; }    // payloads counted (laid out as data packets)
  size_t rejected() const { return rejected_; }  // payloads of 1206 bytes that were not

 private:
  std::array<uint32_t, 256> product_votes_{};  // packets counted per product byte
  uint8_t leading_product_ = 0;                // the byte with the most votes
  std::optional<ReturnMode> mode_;
  std::array<uint32_t, 64> steps_{};
  size_t step_count_ = 0;
  size_t packets_ = 0;
  size_t rejected_ = 0;
  bool has_bank_flags_ = false;
  std::optional<uint32_t> last_usec_;
};

// True when `payload` is laid out as a data packet: 1206 bytes, the first 8 block flags known.
[[nodiscard]] bool looks_like_data_packet(std::span<const uint8_t> payload);

}  // namespace lidartag::velodyne
