#include "lidartag/driver/velodyne/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <new>
#include <numbers>
#include <type_traits>
#include <vector>

#include "lidartag/driver/angles.hpp"

namespace lidartag::velodyne {

using driver::wrap360;
using driver::wrap_near;

driver::SensorLayout sensor_layout(const ModelSpec& spec) {
  driver::SensorLayout layout;
  layout.model = static_cast<uint8_t>(spec.model);
  layout.rings = spec.lasers;
  layout.column_period_us = spec.firing_period_us;
  layout.packet_columns_single = spec.columns_per_packet(ReturnMode::kStrongest);
  layout.packet_columns_dual = spec.columns_per_packet(ReturnMode::kDual);
  layout.max_payload_bytes = kDataPacketSize;
  layout.delimiter = driver::RotationDelimiter::kCutAzimuth;  // packets carry no rotation number
  return layout;
}

namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
// Fastest plausible spin (1300 rpm) in degrees per microsecond; larger steps are FOV jumps.
constexpr double kMaxRateDegPerUs = 1300.0 * 360.0 / 60e6;
constexpr double kDefaultRateDegPerUs = 600.0 * 360.0 / 60e6;
// Runs of at least this many columns are decoded ring by ring, shorter ones firing by firing.
constexpr int kRingKernelMinColumns = 6;
// The per-ring loops of write_batch() run 8 floats wide where the CPU has AVX2 (a clone chosen
// when the library is loaded; the build itself targets baseline x86-64). AVX2 brings no fused
// multiply-add: the points stay bit-identical to the baseline clone's. GCC only: clang 14 (the fuzz
// build) refuses to clone a member function used before its definition.
#if defined(__x86_64__) && defined(__has_attribute) && !defined(__clang__)
#if __has_attribute(target_clones)
#define LIDARTAG_AVX2_CLONE __attribute__((target_clones("avx2", "default")))
#endif
#endif
#ifndef LIDARTAG_AVX2_CLONE
#define LIDARTAG_AVX2_CLONE
#endif

// cos/sin of the azimuth at 0.01 deg steps; linear interpolation between entries is accurate to
// 4e-9, far below the 0.01 deg resolution of the packets. One spare entry past 360 deg so that an
// index rounded up to 36000 still has a right neighbour. Interleaved (cos, sin): a column's
// lookup reads one cache line, not two (the table is evicted by the scan's writes every rotation).
constexpr int kTrigSteps = 36000;
struct TrigTable {
  std::vector<float> cos_sin;
  TrigTable() : cos_sin(2 * (kTrigSteps + 2)) {
    for (size_t i = 0; i < kTrigSteps + 2; ++i) {
      const double a = static_cast<double>(i) * 0.01 * kDegToRad;
      cos_sin[2 * i] = static_cast<float>(std::cos(a));
      cos_sin[2 * i + 1] = static_cast<float>(std::sin(a));
    }
  }
};
const TrigTable& trig() {
  static const TrigTable t;
  return t;
}

// One firing of up to 32 lasers, in laser order: the echoes in, the points out.
struct FiringPoints {
  std::array<uint16_t, 32> distance;
  std::array<uint8_t, 32> intensity;
  std::array<ReturnType, 32> return_type;
  std::array<float, 32> x, y, z, range, azimuth_deg, time_us;
};

// What every firing of a packet shares: distance unit, range limits, lasers per firing.
struct PacketContext {
  double unit_m, min_range_m, max_range_m;
  int lasers;
};

// The firing's azimuth, its sin/cos, the spin rate and its time from the packet's first firing.
struct Firing {
  float azimuth_deg, cos_az, sin_az, rate_deg_per_us, rate_rad_per_us, time_us;
};

// Dual return: the two blocks' echoes of one cell into the scan's slots. Slot 0 always holds the
// strongest echo; e0 is the last echo, e1 the strongest or second strongest.
inline void sort_echoes(uint16_t d0, uint8_t i0, uint16_t d1, uint8_t i1, uint16_t& da, uint8_t& ia,
                        ReturnType& ta, uint16_t& db, uint8_t& ib, ReturnType& tb) {
  if (d0 == d1 && i0 == i1) {
    da = d0, ia = i0, ta = ReturnType::kBoth;
    db = 0, ib = 0, tb = ReturnType::kNone;
  } else if (d1 != 0 && (d0 == 0 || i1 > i0)) {
    da = d1, ia = i1, ta = ReturnType::kStrongest;
    db = d0, ib = i0, tb = ReturnType::kLast;
  } else {
    da = d0, ia = i0, ta = ReturnType::kLast;
    db = d1, ib = i1, tb = ReturnType::kSecond;
  }
}

// Points of one firing, in laser order, branch-free so that it vectorises. The (cos, sin) of a
// point's azimuth are the firing's, turned by the laser's offset and by eps, the spin during the
// laser's delay in the sequence (under 0.5 deg: two terms of its series are exact to 1e-10).
// ring_points() computes the same expressions in the same order (the results are bit-identical).
void compute_firing(const detail::LaserTable& __restrict t, int base, const PacketContext& cc,
                    const Firing& fr, FiringPoints& __restrict pts) {
  // Invariants in locals: the compiler cannot hoist loads that the stores might alias.
  const auto min_r = static_cast<float>(cc.min_range_m), max_r = static_cast<float>(cc.max_range_m);
  const double unit = cc.unit_m;
  const float cos_az = fr.cos_az, sin_az = fr.sin_az, az0 = fr.azimuth_deg;
  const float rate_deg = fr.rate_deg_per_us, rate_rad = fr.rate_rad_per_us, t0 = fr.time_us;
  const int n = cc.lasers;
  for (int j = 0; j < n; ++j) {
    const auto l = static_cast<size_t>(base + j);
    const auto uj = static_cast<size_t>(j);
    const uint16_t raw = pts.distance[uj];
    const auto d = static_cast<float>(raw * unit + t.dist_offset_m[l]);
    // Invalid returns become zeros by a multiplication, not a branch: GCC would sink the loads
    // of the valid case under the branch and then refuse to vectorise (loads that may trap).
    const bool ok = (raw != 0) & (d >= min_r) & (d <= max_r);
    const float okf = ok ? 1.0f : 0.0f;
    const float cb = cos_az * t.cos_off[l] + sin_az * t.sin_off[l];  // azimuth - offset
    const float sb = sin_az * t.cos_off[l] - cos_az * t.sin_off[l];
    const float eps = rate_rad * t.time_us[l];
    const float ce = 1.0f - 0.5f * eps * eps;
    const float se = eps * (1.0f - eps * eps * (1.0f / 6.0f));
    const float ca = cb * ce - sb * se;
    const float sa = sb * ce + cb * se;
    const float xy = d * t.cos_el[l] - t.v_sin[l];
    pts.x[uj] = (xy * ca + t.horiz_offset_m[l] * sa) * okf;
    pts.y[uj] = (t.horiz_offset_m[l] * ca - xy * sa) * okf;
    pts.z[uj] = (d * t.sin_el[l] + t.v_cos[l]) * okf;
    pts.range[uj] = d * okf;
    pts.azimuth_deg[uj] = wrap_near(az0 + rate_deg * t.time_us[l] - t.az_offset_deg[l]);
    pts.time_us[uj] = t0 + t.time_us[l];
    pts.return_type[uj] =
        static_cast<ReturnType>(static_cast<uint8_t>(pts.return_type[uj]) * uint8_t{ok});
  }
}

// Laser order -> ring order: cell `col` of each laser's ring in the sink.
void scatter_firing(const FiringPoints& pts, const detail::LaserTable& t, int base, int n,
                    const PointSink& s, size_t first_cell) {
  const float t_off = s.time_offset, t_scale = s.time_scale;
  for (int j = 0; j < n; ++j) {
    const auto uj = static_cast<size_t>(j);
    const size_t c =
        first_cell + static_cast<size_t>(t.ring[static_cast<size_t>(base + j)]) * s.ring_stride;
    s.x[c] = pts.x[uj];
    s.y[c] = pts.y[uj];
    s.z[c] = pts.z[uj];
    s.range[c] = pts.range[uj];
    s.azimuth_deg[c] = pts.azimuth_deg[uj];
    s.time[c] = t_off + pts.time_us[uj] * t_scale;
    s.intensity[c] = pts.intensity[uj];
    s.return_type[c] = pts.return_type[uj];
  }
}

// One laser's constants, for the per-ring kernel.
struct LaserConstants {
  float cos_el, sin_el, v_sin, v_cos, horiz, time_us, az_offset, cos_off, sin_off;
  double dist_offset;
};

// One ring over a run of columns. Each echo is gathered from the payload as a 24-bit key,
// distance | intensity << 16 (one load, one compare for a pair of echoes), one ring ahead of
// its conversion (see write_batch()).
constexpr int kRowLasers = 32;  // RingEchoes::rows
struct RingEchoes {
  static constexpr size_t kN = detail::BatchColumns::kMaxColumns;
  // As gathered: the last echo and the strongest (or second strongest), or the only one; whether
  // any cell has two different echoes.
  struct Gathered {
    std::array<uint32_t, kN> raw[2];
    const uint32_t* key[2];  // the ring's echoes: raw, or its laser's rows
    bool differ;
  } gathered[2];
  // One bank: per echo and laser, the run's echoes (write_columns()).
  std::array<std::array<uint32_t, kN>, kRowLasers> rows[2];
  std::array<uint32_t, kN> key[2];   // per slot, dual return with two different echoes
  std::array<uint32_t, kN> type[2];  // their ReturnType before the range check
  std::array<float, kN> ok[2];       // 1/0: the slot holds a usable return
};

// The echo at `p` (distance, intensity) as a key. Reads a fourth byte, which is inside the
// payload for every channel (the last channel of the last block ends 6 bytes before its end).
inline uint32_t echo_key(const uint8_t* p) {
  return read_u32(p) & 0xFFFFFFu;
}

// Eight bytes, little-endian (one load on x86).
inline uint64_t read_u64(const uint8_t* p) {
  return static_cast<uint64_t>(read_u32(p)) | (static_cast<uint64_t>(read_u32(p + 4)) << 32);
}

// Dual return: the echoes of a run of cells into the scan's slots, branch-free over the run (the
// same choice as sort_echoes()): slot 0 always holds the strongest echo. k0 is the last echo,
// k1 the strongest or second strongest.
[[gnu::always_inline]] inline void select_echoes(int n, const uint32_t* __restrict k0,
                                                 const uint32_t* __restrict k1,
                                                 uint32_t* __restrict a, uint32_t* __restrict ta,
                                                 uint32_t* __restrict b, uint32_t* __restrict tb) {
  for (int k = 0; k < n; ++k) {
    const uint32_t e0 = k0[k], e1 = k1[k];
    const bool both = e0 == e1;
    const uint32_t d0 = e0 & 0xFFFFu, d1 = e1 & 0xFFFFu;
    const bool swap = !both & (d1 != 0) & ((d0 == 0) | ((e1 >> 16) > (e0 >> 16)));
    a[k] = swap ? e1 : e0;
    b[k] = both ? 0u : (swap ? e0 : e1);
    ta[k] = static_cast<uint32_t>(both   ? ReturnType::kBoth
                                  : swap ? ReturnType::kStrongest
                                         : ReturnType::kLast);
    tb[k] = static_cast<uint32_t>(both   ? ReturnType::kNone
                                  : swap ? ReturnType::kLast
                                         : ReturnType::kSecond);
  }
}

// What the per-ring kernel needs besides the echoes: the laser's constants, distance unit and
// limits, the time scale.
struct RingContext {
  LaserConstants lc;
  double unit;
  float min_r, max_r, t_scale;
};

// Which slots a ring's run of columns fills: one (single return), slot 0 with slot 1 cleared
// (dual return, no cell of the run with two different echoes), or both.
enum class Slots { kOne, kFirstOnly, kBoth };

// The points of a ring's run of columns straight into the scan, vectorised over the columns:
// each echo's distance in metres and validity, the rotation of the column azimuth by the laser's
// offset and firing delay (eps: the spin during the delay, under 0.5 deg: two terms of its series
// are exact to 1e-10), shared by both echoes of a cell, the azimuth, the time and the point. The
// same expressions in the same order as compute_firing(): the results are bit-identical. One
// loop, every output a restrict-qualified parameter (GCC then needs no run-time alias checks).
// ok0/ok1: 1/0 per slot for ring_types().
template <Slots kSlots>
[[gnu::always_inline]] inline void ring_points(
    int n, const RingContext& rc, const uint32_t* __restrict key0, const uint32_t* __restrict key1,
    const float* __restrict cos_az, const float* __restrict sin_az, const float* __restrict az0,
    const float* __restrict rate_deg, const float* __restrict rate_rad, const float* __restrict t0,
    const float* __restrict t_off, float* __restrict x0, float* __restrict y0, float* __restrict z0,
    float* __restrict r0, float* __restrict a0, float* __restrict tm0, float* __restrict ok0,
    float* __restrict x1, float* __restrict y1, float* __restrict z1, float* __restrict r1,
    float* __restrict a1, float* __restrict tm1, float* __restrict ok1) {
  const float cos_el = rc.lc.cos_el, sin_el = rc.lc.sin_el, v_sin = rc.lc.v_sin;
  const float v_cos = rc.lc.v_cos, h = rc.lc.horiz;
  const float lt = rc.lc.time_us, az_off = rc.lc.az_offset;
  const float cos_off = rc.lc.cos_off, sin_off = rc.lc.sin_off;
  const double unit = rc.unit, dist_off = rc.lc.dist_offset;
  const float min_r = rc.min_r, max_r = rc.max_r, t_scale = rc.t_scale;
  for (int k = 0; k < n; ++k) {
    const float cb = cos_az[k] * cos_off + sin_az[k] * sin_off;  // azimuth - offset
    const float sb = sin_az[k] * cos_off - cos_az[k] * sin_off;
    const float eps = rate_rad[k] * lt;
    const float ce = 1.0f - 0.5f * eps * eps;
    const float se = eps * (1.0f - eps * eps * (1.0f / 6.0f));
    const float ca = cb * ce - sb * se;
    const float sa = sb * ce + cb * se;
    const float az = wrap_near(az0[k] + rate_deg[k] * lt - az_off);
    const float tm = t_off[k] + (t0[k] + lt) * t_scale;
    // Invalid returns become zeros by a multiplication, not a branch (which would keep the loop
    // from vectorising).
    const auto raw0 = static_cast<int>(key0[k] & 0xFFFFu);
    const auto d0 = static_cast<float>(raw0 * unit + dist_off);
    const float okf0 = (raw0 != 0) & (d0 >= min_r) & (d0 <= max_r) ? 1.0f : 0.0f;
    const float xy0 = d0 * cos_el - v_sin;
    x0[k] = (xy0 * ca + h * sa) * okf0;
    y0[k] = (h * ca - xy0 * sa) * okf0;
    z0[k] = (d0 * sin_el + v_cos) * okf0;
    r0[k] = d0 * okf0;
    a0[k] = az;
    tm0[k] = tm;
    ok0[k] = okf0;
    if constexpr (kSlots == Slots::kFirstOnly) {
      x1[k] = y1[k] = z1[k] = r1[k] = 0.0f;
      a1[k] = az;
      tm1[k] = tm;
    } else if constexpr (kSlots == Slots::kBoth) {
      const auto raw1 = static_cast<int>(key1[k] & 0xFFFFu);
      const auto d1 = static_cast<float>(raw1 * unit + dist_off);
      const float okf1 = (raw1 != 0) & (d1 >= min_r) & (d1 <= max_r) ? 1.0f : 0.0f;
      const float xy1 = d1 * cos_el - v_sin;
      x1[k] = (xy1 * ca + h * sa) * okf1;
      y1[k] = (h * ca - xy1 * sa) * okf1;
      z1[k] = (d1 * sin_el + v_cos) * okf1;
      r1[k] = d1 * okf1;
      a1[k] = az;
      tm1[k] = tm;
      ok1[k] = okf1;
    }
  }
}

// Intensities and return types of a ring's run of columns (kNone where a slot holds no usable
// return). type0/type1 per cell, or null: every slot-0 echo is of type `type`.
template <Slots kSlots>
[[gnu::always_inline]] inline void ring_types(
    int n, const uint32_t* __restrict key0, const uint32_t* __restrict key1,
    const uint32_t* __restrict type0, const uint32_t* __restrict type1, ReturnType type,
    const float* __restrict ok0, const float* __restrict ok1, uint8_t* __restrict in0,
    uint8_t* __restrict ty0, uint8_t* __restrict in1, uint8_t* __restrict ty1) {
  const auto t = static_cast<uint32_t>(type);
  for (int k = 0; k < n; ++k) {
    const uint32_t t0 = kSlots == Slots::kBoth ? type0[k] : t;
    in0[k] = static_cast<uint8_t>(key0[k] >> 16);
    ty0[k] = static_cast<uint8_t>(t0 * static_cast<uint32_t>(ok0[k] != 0.0f));
    if constexpr (kSlots == Slots::kFirstOnly) {
      in1[k] = 0;
      ty1[k] = 0;
    } else if constexpr (kSlots == Slots::kBoth) {
      in1[k] = static_cast<uint8_t>(key1[k] >> 16);
      ty1[k] = static_cast<uint8_t>(type1[k] * static_cast<uint32_t>(ok1[k] != 0.0f));
    }
  }
}

int bank_of_flag(uint16_t flag) {
  for (size_t k = 0; k < kBankFlags.size(); ++k)
    if (kBankFlags[k] == flag) return static_cast<int>(k);
  return -1;
}

}  // namespace

