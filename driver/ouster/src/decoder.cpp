#include "lidartag/driver/ouster/decoder.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <new>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>

#include "lidartag/driver/angles.hpp"
#include "lidartag/driver/packet_source.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && defined(__linux__)
#define LIDARTAG_OUSTER_KERNEL_CLONES [[gnu::target_clones("avx2", "default")]]
#else
#define LIDARTAG_OUSTER_KERNEL_CLONES
#endif

namespace lidartag::driver::ouster {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

// wrap360() for -360 < deg < 720 as selects the vectoriser can take: there fmod(deg, 360) is
// deg - 360 exactly, so the result is the same bit for bit.
inline double wrap360_near(double deg) {
  return deg < 0 ? deg + 360.0 : (deg >= 360.0 ? deg - 360.0 : deg);
}

constexpr std::array<std::string_view, kDecodeStatusCount> kStatusNames = {"ok",
                                                                           "wrong size",
                                                                           "wrong packet type",
                                                                           "wrong init id",
                                                                           "wrong serial number",
                                                                           "bad measurement id",
                                                                           "no valid column",
                                                                           "bad timestamp"};

// What the kernel needs of one ring (beam).
struct RingGeometry {
  float ca, sa, cp, sp;  // cos/sin of the beam's azimuth and altitude
  float n;               // lidar_origin_to_beam_origin, metres
  std::array<float, 12> T;
};

// Where the kernel writes one ring's cells.
struct CellOut {
  float *x, *y, *z, *range, *time, *azimuth;
  uint8_t* intensity;
  ReturnType* return_type;
};

// One ring's cells of a batch (the kernel): x, y, z, range, intensity, return type, time and
// azimuth, from `read(c)`, the ring's raw range (0: a hole) and intensity in column c, and the
// columns' encoder cos/sin `ce`, `se`, times `t` and azimuths `az`. Inlined into the functions
// below, whose restrict parameters let the loop vectorise; azimuths wrap with wrap360_near().
template <class Read>
[[gnu::always_inline]] inline void ring_cells(int columns, Read read, const RingGeometry& g,
                                              ReturnType type, const float* ce, const float* se,
                                              const float* t, const float* az, double ring_az,
                                              const CellOut& out) {
  const auto& T = g.T;
  const float ca = g.ca, sa = g.sa, cp = g.cp, sp = g.sp, n = g.n;
  for (int c = 0; c < columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    const auto [mm, iv] = read(uc);
    // As a mask (no branch, so that the loop vectorises): all ones where there is a return.
    const uint32_t keep = 0u - static_cast<uint32_t>(mm != 0);
    // Ouster's range-to-xyz (lidar frame): r the range, n the beam origin's offset, theta_e the
    // encoder angle, theta_a the beam's azimuth, phi its altitude:
    //   x = (r - n) cos(theta_e + theta_a) cos(phi) + n cos(theta_e)
    //   y = (r - n) sin(theta_e + theta_a) cos(phi) + n sin(theta_e)
    //   z = (r - n) sin(phi)
    // then the lidar-to-sensor transform. Ranges fit 31 bits (the profiles' widest: 20 + 3).
    const auto r = static_cast<float>(static_cast<int32_t>(mm) * 1e-3);  // one rounding
    const float rn = r - n;
    const float cea = ce[uc] * ca - se[uc] * sa;
    const float sea = se[uc] * ca + ce[uc] * sa;
    const float xl = rn * cea * cp + n * ce[uc];
    const float yl = rn * sea * cp + n * se[uc];
    const float zl = rn * sp;
    const float xs = T[0] * xl + T[1] * yl + T[2] * zl + T[3];
    const float ys = T[4] * xl + T[5] * yl + T[6] * zl + T[7];
    const float zs = T[8] * xl + T[9] * yl + T[10] * zl + T[11];
    out.x[uc] = std::bit_cast<float>(std::bit_cast<uint32_t>(xs) & keep);
    out.y[uc] = std::bit_cast<float>(std::bit_cast<uint32_t>(ys) & keep);
    out.z[uc] = std::bit_cast<float>(std::bit_cast<uint32_t>(zs) & keep);
    out.range[uc] = std::bit_cast<float>(std::bit_cast<uint32_t>(r) & keep);
    out.intensity[uc] = static_cast<uint8_t>(std::min<uint32_t>(iv, 255u) & keep);
    out.return_type[uc] = static_cast<ReturnType>(static_cast<uint32_t>(type) & keep);  // kNone: 0
    out.time[uc] = t[uc];
    out.azimuth[uc] = static_cast<float>(wrap360_near(double(az[uc]) + ring_az));
  }
}

struct RawValues {
  uint32_t mm, iv;
};

// The kernel reading the ring's pixels itself: column c's pixel at `pixels + off[c]`. The
// columns of a batch may lie in different packets' buffers, so that this addresses one buffer
// from another's: it relies on a flat address space (as every target of this project has; an
// integer address instead keeps the loop from vectorising, at 1.6x the time). On x86-64
// an AVX2 copy beside the baseline one, chosen at load time (glibc's ifunc): same arithmetic in
// wider registers (no FMA: the results are the same bit for bit).
LIDARTAG_OUSTER_KERNEL_CLONES void write_ring_pixels(
    int columns, const uint8_t* __restrict pixels, const int32_t* __restrict off,
    const FastField range_field, const FastField intensity_field,
    const uint32_t* __restrict valid_mask, const RingGeometry& g, ReturnType type,
    const float* __restrict ce, const float* __restrict se, const float* __restrict t,
    const float* __restrict az, double ring_az, float* __restrict x, float* __restrict y,
    float* __restrict z, float* __restrict range, float* __restrict time, float* __restrict azimuth,
    uint8_t* __restrict intensity, ReturnType* __restrict return_type) {
  auto read = [&](size_t c) {
    const uint8_t* pixel = pixels + off[c];
    return RawValues{range_field.read(pixel) & valid_mask[c], intensity_field.read(pixel)};
  };
  ring_cells(columns, read, g, type, ce, se, t, az, ring_az,
             {x, y, z, range, time, azimuth, intensity, return_type});
}

// The kernel on raw values read beforehand (`mm`: 0 in invalid columns).
void write_ring_values(int columns, const uint32_t* __restrict mm, const uint32_t* __restrict iv,
                       const RingGeometry& g, ReturnType type, const float* __restrict ce,
                       const float* __restrict se, const float* __restrict t,
                       const float* __restrict az, double ring_az, float* __restrict x,
                       float* __restrict y, float* __restrict z, float* __restrict range,
                       float* __restrict time, float* __restrict azimuth,
                       uint8_t* __restrict intensity, ReturnType* __restrict return_type) {
  auto read = [&](size_t c) { return RawValues{mm[c], iv[c]}; };
  ring_cells(columns, read, g, type, ce, se, t, az, ring_az,
             {x, y, z, range, time, azimuth, intensity, return_type});
}

}  // namespace

