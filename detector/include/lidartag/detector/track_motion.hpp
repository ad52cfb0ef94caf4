// How a tag moves through the sensor's frame while the sensor moves (issue 33, item 1). A tag is
// static in the world, so in the sensor's frame it moves as the whole world does: with the sensor
// turning at w and translating, every static point X follows
//   X(t + tau) = exp([a] tau) X(t) + B(tau) u,   R(t + tau) = exp([a] tau) R(t),
// with a = -w (the world turns the other way) and u the apparent velocity, one (a, u) for every
// tag in view ("tags that move together are the sensor moving"). Two conventions of a constant
// velocity are told apart by the fit: one constant in the sensor's frame (a robot driving an arc:
// B(tau) = integral of exp([a] s) over [0, tau]) and one constant in the world (a sensor that
// spins while carried straight: B(tau) = tau exp([a] tau)). Pure functions: a window of timed
// poses in, the pose now and the motion out; no allocation.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>

namespace lidartag::detector {

// A tag's pose (tag frame -> sensor frame) at a time, seconds on the tracker's clock.
struct TimedPose {
  double t_s = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond frame = Eigen::Quaterniond::Identity();
};

enum class VelocityFrame : unsigned char {
  kSensor,  // u constant in the sensor's frame (driving an arc)
  kWorld,   // u constant in the world (turning while carried straight)
};

// The apparent motion of the static world in the sensor's frame.
struct Motion {
  bool known = false;                              // false: nothing is known (not: standing still)
  Eigen::Vector3d turn = Eigen::Vector3d::Zero();  // a, rad/s, sensor frame (-the sensor's)
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // u, m/s, at the pose's time
  VelocityFrame frame = VelocityFrame::kSensor;
};

// `pose` moved by `motion` over dt seconds (either sign). Unknown motion: the pose itself.
TimedPose predict(const TimedPose& pose, const Motion& motion, double dt);

struct MotionFit {
  TimedPose pose;  // at the newest pose's time
  Motion motion;   // known and non-zero when the poses moved (else known and zero: static)
  bool moving = false;
  // Spread of the window about the fitted model: per sensor axis (m) and RMS angle (deg).
  Eigen::Vector3d position_std_m = Eigen::Vector3d::Zero();
  double angle_std_deg = 0.0;
};

// The pose now and the motion from a window of poses of one tag, oldest first (any order works),
// the newest last. The static model (the window's mean) unless a moving one explains the
// positions clearly better: its residual sum of squares times `static_ratio`, plus
// `noise_m`^2 per pose (the RMS scatter of one pose's position, metres; with 2 poses, which any
// motion fits exactly, 3 noise_m and at least 2 cm), still below the static one's. With 2 poses
// only a translation is fitted (one orientation step is too noisy to give a turn rate), from 3 on
// the turn rate too. `fallback` (the motion of other tags, when known) is used for the turn rate of
// a window too short for its own. A fitted turn rate is kept only when it stands 4 standard errors
// from zero, the orientations' scatter being the larger of the fit's residuals and
// `angle_noise_rad` (RMS angle of one pose, radians); else the window turns at no rate (its mean
// orientation).
MotionFit fit_motion(std::span<const TimedPose> window, const Motion& fallback,
                     double static_ratio = 4.0, double noise_m = 0.002,
                     double angle_noise_rad = 0.0);

}  // namespace lidartag::detector
