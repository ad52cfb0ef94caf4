// A synthetic wall at a known distance decodes to that distance for every laser.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/encoder.hpp"

namespace lidartag::velodyne {
namespace {

constexpr double kRad = std::numbers::pi / 180.0;

// Wall x = D in front of the sensor. For each laser, the distance its beam travels to the wall
// follows from the elevation, the azimuth offset and the vertical offset of the factory table.
TEST(Geometry, WallInFrontDecodesAtItsDistanceForEveryLaser) {
  const double D = 7.5;
  for (Model m : all_models()) {
    const ModelSpec& spec = model_spec(m);
    const int n = spec.columns_per_packet(ReturnMode::kStrongest);
    std::vector<FiringColumn> cols(static_cast<size_t>(n));
    // Block azimuths at 0 deg (straight ahead); all firings at the same azimuth (rate ~ 0).
    for (auto& c : cols) c.azimuth_centideg = 0;
    const double rate = 0.0;  // the decoder falls back to its nominal rate: account for it below
    (void)rate;
    Decoder decoder(Calibration::builtin(m));
    // First pass: learn each laser's decoded azimuth with a dummy distance.
    for (auto& c : cols)
      for (int l = 0; l < spec.lasers; ++l) c.echo[0].distance[static_cast<size_t>(l)] = 1000;
    std::array<uint8_t, kDataPacketSize> pkt{};
    encode_data_packet(spec, ReturnMode::kStrongest, cols, 0, pkt);
    SensorClock clock;
    DecodedPacket out;
    ASSERT_EQ(decoder.decode(pkt, clock, 0, out), DecodeStatus::kOk);
    for (int l = 0; l < spec.lasers; ++l) {
      const LaserSpec& ls = spec.laser_table[static_cast<size_t>(l)];
      const auto cell = static_cast<size_t>(out.at(0, 0, spec.ring_of_laser(l)));
      const double a = out.azimuth_deg[cell] * kRad, e = ls.elevation_deg * kRad;
      // x = (d cos e - v sin e) cos a = D  =>  d = (D / cos a + v sin e) / cos e
      const double d = (D / std::cos(a) + ls.vertical_offset_m * std::sin(e)) / std::cos(e);
      cols[0].echo[0].distance[static_cast<size_t>(l)] =
          static_cast<uint16_t>(std::lround(d / spec.distance_unit_m));
    }
    encode_data_packet(spec, ReturnMode::kStrongest, cols, 0, pkt);
    ASSERT_EQ(decoder.decode(pkt, clock, 0, out), DecodeStatus::kOk);
    double prev_z = -1e9;
    for (int ring = 0; ring < spec.lasers; ++ring) {
      const auto cell = static_cast<size_t>(out.at(0, 0, ring));
      const int l = spec.laser_of_ring(ring);
      const LaserSpec& ls = spec.laser_table[static_cast<size_t>(l)];
      // Within one distance unit (projected) of the wall.
      EXPECT_NEAR(out.x[cell], D, spec.distance_unit_m) << spec.name << " laser " << l;
      // Height on the wall: D tan(elevation) plus the laser's vertical offset.
      const double a = out.azimuth_deg[cell] * kRad;
      const double want_z = D / std::cos(a) * std::tan(ls.elevation_deg * kRad) +
                            ls.vertical_offset_m / std::cos(ls.elevation_deg * kRad);
      EXPECT_NEAR(out.z[cell], want_z, 2 * spec.distance_unit_m) << spec.name << " laser " << l;
      // Rings climb the wall in order.
      EXPECT_GT(out.z[cell], prev_z) << spec.name << " ring " << ring;
      prev_z = out.z[cell];
      // Lateral position from the azimuth offset: y = -D tan(a).
      EXPECT_NEAR(out.y[cell], -D * std::tan(a), 2 * spec.distance_unit_m);
    }
  }
}

TEST(Geometry, KnownPointsOfTheManualTables) {
  // VLP-16 laser 0 (-15 deg, +11.2 mm) at 10 m, azimuth 90 deg (to the right, -y).
  const ModelSpec& spec = model_spec(Model::kVLP16);
  std::vector<FiringColumn> cols(24);
  for (auto& c : cols) {
    c.azimuth_centideg = 9000;
    c.echo[0].distance[0] = 5000;  // 10 m in 2 mm units
  }
  std::array<uint8_t, kDataPacketSize> pkt{};
  encode_data_packet(spec, ReturnMode::kStrongest, cols, 0, pkt);
  Decoder decoder(Calibration::builtin(Model::kVLP16));
  SensorClock clock;
  DecodedPacket out;
  ASSERT_EQ(decoder.decode(pkt, clock, 0, out), DecodeStatus::kOk);
  const auto cell = static_cast<size_t>(out.at(0, 0, 0));
  const double e = -15 * kRad;
  EXPECT_NEAR(out.x[cell], 0.0, 1e-4);
  EXPECT_NEAR(out.y[cell], -(10 * std::cos(e) - 0.0112 * std::sin(e)), 1e-4);
  EXPECT_NEAR(out.z[cell], 10 * std::sin(e) + 0.0112 * std::cos(e), 1e-4);
}

}  // namespace
}  // namespace lidartag::velodyne