std::string_view decode_status_name(DecodeStatus s) {
  switch (s) {
    case DecodeStatus::kOk:
      return "ok";
    case DecodeStatus::kWrongSize:
      return "wrong_size";
    case DecodeStatus::kBadBlockFlag:
      return "bad_block_flag";
    case DecodeStatus::kBadAzimuth:
      return "bad_azimuth";
    case DecodeStatus::kBadReturnMode:
      return "bad_return_mode";
  }
  return "unknown";
}

bool read_header(std::span<const uint8_t> payload, PacketHeader& out) {
  if (payload.size() != kDataPacketSize) return false;
  out.usec_since_hour = read_u32(payload.data() + kTimestampOffset);
  out.return_mode = payload[kReturnModeOffset];
  out.product_id = payload[kProductIdOffset];
  return true;
}

Decoder::Decoder(Calibration calibration, DecoderOptions options)
    : calibration_(std::move(calibration)),
      options_(options),
      spec_(&model_spec(calibration_.model)),
      min_range_m_(options.min_range_m > 0 ? options.min_range_m : spec_->min_range_m),
      max_range_m_(options.max_range_m > 0 ? options.max_range_m : spec_->max_range_m),
      rate_deg_per_us_(kDefaultRateDegPerUs),
      trig_table_(trig().cos_sin.data()) {
  if (calibration_.ring_of_laser.size() != calibration_.lasers.size()) calibration_.update_rings();
  for (int l = 0; l < spec_->lasers; ++l) {
    const auto ul = static_cast<size_t>(l);
    const LaserCorrection& c = calibration_.lasers[ul];
    const double el = c.elevation_deg * kDegToRad;
    const int ring = calibration_.ring_of_laser[ul];
    const double off = c.azimuth_offset_deg * kDegToRad;
    detail::LaserTable& t = lasers_;
    t.cos_el[ul] = static_cast<float>(std::cos(el));
    t.sin_el[ul] = static_cast<float>(std::sin(el));
    t.v_sin[ul] = static_cast<float>(c.vertical_offset_m * std::sin(el));
    t.v_cos[ul] = static_cast<float>(c.vertical_offset_m * std::cos(el));
    t.horiz_offset_m[ul] = static_cast<float>(c.horizontal_offset_m);
    t.dist_offset_m[ul] = c.distance_offset_m;
    t.time_us[ul] = static_cast<float>(spec_->laser_time_us(l));
    t.az_offset_deg[ul] = static_cast<float>(c.azimuth_offset_deg);
    t.cos_off[ul] = static_cast<float>(std::cos(off));
    t.sin_off[ul] = static_cast<float>(std::sin(off));
    t.ring[ul] = ring;
    laser_of_ring_[static_cast<size_t>(ring)] = static_cast<uint8_t>(l);
  }
}

