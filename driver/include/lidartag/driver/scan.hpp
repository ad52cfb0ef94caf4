// A whole rotation as a struct of arrays, rings x columns (x returns).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "lidartag/driver/reusing_allocator.hpp"

namespace lidartag {

// The per-cell storage of a scan: a std::vector but for resize(), which does not zero-fill, and
// for its blocks, which the thread reuses (ReusingAllocator).
template <class T>
using CellArray = std::vector<T, ReusingAllocator<T>>;

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
// Sized once by reserve() or reserve_lazily(); reused from a pool afterwards, never reallocated in
// steady state.
struct Scan {
  int rings = 0;            // number of lasers; ring 0 is the lowest beam
  int returns = 1;          // 1 in single-return modes, 2 in dual mode
  int column_capacity = 0;  // allocated columns per ring
  int columns = 0;          // columns filled in this rotation

  // Per cell, index with at(ret, ring, col); at least rings x returns x column_capacity cells
  // (more when the scan had a larger shape before). range == 0 marks "no return".
  CellArray<float> x, y, z;           // metres, sensor frame (x forward, y left, z up)
  CellArray<float> range;             // metres, after distance correction; 0 = no return
  CellArray<float> azimuth_deg;       // firing-time azimuth with the laser's offset, [0, 360)
  CellArray<float> time_s;            // seconds from the rotation start (first column's firing)
  CellArray<uint8_t> intensity;       // calibrated reflectivity, 0..255
  CellArray<ReturnType> return_type;  // see ReturnType

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

  // Storage that reserve_lazily() added and that no writer has reached yet: the cells at index
  // `fresh_from` and beyond in the columns from `prepared_columns` on. They hold nothing yet (not
  // even zeros): prepare_columns() zeroes them before a writer writes there, so that every cell
  // reads as reserve() would have left it. kNoFreshCells: none.
  static constexpr size_t kNoFreshCells = static_cast<size_t>(-1);
  size_t fresh_from = kNoFreshCells;
  int prepared_columns = 0;

  // Lays the storage out for the shape. Storage already large enough is kept as it is, neither
  // shrunk nor cleared (every cell of a column is written when the column is appended, and only
  // the `columns` filled are read), so a scan used for both single and dual return (up to 26 MB
  // for a VLS-128) is allocated and zero-filled once, not at every change of shape. Storage added
  // reads as zero (range 0: no return).
  void reserve(int n_rings, int n_returns, int n_columns) {
    const size_t n = shape(n_rings, n_returns, n_columns);
    auto at_least = [n](auto& v) {
      if (v.size() < n) v.resize(n, typename std::decay_t<decltype(v)>::value_type{});
    };
    for (auto* v : {&x, &y, &z, &range, &azimuth_deg, &time_s}) at_least(*v);
    at_least(intensity);
    at_least(return_type);
    fresh_from = kNoFreshCells;
    clear();
  }

  // As reserve(), but the storage added is neither zero-filled nor touched here: prepare_columns()
  // zeroes each column's share of it when a writer first reaches that column. For a writer that
  // appends columns in order (the driver's rotation assembler): a scan sized for a 300 rpm
  // rotation costs only the columns filled (a reader of a short capture page-faulted and zeroed
  // the whole scan, 1.6 MB for a VLP-16, 13 MB for a VLS-128, before its first rotation).
  void reserve_lazily(int n_rings, int n_returns, int n_columns) {
    const size_t n = shape(n_rings, n_returns, n_columns);
    size_t have = n;
    for (const size_t s : {x.size(), y.size(), z.size(), range.size(), azimuth_deg.size(),
                           time_s.size(), intensity.size(), return_type.size()})
      have = std::min(have, s);
    for (auto* v : {&x, &y, &z, &range, &azimuth_deg, &time_s})
      if (v->size() < n) v->resize(n);
    if (intensity.size() < n) intensity.resize(n);
    if (return_type.size() < n) return_type.resize(n);
    fresh_from = have < n ? have : kNoFreshCells;
    prepared_columns = 0;
    clear();
  }

  // Columns [0, end) may be written and read: zeroes what reserve_lazily() left unwritten in
  // them, but for the cells of returns [0, written_returns) in columns [written_from, end), which
  // the caller is about to write whole (every field).
  void prepare_columns(int end, int written_from = 0, int written_returns = 0) {
    end = std::min(end, column_capacity);
    if (fresh_from == kNoFreshCells || end <= prepared_columns) return;
    const int zero_to = std::clamp(written_from, prepared_columns, end);
    for (int r = 0; r < returns; ++r)
      for (int ring = 0; ring < rings; ++ring) {
        const size_t from = std::max(at(r, ring, prepared_columns), fresh_from);
        const size_t to = at(r, ring, r < written_returns ? zero_to : end);
        if (from >= to) continue;
        const auto b = static_cast<std::ptrdiff_t>(from), e = static_cast<std::ptrdiff_t>(to);
        for (auto* v : {&x, &y, &z, &range, &azimuth_deg, &time_s})
          std::fill(v->begin() + b, v->begin() + e, 0.0f);
        std::fill(intensity.begin() + b, intensity.begin() + e, uint8_t{0});
        std::fill(return_type.begin() + b, return_type.begin() + e, ReturnType::kNone);
      }
    prepared_columns = end;
    if (end == column_capacity) fresh_from = kNoFreshCells;
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

 private:
  // The new shape (after zeroing what a lazy reserve left of the old one, whose layout it
  // changes), the per-ring and per-column storage; the number of cells it needs.
  size_t shape(int n_rings, int n_returns, int n_columns) {
    prepare_columns(column_capacity);
    rings = n_rings;
    returns = n_returns;
    column_capacity = n_columns;
    laser_id.assign(static_cast<size_t>(n_rings), 0);
    if (column_azimuth_deg.size() < static_cast<size_t>(n_columns))
      column_azimuth_deg.resize(static_cast<size_t>(n_columns));
    if (column_time_s.size() < static_cast<size_t>(n_columns))
      column_time_s.resize(static_cast<size_t>(n_columns));
    return static_cast<size_t>(n_rings) * static_cast<size_t>(n_returns) *
           static_cast<size_t>(n_columns);
  }
};

}  // namespace lidartag
