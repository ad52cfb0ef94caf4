// The motion model of a track: prediction under each velocity convention against the sensor's
// trajectory written out by hand, and the fit of a window (static scatter stays the mean; a
// turning, driving or both sensor is recovered with its convention; two poses give a
// translation; one pose takes the other tags' motion).
#include "lidartag/detector/track_motion.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <span>
#include <vector>

namespace lidartag::detector {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Matrix3d rot_z(double deg) {
  return Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// A tag fixed in the world (centre `w`, frame `wr`) seen from a sensor at time t: the sensor
// yawing at `yaw_deg_s` (about its own z) and moving at `v` (world frame, constant: a sensor
// turning while carried straight) or at `v` in its own frame (`arc`: a robot driving an arc).
TimedPose seen(double t, double yaw_deg_s, const Eigen::Vector3d& v, bool arc,
               const Eigen::Vector3d& w, const Eigen::Matrix3d& wr) {
  const Eigen::Matrix3d r = rot_z(yaw_deg_s * t);
  Eigen::Vector3d p = v * t;
  if (arc && yaw_deg_s != 0.0) {
    // Integral of R(s) v ds for a yaw rate: the arc's chord.
    const double om = yaw_deg_s * kDeg;
    const Eigen::Matrix3d k = (Eigen::Matrix3d() << 0, -1, 0, 1, 0, 0, 0, 0, 0).finished();
    p = (t * Eigen::Matrix3d::Identity() + (1 - std::cos(om * t)) / om * k +
         (t - std::sin(om * t) / om) * k * k) *
        v;
  }
  TimedPose out;
  out.t_s = t;
  out.position = r.transpose() * (w - p);
  out.frame = Eigen::Quaterniond(r.transpose() * wr);
  return out;
}

const Eigen::Vector3d kTag{7.0, 0.5, 0.2};
const Eigen::Matrix3d kTagFrame = rot_z(170.0);

TEST(TrackMotion, PredictionFollowsTheSensorUnderEachConvention) {
  const Eigen::Vector3d v{1.0, 0.3, 0.0};
  for (const bool arc : {false, true}) {
    SCOPED_TRACE(arc ? "arc" : "straight");
    const TimedPose now = seen(0.4, 30.0, v, arc, kTag, kTagFrame);
    // The apparent motion at 0.4 s: the world turns at -30 deg/s; its velocity is -v in the
    // sensor's frame (arc), or -v turned into the sensor's frame then (straight).
    Motion m;
    m.known = true;
    m.turn = {0.0, 0.0, -30.0 * kDeg};
    m.frame = arc ? VelocityFrame::kSensor : VelocityFrame::kWorld;
    m.velocity = arc ? Eigen::Vector3d(-v) : Eigen::Vector3d(-(rot_z(12.0).transpose() * v));
    for (const double dt : {-0.4, -0.1, 0.1, 0.5}) {
      const TimedPose p = predict(now, m, dt);
      const TimedPose truth = seen(0.4 + dt, 30.0, v, arc, kTag, kTagFrame);
      EXPECT_NEAR((p.position - truth.position).norm(), 0.0, 1e-9) << dt;
      EXPECT_NEAR(p.frame.angularDistance(truth.frame), 0.0, 1e-9) << dt;
      EXPECT_NEAR(p.t_s, 0.4 + dt, 1e-12);
    }
  }
  // Unknown motion: the pose stays.
  const TimedPose now = seen(0.0, 0.0, Eigen::Vector3d::Zero(), false, kTag, kTagFrame);
  EXPECT_EQ(predict(now, Motion{}, 0.3).position, now.position);
}

TEST(TrackMotion, ScatterOfAStillTagIsTheMeanNotMotion) {
  std::mt19937 rng(3);
  std::normal_distribution<double> mm(0.0, 0.003), deg(0.0, 0.4 * kDeg);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<TimedPose> w;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int k = 0; k < 10; ++k) {
      TimedPose p = seen(0.1 * k, 0.0, Eigen::Vector3d::Zero(), false, kTag, kTagFrame);
      p.position += Eigen::Vector3d(mm(rng), mm(rng), mm(rng));
      p.frame = Eigen::Quaterniond(
          Eigen::AngleAxisd(deg(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
          p.frame.toRotationMatrix());
      mean += p.position;
      w.push_back(p);
    }
    mean /= 10.0;
    const MotionFit fit = fit_motion(w, Motion{});
    EXPECT_FALSE(fit.moving) << trial;
    EXPECT_TRUE(fit.motion.known);
    EXPECT_EQ(fit.motion.turn, Eigen::Vector3d::Zero());
    EXPECT_NEAR((fit.pose.position - mean).norm(), 0.0, 1e-12);
    EXPECT_NEAR(fit.pose.t_s, 0.9, 1e-12);
    EXPECT_GT(fit.position_std_m.x(), 0.001);
    EXPECT_LT(fit.position_std_m.x(), 0.006);
  }
}

// A far tag (a VLP-32C's at 28 m and 45 degrees: 2-3 cm and 3 degrees RMS from one rotation to
// the next): told the poses' noise, the fit keeps the static world however short the window, and
// still recovers a sensor yawing at 30 deg/s (its turn 4 standard errors from zero) with the
// same noise. Without the noise, such windows are taken for motion.
TEST(TrackMotion, AFarTagsScatterIsNotTakenForMotion) {
  const Eigen::Vector3d far{28.0 / std::sqrt(2.0), 28.0 / std::sqrt(2.0), 0.0};
  std::mt19937 rng(5);
  std::normal_distribution<double> cm(0.0, 0.015), deg(0.0, 1.8 * kDeg);
  const double noise_m = 0.026, noise_rad = 3.1 * kDeg;  // RMS of the 3-D offset and angle
  auto noisy = [&](TimedPose p) {
    p.position += Eigen::Vector3d(cm(rng), cm(rng), cm(rng));
    const Eigen::Vector3d axis(deg(rng), deg(rng), deg(rng));
    p.frame = Eigen::Quaterniond(Eigen::AngleAxisd(axis.norm(), axis.normalized()) * p.frame);
    return p;
  };
  int still_moving = 0, moving_without_noise = 0, yaw_missed = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<TimedPose> still, yawing;
    for (int k = 0; k < 10; ++k) {
      still.push_back(noisy(seen(0.1 * k, 0.0, Eigen::Vector3d::Zero(), false, far, kTagFrame)));
      yawing.push_back(noisy(seen(0.1 * k, 30.0, Eigen::Vector3d::Zero(), false, far, kTagFrame)));
    }
    for (size_t n = 2; n <= still.size(); ++n) {
      const auto w = std::span(still).first(n);
      const MotionFit fit = fit_motion(w, Motion{}, 4.0, noise_m, noise_rad);
      still_moving += fit.moving ? 1 : 0;
      if (n >= 3) {
        EXPECT_EQ(fit.motion.turn, Eigen::Vector3d::Zero()) << trial << " " << n;
      }
      moving_without_noise += fit_motion(w, Motion{}).moving ? 1 : 0;
    }
    const MotionFit fit = fit_motion(yawing, Motion{}, 4.0, noise_m, noise_rad);
    yaw_missed += fit.moving && std::abs(fit.motion.turn.z() + 30.0 * kDeg) < 10.0 * kDeg ? 0 : 1;
  }
  EXPECT_LE(still_moving, 2);           // of 1,800 windows
  EXPECT_GT(moving_without_noise, 50);  // 117 of 1,800 with this seed
  EXPECT_LE(yaw_missed, 2);
}

TEST(TrackMotion, ATurningOrDrivingSensorIsRecoveredWithItsConvention) {
  struct Case {
    double yaw;
    Eigen::Vector3d v;
    bool arc;
  };
  const Case cases[] = {{30.0, {0.0, 0.0, 0.0}, false},
                        {0.0, {1.0, 0.0, 0.0}, false},
                        {-30.0, {1.0, 0.0, 0.0}, false},
                        {30.0, {1.0, 0.0, 0.0}, true}};
  for (const Case& c : cases) {
    SCOPED_TRACE(::testing::Message()
                 << c.yaw << " deg/s, " << c.v.x() << " m/s, " << (c.arc ? "arc" : "straight"));
    std::vector<TimedPose> w;
    for (int k = 0; k < 10; ++k) w.push_back(seen(0.1 * k, c.yaw, c.v, c.arc, kTag, kTagFrame));
    const MotionFit fit = fit_motion(w, Motion{});
    ASSERT_TRUE(fit.moving);
    EXPECT_NEAR((fit.pose.position - w.back().position).norm(), 0.0, 1e-6);
    EXPECT_NEAR(fit.pose.frame.angularDistance(w.back().frame), 0.0, 1e-6);
    EXPECT_NEAR(fit.motion.turn.z(), -c.yaw * kDeg, 1e-6);
    EXPECT_LT(fit.position_std_m.norm(), 1e-6);
    // Where the tag will be a rotation later, as the sensor sees it then.
    const TimedPose next = seen(1.0, c.yaw, c.v, c.arc, kTag, kTagFrame);
    EXPECT_NEAR((predict(fit.pose, fit.motion, 0.1).position - next.position).norm(), 0.0, 1e-6);
    if (c.yaw != 0.0 && c.v.norm() > 0.0) {
      EXPECT_EQ(fit.motion.frame, c.arc ? VelocityFrame::kSensor : VelocityFrame::kWorld);
    }
  }
}

TEST(TrackMotion, TwoPosesGiveATranslationAndOnePoseTheOtherTagsMotion) {
  const Eigen::Vector3d v{1.0, 0.0, 0.0};
  std::vector<TimedPose> w = {seen(0.0, 0.0, v, false, kTag, kTagFrame),
                              seen(0.1, 0.0, v, false, kTag, kTagFrame)};
  MotionFit fit = fit_motion(w, Motion{});
  ASSERT_TRUE(fit.moving);
  EXPECT_EQ(fit.motion.turn, Eigen::Vector3d::Zero());
  EXPECT_NEAR((fit.motion.velocity - Eigen::Vector3d(-1.0, 0.0, 0.0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((fit.pose.position - w.back().position).norm(), 0.0, 1e-9);
  // Two poses 1 cm apart: scatter (a single pose's at 10 m), not motion.
  w[1] = w[0];
  w[1].t_s = 0.1;
  w[1].position.x() += 0.01;
  EXPECT_FALSE(fit_motion(w, Motion{}).moving);
  // Two poses of a turning sensor with the other tags' turn rate known: exact.
  Motion others;
  others.known = true;
  others.turn = {0.0, 0.0, -30.0 * kDeg};
  w = {seen(0.0, 30.0, Eigen::Vector3d::Zero(), false, kTag, kTagFrame),
       seen(0.1, 30.0, Eigen::Vector3d::Zero(), false, kTag, kTagFrame)};
  fit = fit_motion(w, others);
  ASSERT_TRUE(fit.moving);
  EXPECT_NEAR(fit.motion.velocity.norm(), 0.0, 1e-9);
  // One pose: its own, moving as the others say (or unknown when they say nothing).
  fit = fit_motion(std::span(w).first(1), others);
  EXPECT_TRUE(fit.moving);
  EXPECT_EQ(fit.motion.turn, others.turn);
  EXPECT_EQ(fit.pose.position, w[0].position);
  EXPECT_FALSE(fit_motion(std::span(w).first(1), Motion{}).motion.known);
  EXPECT_FALSE(fit_motion({}, Motion{}).motion.known);
}

}  // namespace
}  // namespace lidartag::detector
