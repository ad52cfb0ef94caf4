#include "lidartag/calib/correspondence.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace lidartag::calib {
namespace {

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

std::string tag_name(std::string_view family, int id) {
  return std::string(family) + ":" + std::to_string(id);
}

}  // namespace

Eigen::Vector3d tag_frame_corner(int k, double h) {
  // Bottom-left, bottom-right, top-right, top-left (y right, z up).
  constexpr double kY[4] = {-1, 1, 1, -1};
  constexpr double kZ[4] = {-1, -1, 1, 1};
  return {0.0, kY[k & 3] * h, kZ[k & 3] * h};
}

double black_half_side(const tags::TagFamily& family, double size_m) {
  return static_cast<double>(family.width_at_border) / family.total_width * size_m / 2;
}

Eigen::Matrix<double, 12, 12> pose_corner_covariance(const LidarTag& tag,
                                                     const Eigen::Matrix3d& position_cov,
                                                     double angle_sigma_rad) {
  Eigen::Matrix<double, 12, 6> j;
  for (int k = 0; k < 4; ++k) {
    j.block<3, 3>(3 * k, 0).setIdentity();
    j.block<3, 3>(3 * k, 3) = -hat(tag.corners[static_cast<std::size_t>(k)] - tag.position);
  }
  Eigen::Matrix<double, 6, 6> pose = Eigen::Matrix<double, 6, 6>::Zero();
  pose.block<3, 3>(0, 0) = position_cov;
  pose.block<3, 3>(3, 3) = Eigen::Matrix3d::Identity() * angle_sigma_rad * angle_sigma_rad;
  return j * pose * j.transpose();
}

namespace {

LidarTag make_tag(std::string_view family_name, int id, double size_m,
                  const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                  const tags::TagFamily& family) {
  LidarTag t;
  t.family = std::string(family_name);
  t.id = id;
  t.size_m = size_m;
  t.position = position;
  t.orientation = orientation.normalized();
  const double h = black_half_side(family, size_m);
  const Eigen::Matrix3d r = t.orientation.toRotationMatrix();
  for (int k = 0; k < 4; ++k)
    t.corners[static_cast<std::size_t>(k)] = position + r * tag_frame_corner(k, h);
  return t;
}

}  // namespace

LidarTag lidar_tag_from_detection(const detector::Detection& det, const tags::TagFamily& family,
                                  const LidarCornerNoise& noise) {
  LidarTag t = make_tag(det.family, det.id, det.size_m, det.position, det.orientation, family);
  t.corners = det.corners;  // the detector's own, in the same order
  const double s = noise.position_sigma_m;
  t.corner_cov = pose_corner_covariance(t, Eigen::Matrix3d::Identity() * s * s,
                                        noise.angle_sigma_deg * std::numbers::pi / 180);
  t.corner_cov.diagonal().array() += noise.floor_m * noise.floor_m;
  return t;
}

LidarTag lidar_tag_from_track(const detector::TrackInfo& track, const tags::TagFamily& family,
                              double size_m, const LidarCornerNoise& noise) {
  LidarTag t = make_tag(family.name, track.id, size_m, track.position, track.orientation, family);
  const double n = std::max(1, track.window_rotations);
  const Eigen::Matrix3d pos_cov = track.position_std_m.cwiseAbs2().asDiagonal();
  const double angle_rad = track.angle_std_deg * std::numbers::pi / 180 / std::sqrt(3.0);
  t.corner_cov = pose_corner_covariance(t, pos_cov / n, angle_rad / std::sqrt(n));
  t.corner_cov.diagonal().array() += noise.floor_m * noise.floor_m;
  return t;
}