std::string_view decode_status_name(DecodeStatus s) {
  return kStatusNames[static_cast<size_t>(s)];
}

SensorLayout sensor_layout(const SensorInfo& info) {
  const PacketFormat f = PacketFormat::of(info);
  SensorLayout l;
  l.model = kScanModel;
  l.rings = info.pixels_per_column;
  l.column_period_us = info.column_period_us();
  l.packet_columns_single = l.packet_columns_dual = info.columns_per_packet;
  l.max_payload_bytes = f.packet_bytes;
  l.delimiter = RotationDelimiter::kFrameId;
  l.frame_id_bits = f.frame_id_bits;
  l.frame_columns = info.columns_per_frame;
  return l;
}

Decoder::Decoder(const SensorInfo& info, DecoderOptions options)
    : info_(info),
      options_(options),
      format_(PacketFormat::of(info)),
      layout_(sensor_layout(info)),
      period_us_(info.column_period_us()) {
  // A SensorInfo not from load_metadata() is checked too: the tables below are sized by it.
  const auto beams = static_cast<size_t>(info.pixels_per_column);
  if (info.pixels_per_column < 1 || info.pixels_per_column > ColumnPacket::kMaxRings ||
      info.columns_per_packet < 1 || info.columns_per_packet > ColumnPacket::kMaxColumns ||
      info.columns_per_frame < info.columns_per_packet || info.mode_columns < 1 ||
      info.mode_rate_hz < 1 || info.beam_altitude_deg.size() != beams ||
      info.beam_azimuth_deg.size() != beams || info.pixel_shift_by_row.size() != beams) {
    throw std::invalid_argument("Ouster metadata inconsistent: " + std::to_string(beams) +
                                " pixels per column, " + std::to_string(info.columns_per_packet) +
                                " columns per packet, " + std::to_string(info.columns_per_frame) +
                                " per frame, beam tables " +
                                std::to_string(info.beam_altitude_deg.size()) + "/" +
                                std::to_string(info.beam_azimuth_deg.size()) + "/" +
                                std::to_string(info.pixel_shift_by_row.size()));
  }
  const ProfileSpec& spec = *format_.spec;
  const Field range_fields[2] = {Field::kRange, Field::kRange2};
  const bool signal = options_.intensity == IntensitySource::kSignal;
  const Field intensity_fields[2] = {signal ? Field::kSignal : Field::kReflectivity,
                                     signal ? Field::kSignal2 : Field::kReflectivity2};
  for (int r = 0; r < spec.returns; ++r) {
    range_[r] = find_field(spec, range_fields[r]);
    intensity_[r] = find_field(spec, intensity_fields[r]);
    if (!range_[r] || !intensity_[r]) {
      throw std::invalid_argument(std::string("Ouster profile ") +
                                  std::string(profile_name(info.profile)) + " has no " +
                                  std::string(field_name(intensity_fields[r])) + " field");
    }
  }
  // Rings ordered by elevation, ring 0 the lowest beam (ties: the sensor's order).
  const int n = format_.pixels;
  std::array<int, ColumnPacket::kMaxRings> order{};
  std::iota(order.begin(), order.begin() + n, 0);
  std::stable_sort(order.begin(), order.begin() + n, [&](int a, int b) {
    return info.beam_altitude_deg[static_cast<size_t>(a)] <
           info.beam_altitude_deg[static_cast<size_t>(b)];
  });
  for (int ring = 0; ring < n; ++ring) {
    const auto u = static_cast<size_t>(ring);
    const auto beam = static_cast<size_t>(order[u]);
    beam_of_ring_[u] = static_cast<uint8_t>(beam);
    const double alt = info.beam_altitude_deg[beam] * kDegToRad;
    // The published formula's beam azimuth angle is minus the metadata's.
    const double az = -info.beam_azimuth_deg[beam] * kDegToRad;
    cos_alt_[u] = static_cast<float>(std::cos(alt));
    sin_alt_[u] = static_cast<float>(std::sin(alt));
    cos_az_[u] = static_cast<float>(std::cos(az));
    sin_az_[u] = static_cast<float>(std::sin(az));
    az_deg_[u] = static_cast<float>(info.beam_azimuth_deg[beam]);
  }
  const auto& t = info.lidar_to_sensor_transform;
  for (size_t row = 0; row < 3; ++row)
    for (size_t col = 0; col < 4; ++col)
      transform_[row * 4 + col] = static_cast<float>(t[row * 4 + col] * (col == 3 ? 1e-3 : 1.0));
  near_azimuths_ = std::all_of(az_deg_.begin(), az_deg_.begin() + n,
                               [](float a) { return std::abs(a) < 360.0f; });
  // One 32-bit load per field and pixel when every such load, up to the last pixel of the last
  // column, stays inside the packet.
  fast_fields_ = std::endian::native == std::endian::little;
  const size_t last_pixel = format_.header_bytes +
                            static_cast<size_t>(format_.columns - 1) * format_.column_bytes +
                            format_.column_header_bytes +
                            static_cast<size_t>(n - 1) * static_cast<size_t>(spec.pixel_bytes);
  auto fast = [&](const FieldSpec& f, FastField& out) {
    out.byte = f.bit / 8u;
    out.shift = f.bit % 8u;
    out.mask = f.bits >= 32 ? ~0u : (1u << f.bits) - 1u;
    out.upshift = f.upshift;
    if (out.shift + f.bits > 32 || last_pixel + out.byte + 4 > format_.packet_bytes)
      fast_fields_ = false;
  };
  for (int r = 0; r < spec.returns; ++r) {
    fast(*range_[r], fast_range_[r]);
    fast(*intensity_[r], fast_intensity_[r]);
  }
  yaw_deg_ = std::atan2(t[4], t[0]) / kDegToRad;
  n_m_ = static_cast<float>(info.lidar_origin_to_beam_origin_mm * 1e-3);
  const auto w = static_cast<size_t>(info.columns_per_frame);
  cos_enc_.resize(w);
  sin_enc_.resize(w);
  for (size_t m = 0; m < w; ++m) {
    // The encoder angle of measurement id m: 2 pi (1 - m / W), counter-clockwise in the lidar
    // frame.
    const double enc = 2.0 * std::numbers::pi * (1.0 - double(m) / double(w));
    cos_enc_[m] = static_cast<float>(std::cos(enc));
    sin_enc_[m] = static_cast<float>(std::sin(enc));
  }
}