DecodeStatus Decoder::decode(std::span<const uint8_t> payload, const SensorClock& clock,
                             int64_t receive_time_ns, DecodedPacket& out) {
  const DecodeStatus status = parse(payload, clock, receive_time_ns, out);
  if (status != DecodeStatus::kOk) return status;
  const auto ring_stride = static_cast<size_t>(out.columns);
  const PointSink sink{out.x.data(),
                       out.y.data(),
                       out.z.data(),
                       out.range.data(),
                       out.azimuth_deg.data(),
                       out.time_us.data(),
                       out.intensity.data(),
                       out.return_type.data(),
                       ring_stride,
                       ring_stride * static_cast<size_t>(out.rings),
                       0.0f,
                       1.0f};
  write_points(out, 0, out.columns, sink);
  return DecodeStatus::kOk;
}

DecodeStatus Decoder::parse(std::span<const uint8_t> payload, const SensorClock& clock,
                            int64_t receive_time_ns, PacketColumns& out) {
  if (payload.size() != kDataPacketSize) return DecodeStatus::kWrongSize;
  const uint8_t* p = payload.data();
  ReturnMode mode = ReturnMode::kStrongest;  // 0x00: firmware without the byte
  if (p[kReturnModeOffset] != 0) {
    const auto m = return_mode_from_byte(p[kReturnModeOffset]);
    if (!m) return DecodeStatus::kBadReturnMode;
    mode = *m;
  }
  const ModelSpec& spec = *spec_;
  const bool dual = mode == ReturnMode::kDual;
  const bool banked = spec.blocks_per_firing > 1;  // VLS-128
  // Blocks that share one azimuth: the banks of one firing, times two echoes in dual mode.
  const int group_blocks = spec.blocks_per_firing * (dual ? 2 : 1);
  const int groups = banked && dual ? 1 : 12 / group_blocks;
  const int fpb = spec.firings_per_block;
  const int lasers_per_firing = 32 / fpb;  // lasers of one block in one firing
  const double group_us = fpb * spec.firing_period_us;

  // Where each (group, echo, bank) block is; check flags and azimuths first so that a corrupt
  // packet leaves `out` untouched. One bank (all but the VLS-128): block g * group_blocks + echo.
  std::array<std::array<std::array<int8_t, 4>, 2>, 12> block_of;
  std::array<uint16_t, 12> group_azimuth;
  if (!banked) {
    for (int b = 0; b < 12; ++b) {
      const uint8_t* blk = p + static_cast<size_t>(b) * kBlockSize;
      if (read_u16(blk + 2) > kMaxAzimuth) return DecodeStatus::kBadAzimuth;
      if (read_u16(blk) != kBankFlags[0]) return DecodeStatus::kBadBlockFlag;
    }
    for (int g = 0; g < groups; ++g)
      group_azimuth[static_cast<size_t>(g)] =
          read_u16(p + static_cast<size_t>(g * group_blocks) * kBlockSize + 2);
  }
  for (int g = 0; banked && g < groups; ++g) {
    auto& slots = block_of[static_cast<size_t>(g)];
    for (auto& e : slots) e.fill(-1);
    for (int i = 0; i < group_blocks; ++i) {
      const int b = g * group_blocks + i;
      const uint8_t* blk = p + static_cast<size_t>(b) * kBlockSize;
      const uint16_t flag = read_u16(blk);
      const uint16_t az = read_u16(blk + 2);
      if (az > kMaxAzimuth) return DecodeStatus::kBadAzimuth;
      const int bank = bank_of_flag(flag);
      if (bank < 0) return DecodeStatus::kBadBlockFlag;
      // Dual: the first block of a bank holds the last echo, the second the strongest.
      const int echo = slots[0][static_cast<size_t>(bank)] < 0 ? 0 : 1;
      if (echo == 1 && (!dual || slots[1][static_cast<size_t>(bank)] >= 0))
        return DecodeStatus::kBadBlockFlag;
      slots[static_cast<size_t>(echo)][static_cast<size_t>(bank)] = static_cast<int8_t>(b);
      if (i == 0) group_azimuth[static_cast<size_t>(g)] = az;
    }
    for (int k = 0; k < spec.blocks_per_firing; ++k)
      for (int e = 0; e < (dual ? 2 : 1); ++e)
        if (slots[static_cast<size_t>(e)][static_cast<size_t>(k)] < 0)
          return DecodeStatus::kBadBlockFlag;
  }

  // The lines of the trig table the columns will read (below), asked for now: the scan's writes
  // evict the table every rotation, and each column's lookup would otherwise wait for its line in
  // turn. A group's second firing (VLP-16, Puck Hi-Res) lies about 0.2 deg (20 entries) later.
  for (int g = 0; g < groups; ++g) {
    const float* cs = trig_table_ + 2 * static_cast<size_t>(group_azimuth[static_cast<size_t>(g)]);
    __builtin_prefetch(cs);
    if (fpb > 1) __builtin_prefetch(cs + 40);
  }
  // Rotation rate per group from the next group's azimuth; the last group reuses the previous
  // one (never 0); implausible steps (FOV jumps) fall back to the last good rate.
  const uint32_t usec = read_u32(p + kTimestampOffset);
  if (groups == 1 && have_previous_) {
    const double dt = static_cast<double>(usec - previous_usec_);
    const double step = wrap360((group_azimuth[0] - previous_azimuth_) * 0.01);
    if (dt > 0 && dt < 4 * group_us * 12 && step / dt <= kMaxRateDegPerUs && step > 0)
      rate_deg_per_us_ = step / dt;
  }
  have_previous_ = true;
  previous_azimuth_ = group_azimuth[0];
  previous_usec_ = usec;
  std::array<double, 12> rate{};
  for (int g = 0; g < groups; ++g) {
    double r = rate_deg_per_us_;
    if (g + 1 < groups) {
      const double step = wrap360(
          (group_azimuth[static_cast<size_t>(g + 1)] - group_azimuth[static_cast<size_t>(g)]) *
          0.01);
      if (step > 0 && step / group_us <= kMaxRateDegPerUs) r = step / group_us;
    } else if (g > 0) {
      r = rate[static_cast<size_t>(g - 1)];
    }
    rate[static_cast<size_t>(g)] = r;
    rate_deg_per_us_ = r;
  }

  out.columns = groups * fpb;
  out.rings = spec.lasers;
  out.returns = dual ? 2 : 1;
  out.laser_of_ring = laser_of_ring_.data();
  out.return_mode = static_cast<uint8_t>(mode);
  out.usec_since_hour = usec;
  out.stamp_ns = clock.join(usec, receive_time_ns);
  out.decoder = this;
  out.payload = p;
  out.payload_size = payload.size();

  const float* trig_t = trig_table_;
  for (int g = 0; g < groups; ++g) {
    const auto ug = static_cast<size_t>(g);
    for (int f = 0; f < fpb; ++f) {
      const int col = g * fpb + f;
      const auto ucol = static_cast<size_t>(col);
      const double col_t = col * spec.firing_period_us;
      const double col_az = group_azimuth[ug] * 0.01 + rate[ug] * f * spec.firing_period_us;
      const auto col_az_w = static_cast<float>(wrap360(col_az));
      out.column_time_us[ucol] = col_t;
      out.column_azimuth_deg[ucol] = col_az_w;
      // sin/cos of the column azimuth, once per column.
      const float idx = col_az_w * 100.0f;
      const auto ti = std::min(static_cast<size_t>(idx), static_cast<size_t>(kTrigSteps));
      const float tf = idx - static_cast<float>(ti);
      const float* cs = trig_t + 2 * ti;  // cos, sin at ti, then at ti + 1
      out.cos_az[ucol] = cs[0] + tf * (cs[2] - cs[0]);
      out.sin_az[ucol] = cs[1] + tf * (cs[3] - cs[1]);
      out.rate_deg[ucol] = static_cast<float>(rate[ug]);
      out.rate_rad[ucol] = static_cast<float>(rate[ug] * kDegToRad);
      out.time0_us[ucol] = static_cast<float>(col_t);
      const int ch0 = f * lasers_per_firing * 3 + 4;
      auto& offsets = out.channel_offset[ucol];
      if (!banked) {
        for (int e = 0; e < out.returns; ++e)
          offsets[static_cast<size_t>(e)][0] =
              static_cast<uint16_t>((g * group_blocks + e) * static_cast<int>(kBlockSize) + ch0);
        continue;
      }
      for (int e = 0; e < out.returns; ++e)
        for (int bank = 0; bank < spec.blocks_per_firing; ++bank)
          offsets[static_cast<size_t>(e)][static_cast<size_t>(bank)] = static_cast<uint16_t>(
              block_of[ug][static_cast<size_t>(e)][static_cast<size_t>(bank)] *
                  static_cast<int>(kBlockSize) +
              ch0);
    }
  }
  return DecodeStatus::kOk;
}

