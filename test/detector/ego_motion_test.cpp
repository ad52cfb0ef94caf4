// EgoMotion: the sensor's stamped poses (or twists) interpolated to any time; what it refuses and
// where it has no pose (before its samples, in a gap, stale), each counted, never a crash.
#include "lidartag/detector/ego_motion.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace lidartag::detector {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int64_t kMs = 1'000'000;
constexpr int64_t kT0 = 1'700'000'000'000'000'000;  // ns: stamps of the epoch's size

Eigen::Quaterniond yaw(double rad) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ()));
}

TEST(EgoMotionTest, PosesAreInterpolatedBetweenTheSamplesAroundATime) {
  EgoMotion ego;
  EgoPose p;
  EXPECT_EQ(ego.at(kT0, p), EgoLookup::kEmpty);
  // A sensor yawing at 30 deg/s while driving 1 m/s along x, sampled at 100 Hz.
  const double w = 30.0 * kPi / 180.0;
  for (int k = 0; k <= 100; ++k)
    ASSERT_EQ(
        ego.add_pose(kT0 + k * 10 * kMs, Eigen::Vector3d(0.01 * k, 0.0, 0.0), yaw(w * 0.01 * k)),
        EgoSample::kAccepted);
  EXPECT_EQ(ego.counters().accepted, 101u);
  EXPECT_EQ(ego.newest_ns(), kT0 + 1000 * kMs);
  // Between two samples: linear position, slerped orientation.
  ASSERT_EQ(ego.at(kT0 + 503 * kMs + kMs / 2, p), EgoLookup::kOk);
  EXPECT_NEAR(p.position.x(), 0.5035, 1e-9);
  EXPECT_NEAR(p.orientation.angularDistance(yaw(w * 0.5035)), 0.0, 1e-9);
  // On a sample, and a little past the newest (extrapolated along the last step).
  ASSERT_EQ(ego.at(kT0, p), EgoLookup::kOk);
  EXPECT_NEAR(p.position.norm(), 0.0, 1e-12);
  ASSERT_EQ(ego.at(kT0 + 1020 * kMs, p), EgoLookup::kOk);
  EXPECT_NEAR(p.position.x(), 1.02, 1e-9);
  EXPECT_NEAR(p.orientation.angularDistance(yaw(w * 1.02)), 0.0, 1e-9);
  // Before the first sample, and stale: past the newest by more than max_extrapolation_s.
  EXPECT_EQ(ego.at(kT0 - 1, p), EgoLookup::kBefore);
  EXPECT_EQ(ego.at(kT0 + 1051 * kMs, p), EgoLookup::kStale);
}

TEST(EgoMotionTest, OutOfOrderAndInvalidSamplesAreCountedAndDropped) {
  EgoMotion ego;
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  ASSERT_EQ(ego.add_pose(kT0 + 100 * kMs, zero, yaw(0.0)), EgoSample::kAccepted);
  EXPECT_EQ(ego.add_pose(kT0 + 100 * kMs, zero, yaw(0.0)), EgoSample::kOutOfOrder);
  EXPECT_EQ(ego.add_pose(kT0 + 50 * kMs, zero, yaw(0.0)), EgoSample::kOutOfOrder);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(ego.add_pose(kT0 + 110 * kMs, Eigen::Vector3d(nan, 0, 0), yaw(0.0)),
            EgoSample::kInvalid);
  EXPECT_EQ(ego.add_pose(kT0 + 110 * kMs, zero, Eigen::Quaterniond(2.0, 0.0, 0.0, 0.0)),
            EgoSample::kInvalid);
  EXPECT_EQ(ego.add_twist(kT0 + 110 * kMs, Eigen::Vector3d(nan, 0, 0), zero), EgoSample::kInvalid);
  EXPECT_EQ(ego.counters().accepted, 1u);
  EXPECT_EQ(ego.counters().out_of_order, 2u);
  EXPECT_EQ(ego.counters().invalid, 3u);
  // A quaternion off unit by rounding is normalised.
  ASSERT_EQ(ego.add_pose(kT0 + 120 * kMs, zero, Eigen::Quaterniond(1.005, 0.0, 0.0, 0.0)),
            EgoSample::kAccepted);
  EgoPose p;
  ASSERT_EQ(ego.at(kT0 + 120 * kMs, p), EgoLookup::kOk);
  EXPECT_NEAR(p.orientation.norm(), 1.0, 1e-12);
}