double Decoder::column_azimuth_deg(int m) const {
  // Clockwise seen from above, in the sensor frame: the encoder turns clockwise as m grows.
  return wrap360(360.0 * m / info_.columns_per_frame - yaw_deg_);
}

bool Decoder::destagger(Scan& scan) const {
  const int w = info_.columns_per_frame;
  if (scan.columns != w || scan.rings != format_.pixels || scan.model != kScanModel ||
      scan.column_azimuth_deg[0] != static_cast<float>(column_azimuth_deg(0)))
    return false;
  const auto uw = static_cast<size_t>(w);
  for (int ret = 0; ret < scan.returns; ++ret) {
    for (int ring = 0; ring < scan.rings; ++ring) {
      const int shift = info_.pixel_shift_by_row[beam_of_ring_[static_cast<size_t>(ring)]];
      // Cell c to (c + shift) mod w: a right rotation by shift.
      const auto left = static_cast<size_t>(((w - shift) % w + w) % w);
      if (left == 0) continue;
      const size_t first = scan.at(ret, ring, 0);
      auto turn = [&](auto& v) {
        const auto b = v.begin() + static_cast<std::ptrdiff_t>(first);
        std::rotate(b, b + static_cast<std::ptrdiff_t>(left), b + static_cast<std::ptrdiff_t>(uw));
      };
      for (auto* v : {&scan.x, &scan.y, &scan.z, &scan.range, &scan.azimuth_deg, &scan.time_s})
        turn(*v);
      turn(scan.intensity);
      turn(scan.return_type);
    }
  }
  return true;
}