void Decoder::write_points(const PacketColumns& pk, int first, int count,
                           const PointSink& sink) const {
  if (count <= 0) return;
  const ModelSpec& spec = *spec_;
  const bool dual = pk.returns == 2;
  const int lasers_per_firing = 32 / spec.firings_per_block;
  const PacketContext cc{calibration_.distance_unit_m, min_range_m_, max_range_m_,
                         lasers_per_firing};
  const uint8_t* p = pk.payload;
  const ReturnType single_type =
      pk.mode() == ReturnMode::kLast ? ReturnType::kLast : ReturnType::kStrongest;
  // Runs of a few columns (VLS-128 packets, the ends of a rotation): per firing, vectorised over
  // the lasers, scattered into the rings. Longer runs: per ring, vectorised over the columns,
  // stored as runs.
  if (count >= kRingKernelMinColumns) {
    detail::BatchColumns batch;
    (void)batch.append(pk, first, count, sink.time_offset);
    write_columns(batch, sink);
    return;
  }
  {
    FiringPoints pts[2];
    const auto n_lasers = static_cast<size_t>(lasers_per_firing);
    for (int col = first; col < first + count; ++col) {
      const auto ucol = static_cast<size_t>(col);
      const Firing firing{pk.column_azimuth_deg[ucol], pk.cos_az[ucol],   pk.sin_az[ucol],
                          pk.rate_deg[ucol],           pk.rate_rad[ucol], pk.time0_us[ucol]};
      for (int bank = 0; bank < spec.blocks_per_firing; ++bank) {
        const auto ub = static_cast<size_t>(bank);
        const uint8_t* blk0 = p + pk.channel_offset[ucol][0][ub];
        const int base = bank * 32;
        if (!dual) {
          for (size_t j = 0; j < n_lasers; ++j) {
            pts[0].distance[j] = read_u16(blk0 + j * 3);
            pts[0].intensity[j] = blk0[j * 3 + 2];
            pts[0].return_type[j] = single_type;
          }
        } else {
          const uint8_t* blk1 = p + pk.channel_offset[ucol][1][ub];
          for (size_t j = 0; j < n_lasers; ++j)
            sort_echoes(read_u16(blk0 + j * 3), blk0[j * 3 + 2], read_u16(blk1 + j * 3),
                        blk1[j * 3 + 2], pts[0].distance[j], pts[0].intensity[j],
                        pts[0].return_type[j], pts[1].distance[j], pts[1].intensity[j],
                        pts[1].return_type[j]);
        }
        for (int e = 0; e < pk.returns; ++e) {
          compute_firing(lasers_, base, cc, firing, pts[e]);
          scatter_firing(
              pts[e], lasers_, base, lasers_per_firing, sink,
              static_cast<size_t>(e) * sink.return_stride + static_cast<size_t>(col - first));
        }
      }
    }
    return;
  }
}