TEST(EgoMotionTest, NoPoseAcrossAGapAndTheRingKeepsTheNewestSamples) {
  EgoMotionOptions options;
  options.capacity = 8;
  EgoMotion ego(options);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  ASSERT_EQ(ego.add_pose(kT0, zero, yaw(0.0)), EgoSample::kAccepted);
  ASSERT_EQ(ego.add_pose(kT0 + 300 * kMs, zero, yaw(0.0)), EgoSample::kAccepted);  // > 0.2 s
  EgoPose p;
  EXPECT_EQ(ego.at(kT0 + 150 * kMs, p), EgoLookup::kGap);
  // Ten more samples: the oldest are forgotten.
  for (int k = 1; k <= 10; ++k)
    ASSERT_EQ(ego.add_pose(kT0 + (300 + 10 * k) * kMs, Eigen::Vector3d(k, 0, 0), yaw(0.0)),
              EgoSample::kAccepted);
  EXPECT_EQ(ego.at(kT0 + 310 * kMs, p), EgoLookup::kBefore);
  ASSERT_EQ(ego.at(kT0 + 335 * kMs, p), EgoLookup::kOk);
  EXPECT_NEAR(p.position.x(), 3.5, 1e-9);
  ego.clear();
  EXPECT_TRUE(ego.empty());
  EXPECT_EQ(ego.at(kT0 + 335 * kMs, p), EgoLookup::kEmpty);
}

TEST(EgoMotionTest, TwistsAreIntegratedIntoPosesAndAGapStartsANewFrame) {
  EgoMotion ego;
  // Driving an arc: 1 m/s forward (the sensor's x) while yawing 90 deg/s, for one second at
  // 100 Hz: a quarter circle of radius 2/pi m.
  const Eigen::Vector3d v(1.0, 0.0, 0.0), w(0.0, 0.0, kPi / 2);
  for (int k = 0; k <= 100; ++k)
    ASSERT_EQ(ego.add_twist(kT0 + k * 10 * kMs, v, w), EgoSample::kAccepted);
  EgoPose p;
  ASSERT_EQ(ego.at(kT0 + 1000 * kMs, p), EgoLookup::kOk);
  const double r = 2.0 / kPi;
  EXPECT_NEAR(p.position.x(), r, 1e-6);
  EXPECT_NEAR(p.position.y(), r, 1e-6);
  EXPECT_NEAR(p.orientation.angularDistance(yaw(kPi / 2)), 0.0, 1e-9);
  EXPECT_EQ(p.segment, 1u);
  EXPECT_EQ(ego.counters().segments, 1u);
  // Half a second without twists: the integration across is unknown, a new frame starts.
  ASSERT_EQ(ego.add_twist(kT0 + 1500 * kMs, v, w), EgoSample::kAccepted);
  ASSERT_EQ(ego.add_twist(kT0 + 1510 * kMs, v, w), EgoSample::kAccepted);
  EXPECT_EQ(ego.counters().segments, 2u);
  ASSERT_EQ(ego.at(kT0 + 1505 * kMs, p), EgoLookup::kOk);
  EXPECT_EQ(p.segment, 2u);
  EXPECT_NEAR(p.position.x(), 0.005, 1e-6);  // half the chord of the arc
  EXPECT_EQ(ego.at(kT0 + 1200 * kMs, p), EgoLookup::kGap);
}

TEST(EgoMotionTest, EveryRuleOfTheTableIsChecked) {
  EXPECT_NO_THROW(validate_ego_motion_options({}));
  EgoMotionOptions bad;
  bad.capacity = 1;
  EXPECT_THROW(EgoMotion{bad}, OptionsError);
  bad = {};
  bad.max_gap_s = 0.0;
  EXPECT_THROW(validate_ego_motion_options(bad), OptionsError);
  bad = {};
  bad.max_extrapolation_s = -1.0;
  try {
    validate_ego_motion_options(bad);
    FAIL() << "no error";
  } catch (const OptionsError& e) {
    EXPECT_EQ(e.key(), "ego_motion.max_extrapolation_s");
  }
}

}  // namespace
}  // namespace lidartag::detector
