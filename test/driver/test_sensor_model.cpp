#include <gtest/gtest.h>

#include <set>

#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::velodyne {
namespace {

TEST(SensorModel, EveryModelHasAFullLaserTableAndAName) {
  for (Model m : all_models()) {
    const ModelSpec& s = model_spec(m);
    EXPECT_EQ(static_cast<int>(s.laser_table.size()), s.lasers) << s.name;
    EXPECT_EQ(model_from_name(s.name), m);
    EXPECT_EQ(model_from_product_id(s.product_id), m);
  }
  EXPECT_FALSE(model_from_name("vlp64").has_value());
  EXPECT_EQ(model_names(), "vlp16, puck-hires, vlp32c, hdl32e, vls128");
}

TEST(SensorModel, NamesAreCaseInsensitiveAndIgnorePunctuation) {
  EXPECT_EQ(model_from_name("VLP32C"), Model::kVLP32C);
  EXPECT_EQ(model_from_name("VLP-32C"), Model::kVLP32C);
  EXPECT_EQ(model_from_name("vlp_32c"), Model::kVLP32C);
  EXPECT_EQ(model_from_name("Puck Hi-Res"), Model::kPuckHiRes);
  EXPECT_EQ(model_from_name("PUCKHIRES"), Model::kPuckHiRes);
  EXPECT_EQ(model_from_name("HDL-32E"), Model::kHDL32E);
  EXPECT_EQ(model_from_name("VLS-128"), Model::kVLS128);
  EXPECT_EQ(model_from_name("Alpha Prime"), Model::kVLS128);
  EXPECT_EQ(model_from_name("Ultra Puck"), Model::kVLP32C);
  EXPECT_EQ(model_from_name("puck"), Model::kVLP16);
  EXPECT_EQ(model_from_name("Puck LITE"), Model::kVLP16);
  EXPECT_FALSE(model_from_name("").has_value());
  EXPECT_FALSE(model_from_name("-").has_value());
  EXPECT_FALSE(model_from_name("vlp32").has_value());
  EXPECT_FALSE(model_from_name("hdl64e").has_value());
}

TEST(SensorModel, RingsArePermutationsInElevationOrder) {
  for (Model m : all_models()) {
    const ModelSpec& s = model_spec(m);
    std::set<int> rings;
    for (int l = 0; l < s.lasers; ++l) {
      rings.insert(s.ring_of_laser(l));
      EXPECT_EQ(s.laser_of_ring(s.ring_of_laser(l)), l);
    }
    EXPECT_EQ(static_cast<int>(rings.size()), s.lasers) << s.name;
    for (int r = 1; r < s.lasers; ++r)
      EXPECT_LT(s.laser_table[static_cast<size_t>(s.laser_of_ring(r - 1))].elevation_deg,
                s.laser_table[static_cast<size_t>(s.laser_of_ring(r))].elevation_deg)
          << s.name << " ring " << r;
  }
}

TEST(SensorModel, RingFormulasOfTheManuals) {
  const ModelSpec& vlp16 = model_spec(Model::kVLP16);
  const ModelSpec& hdl = model_spec(Model::kHDL32E);
  for (int l = 0; l < 16; ++l) EXPECT_EQ(vlp16.ring_of_laser(l), l / 2 + 8 * (l % 2));
  for (int l = 0; l < 32; ++l) EXPECT_EQ(hdl.ring_of_laser(l), l / 2 + 16 * (l % 2));
  // VLP-32C: spot checks against velodyne.md.
  const ModelSpec& vlp32 = model_spec(Model::kVLP32C);
  EXPECT_EQ(vlp32.ring_of_laser(0), 0);
  EXPECT_EQ(vlp32.ring_of_laser(1), 17);
  EXPECT_EQ(vlp32.ring_of_laser(29), 31);
  EXPECT_EQ(vlp32.ring_of_laser(31), 16);
  EXPECT_EQ(vlp32.ring_of_laser(20), 10);
}

TEST(SensorModel, PacketRatesMatchTheDocumentedRates) {
  EXPECT_NEAR(model_spec(Model::kVLP16).packet_rate_hz(ReturnMode::kStrongest), 754, 1);
  EXPECT_NEAR(model_spec(Model::kVLP16).packet_rate_hz(ReturnMode::kDual), 1508, 1);
  EXPECT_NEAR(model_spec(Model::kVLP32C).packet_rate_hz(ReturnMode::kStrongest), 1507, 1);
  EXPECT_NEAR(model_spec(Model::kHDL32E).packet_rate_hz(ReturnMode::kStrongest), 1808.5, 1);
  EXPECT_NEAR(model_spec(Model::kVLS128).packet_rate_hz(ReturnMode::kStrongest), 6028, 10);
  EXPECT_EQ(model_spec(Model::kVLP16).columns_per_packet(ReturnMode::kStrongest), 24);
  EXPECT_EQ(model_spec(Model::kVLP16).columns_per_packet(ReturnMode::kDual), 12);
  EXPECT_EQ(model_spec(Model::kVLP32C).columns_per_packet(ReturnMode::kLast), 12);
  EXPECT_EQ(model_spec(Model::kVLS128).columns_per_packet(ReturnMode::kStrongest), 3);
  EXPECT_EQ(model_spec(Model::kVLS128).columns_per_packet(ReturnMode::kDual), 1);
  EXPECT_NEAR(model_spec(Model::kVLS128).packet_rate_hz(ReturnMode::kDual), 18084, 1);
}

TEST(SensorModel, FiringTimesOfTheManuals) {
  EXPECT_DOUBLE_EQ(model_spec(Model::kVLP16).laser_time_us(15), 15 * 2.304);
  EXPECT_DOUBLE_EQ(model_spec(Model::kVLP32C).laser_time_us(31), 15 * 2.304);
  EXPECT_DOUBLE_EQ(model_spec(Model::kVLP32C).laser_time_us(30), 15 * 2.304);
  EXPECT_DOUBLE_EQ(model_spec(Model::kHDL32E).laser_time_us(31), 31 * 1.152);
  EXPECT_DOUBLE_EQ(model_spec(Model::kVLS128).laser_time_us(7), 0.0);
  EXPECT_DOUBLE_EQ(model_spec(Model::kVLS128).laser_time_us(64), 9 * 2.665);
  for (Model m : all_models()) {
    const ModelSpec& s = model_spec(m);
    for (int l = 0; l < s.lasers; ++l) EXPECT_LT(s.laser_time_us(l), s.firing_period_us);
  }
}

}  // namespace
}  // namespace lidartag::velodyne
