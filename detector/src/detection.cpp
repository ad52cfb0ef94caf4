// Detection assembly: pose from the fit and the decoded quarter turns, corners of the black square.
#include "lidartag/detector/detection.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <numbers>

namespace lidartag::detector {

TagFrame tag_frame(const RigidPose& pull_back, const Eigen::Vector3d& unseen_axis, double shift) {
  TagFrame f;
  f.undecoded = pull_back.R.transpose();
  f.center = -f.undecoded * pull_back.p + shift * unseen_axis;
  return f;
}

Eigen::Matrix3d decoded_rotation(const Eigen::Matrix3d& undecoded, int quarter_turns) {
  return undecoded *
         Eigen::AngleAxisd(-quarter_turns * std::numbers::pi / 2, Eigen::Vector3d::UnitX())
             .toRotationMatrix();
}

Eigen::Quaterniond unit_quaternion(const Eigen::Matrix3d& r) {
  Eigen::Quaterniond q = Eigen::Quaterniond(r).normalized();
  if (q.w() < 0) q.coeffs() *= -1.0;
  return q;
}

FiringTimes firing_times(std::span<const ClusterPoint> points, const Scan& scan,
                         const Eigen::Vector3d& center) {
  FiringTimes t;
  if (points.empty()) return t;
  t.first_s = std::numeric_limits<double>::max();
  t.last_s = std::numeric_limits<double>::lowest();
  double nearest = std::numeric_limits<double>::max();
  for (const ClusterPoint& p : points) {
    const double time = scan.time_s[scan.at(0, p.ring, p.col)];
    t.first_s = std::min(t.first_s, time);
    t.last_s = std::max(t.last_s, time);
    const double d = (Eigen::Vector3d(p.x, p.y, p.z) - center).squaredNorm();
    if (d < nearest) {
      nearest = d;
      t.center_s = time;
    }
  }
  return t;
}

Detection assemble_detection(const TagFrame& frame, const DecodeResult& decoded, int family_index,
                             const tags::TagFamily& family, double t, int points, double fit_cost) {
  const Eigen::Matrix3d r_st = decoded_rotation(frame.undecoded, decoded.quarter_turns);
  Detection det;
  det.family_index = family_index;
  det.family = family.name;
  det.id = decoded.code_index;
  det.size_m = t;
  det.position = frame.center;
  det.orientation = unit_quaternion(r_st);
  // The black square: width_at_border of total_width cells.
  const double h = static_cast<double>(family.width_at_border) / family.total_width * t / 2;
  const std::array<Eigen::Vector2d, 4> yz = {Eigen::Vector2d(-h, -h), Eigen::Vector2d(h, -h),
                                             Eigen::Vector2d(h, h), Eigen::Vector2d(-h, h)};
  for (size_t k = 0; k < 4; ++k)
    det.corners[k] = frame.center + r_st * Eigen::Vector3d(0.0, yz[k].x(), yz[k].y());
  det.score = decoded.score;
  det.margin = decoded.margin_bits;
  det.points = points;
  det.fit_cost = fit_cost;
  return det;
}

}  // namespace lidartag::detector