driver::ColumnPacket* Decoder::copy_packet(const driver::ColumnPacket& packet,
                                           std::span<std::byte> storage) const {
  static_assert(std::is_trivially_copyable_v<PacketColumns>);
  static_assert(sizeof(PacketColumns) <= driver::ColumnPacket::kMaxObjectBytes);
  static_assert(alignof(PacketColumns) <= alignof(std::max_align_t));
  // The assembly gives this decoder only the packets it parsed: PacketColumns.
  return new (storage.data()) PacketColumns(static_cast<const PacketColumns&>(packet));
}

void Decoder::write_batch(const driver::ColumnBatch& batch, const PointSink& sink) const {
  detail::BatchColumns columns;
  for (int i = 0; i < batch.runs; ++i) {
    const driver::ColumnBatch::Run& r = batch.run[static_cast<size_t>(i)];
    (void)columns.append(static_cast<const PacketColumns&>(*r.packet), r.first, r.count,
                         r.time_offset);
  }
  write_columns(columns, sink);
}

bool detail::BatchColumns::append(const PacketColumns& pk, int first, int count, float t_off) {
  const int n = columns;
  if (count <= 0 || n + count > kMaxColumns) return false;
  const int pk_returns = pk.mode() == ReturnMode::kDual ? 2 : 1;
  if (n == 0) {
    mode = pk.mode();
    returns = pk_returns;
  } else if (pk.mode() != mode) {
    return false;
  }
  const auto src = static_cast<std::ptrdiff_t>(first), dst = static_cast<std::ptrdiff_t>(n);
  std::fill_n(payload.begin() + dst, count, pk.payload);
  std::copy_n(pk.channel_offset.begin() + src, count, channel_offset.begin() + dst);
  std::copy_n(pk.cos_az.begin() + src, count, cos_az.begin() + dst);
  std::copy_n(pk.sin_az.begin() + src, count, sin_az.begin() + dst);
  std::copy_n(pk.column_azimuth_deg.begin() + src, count, azimuth_deg.begin() + dst);
  std::copy_n(pk.rate_deg.begin() + src, count, rate_deg.begin() + dst);
  std::copy_n(pk.rate_rad.begin() + src, count, rate_rad.begin() + dst);
  std::copy_n(pk.time0_us.begin() + src, count, time0_us.begin() + dst);
  std::fill_n(time_offset.begin() + dst, count, t_off);
  columns = n + count;
  return true;
}

