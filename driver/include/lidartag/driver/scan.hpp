// A whole rotation as a struct of arrays, rings x columns (x returns).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace lidartag {

// What a point is, as the sensor reports it (dual mode tells the echoes apart).
enum class ReturnType : uint8_t {
  kNone = 0,       // no return in this cell
  kStrongest = 1,  // single strongest mode, or the strongest echo of a dual pair
  kLast = 2,       // single last mode, or the last echo of a dual pair
  kBoth = 3,       // dual mode, the strongest echo is also the last one (one point)
  kSecond = 4,     // dual mode, second strongest (the strongest was also the last)
};

// One rotation. Storage is laid out ring-major: the cells of one ring and one return are contiguous
// in column (firing) order, so a detector walks a ring as a plain array. A column is one firing
// sequence of all lasers; columns are appended in firing order, so missing packets leave no holes
// (see `missing_packets`) and `column_azimuth_deg` is monotonic from the cut.
// Sized once by reserve(); reused from a pool afterwards, never reallocated in steady state.
struct Scan {
  int rings = 0;            // number of lasers; ring 0 is the lowest beam
  int returns = 1;          // 1 in single-return modes, 2 in dual mode
  int column_capacity = 0;  // allocated columns per ring
  int columns = 0;          // columns filled in this rotation

  // Per cell, index with at(ret, ring, col); at least rings x returns x column_capacity cells
  // (more when the scan had a larger shape before). range == 0 marks "no return".
  std::vector<float> x, y, z;           // metres, sensor frame (x forward, y left, z up)
  std::vector<float> range;             // metres, after distance correction; 0 = no return
  std::vector<float> azimuth_deg;       // firing-time azimuth with the laser's offset, [0, 360)
  std::vector<float> time_s;            // seconds from the rotation start (first column's firing)
  std::vector<uint8_t> intensity;       // calibrated reflectivity, 0..255
  std::vector<ReturnType> return_type;  // see ReturnType

  // Per ring: the sensor's laser (channel) id of each ring, from the calibration in use.
  std::vector<uint8_t> laser_id;

  // Per column.
  std::vector<float> column_azimuth_deg;  // azimuth of the column's first firing, [0, 360)
  std::vector<double> column_time_s;      // seconds from the rotation start

  // Per rotation.
  uint64_t sequence = 0;       // rotation counter of the batcher that produced it
  int64_t stamp_ns = 0;        // absolute time of the first column's firing, ns since epoch
  uint8_t model = 0;           // lidartag::velodyne::Model, as a number (the scan knows no driver)
  uint8_t return_mode = 0;     // packet return-mode byte: 0x37, 0x38, 0x39
  bool complete = false;       // began and ended at the cut with no packet lost
  bool starts_at_cut = false;  // false for the first, partial rotation of a stream
  bool ends_at_cut = false;    // false when flushed (stream stopped or jumped)
  uint32_t packets = 0;        // data packets that contributed columns
  uint32_t missing_packets = 0;  // packets lost inside this rotation (timestamp gaps)
  uint32_t azimuth_jumps = 0;    // discontinuities not explained by loss or a known FOV gap
  float rpm = 0.0f;              // measured rotation rate

  // Lays the storage out for the shape. Storage already large enough is kept as it is, neither
  // shrunk nor cleared (every cell of a column is written when the column is appended, and only
  // the `columns` filled are read), so a scan used for both single and dual return (up to 26 MB
  // for a VLS-128) is allocated and zero-filled once, not at every change of shape.
  void reserve(int n_rings, int n_returns, int n_columns) {
    rings = n_rings;
    returns = n_returns;
    column_capacity = n_columns;
    const size_t n = static_cast<size_t>(n_rings) * static_cast<size_t>(n_returns) *
                     static_cast<size_t>(n_columns);
    auto at_least = [](auto& v, size_t size) {
      if (v.size() < size) v.resize(size);
    };
    for (auto* v : {&x, &y, &z, &range, &azimuth_deg, &time_s}) at_least(*v, n);
    at_least(intensity, n);
    at_least(return_type, n);
    laser_id.assign(static_cast<size_t>(n_rings), 0);
    at_least(column_azimuth_deg, static_cast<size_t>(n_columns));
    at_least(column_time_s, static_cast<size_t>(n_columns));
    clear();
  }

  // Forget the contents, keep the storage.
  void clear() {
    columns = 0;
    sequence = 0;
    stamp_ns = 0;
    complete = starts_at_cut = ends_at_cut = false;
    packets = missing_packets = azimuth_jumps = 0;
    rpm = 0.0f;
  }

  size_t at(int ret, int ring, int col) const {
    return (static_cast<size_t>(ret) * static_cast<size_t>(rings) + static_cast<size_t>(ring)) *
               static_cast<size_t>(column_capacity) +
           static_cast<size_t>(col);
  }
  bool valid(size_t i) const { return range[i] > 0.0f; }

  // Number of cells with a return.
  size_t point_count() const {
    size_t n = 0;
    for (int r = 0; r < returns; ++r)
      for (int ring = 0; ring < rings; ++ring)
        for (int c = 0; c < columns; ++c) n += valid(at(r, ring, c)) ? 1u : 0u;
    return n;
  }
};

}  // namespace lidartag
