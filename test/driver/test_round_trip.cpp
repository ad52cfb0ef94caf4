// Encode known points into packets, decode them back: every model and return mode.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lidartag/driver/velodyne/decoder.hpp"
#include "synthetic_stream.hpp"

namespace lidartag::velodyne {
namespace {

using testing::make_stream;
using testing::synthetic_distance;
using testing::synthetic_intensity;

struct Case {
  Model model;
  ReturnMode mode;
  bool dual_differs;
};

class RoundTrip : public ::testing::TestWithParam<Case> {};

TEST_P(RoundTrip, DecodingGivesBackEveryEncodedCell) {
  const Case c = GetParam();
  const ModelSpec& spec = model_spec(c.model);
  testing::StreamOptions so;
  so.dual_differs = c.dual_differs;
  so.start_azimuth_deg = 359.0;  // the azimuth wraps inside the stream
  const auto packets = make_stream(spec, c.mode, 8, so);
  Decoder decoder(Calibration::builtin(c.model));
  SensorClock clock;
  DecodedPacket out;
  const int per_packet = spec.columns_per_packet(c.mode);
  const double rate = so.rpm * 360.0 / 60e6;
  const double unit = spec.distance_unit_m;
  for (size_t p = 0; p < packets.size(); ++p) {
    ASSERT_EQ(decoder.decode(packets[p].bytes, clock, packets[p].time_ns, out), DecodeStatus::kOk);
    ASSERT_EQ(out.columns, per_packet);
    ASSERT_EQ(out.rings, spec.lasers);
    ASSERT_EQ(out.returns, c.mode == ReturnMode::kDual ? 2 : 1);
    // Host clock joined with the hour counter, which has whole microseconds.
    EXPECT_EQ(out.stamp_ns, packets[p].time_ns / 1000 * 1000);
    for (int col = 0; col < per_packet; ++col) {
      const long k = static_cast<long>(p) * per_packet + col;
      const double t_col = static_cast<double>(k) * spec.firing_period_us;
      const double true_az = std::fmod(so.start_azimuth_deg + rate * t_col, 360.0);
      EXPECT_DOUBLE_EQ(out.column_time_us[static_cast<size_t>(col)], col * spec.firing_period_us);
      // Quantised to 0.01 deg by the packet, interpolated for firings without their own azimuth.
      const double daz =
          std::remainder(out.column_azimuth_deg[static_cast<size_t>(col)] - true_az, 360.0);
      EXPECT_LE(std::abs(daz), 0.015) << "column " << k;
      for (int laser = 0; laser < spec.lasers; ++laser) {
        const int ring = spec.ring_of_laser(laser);
        const uint16_t d = synthetic_distance(laser, k);
        const uint8_t i = synthetic_intensity(laser, k);
        // Expected (range, intensity, type) of slot 0 and 1.
        struct Want {
          uint16_t d;
          uint8_t i;
          ReturnType t;
        };
        Want w0{d, i, c.mode == ReturnMode::kLast ? ReturnType::kLast : ReturnType::kStrongest};
        Want w1{0, 0, ReturnType::kNone};
        if (c.mode == ReturnMode::kDual) {
          const uint16_t d1 = static_cast<uint16_t>(d / 2);
          const auto i1 = static_cast<uint8_t>(i ^ 0x55);
          if (!c.dual_differs || (d == d1 && i == i1)) {
            w0 = {d, i, ReturnType::kBoth};
          } else if (d1 != 0 && (d == 0 || i1 > i)) {
            w0 = {d1, i1, ReturnType::kStrongest};
            w1 = {d, i, ReturnType::kLast};
          } else {
            w0 = {d, i, ReturnType::kLast};
            w1 = {d1, i1, ReturnType::kSecond};
          }
        }
        const Want wants[2] = {w0, w1};
        for (int r = 0; r < out.returns; ++r) {
          const auto cell = static_cast<size_t>(out.at(r, col, ring));
          const Want& want = wants[r];
          if (want.d == 0) {
            EXPECT_EQ(out.range[cell], 0.0f);
            EXPECT_EQ(out.return_type[cell], ReturnType::kNone);
            continue;
          }
          ASSERT_EQ(out.range[cell], static_cast<float>(want.d * unit))
              << spec.name << " col " << k << " laser " << laser << " slot " << r;
          EXPECT_EQ(out.intensity[cell], want.i);
          EXPECT_EQ(out.return_type[cell], want.t);
          // Firing time and azimuth of this laser.
          const double lt = spec.laser_time_us(laser);
          EXPECT_NEAR(out.time_us[cell], col * spec.firing_period_us + lt, 1e-3);
          const LaserSpec& ls = spec.laser_table[static_cast<size_t>(laser)];
          const double want_az = true_az + rate * lt - ls.azimuth_offset_deg;
          EXPECT_LE(std::abs(std::remainder(out.azimuth_deg[cell] - want_az, 360.0)), 0.02);
          // Geometry, recomputed here in double from the table.
          const double a = out.azimuth_deg[cell] * std::numbers::pi / 180.0;
          const double e = ls.elevation_deg * std::numbers::pi / 180.0;
          const double dm = want.d * unit, v = ls.vertical_offset_m;
          const double xy = dm * std::cos(e) - v * std::sin(e);
          EXPECT_NEAR(out.x[cell], xy * std::cos(a), 1e-4);
          EXPECT_NEAR(out.y[cell], -xy * std::sin(a), 1e-4);
          EXPECT_NEAR(out.z[cell], dm * std::sin(e) + v * std::cos(e), 1e-4);
        }
      }
    }
  }
}

std::vector<Case> all_cases() {
  std::vector<Case> v;
  for (Model m : all_models()) {
    v.push_back({m, ReturnMode::kStrongest, true});
    v.push_back({m, ReturnMode::kLast, true});
    v.push_back({m, ReturnMode::kDual, true});
    v.push_back({m, ReturnMode::kDual, false});
  }
  return v;
}

INSTANTIATE_TEST_SUITE_P(AllModelsAndModes, RoundTrip, ::testing::ValuesIn(all_cases()),
                         [](const ::testing::TestParamInfo<Case>& param_info) {
                           std::string n(model_spec(param_info.param.model).name);
                           for (auto& ch : n)
                             if (ch == '-') ch = '_';
                           // Appended piecewise: GCC 12 at -O3 reports a false -Wrestrict on
                           // `"_" + std::string(...)` (GCC bug 105651).
                           n += '_';
                           n += return_mode_name(param_info.param.mode);
                           if (param_info.param.mode == ReturnMode::kDual)
                             n += param_info.param.dual_differs ? "_two_echoes" : "_one_echo";
                           return n;
                         });

}  // namespace
}  // namespace lidartag::velodyne