LIDARTAG_AVX2_CLONE void Decoder::write_columns(const detail::BatchColumns& b,
                                                const PointSink& sink) const {
  const int count = b.columns;
  if (count <= 0) return;
  const bool dual = b.returns == 2;
  const int lasers_per_firing = 32 / spec_->firings_per_block;
  const ReturnType single_type =
      b.mode == ReturnMode::kLast ? ReturnType::kLast : ReturnType::kStrongest;
  RingEchoes echoes;
  const detail::LaserTable& t = lasers_;
  const auto min_r = static_cast<float>(min_range_m_), max_r = static_cast<float>(max_range_m_);
  const double unit = calibration_.distance_unit_m;
  // The echoes of a ring are gathered (scalar: 3-byte fields 100 or 48 bytes apart) one ring
  // ahead of their conversion: the vectorised loops then load them from the cache, not from
  // stores still in flight (which a wide load cannot take from the store buffer: it would wait).
  // Each column's firing in each echo and bank, once per batch, not once per ring.
  std::array<std::array<const uint8_t*, RingEchoes::kN>, 4> firing[2];
  for (int e = 0; e < b.returns; ++e)
    for (int bank = 0; bank < spec_->blocks_per_firing; ++bank)
      for (int k = 0; k < count; ++k) {
        const auto uk = static_cast<size_t>(k);
        firing[e][static_cast<size_t>(bank)][uk] =
            b.payload[uk] + b.channel_offset[uk][static_cast<size_t>(e)][static_cast<size_t>(bank)];
      }
  // One bank (every model but the VLS-128): a firing's channels are contiguous, so the echoes of
  // every laser are read column by column (sequential loads, no per-cell pointer) into a row per
  // laser and echo, which the ring loop then reads whole. (Stored all before the first ring is
  // converted: the vector loads do not wait for stores still in flight.)
  const bool by_column = spec_->blocks_per_firing == 1 && lasers_per_firing == spec_->lasers &&
                         spec_->lasers <= kRowLasers;
  // Two channels (6 bytes) per 8-byte load; a firing's trip count known at compile time, so that
  // the loop is unrolled. (The last load reads 2 bytes past the firing's channels: the next
  // firing's, the next block's flag or the timestamp, all inside the payload.)
  auto rows_of = [&]<int kLasers>(std::integral_constant<int, kLasers>) {
    for (int e = 0; e < b.returns; ++e) {
      auto& rows = echoes.rows[static_cast<size_t>(e)];
      for (int k = 0; k < count; ++k) {
        const auto uk = static_cast<size_t>(k);
        const uint8_t* f = firing[e][0][uk];
        for (size_t l = 0; l < static_cast<size_t>(kLasers); l += 2) {
          const uint64_t pair = read_u64(f + l * 3);
          rows[l][uk] = static_cast<uint32_t>(pair) & 0xFFFFFFu;
          rows[l + 1][uk] = static_cast<uint32_t>(pair >> 24) & 0xFFFFFFu;
        }
      }
    }
  };
  if (by_column && lasers_per_firing == 16) {
    rows_of(std::integral_constant<int, 16>{});
  } else if (by_column && lasers_per_firing == 32) {
    rows_of(std::integral_constant<int, 32>{});
  } else if (by_column) {
    for (int e = 0; e < b.returns; ++e) {
      auto& rows = echoes.rows[static_cast<size_t>(e)];
      for (int k = 0; k < count; ++k) {
        const auto uk = static_cast<size_t>(k);
        const uint8_t* f = firing[e][0][uk];
        for (int l = 0; l < lasers_per_firing; ++l)
          rows[static_cast<size_t>(l)][uk] = echo_key(f + static_cast<size_t>(l) * 3);
      }
    }
  }
  auto gather = [&](int ring, RingEchoes::Gathered& g) {
    const int l = laser_of_ring_[static_cast<size_t>(ring)];
    if (by_column) {
      const auto ul = static_cast<size_t>(l);
      g.key[0] = echoes.rows[0][ul].data();
      if (!dual) {
        g.differ = false;
        return;
      }
      g.key[1] = echoes.rows[1][ul].data();
      const uint32_t* __restrict k0 = g.key[0];
      const uint32_t* __restrict k1 = g.key[1];
      uint32_t differ = 0;
      for (int k = 0; k < count; ++k) differ |= k0[k] ^ k1[k];
      g.differ = differ != 0;
      return;
    }
    const auto bank = static_cast<size_t>(l / lasers_per_firing);
    const auto ch = static_cast<size_t>(l % lasers_per_firing) * 3;
    const uint8_t* const* f0 = firing[0][bank].data();
    g.key[0] = g.raw[0].data();
    g.key[1] = g.raw[1].data();
    if (!dual) {
      for (int k = 0; k < count; ++k) {
        const auto uk = static_cast<size_t>(k);
        g.raw[0][uk] = echo_key(f0[uk] + ch);
      }
      g.differ = false;
      return;
    }
    const uint8_t* const* f1 = firing[1][bank].data();
    uint32_t differ = 0;
    for (int k = 0; k < count; ++k) {
      const auto uk = static_cast<size_t>(k);
      const uint32_t k0 = echo_key(f0[uk] + ch);
      const uint32_t k1 = echo_key(f1[uk] + ch);
      g.raw[0][uk] = k0;
      g.raw[1][uk] = k1;
      differ |= k0 ^ k1;
    }
    g.differ = differ != 0;
  };
  gather(0, echoes.gathered[0]);
  for (int ring = 0; ring < spec_->lasers; ++ring) {
    const auto ul = static_cast<size_t>(laser_of_ring_[static_cast<size_t>(ring)]);
    const size_t cell0 = static_cast<size_t>(ring) * sink.ring_stride;
    const RingEchoes::Gathered& g = echoes.gathered[ring & 1];
    if (ring + 1 < spec_->lasers) gather(ring + 1, echoes.gathered[(ring + 1) & 1]);
    // The ring's next run (the next batch) lands in the next two lines of each field: ask for
    // them now, into L2 (the rings x returns x fields streams are more than the hardware
    // prefetcher follows, and the lines are not written before the next batch).
    for (int e = 0; e < b.returns; ++e) {
      const size_t c =
          cell0 + static_cast<size_t>(e) * sink.return_stride + static_cast<size_t>(count);
      for (float* f : {sink.x, sink.y, sink.z, sink.range, sink.azimuth_deg, sink.time}) {
        __builtin_prefetch(f + c + 16, 1, 2);
        __builtin_prefetch(f + c + 32, 1, 2);
      }
      __builtin_prefetch(sink.intensity + c + 64, 1, 2);
      __builtin_prefetch(sink.return_type + c + 64, 1, 2);
    }
    const RingContext rc{
        {t.cos_el[ul], t.sin_el[ul], t.v_sin[ul], t.v_cos[ul], t.horiz_offset_m[ul], t.time_us[ul],
         t.az_offset_deg[ul], t.cos_off[ul], t.sin_off[ul], t.dist_offset_m[ul]},
        unit,
        min_r,
        max_r,
        sink.time_scale};
    const size_t c1 = cell0 + (dual ? sink.return_stride : 0);
    auto* ty0 = reinterpret_cast<uint8_t*>(sink.return_type + cell0);
    auto* ty1 = reinterpret_cast<uint8_t*>(sink.return_type + c1);
    // One ring's run, stored as contiguous runs (the layout of a scan: no scatter). Dual return:
    // mostly no cell of the run has two different echoes (one echo or none: both blocks say the
    // same); then slot 1 holds no return and is only cleared.
    auto points = [&](auto slots, const uint32_t* key0, const uint32_t* key1) {
      ring_points<decltype(slots)::value>(
          count, rc, key0, key1, b.cos_az.data(), b.sin_az.data(), b.azimuth_deg.data(),
          b.rate_deg.data(), b.rate_rad.data(), b.time0_us.data(), b.time_offset.data(),
          sink.x + cell0, sink.y + cell0, sink.z + cell0, sink.range + cell0,
          sink.azimuth_deg + cell0, sink.time + cell0, echoes.ok[0].data(), sink.x + c1,
          sink.y + c1, sink.z + c1, sink.range + c1, sink.azimuth_deg + c1, sink.time + c1,
          echoes.ok[1].data());
    };
    using One = std::integral_constant<Slots, Slots::kOne>;
    using FirstOnly = std::integral_constant<Slots, Slots::kFirstOnly>;
    using Both = std::integral_constant<Slots, Slots::kBoth>;
    if (!dual) {
      points(One{}, g.key[0], nullptr);
      ring_types<Slots::kOne>(count, g.key[0], nullptr, nullptr, nullptr, single_type,
                              echoes.ok[0].data(), nullptr, sink.intensity + cell0, ty0, nullptr,
                              nullptr);
    } else if (!g.differ) {
      points(FirstOnly{}, g.key[0], nullptr);
      ring_types<Slots::kFirstOnly>(count, g.key[0], nullptr, nullptr, nullptr, ReturnType::kBoth,
                                    echoes.ok[0].data(), nullptr, sink.intensity + cell0, ty0,
                                    sink.intensity + c1, ty1);
    } else {
      // Which echo goes to which slot, then both slots converted together.
      select_echoes(count, g.key[0], g.key[1], echoes.key[0].data(), echoes.type[0].data(),
                    echoes.key[1].data(), echoes.type[1].data());
      points(Both{}, echoes.key[0].data(), echoes.key[1].data());
      ring_types<Slots::kBoth>(count, echoes.key[0].data(), echoes.key[1].data(),
                               echoes.type[0].data(), echoes.type[1].data(), ReturnType::kNone,
                               echoes.ok[0].data(), echoes.ok[1].data(), sink.intensity + cell0,
                               ty0, sink.intensity + c1, ty1);
    }
  }
}

