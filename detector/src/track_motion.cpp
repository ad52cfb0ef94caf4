// The motion of a tag through the sensor's frame: a constant turn rate from the window's
// orientations (a line through their rotation vectors), then the position now and the velocity by
// linear least squares under each convention, and the static mean unless motion explains the
// window clearly better.
#include "lidartag/detector/track_motion.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "geometry.hpp"

namespace lidartag::detector {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

using geometry::hat;

// exp([a] tau).
Matrix3d turn(const Vector3d& a, double tau) {
  return geometry::exp_so3(a * tau);
}

// B(tau): how the velocity moves a point over tau, under each convention.
Matrix3d drift(const Vector3d& a, double tau, VelocityFrame frame) {
  if (frame == VelocityFrame::kWorld) return tau * turn(a, tau);
  const double n = a.norm(), th = n * tau;
  const Matrix3d k = hat(a), k2 = k * k;
  if (std::abs(th) < 1e-4)  // the series: tau I + tau^2/2 [a] + tau^3/6 [a]^2
    return tau * Matrix3d::Identity() + tau * tau / 2 * k + tau * tau * tau / 6 * k2;
  return tau * Matrix3d::Identity() + (1 - std::cos(th)) / (n * n) * k +
         (tau - std::sin(th) / n) / (n * n) * k2;
}

Vector3d rotation_vector(const Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.angle() * aa.axis();
}

struct PositionFit {
  Vector3d position = Vector3d::Zero(), velocity = Vector3d::Zero();
  double rss = 0.0;
  bool ok = false;
};

// p_i = exp([a] tau_i) X + B(tau_i) u over the window, for X and u (tau_i from the newest pose).
PositionFit fit_positions(std::span<const TimedPose> w, double t_now, const Vector3d& a,
                          VelocityFrame frame) {
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
  for (const TimedPose& p : w) {
    const double tau = p.t_s - t_now;
    Eigen::Matrix<double, 3, 6> row;
    row << turn(a, tau), drift(a, tau, frame);
    normal += row.transpose() * row;
    rhs += row.transpose() * p.position;
  }
  PositionFit fit;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(normal);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 1e-12 * normal.trace())
    return fit;  // the poses' times do not tell a velocity (all at one time)
  const Eigen::Matrix<double, 6, 1> x = ldlt.solve(rhs);
  fit.position = x.head<3>();
  fit.velocity = x.tail<3>();
  for (const TimedPose& p : w) {
    const double tau = p.t_s - t_now;
    fit.rss += (p.position - turn(a, tau) * fit.position - drift(a, tau, frame) * fit.velocity)
                   .squaredNorm();
  }
  fit.ok = fit.position.allFinite() && fit.velocity.allFinite();
  return fit;
}

// The spread of the window about a model: per axis and RMS angle.
void spread(std::span<const TimedPose> w, const TimedPose& now, const Motion& m, MotionFit& out) {
  Vector3d var = Vector3d::Zero();
  double angle2 = 0.0;
  for (const TimedPose& p : w) {
    const TimedPose at = predict(now, m, p.t_s - now.t_s);
    var += (p.position - at.position).cwiseAbs2();
    const double angle = p.frame.angularDistance(at.frame);
    angle2 += angle * angle;
  }
  const auto n = static_cast<double>(w.size());
  out.position_std_m = (var / n).cwiseSqrt();
  out.angle_std_deg = std::sqrt(angle2 / n) * 180.0 / std::numbers::pi;
}

}  // namespace

TimedPose predict(const TimedPose& pose, const Motion& motion, double dt) {
  TimedPose out = pose;
  out.t_s = pose.t_s + dt;
  if (!motion.known) return out;
  const Matrix3d r = turn(motion.turn, dt);
  out.position = r * pose.position + drift(motion.turn, dt, motion.frame) * motion.velocity;
  out.frame = Eigen::Quaterniond(r * pose.frame.toRotationMatrix()).normalized();
  return out;
}

