// The picture `lidartag calibrate --pictures` draws for each pair: the camera image with the
// LiDAR's points projected onto it through the calibrated extrinsic (coloured by range), and each
// tag's corners as the image found them beside the LiDAR's corners reprojected, so that a person
// sees at a glance whether the calibration is right.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <span>
#include <string>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/image_io.hpp"

namespace lidartag::draw {

struct CalibrationViewTag {
  std::string label;                     // "tag36h11:5"
  std::array<Eigen::Vector2d, 4> image;  // the image's corners, pixels
  std::array<Eigen::Vector3d, 4> lidar;  // the LiDAR's corners, LiDAR frame
  bool used = true;                      // in the solution (else rejected: drawn dashed)
};

struct CalibrationView {
  const calib::GrayImage* image = nullptr;
  const calib::CameraModel* camera = nullptr;
  Eigen::Isometry3d camera_from_lidar = Eigen::Isometry3d::Identity();
  std::span<const Eigen::Vector3f> points;  // LiDAR frame
  std::vector<CalibrationViewTag> tags;
  std::vector<std::string> title;  // lines under the image
};

struct CalibrationViewStats {
  size_t points_drawn = 0;     // points that fall on the image
  double max_corner_px = 0.0;  // largest image-to-LiDAR corner distance drawn
};

// Writes the PNG (the image's size plus a strip for the title and legend). Throws
// std::runtime_error when it cannot be written.
CalibrationViewStats write_calibration_view(const CalibrationView& view, const std::string& path);

}  // namespace lidartag::draw
