// Synthetic calibration scenes for the solver's tests: a known extrinsic, tags around the image
// at known ranges, corners with Gaussian noise of known sigma on both sides.
#pragma once

#include <Eigen/Dense>
#include <numbers>
#include <random>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/correspondence.hpp"

namespace lidartag::calib::testing {

// 1280 x 720, fx 900, plumb-bob.
inline CameraModel test_camera() {
  CameraModel c;
  c.width = 1280;
  c.height = 720;
  c.fx = 900;
  c.fy = 898;
  c.cx = 641.3;
  c.cy = 357.8;
  c.distortion = Distortion::kPlumbBob;
  c.d = {-0.12, 0.03, 0.0004, -0.0006, -0.004};
  return c;
}

// LiDAR (x forward, y left, z up) to the camera's optical frame, turned a few degrees and offset
// as a camera mounted beside a LiDAR is.
inline Eigen::Isometry3d true_extrinsic() {
  Eigen::Matrix3d axes;
  axes << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Matrix3d tweak = (Eigen::AngleAxisd(0.031, Eigen::Vector3d::UnitX()) *
                                 Eigen::AngleAxisd(-0.022, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(0.047, Eigen::Vector3d::UnitZ()))
                                    .toRotationMatrix();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = tweak * axes;
  t.translation() = Eigen::Vector3d(0.083, -0.142, -0.061);
  return t;
}

// Defaults: AprilTag's refined corners, and the tracker's mean over 10 rotations of a tag whose
// single rotations scatter by 2-3 mm and 0.3 degrees, plus what averaging leaves.
struct SceneNoise {
  double pixel_sigma = 0.3;       // per image coordinate, px
  double position_sigma = 0.001;  // tag centre, per axis, m
  double angle_sigma_deg = 0.1;   // tag orientation, per axis
  double floor_m = 0.001;         // per corner, per axis
};

struct Scene {
  std::vector<TagPose> poses;
  std::vector<Eigen::Vector3d> true_centres_camera;
};

// `n` tags of 0.8-1.2 m at 2-8 m spread over a grid of image directions (or all at one spot
// when `one_spot`), tilted up to 30 degrees, turned by random quarter turns in their plane.
inline Scene make_scene(unsigned seed, int n = 9, const SceneNoise& noise = {},
                        bool one_spot = false,
                        const Eigen::Isometry3d& extrinsic = true_extrinsic(),
                        const CameraModel& cam = test_camera()) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  Scene s;
  const Eigen::Isometry3d lidar_from_camera = extrinsic.inverse();
  for (int i = 0; s.poses.size() < static_cast<std::size_t>(n) && i < 1000; ++i) {
    const int idx = static_cast<int>(s.poses.size());
    double u, v, range, size;
    if (one_spot) {
      u = 0.55 * cam.width + 5 * uni(rng);
      v = 0.5 * cam.height + 5 * uni(rng);
      range = 5.0 + 0.02 * uni(rng);
      size = 1.0;
    } else {
      u = (0.18 + 0.32 * (idx % 3)) * cam.width + 40 * uni(rng);
      v = (0.22 + 0.28 * ((idx / 3) % 3)) * cam.height + 30 * uni(rng);
      range = 2.0 + 6.0 * ((idx * 5) % 9) / 8.0 + 0.3 * uni(rng);
      range = std::clamp(range, 2.0, 8.0);
      size = 1.0 + 0.2 * uni(rng);
    }
    const Eigen::Vector3d centre = cam.unproject(Eigen::Vector2d(u, v)) * range;
    // Tag frame in the camera: x (normal) towards the camera, y right, z up, then tilted.
    Eigen::Matrix3d r;
    r.col(0) = -centre.normalized();
    r.col(2) = (-Eigen::Vector3d::UnitY() - (-Eigen::Vector3d::UnitY()).dot(r.col(0)) * r.col(0))
                   .normalized();
    r.col(1) = r.col(2).cross(r.col(0));
    const double tilt = one_spot ? 0.05 : 0.5;
    r = r * (Eigen::AngleAxisd(tilt * uni(rng), Eigen::Vector3d::UnitZ()) *
             Eigen::AngleAxisd(tilt * uni(rng), Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(std::numbers::pi / 2 * static_cast<int>(rng() % 4),
                               Eigen::Vector3d::UnitX()))
                .toRotationMatrix();
    const double h = black_half_side(fam, size);
    TagPose p;
    bool inside = true;
    for (int k = 0; k < 4; ++k) {
      const auto px = cam.project(centre + r * tag_frame_corner(k, h));
      if (!px || !cam.in_image(*px) || px->x() < 20 || px->y() < 20 || px->x() > cam.width - 20 ||
          px->y() > cam.height - 20)
        inside = false;
      else
        p.pixels[static_cast<std::size_t>(k)] =
            *px + noise.pixel_sigma * Eigen::Vector2d(g(rng), g(rng));
    }
    if (!inside) continue;
    p.sigma_px = noise.pixel_sigma;
    // The LiDAR's view: the true pose in the LiDAR frame, perturbed.
    LidarTag& lt = p.lidar;
    lt.family = "tag36h11";
    lt.id = idx;
    lt.size_m = size;
    const Eigen::Vector3d dp = noise.position_sigma * Eigen::Vector3d(g(rng), g(rng), g(rng));
    const Eigen::Vector3d dth =
        noise.angle_sigma_deg * std::numbers::pi / 180 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    const Eigen::Matrix3d r_lidar =
        Eigen::AngleAxisd(dth.norm(), dth.normalized()).toRotationMatrix() *
        lidar_from_camera.linear() * r;
    lt.position = lidar_from_camera * centre + dp;
    lt.orientation = Eigen::Quaterniond(r_lidar);
    for (int k = 0; k < 4; ++k)
      lt.corners[static_cast<std::size_t>(k)] =
          lt.position + r_lidar * tag_frame_corner(k, h) +
          noise.floor_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
    lt.corner_cov = pose_corner_covariance(
        lt, Eigen::Matrix3d::Identity() * noise.position_sigma * noise.position_sigma,
        noise.angle_sigma_deg * std::numbers::pi / 180);
    lt.corner_cov.diagonal().array() += noise.floor_m * noise.floor_m;
    p.label = "pose " + std::to_string(idx);
    s.poses.push_back(p);
    s.true_centres_camera.push_back(centre);
  }
  return s;
}

inline double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle() * 180 / std::numbers::pi;
}

inline double translation_error_mm(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm() * 1e3;
}

}  // namespace lidartag::calib::testing