// ---------------------------------------------------------------------------------------------

bool looks_like_data_packet(std::span<const uint8_t> payload) {
  if (payload.size() != kDataPacketSize) return false;
  // Every model fills at least the first 8 blocks (a VLS-128 in dual mode leaves the last 4).
  for (size_t b = 0; b < 8; ++b)
    if (bank_of_flag(read_u16(payload.data() + b * kBlockSize)) < 0) return false;
  return true;
}

void ModelCheck::add(std::span<const uint8_t> payload) {
  PacketHeader h;
  if (!read_header(payload, h)) return;
  if (!looks_like_data_packet(payload)) {
    ++rejected_;
    return;
  }
  ++packets_;
  if (++product_votes_[h.product_id] > product_votes_[leading_product_]) {
    leading_product_ = h.product_id;
  }
  if (const auto mode = return_mode_from_byte(h.return_mode)) {
    mode_ = *mode;
  } else if (!mode_) {
    mode_ = ReturnMode::kStrongest;
  }
  for (size_t b = 0; b < 4; ++b)
    if (bank_of_flag(read_u16(payload.data() + b * kBlockSize)) > 0) has_bank_flags_ = true;
  if (last_usec_) {
    const uint32_t step = h.usec_since_hour - *last_usec_;
    if (step > 0 && step < 5000) steps_[step_count_++ % steps_.size()] = step;
  }
  last_usec_ = h.usec_since_hour;
}

