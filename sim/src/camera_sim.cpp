#include "lidartag/sim/camera_sim.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "lidartag/sim/random.hpp"

namespace lidartag::sim {
namespace {

constexpr double kMaxRange = 500.0;  // metres: farther than any surface, else background

// Separable Gaussian blur of a float image, edges clamped.
void blur(std::vector<double>& img, int w, int h, double sigma) {
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  std::vector<double> k(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int i = -r; i <= r; ++i)
    sum += k[static_cast<size_t>(i + r)] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= sum;
  std::vector<double> tmp(img.size());
  auto idx = [w](int u, int v) {
    return static_cast<size_t>(v) * static_cast<size_t>(w) + static_cast<size_t>(u);
  };
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double acc = 0;
      for (int i = -r; i <= r; ++i)
        acc += k[static_cast<size_t>(i + r)] * img[idx(std::clamp(u + i, 0, w - 1), v)];
      tmp[idx(u, v)] = acc;
    }
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double acc = 0;
      for (int i = -r; i <= r; ++i)
        acc += k[static_cast<size_t>(i + r)] * tmp[idx(u, std::clamp(v + i, 0, h - 1))];
      img[idx(u, v)] = acc;
    }
}

}  // namespace

Eigen::Matrix3d camera_rotation(const CameraOptions& c) {
  const auto& q = c.rotation_wxyz;
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

Eigen::Vector3d camera_translation(const CameraOptions& c) {
  return {c.translation_m[0], c.translation_m[1], c.translation_m[2]};
}

calib::GrayImage render_camera(const World& world, const CameraOptions& camera,
                               const Eigen::Vector3d& lidar_position,
                               const Eigen::Matrix3d& lidar_rotation, uint64_t seed) {
  const calib::CameraModel& m = camera.model;
  const Eigen::Matrix3d r_cl = camera_rotation(camera);
  // Camera in the world: origin -R^T t in the LiDAR frame; directions R^T d.
  const Eigen::Matrix3d r_wc = lidar_rotation * r_cl.transpose();
  const Eigen::Vector3d origin =
      lidar_position + lidar_rotation * (-r_cl.transpose() * camera_translation(camera));
  const int s = camera.supersample;
  const int w = m.width, h = m.height;
  std::vector<double> img(static_cast<size_t>(w) * static_cast<size_t>(h));
  // Rows in parallel: each pixel's value depends on its rays alone, so the image is the same for
  // any number of threads (the noise is drawn afterwards, in pixel order).
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    Ray ray;
    ray.origin = origin;
    for (int v = rows.begin(); v < rows.end(); ++v)
      for (int u = 0; u < w; ++u) {
        double sum = 0;
        for (int j = 0; j < s; ++j)
          for (int i = 0; i < s; ++i) {
            // Sub-pixel positions spread evenly over the pixel [u - 0.5, u + 0.5).
            const Eigen::Vector2d px(u - 0.5 + (i + 0.5) / s, v - 0.5 + (j + 0.5) / s);
            ray.dir = (r_wc * m.unproject(px)).normalized();
            const Hit hit = world.cast(ray, kMaxRange);
            sum += hit.hit() ? std::min(255.0, hit.reflectivity * camera.gain) : camera.background;
          }
        img[static_cast<size_t>(v) * static_cast<size_t>(w) + static_cast<size_t>(u)] =
            sum / (s * s);
      }
  });
  if (camera.blur_sigma > 0.0) blur(img, w, h, camera.blur_sigma);
  Rng rng(seed ^ 0x63616d657261ull);  // "camera": a stream apart from the LiDAR's noise
  calib::GrayImage out(w, h);
  for (size_t k = 0; k < img.size(); ++k)
    out.pixels[k] = static_cast<uint8_t>(
        std::clamp(std::lround(rng.normal(img[k], camera.noise_sigma)), 0L, 255L));
  return out;
}

std::optional<std::array<Eigen::Vector2d, 4>> project_corners(
    const CameraOptions& camera, const std::array<Eigen::Vector3d, 4>& lidar_points) {
  const Eigen::Matrix3d r = camera_rotation(camera);
  const Eigen::Vector3d t = camera_translation(camera);
  std::array<Eigen::Vector2d, 4> out;
  for (size_t k = 0; k < 4; ++k) {
    const auto p = camera.model.project(r * lidar_points[k] + t);
    if (!p) return std::nullopt;
    out[k] = *p;
  }
  return out;
}

}  // namespace lidartag::sim