MotionFit fit_motion(std::span<const TimedPose> window, const Motion& fallback, double static_ratio,
                     double noise_m, double angle_noise_rad) {
  MotionFit out;
  if (window.empty()) return out;
  const TimedPose& newest = window.back();
  const double t_now = newest.t_s;
  const auto n = static_cast<double>(window.size());
  // The static model: the mean position and orientation (quaternions turned to the newest one's
  // side, summed and normalised).
  Vector3d mean = Vector3d::Zero();
  Eigen::Vector4d qsum = Eigen::Vector4d::Zero();
  for (const TimedPose& p : window) {
    mean += p.position;
    qsum += (p.frame.dot(newest.frame) < 0 ? -1.0 : 1.0) * p.frame.coeffs();
  }
  mean /= n;
  out.pose.t_s = t_now;
  out.pose.position = mean;
  out.pose.frame = Eigen::Quaterniond(Eigen::Vector4d(qsum.normalized())).normalized();
  if (window.size() == 1) {
    out.motion = fallback;
    out.moving = fallback.known &&
                 (fallback.turn.squaredNorm() > 0.0 || fallback.velocity.squaredNorm() > 0.0);
    return out;
  }
  double rss_static = 0.0;
  for (const TimedPose& p : window) rss_static += (p.position - mean).squaredNorm();

  // The turn rate and the orientation now: rotation vectors of the frames from the newest one,
  // a line in time (its intercept the correction of the newest frame). From 3 poses; with 2, the
  // other tags' rate when known, else none.
  Vector3d a = Vector3d::Zero();
  Eigen::Quaterniond frame_now = newest.frame;
  if (window.size() >= 3) {
    const Matrix3d anchor = newest.frame.toRotationMatrix();
    double st = 0, stt = 0;
    Vector3d sd = Vector3d::Zero(), std_ = Vector3d::Zero();
    for (const TimedPose& p : window) {
      const double tau = p.t_s - t_now;
      const Vector3d d = rotation_vector(p.frame.toRotationMatrix() * anchor.transpose());
      st += tau;
      stt += tau * tau;
      sd += d;
      std_ += tau * d;
    }
    const double det = n * stt - st * st;
    if (det > 1e-12) {
      a = (n * std_ - st * sd) / det;
      const Vector3d c = (sd - a * st) / n;
      // The turn rate is taken only when it stands 4 standard errors (of a line's slope: the
      // scatter over sqrt(sum (tau - mean tau)^2) = sqrt(det / n)) from zero; the scatter per
      // axis is the larger of the line's residuals' and the expected noise's (a far tag's
      // orientations scatter by degrees from one rotation to the next: a turn fitted to three of
      // them would carry its track away).
      double rss = 0.0;
      for (const TimedPose& p : window) {
        const double tau = p.t_s - t_now;
        rss += (rotation_vector(p.frame.toRotationMatrix() * anchor.transpose()) - c - a * tau)
                   .squaredNorm();
      }
      const double scatter2 =
          std::max(n > 2 ? rss / (3.0 * (n - 2)) : 0.0, angle_noise_rad * angle_noise_rad / 3.0);
      if (a.squaredNorm() * det / n > 16.0 * scatter2)
        frame_now = Eigen::Quaterniond(turn(c, 1.0) * anchor).normalized();
      else
        a.setZero();
    }
  } else if (fallback.known) {
    a = fallback.turn;
  }
  PositionFit best;
  VelocityFrame best_frame = VelocityFrame::kSensor;
  for (const VelocityFrame f : {VelocityFrame::kSensor, VelocityFrame::kWorld}) {
    const PositionFit fit = fit_positions(window, t_now, a, f);
    if (fit.ok && (!best.ok || fit.rss < best.rss)) {
      best = fit;
      best_frame = f;
    }
  }
  // Two poses fit any motion exactly: only a step well beyond a single pose's scatter (4-12 mm
  // at 10 m on a VLP-16, 2-3 cm at 28 m on a VLP-32C) is taken for motion, 3 noise_m and at
  // least 2 cm; a slower one is followed by the gates anyway.
  const double floor_m = window.size() == 2 ? std::max(0.02, 3.0 * noise_m) : noise_m;
  if (a.squaredNorm() == 0.0) frame_now = out.pose.frame;  // no turn: the mean orientation
  if (best.ok && rss_static > static_ratio * best.rss + n * floor_m * floor_m) {
    out.moving = true;
    out.pose.position = best.position;
    out.pose.frame = frame_now;
    out.motion = {true, a, best.velocity, best_frame};
  } else {
    out.motion = {true, Vector3d::Zero(), Vector3d::Zero(), VelocityFrame::kSensor};
  }
  spread(window, out.pose, out.motion, out);
  return out;
}

}  // namespace lidartag::detector
