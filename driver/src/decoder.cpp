#include "lidartag/driver/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace lidartag::velodyne {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
// Fastest plausible spin (1300 rpm) in degrees per microsecond; larger steps are FOV jumps.
constexpr double kMaxRateDegPerUs = 1300.0 * 360.0 / 60e6;
constexpr double kDefaultRateDegPerUs = 600.0 * 360.0 / 60e6;

// sin/cos of the azimuth at 0.01 deg steps; linear interpolation between entries is accurate to
// 4e-9, far below the 0.01 deg resolution of the packets.
struct TrigTable {
  std::vector<float> sin_v, cos_v;
  TrigTable() : sin_v(36001), cos_v(36001) {
    for (size_t i = 0; i <= 36000; ++i) {
      const double a = static_cast<double>(i) * 0.01 * kDegToRad;
      sin_v[i] = static_cast<float>(std::sin(a));
      cos_v[i] = static_cast<float>(std::cos(a));
    }
  }
};
const TrigTable& trig() {
  static const TrigTable t;
  return t;
}

inline double wrap360(double deg) {
  deg = std::fmod(deg, 360.0);
  return deg < 0 ? deg + 360.0 : deg;
}

// For angles already within one turn of [0, 360): the per-point hot path.
inline double wrap_near(double deg) {
  if (deg < 0) return deg + 360.0;
  if (deg >= 360.0) return deg - 360.0;
  return deg;
}

int bank_of_flag(uint16_t flag) {
  for (size_t k = 0; k < kBankFlags.size(); ++k)
    if (kBankFlags[k] == flag) return static_cast<int>(k);
  return -1;
}

struct Echo {
  uint16_t distance;
  uint8_t intensity;
};

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
      sin_table_(trig().sin_v.data()),
      cos_table_(trig().cos_v.data()) {
  if (calibration_.ring_of_laser.size() != calibration_.lasers.size()) calibration_.update_rings();
  for (int l = 0; l < spec_->lasers; ++l) {
    const auto ul = static_cast<size_t>(l);
    const double el = calibration_.lasers[ul].elevation_deg * kDegToRad;
    sin_el_[ul] = std::sin(el);
    cos_el_[ul] = std::cos(el);
    laser_time_us_[ul] = spec_->laser_time_us(l);
    ring_[ul] = calibration_.ring_of_laser[ul];
    laser_of_ring_[static_cast<size_t>(ring_[ul])] = static_cast<uint8_t>(l);
    az_offset_[ul] = calibration_.lasers[ul].azimuth_offset_deg;
    vert_offset_[ul] = calibration_.lasers[ul].vertical_offset_m;
    horiz_offset_[ul] = calibration_.lasers[ul].horizontal_offset_m;
    dist_offset_[ul] = calibration_.lasers[ul].distance_offset_m;
  }
}