void add_ring_spacing_uncertainty(LidarTag& tag, const tags::TagFamily& family,
                                  std::span<const double> ring_elevations_rad) {
  std::vector<double> el(ring_elevations_rad.begin(), ring_elevations_rad.end());
  std::sort(el.begin(), el.end());
  const double range = tag.position.norm();
  if (el.size() < 2 || range <= 0) return;
  // The widest gap between rings over the tag's elevation span (centre +- half its diagonal).
  const double h = black_half_side(family, tag.size_m);
  const double centre = std::atan2(tag.position.z(), tag.position.head<2>().norm());
  const double half_span = std::atan2(h * std::numbers::sqrt2, range);
  double gap_rad = 0;
  for (size_t i = 1; i < el.size(); ++i)
    if (el[i] > centre - half_span && el[i - 1] < centre + half_span)
      gap_rad = std::max(gap_rad, el[i] - el[i - 1]);
  if (gap_rad <= 0) return;
  // The rings' direction at the tag (horizontal, across the line of sight) in the tag's plane,
  // and the direction across them.
  const Eigen::Matrix3d r = tag.orientation.toRotationMatrix();
  const Eigen::Vector3d normal = r.col(0);
  Eigen::Vector3d along = Eigen::Vector3d::UnitZ().cross(tag.position);
  along -= along.dot(normal) * normal;
  if (along.norm() < 1e-9) return;
  along.normalize();
  const Eigen::Vector3d across = normal.cross(along);
  // phi: the edges' (tag y and z) smallest angle to the rings.
  const double c = std::max(std::abs(along.dot(r.col(1))), std::abs(along.dot(r.col(2))));
  const double sin_phi = std::sqrt(std::max(0.0, 1 - c * c));
  const double gap_m = range * gap_rad;
  const double unresolved = std::max(0.0, 1 - 2 * h * sin_phi / gap_m);
  const double sigma = gap_m / std::sqrt(12.0) * unresolved;
  tag.corner_cov += pose_corner_covariance(tag, sigma * sigma * across * across.transpose(), 0.0);
}

std::vector<double> ring_elevations_rad(const Scan& scan) {
  std::vector<double> out;
  for (int ring = 0; ring < scan.rings; ++ring) {
    double sum = 0;
    int n = 0;
    for (int col = 0; col < scan.columns; ++col) {
      const size_t i = scan.at(0, ring, col);
      if (scan.range[i] <= 0) continue;
      sum += std::atan2(scan.z[i], std::hypot(scan.x[i], scan.y[i]));
      ++n;
    }
    if (n > 0) out.push_back(sum / n);
  }
  return out;
}

std::array<Eigen::Vector2d, 4> calibration_order(const std::array<Eigen::Vector2d, 4>& apriltag_p) {
  std::array<Eigen::Vector2d, 4> out;
  for (int k = 0; k < 4; ++k)
    out[static_cast<std::size_t>(k)] = apriltag_p[static_cast<std::size_t>(apriltag_corner_of(k))];
  return out;
}

Pairing pair_tags(std::span<const LidarTag> lidar, std::span<const ImageTagCorners> image,
                  std::string_view scene, double size_tolerance) {
  Pairing out;
  const std::string prefix = scene.empty() ? std::string() : std::string(scene) + " ";
  auto count_lidar = [&](const std::string& f, int id) {
    int n = 0;
    for (const LidarTag& l : lidar) n += l.family == f && l.id == id;
    return n;
  };
  auto count_image = [&](const std::string& f, int id) {
    int n = 0;
    for (const ImageTagCorners& c : image) n += c.family == f && c.id == id;
    return n;
  };
  std::vector<bool> lidar_used(lidar.size(), false);
  for (const ImageTagCorners& im : image) {
    const std::string label = prefix + tag_name(im.family, im.id);
    if (count_image(im.family, im.id) > 1) {
      out.unpaired.push_back({label,
                              "ambiguous: this family and ID appear more than once in the "
                              "image"});
      continue;
    }
    const int nl = count_lidar(im.family, im.id);
    if (nl == 0) {
      out.unpaired.push_back({label, "in the image only: the LiDAR capture has no such tag"});
      continue;
    }
    if (nl > 1) {
      out.unpaired.push_back({label, "ambiguous: the LiDAR capture has this family and ID " +
                                         std::to_string(nl) + " times"});
      for (std::size_t i = 0; i < lidar.size(); ++i)
        if (lidar[i].family == im.family && lidar[i].id == im.id) lidar_used[i] = true;
      continue;
    }
    for (std::size_t i = 0; i < lidar.size(); ++i) {
      if (lidar[i].family != im.family || lidar[i].id != im.id) continue;
      lidar_used[i] = true;
      if (im.size_m > 0 && std::abs(lidar[i].size_m / im.size_m - 1.0) > size_tolerance) {
        out.unpaired.push_back({label, "size: the LiDAR tag is " + std::to_string(lidar[i].size_m) +
                                           " m, the image's is given as " +
                                           std::to_string(im.size_m) + " m"});
        break;
      }
      out.poses.push_back({label, lidar[i], calibration_order(im.apriltag_p), im.sigma_px});
    }
  }
  for (std::size_t i = 0; i < lidar.size(); ++i)
    if (!lidar_used[i])
      out.unpaired.push_back({prefix + tag_name(lidar[i].family, lidar[i].id),
                              "in the LiDAR capture only: the image has no such tag"});
  return out;
}

}  // namespace lidartag::calib
