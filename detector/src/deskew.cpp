// Deskewing a cluster: each point moved from the sensor's pose at its firing time to the sensor's
// pose at the cluster's centre time. With poses P(t) (sensor -> odometry frame), a point X_i fired
// at t_i is P(t_i) X_i in the odometry frame, and P(t_c)^-1 P(t_i) X_i in the sensor's frame at
// t_c. With the constant-velocity model of the static world (track_motion.hpp), it is
// X(t_c) = exp([a] tau) X_i + B(tau) u, tau = t_c - t_i.
#include "lidartag/detector/deskew.hpp"

#include <cmath>

#include "lidartag/detector/detection.hpp"
#include "lidartag/detector/ego_motion.hpp"

namespace lidartag::detector {

namespace {

double time_of(const Scan& scan, const ClusterPoint& p) {
  return static_cast<double>(scan.time_s[scan.at(0, p.ring, p.col)]);
}

int64_t stamp_at(const Scan& scan, double t_s) {
  return scan.stamp_ns + static_cast<int64_t>(std::llround(t_s * 1e9));
}

// The firing times of the cluster (detection.hpp's firing_times), its centre time that of the
// point nearest the points' centroid: the fit has not placed the tag yet.
FiringTimes cluster_times(std::span<const ClusterPoint> points, const Scan& scan) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const ClusterPoint& p : points) centroid += Eigen::Vector3d(p.x, p.y, p.z);
  return firing_times(points, scan, centroid / static_cast<double>(points.size()));
}

void set(ClusterPoint& p, const Eigen::Vector3d& x) {
  p.x = static_cast<float>(x.x());
  p.y = static_cast<float>(x.y());
  p.z = static_cast<float>(x.z());
}

// With the odometry: every time of the cluster covered (its first, centre and last firing in one
// odometry frame), else false and nothing moved.
bool deskew_ego(std::span<ClusterPoint> points, const Scan& scan, const EgoMotion& ego,
                const FiringTimes& t) {
  EgoPose center, first, last;
  if (ego.at(stamp_at(scan, t.center_s), center) != EgoLookup::kOk ||
      ego.at(stamp_at(scan, t.first_s), first) != EgoLookup::kOk ||
      ego.at(stamp_at(scan, t.last_s), last) != EgoLookup::kOk || first.segment != center.segment ||
      last.segment != center.segment) {
    return false;
  }
  const Eigen::Matrix3d to_center = center.orientation.toRotationMatrix().transpose();
  for (ClusterPoint& p : points) {
    EgoPose then;
    if (ego.at(stamp_at(scan, time_of(scan, p)), then) != EgoLookup::kOk) continue;
    const Eigen::Vector3d odom =
        then.orientation * Eigen::Vector3d(p.x, p.y, p.z) + then.position - center.position;
    set(p, to_center * odom);
  }
  return true;
}

}  // namespace

std::string_view deskew_source_name(DeskewSource s) {
  switch (s) {
    case DeskewSource::kEgo:
      return "ego";
    case DeskewSource::kModel:
      return "model";
    case DeskewSource::kNone:
      break;
  }
  return "none";
}

Deskewed deskew_cluster(std::span<ClusterPoint> points, const Scan& scan,
                        const SensorMotion& motion) noexcept {
  if (points.empty() || (motion.ego == nullptr && !motion.model.known)) return {};
  const FiringTimes t = cluster_times(points, scan);
  if (motion.ego != nullptr && deskew_ego(points, scan, *motion.ego, t))
    return {DeskewSource::kEgo, t.center_s};
  if (!motion.model.known) return {};
  for (ClusterPoint& p : points) {
    TimedPose fired;
    fired.t_s = time_of(scan, p);
    fired.position = Eigen::Vector3d(p.x, p.y, p.z);
    set(p, predict(fired, motion.model, t.center_s - fired.t_s).position);
  }
  return {DeskewSource::kModel, t.center_s};
}

}  // namespace lidartag::detector