DecodeStatus Decoder::decode(std::span<const uint8_t> payload, const SensorClock& clock,
                             int64_t receive_time_ns, DecodedPacket& out) {
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
  // packet leaves `out` untouched.
  std::array<std::array<std::array<int8_t, 4>, 2>, 12> block_of{};
  std::array<uint16_t, 12> group_azimuth{};
  for (int g = 0; g < groups; ++g) {
    auto& slots = block_of[static_cast<size_t>(g)];
    for (auto& e : slots) e.fill(-1);
    for (int i = 0; i < group_blocks; ++i) {
      const int b = g * group_blocks + i;
      const uint8_t* blk = p + static_cast<size_t>(b) * kBlockSize;
      const uint16_t flag = read_u16(blk);
      const uint16_t az = read_u16(blk + 2);
      if (az > kMaxAzimuth) return DecodeStatus::kBadAzimuth;
      int bank = 0, echo = 0;
      if (banked) {
        bank = bank_of_flag(flag);
        if (bank < 0) return DecodeStatus::kBadBlockFlag;
        // Dual: the first block of a bank holds the last echo, the second the strongest.
        echo = slots[0][static_cast<size_t>(bank)] < 0 ? 0 : 1;
        if (echo == 1 && (!dual || slots[1][static_cast<size_t>(bank)] >= 0))
          return DecodeStatus::kBadBlockFlag;
      } else {
        if (flag != kBankFlags[0]) return DecodeStatus::kBadBlockFlag;
        echo = dual ? (i & 1) : 0;
      }
      slots[static_cast<size_t>(echo)][static_cast<size_t>(bank)] = static_cast<int8_t>(b);
      if (i == 0) group_azimuth[static_cast<size_t>(g)] = az;
    }
    for (int k = 0; k < spec.blocks_per_firing; ++k)
      for (int e = 0; e < (dual ? 2 : 1); ++e)
        if (slots[static_cast<size_t>(e)][static_cast<size_t>(k)] < 0)
          return DecodeStatus::kBadBlockFlag;
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
  out.mode = mode;
  out.usec_since_hour = usec;
  out.stamp_ns = clock.join(usec, receive_time_ns);

  const ReturnType single_type =
      mode == ReturnMode::kLast ? ReturnType::kLast : ReturnType::kStrongest;
  const double unit = calibration_.distance_unit_m;
  const float* sin_t = sin_table_;
  const float* cos_t = cos_table_;

  auto store = [&](int cell, Echo e, int laser, double az_deg, float t_us, ReturnType type) {
    const auto uc = static_cast<size_t>(cell);
    const auto ul = static_cast<size_t>(laser);
    const double d = e.distance * unit + dist_offset_[ul];
    out.time_us[uc] = t_us;
    out.intensity[uc] = e.intensity;
    if (e.distance == 0 || d < min_range_m_ || d > max_range_m_) {
      out.range[uc] = 0.0f;
      out.x[uc] = out.y[uc] = out.z[uc] = 0.0f;
      out.azimuth_deg[uc] = static_cast<float>(az_deg);
      out.return_type[uc] = ReturnType::kNone;
      return;
    }
    const double idx = az_deg * 100.0;
    const auto i = static_cast<size_t>(idx);
    const double f = idx - static_cast<double>(i);
    const double sa = sin_t[i] + f * (sin_t[i + 1] - sin_t[i]);
    const double ca = cos_t[i] + f * (cos_t[i + 1] - cos_t[i]);
    const double v = vert_offset_[ul], h = horiz_offset_[ul];
    const double xy = d * cos_el_[ul] - v * sin_el_[ul];
    out.x[uc] = static_cast<float>(xy * ca + h * sa);
    out.y[uc] = static_cast<float>(-xy * sa + h * ca);
    out.z[uc] = static_cast<float>(d * sin_el_[ul] + v * cos_el_[ul]);
    out.range[uc] = static_cast<float>(d);
    out.azimuth_deg[uc] = static_cast<float>(az_deg);
    out.return_type[uc] = type;
  };

  for (int g = 0; g < groups; ++g) {
    const auto ug = static_cast<size_t>(g);
    for (int f = 0; f < fpb; ++f) {
      const int col = g * fpb + f;
      const auto ucol = static_cast<size_t>(col);
      const double col_t = col * spec.firing_period_us;
      const double col_az = group_azimuth[ug] * 0.01 + rate[ug] * f * spec.firing_period_us;
      const double col_az_w = wrap360(col_az);
      out.column_time_us[ucol] = col_t;
      out.column_azimuth_deg[ucol] = static_cast<float>(col_az_w);
      for (int bank = 0; bank < spec.blocks_per_firing; ++bank) {
        const auto ub = static_cast<size_t>(bank);
        const uint8_t* blk0 = p + static_cast<size_t>(block_of[ug][0][ub]) * kBlockSize + 4;
        const uint8_t* blk1 =
            dual ? p + static_cast<size_t>(block_of[ug][1][ub]) * kBlockSize + 4 : nullptr;
        for (int j = 0; j < lasers_per_firing; ++j) {
          const int laser = bank * 32 + j;
          const auto ul = static_cast<size_t>(laser);
          const size_t ch = static_cast<size_t>(f * lasers_per_firing + j) * 3;
          const double lt = laser_time_us_[ul];
          const double az = wrap_near(col_az_w + rate[ug] * lt - az_offset_[ul]);
          const auto t = static_cast<float>(col_t + lt);
          const int ring = ring_[ul];
          const Echo e0{read_u16(blk0 + ch), blk0[ch + 2]};
          if (!dual) {
            store(out.at(0, col, ring), e0, laser, az, t, single_type);
            continue;
          }
          // Dual: slot 0 always holds the strongest echo. e0 = last, e1 = strongest or second.
          const Echo e1{read_u16(blk1 + ch), blk1[ch + 2]};
          const int c0 = out.at(0, col, ring), c1 = out.at(1, col, ring);
          if (e0.distance == e1.distance && e0.intensity == e1.intensity) {
            store(c0, e0, laser, az, t, ReturnType::kBoth);
            store(c1, Echo{0, 0}, laser, az, t, ReturnType::kNone);
          } else if (e1.distance != 0 && (e0.distance == 0 || e1.intensity > e0.intensity)) {
            store(c0, e1, laser, az, t, ReturnType::kStrongest);
            store(c1, e0, laser, az, t, ReturnType::kLast);
          } else {
            store(c0, e0, laser, az, t, ReturnType::kLast);
            store(c1, e1, laser, az, t, ReturnType::kSecond);
          }
        }
      }
    }
  }
  return DecodeStatus::kOk;
}

// ---------------------------------------------------------------------------------------------

void ModelCheck::add(std::span<const uint8_t> payload) {
  PacketHeader h;
  if (!read_header(payload, h)) return;
  ++packets_;
  if (!product_model_) product_model_ = model_from_product_id(h.product_id);
  if (!mode_) mode_ = return_mode_from_byte(h.return_mode).value_or(ReturnMode::kStrongest);
  for (size_t b = 0; b < 4; ++b)
    if (bank_of_flag(read_u16(payload.data() + b * kBlockSize)) > 0) has_bank_flags_ = true;
  if (last_usec_) {
    const uint32_t step = h.usec_since_hour - *last_usec_;
    if (step > 0 && step < 5000) steps_[step_count_++ % steps_.size()] = step;
  }
  last_usec_ = h.usec_since_hour;
}

double ModelCheck::median_packet_period_us() const {
  const size_t n = std::min(step_count_, steps_.size());
  if (n == 0) return 0.0;
  std::array<uint32_t, 64> s = steps_;
  std::nth_element(s.begin(), s.begin() + static_cast<long>(n / 2),
                   s.begin() + static_cast<long>(n));
  return s[n / 2];
}

std::optional<Model> ModelCheck::timing_model() const {
  if (std::min(step_count_, steps_.size()) < 8) return std::nullopt;
  const double period = median_packet_period_us();
  const ReturnMode mode = mode_.value_or(ReturnMode::kStrongest);
  auto fits = [&](Model m) {
    const ModelSpec& s = model_spec(m);
    if ((s.blocks_per_firing > 1) != has_bank_flags_) return false;
    return std::abs(period - s.packet_period_us(mode)) < 0.03 * s.packet_period_us(mode);
  };
  if (product_model_ && fits(*product_model_)) return product_model_;
  for (Model m : all_models())
    if (fits(m)) return m;
  return std::nullopt;
}

std::string ModelCheck::mismatch() const {
  const auto timing = timing_model();
  const std::string period = std::to_string(static_cast<int>(median_packet_period_us()));
  if (!product_model_) {
    if (!timing) return {};
    return "product byte names no known model; packet timing (" + period + " us) fits " +
           std::string(model_spec(*timing).name);
  }
  if (!timing || timing == product_model_) return {};
  return "product byte says " + std::string(model_spec(*product_model_).name) +
         " but packet timing (" + period + " us per packet) and layout fit " +
         std::string(model_spec(*timing).name) + "; pass the model explicitly to decode it as such";
}

}  // namespace lidartag::velodyne
