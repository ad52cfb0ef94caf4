// The forms a calibration result is handed over in (issue 30 item 4): the result JSON, a URDF
// joint origin, a ROS static_transform_publisher line (ROS 1 and ROS 2), an OpenCV FileStorage
// YAML. The result maps LiDAR points into the camera's OPTICAL frame (x right, y down, z
// forward): the URDF and ROS forms give the camera optical frame as the child of the LiDAR frame,
// i.e. the optical frame's pose in the LiDAR frame (the inverse of camera_from_lidar); the OpenCV
// form gives camera_from_lidar itself (rvec/tvec as cv::projectPoints takes them for LiDAR
// points).
#pragma once

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <string>

#include "lidartag/calib/extrinsic_solver.hpp"

namespace lidartag::calib {

// The names of the two frames in the ROS and URDF forms.
struct FrameNames {
  std::string lidar = "lidar";                  // the parent
  std::string camera = "camera_optical_frame";  // the child: x right, y down, z forward
};

// Fixed-axis roll, pitch, yaw (radians) of a rotation, R = Rz(yaw) Ry(pitch) Rx(roll): URDF's
// rpy and ROS's. At pitch +-90 degrees roll is 0.
Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& r);

// <origin xyz="..." rpy="..."/> of a joint from `parent` to `child`, given child's pose in
// parent (parent_from_child), inside a fixed <joint> naming the frames.
std::string urdf_joint(const Eigen::Isometry3d& parent_from_child, const FrameNames& frames);

// ROS 1: rosrun tf2_ros static_transform_publisher x y z qx qy qz qw parent child
// (the transform is child's pose in parent: the 7-number quaternion form, no Euler ambiguity).
std::string ros1_static_transform(const Eigen::Isometry3d& parent_from_child,
                                  const FrameNames& frames);
// ROS 2: ros2 run tf2_ros static_transform_publisher --x .. --qw .. --frame-id parent
// --child-frame-id child.
std::string ros2_static_transform(const Eigen::Isometry3d& parent_from_child,
                                  const FrameNames& frames);

// OpenCV FileStorage YAML ("%YAML:1.0"): camera_from_lidar (4 x 4), lidar_from_camera (4 x 4),
// rvec (Rodrigues, 3 x 1) and tvec (3 x 1, m) of camera_from_lidar, as !!opencv-matrix nodes.
std::string opencv_yaml(const Eigen::Isometry3d& camera_from_lidar);

// The result file: lidar_to_camera {rotation_wxyz, translation_m, matrix (4 x 4 row-major lists),
// inverse, sigma {rotation_deg [x y z], rotation_total_deg, translation_mm [x y z], covariance
// (6 x 6: rotation rad, translation m)}}, errors {rms_px, held_out_median_px, held_out_max_px,
// chi2, dof, covariance_scale}, poses [{label, used, reason, corner_px, rms_px, held_out_px,
// range_m, chi2}], poses_used, poses_rejected [{label, reason}], degeneracy {information
// eigenvalues, median_range_m, weak [{name, sigma_deg, direction}], suggestion}, warnings, frames
// and forms {urdf, ros1, ros2, opencv_yaml}.
nlohmann::json calibration_json(const CalibrationResult& result, const FrameNames& frames = {});

}  // namespace lidartag::calib