DecodeStatus Decoder::parse(std::span<const uint8_t> payload, PacketColumns& out) {
  auto count = [this](DecodeStatus s) {
    ++stats_.by_status[static_cast<size_t>(s)];
    return s;
  };
  if (payload.size() != format_.packet_bytes) return count(DecodeStatus::kWrongSize);
  const uint8_t* p = payload.data();
  const PacketHeader header = read_packet_header(p, format_);
  if (format_.profile != Profile::kLegacy) {
    if (header.packet_type != kLidarPacketType) return count(DecodeStatus::kWrongPacketType);
    if (options_.check_init_id && info_.init_id != 0 && header.init_id != info_.init_id)
      return count(DecodeStatus::kWrongInitId);
    if (options_.check_serial && info_.serial_number != 0 &&
        header.serial_number != info_.serial_number)
      return count(DecodeStatus::kWrongSerial);
  }
  const int columns = format_.columns;
  std::array<ColumnHeader, ColumnPacket::kMaxColumns> cols;
  int first_valid = -1;
  int invalid = 0;
  for (int c = 0; c < columns; ++c) {
    ColumnHeader& h = cols[static_cast<size_t>(c)];
    h = read_column_header(p, format_, c);
    if (!h.valid()) {
      ++invalid;
      continue;
    }
    if (h.measurement_id >= info_.columns_per_frame) return count(DecodeStatus::kBadMeasurementId);
    // Times the assembly can subtract without overflow (those of every packet source).
    if (h.timestamp_ns >= static_cast<uint64_t>(kMaxReceiveTimeNs))
      return count(DecodeStatus::kBadTimestamp);
    if (first_valid < 0) first_valid = c;
  }
  if (first_valid < 0) return count(DecodeStatus::kNoValidColumn);
  stats_.invalid_columns += static_cast<uint64_t>(invalid);
  count(DecodeStatus::kOk);

  out.header = header;
  out.columns = columns;
  out.rings = format_.pixels;
  out.returns = format_.spec->returns;
  out.return_mode = static_cast<uint8_t>(kReturnModeBase + static_cast<uint8_t>(format_.profile));
  out.has_frame_id = true;
  out.frame_id = header.frame_id;
  out.laser_of_ring = beam_of_ring_.data();
  // Times: the columns' own timestamps; a column without a valid one (status clear) is placed by
  // its position in the packet, one column period apart.
  const ColumnHeader& ref = cols[static_cast<size_t>(first_valid)];
  const double period_ns = period_us_ * 1e3;
  out.stamp_ns = static_cast<int64_t>(ref.timestamp_ns) - std::llround(first_valid * period_ns);
  const int w = info_.columns_per_frame;
  const auto rate = static_cast<float>(360.0 / (w * period_us_));
  for (int c = 0; c < columns; ++c) {
    const auto u = static_cast<size_t>(c);
    const ColumnHeader& h = cols[u];
    const bool valid = h.valid();
    // An invalid column's measurement id is not trusted: the one its place implies.
    const int m = valid ? h.measurement_id : ((ref.measurement_id + c - first_valid) % w + w) % w;
    out.measurement_id[u] = static_cast<uint16_t>(m);
    out.valid[u] = valid ? 1 : 0;
    out.column_azimuth_deg[u] = static_cast<float>(column_azimuth_deg(m));
    out.column_time_us[u] =
        valid ? static_cast<double>(static_cast<int64_t>(h.timestamp_ns) - out.stamp_ns) * 1e-3
              : c * period_us_;
    out.rate_deg[u] = rate;
  }
  out.decoder = this;
  out.payload = p;
  out.payload_size = payload.size();
  return DecodeStatus::kOk;
}

