// The simulator's camera: the scene's world (tags with their printed cells, boards, walls,
// ground, clutter) ray cast through the camera model into an 8-bit grey image. Each pixel averages
// supersample x supersample rays through sub-pixel positions (unproject() of each, so lens
// distortion bends the rays as a real lens would), then Gaussian blur and pixel noise.
// Pixel convention: lidartag's (pixel centres at integers), as the camera model.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>

#include "lidartag/calib/image_io.hpp"
#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

// lidar_to_camera of the options as a rotation matrix and translation.
Eigen::Matrix3d camera_rotation(const CameraOptions& camera);
Eigen::Vector3d camera_translation(const CameraOptions& camera);

// Renders `world` seen by the camera mounted on the LiDAR whose pose in the world is
// (lidar_position, lidar_rotation: world <- lidar). Same inputs and seed: the same image.
calib::GrayImage render_camera(const World& world, const CameraOptions& camera,
                               const Eigen::Vector3d& lidar_position,
                               const Eigen::Matrix3d& lidar_rotation, uint64_t seed);

// Pixels of points given in the LiDAR frame; nullopt when any is behind the camera or outside
// the lens model's field of view (they may still lie off the image: check in_image()).
std::optional<std::array<Eigen::Vector2d, 4>> project_corners(
    const CameraOptions& camera, const std::array<Eigen::Vector3d, 4>& lidar_points);

}  // namespace lidartag::sim
