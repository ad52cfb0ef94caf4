// Ground truth of a simulated capture, per rotation: the sensor pose in the world and every tag's
// pose, black-square corners and number of returns, in that rotation's sensor frame.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidartag/calib/camera_model.hpp"

namespace lidartag::sim {

// The truth file cannot be written.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TagTruth {
  std::string family;
  int id = 0;
  double size = 0.0;                                   // t, metres
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // tag centre, sensor frame
  Eigen::Vector4d orientation{1, 0, 0, 0};             // w, x, y, z: tag frame -> sensor frame
  std::array<Eigen::Vector3d, 4> corners{};  // bottom-left, bottom-right, top-right, top-left
  int returns = 0;                           // reported points on the printed marker
  // With a camera: `corners` projected into its image (pixels, lidartag's convention: pixel
  // centres at integers), same order; nullopt when a corner is behind the camera or outside its
  // lens model's field of view. Corners may lie off the image.
  std::optional<std::array<Eigen::Vector2d, 4>> image_corners;
};

// The simulated camera: its intrinsics and lidar_to_camera (p_camera = rotation p_lidar +
// translation; camera optical frame x right, y down, z forward).
struct CameraTruth {
  calib::CameraModel model;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};

// A truth file's camera section that cannot be read.
class TruthError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct RotationTruth {
  int index = 0;
  int64_t stamp_ns = 0;  // first firing of the rotation (the batcher's Scan::stamp_ns)
  Eigen::Vector3d sensor_position = Eigen::Vector3d::Zero();  // world
  Eigen::Vector4d sensor_orientation{1, 0, 0, 0};             // w, x, y, z: sensor -> world
  std::vector<TagTruth> tags;
};

struct Truth {
  std::string model;        // model name (vlp32c, ...)
  std::string return_mode;  // strongest, last, dual
  double rpm = 0.0;
  uint64_t seed = 0;
  std::optional<CameraTruth> camera;  // scenes with a `camera:` section
  std::vector<RotationTruth> rotations;
};

// The "camera" object of a truth file (truth_to_json's form) back into intrinsics and extrinsic.
// Throws TruthError naming the missing or bad key.
CameraTruth camera_truth_from_json(const nlohmann::json& camera);

// w, x, y, z with w >= 0 of a rotation matrix.
Eigen::Vector4d quaternion_wxyz(const Eigen::Matrix3d& rotation);

nlohmann::json truth_to_json(const Truth& truth);
// Writes the JSON (2-space indent). Throws OutputError.
void write_truth(const Truth& truth, const std::string& path);

}  // namespace lidartag::sim