ColumnPacket* Decoder::copy_packet(const ColumnPacket& packet, std::span<std::byte> storage) const {
  static_assert(sizeof(PacketColumns) <= ColumnPacket::kMaxObjectBytes);
  return new (storage.data()) PacketColumns(static_cast<const PacketColumns&>(packet));
}

void Decoder::write_batch(const ColumnBatch& batch, const PointSink& sink) const {
  // The batch's columns gathered: their bytes, encoder angle, time and azimuth.
  constexpr int kMax = ColumnBatch::kMaxColumns;
  constexpr int kPrefetchRings = 4;
  std::array<const uint8_t*, kMax> col;
  std::array<float, kMax> ce, se, t, az;
  std::array<uint32_t, kMax> valid_mask;  // all ones for a valid column, else 0
  int k = 0;
  for (int i = 0; i < batch.runs; ++i) {
    const ColumnBatch::Run& run = batch.run[static_cast<size_t>(i)];
    const auto& pk = static_cast<const PacketColumns&>(*run.packet);
    for (int c = run.first; c < run.first + run.count && k < kMax; ++c, ++k) {
      const auto uc = static_cast<size_t>(c);
      const auto uk = static_cast<size_t>(k);
      const size_t m = pk.measurement_id[uc];
      col[uk] = format_.column(pk.payload, c) + format_.column_header_bytes;
      ce[uk] = cos_enc_[m];
      se[uk] = sin_enc_[m];
      valid_mask[uk] = pk.valid[uc] != 0 ? ~0u : 0u;
      t[uk] = run.time_offset + static_cast<float>(pk.column_time_us[uc]) * sink.time_scale;
      az[uk] = pk.column_azimuth_deg[uc];
    }
  }
  const int columns = k;
  // The fast path: every field read with one load, and each column's pixels addressed from the
  // first column's (the batch's packets lie within 2 GiB of each other).
  const uint8_t* first = columns > 0 ? col[0] : nullptr;
  std::array<int32_t, kMax> off;
  bool fast_path = fast_fields_ && near_azimuths_;
  for (int c = 0; c < columns && fast_path; ++c) {
    const auto uc = static_cast<size_t>(c);
    // Addresses as integers: the packets are separate objects, whose pointers C++ does not
    // subtract.
    const auto d = static_cast<std::ptrdiff_t>(reinterpret_cast<std::uintptr_t>(col[uc]) -
                                               reinterpret_cast<std::uintptr_t>(first));
    fast_path = d > -(std::ptrdiff_t{1} << 30) && d < (std::ptrdiff_t{1} << 30);
    off[uc] = static_cast<int32_t>(d);
  }
  const auto pixel_bytes = static_cast<size_t>(format_.spec->pixel_bytes);
  const int returns = std::min(batch.returns, format_.spec->returns);
  for (int ret = 0; ret < returns; ++ret) {
    const ReturnType type = ret == 0 ? ReturnType::kStrongest : ReturnType::kSecond;
    for (int ring = 0; ring < format_.pixels; ++ring) {
      const auto ur = static_cast<size_t>(ring);
      const size_t offset = beam_of_ring_[ur] * pixel_bytes;
      const size_t base = ur * sink.ring_stride + static_cast<size_t>(ret) * sink.return_stride;
      if (ring + kPrefetchRings < format_.pixels) {
        // The cells of a ring further on, for writing: they are rarely in cache (a scan is
        // larger than it), and their misses then overlap with this ring's work.
        const size_t ahead = base + static_cast<size_t>(kPrefetchRings) * sink.ring_stride;
        const auto ucols = static_cast<size_t>(columns);
        for (size_t i = 0; i < ucols; i += 16) {
          for (float* v : {sink.x, sink.y, sink.z, sink.range, sink.time, sink.azimuth_deg})
            __builtin_prefetch(v + ahead + i, 1);
        }
        for (size_t i = 0; i < ucols; i += 64) {
          __builtin_prefetch(sink.intensity + ahead + i, 1);
          __builtin_prefetch(sink.return_type + ahead + i, 1);
        }
      }
      const RingGeometry g{cos_az_[ur], sin_az_[ur], cos_alt_[ur], sin_alt_[ur], n_m_, transform_};
      float* x = sink.x + base;
      float* y = sink.y + base;
      float* z = sink.z + base;
      float* range = sink.range + base;
      float* time = sink.time + base;
      float* azimuth = sink.azimuth_deg + base;
      uint8_t* intensity = sink.intensity + base;
      ReturnType* return_type = sink.return_type + base;
      if (fast_path) {
        write_ring_pixels(columns, first + offset, off.data(), fast_range_[ret],
                          fast_intensity_[ret], valid_mask.data(), g, type, ce.data(), se.data(),
                          t.data(), az.data(), az_deg_[ur], x, y, z, range, time, azimuth,
                          intensity, return_type);
        continue;
      }
      // The ring's raw values read first, field by field.
      std::array<uint32_t, kMax> mm, iv;
      for (int c = 0; c < columns; ++c) {
        const auto uc = static_cast<size_t>(c);
        const uint8_t* pixel = col[uc] + offset;
        mm[uc] = valid_mask[uc] ? field_value(pixel, *range_[ret]) : 0u;
        iv[uc] = field_value(pixel, *intensity_[ret]);
      }
      write_ring_values(columns, mm.data(), iv.data(), g, type, ce.data(), se.data(), t.data(),
                        az.data(), az_deg_[ur], x, y, z, range, time, azimuth, intensity,
                        return_type);
      if (!near_azimuths_) {
        for (int c = 0; c < columns; ++c) {
          const auto uc = static_cast<size_t>(c);
          azimuth[uc] = static_cast<float>(wrap360(double(az[uc]) + az_deg_[ur]));
        }
      }
    }
  }
}

}  // namespace lidartag::driver::ouster
