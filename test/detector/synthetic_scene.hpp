// Analytic scenes rendered into a lidartag::Scan for the detector's tests: a spinning sensor with
// given beam elevations, tags drawn with TagFamily::render, a wall and a floor.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::test {

struct SensorSpec {
  std::vector<double> elevations_deg;  // ascending: ring 0 lowest
  int columns = 1800;                  // per rotation (0.2 degrees at 10 Hz)
};

// VLP-32C beam elevations (factory table), sorted.
SensorSpec vlp32c();
// 16 beams, -15..15 degrees in 2 degree steps (VLP-16).
SensorSpec vlp16();

struct SyntheticTag {
  const tags::TagFamily* family = nullptr;
  int id = 0;
  double size = 1.2;  // full marker size, metres
  Eigen::Vector3d center = Eigen::Vector3d(6, 0, 0);
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // tag frame -> sensor frame
  std::vector<int> flipped_cells;                          // row * W + col to draw inverted
};

struct SyntheticScene {
  std::vector<SyntheticTag> tags;
  bool wall = true;  // plane x = wall_x, |y| < 15 m
  double wall_x = 12.0;
  bool floor = true;  // plane z = floor_z
  double floor_z = -1.5;
  // Boxes (axis-aligned) as clutter: min and max corners.
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> boxes;
  double range_noise_m = 0.0;  // Gaussian, per return
  uint8_t white = 220, black = 20, wall_intensity = 60, floor_intensity = 30, box_intensity = 90;
  uint32_t seed = 1;
};

// Tag frame -> sensor frame rotation of a tag facing the sensor (its +x toward the origin) from
// `center`, turned `roll_deg` about its normal (45 = diamond) and `yaw_deg` about the vertical.
Eigen::Matrix3d facing_sensor(const Eigen::Vector3d& center, double roll_deg, double yaw_deg = 0);

void render_scene(const SyntheticScene& scene, const SensorSpec& sensor, Scan& out);

// Rotation angle between two rotations, degrees.
double angle_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

}  // namespace lidartag::test
