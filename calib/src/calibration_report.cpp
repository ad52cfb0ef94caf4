#include "lidartag/calib/calibration_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <sstream>

namespace lidartag::calib {
namespace {

// Shortest decimal that reads back to the same double.
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  for (int p = 6; p < 17; ++p) {
    char b[32];
    std::snprintf(b, sizeof b, "%.*g", p, v);
    if (std::strtod(b, nullptr) == v) return b;
  }
  return buf;
}

nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json vec_json(const Eigen::VectorXd& v) {
  nlohmann::json a = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v(i));
  return a;
}

Eigen::Quaterniond unit_w_positive(const Eigen::Matrix3d& r) {
  Eigen::Quaterniond q(r);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  return q;
}

std::string opencv_matrix(const std::string& key, const Eigen::MatrixXd& m) {
  std::ostringstream s;
  s << key << ": !!opencv-matrix\n   rows: " << m.rows() << "\n   cols: " << m.cols()
    << "\n   dt: d\n   data: [ ";
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      s << num(m(r, c)) << (r + 1 == m.rows() && c + 1 == m.cols() ? " ]\n" : ", ");
  return s.str();
}

}  // namespace

Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& r) {
  // atan2 rather than asin for the pitch: exact near +-90 degrees too.
  const double c = std::hypot(r(0, 0), r(1, 0));
  const double pitch = std::atan2(-r(2, 0), c);
  if (c < 1e-12) return {0.0, pitch, std::atan2(-r(0, 1), r(1, 1))};  // gimbal lock
  return {std::atan2(r(2, 1), r(2, 2)), pitch, std::atan2(r(1, 0), r(0, 0))};
}

std::string urdf_joint(const Eigen::Isometry3d& parent_from_child, const FrameNames& frames) {
  const Eigen::Vector3d t = parent_from_child.translation();
  const Eigen::Vector3d rpy = roll_pitch_yaw(parent_from_child.linear());
  std::ostringstream s;
  s << "<joint name=\"" << frames.lidar << "_to_" << frames.camera << "\" type=\"fixed\">\n"
    << "  <parent link=\"" << frames.lidar << "\"/>\n"
    << "  <child link=\"" << frames.camera << "\"/>\n"
    << "  <origin xyz=\"" << num(t.x()) << " " << num(t.y()) << " " << num(t.z()) << "\" rpy=\""
    << num(rpy.x()) << " " << num(rpy.y()) << " " << num(rpy.z()) << "\"/>\n"
    << "</joint>";
  return s.str();
}

std::string ros1_static_transform(const Eigen::Isometry3d& parent_from_child,
                                  const FrameNames& frames) {
  const Eigen::Vector3d t = parent_from_child.translation();
  const Eigen::Quaterniond q = unit_w_positive(parent_from_child.linear());
  std::ostringstream s;
  s << "rosrun tf2_ros static_transform_publisher " << num(t.x()) << " " << num(t.y()) << " "
    << num(t.z()) << " " << num(q.x()) << " " << num(q.y()) << " " << num(q.z()) << " "
    << num(q.w()) << " " << frames.lidar << " " << frames.camera;
  return s.str();
}

std::string ros2_static_transform(const Eigen::Isometry3d& parent_from_child,
                                  const FrameNames& frames) {
  const Eigen::Vector3d t = parent_from_child.translation();
  const Eigen::Quaterniond q = unit_w_positive(parent_from_child.linear());
  std::ostringstream s;
  s << "ros2 run tf2_ros static_transform_publisher --x " << num(t.x()) << " --y " << num(t.y())
    << " --z " << num(t.z()) << " --qx " << num(q.x()) << " --qy " << num(q.y()) << " --qz "
    << num(q.z()) << " --qw " << num(q.w()) << " --frame-id " << frames.lidar
    << " --child-frame-id " << frames.camera;
  return s.str();
}

std::string opencv_yaml(const Eigen::Isometry3d& camera_from_lidar) {
  const Eigen::AngleAxisd aa(camera_from_lidar.linear());
  const Eigen::Vector3d rvec = aa.axis() * aa.angle();
  std::string s = "%YAML:1.0\n---\n";
  s += opencv_matrix("camera_from_lidar", camera_from_lidar.matrix());
  s += opencv_matrix("lidar_from_camera", camera_from_lidar.inverse().matrix());
  s += opencv_matrix("rvec", rvec);
  s += opencv_matrix("tvec", camera_from_lidar.translation());
  return s;
}

nlohmann::json calibration_json(const CalibrationResult& r, const FrameNames& frames) {
  using nlohmann::json;
  const Eigen::Isometry3d& t = r.camera_from_lidar;
  const Eigen::Isometry3d inv = t.inverse();
  const Eigen::Quaterniond q = unit_w_positive(t.linear());
  json out;
  json& l2c = out["lidar_to_camera"];
  l2c["rotation_wxyz"] = {q.w(), q.x(), q.y(), q.z()};
  l2c["translation_m"] = vec_json(t.translation());
  l2c["matrix"] = matrix_json(t.matrix());
  l2c["inverse"] = matrix_json(inv.matrix());
  l2c["sigma"] = {{"rotation_deg", vec_json(r.rotation_sigma_deg)},
                  {"rotation_total_deg", r.rotation_sigma_total_deg},
                  {"translation_mm", vec_json(r.translation_sigma_mm)},
                  {"covariance", matrix_json(r.covariance)},
                  {"covariance_units", "rotation vector rad (camera side), translation m"}};
  out["errors"] = {{"rms_px", r.rms_px},
                   {"held_out_median_px", r.held_out_median_px},
                   {"held_out_max_px", r.held_out_max_px},
                   {"chi2", r.chi2},
                   {"dof", r.dof},
                   {"covariance_scale", r.covariance_scale}};
  json poses = json::array(), rejected = json::array();
  for (const PoseReport& p : r.poses) {
    poses.push_back({{"label", p.label},
                     {"used", p.used},
                     {"reason", p.reason},
                     {"corner_px", p.corner_px},
                     {"rms_px", p.rms_px},
                     {"held_out_px", p.held_out_px},
                     {"range_m", p.range_m},
                     {"chi2", p.chi2}});
    if (!p.used) rejected.push_back({{"label", p.label}, {"reason", p.reason}});
  }
  out["poses"] = poses;
  out["poses_used"] = r.used_poses;
  out["poses_rejected"] = rejected;
  json weak = json::array();
  for (const WeakDirection& w : r.weak)
    weak.push_back(
        {{"name", w.name}, {"sigma_deg", w.sigma_deg}, {"direction", vec_json(w.direction)}});
  out["degeneracy"] = {{"information_eigenvalues", vec_json(r.information_eigenvalues)},
                       {"median_range_m", r.median_range_m},
                       {"weak", weak},
                       {"suggestion", r.suggestion}};
  out["warnings"] = r.warnings;
  out["frames"] = {{"parent", frames.lidar}, {"child", frames.camera}};
  out["forms"] = {{"urdf", urdf_joint(inv, frames)},
                  {"ros1", ros1_static_transform(inv, frames)},
                  {"ros2", ros2_static_transform(inv, frames)},
                  {"opencv_yaml", opencv_yaml(t)}};
  return out;
}

}  // namespace lidartag::calib