std::optional<Model> ModelCheck::product_model() const {
  if (2 * static_cast<size_t>(product_votes_[leading_product_]) <= packets_) return std::nullopt;
  return model_from_product_id(leading_product_);
}

double ModelCheck::packet_period_us() const {
  const size_t n = std::min(step_count_, steps_.size());
  if (n == 0) return 0.0;
  // Lost packets make steps of whole multiples of the period: at 50 % loss the median step is
  // twice the period (a VLP-32C's 664 us would read as a VLP-16's 1327 us). The eighth of the
  // steps from the shortest is the period itself while at least that share arrives in order
  // (reordered and duplicated packets give no positive short step).
  std::array<uint32_t, 64> s = steps_;
  const size_t k = n / 8;
  std::nth_element(s.begin(), s.begin() + static_cast<long>(k), s.begin() + static_cast<long>(n));
  // The clock counts whole microseconds: the mean of the steps near that one (663 and 664 for a
  // VLP-32C's 663.55 us) is the period.
  const double near = s[k];
  double sum = 0.0;
  int count = 0;
  for (size_t i = 0; i < n; ++i) {
    if (std::abs(static_cast<double>(steps_[i]) - near) <= 0.03 * near) {
      sum += steps_[i];
      ++count;
    }
  }
  return sum / count;
}

std::optional<Model> ModelCheck::timing_model() const {
  if (std::min(step_count_, steps_.size()) < 8) return std::nullopt;
  const double period = packet_period_us();
  const ReturnMode mode = mode_.value_or(ReturnMode::kStrongest);
  auto fits = [&](Model m) {
    const ModelSpec& s = model_spec(m);
    if ((s.blocks_per_firing > 1) != has_bank_flags_) return false;
    return std::abs(period - s.packet_period_us(mode)) < 0.03 * s.packet_period_us(mode);
  };
  const std::optional<Model> product = product_model();
  if (product && fits(*product)) return product;
  for (Model m : all_models())
    if (fits(m)) return m;
  return std::nullopt;
}

std::string ModelCheck::mismatch() const {
  const auto timing = timing_model();
  const auto product = product_model();
  const std::string period = std::to_string(std::lround(packet_period_us()));
  if (!product) {
    if (!timing) return {};
    return "product byte names no known model; packet timing (" + period + " us) fits " +
           std::string(model_spec(*timing).name);
  }
  if (!timing || timing == product) return {};
  return "product byte says " + std::string(model_spec(*product).name) + " but packet timing (" +
         period + " us per packet) and layout fit " + std::string(model_spec(*timing).name) +
         "; pass the model explicitly to decode it as such";
}

}  // namespace lidartag::velodyne
