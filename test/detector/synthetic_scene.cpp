#include "synthetic_scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace lidartag::test {

SensorSpec vlp32c() {
  SensorSpec s;
  s.elevations_deg = {-25,    -15.639, -11.31, -8.843, -7.254, -6.148, -5.333, -4.667,
                      -4,     -3.667,  -3.333, -3,     -2.667, -2.333, -2,     -1.667,
                      -1.333, -1,      -0.667, -0.333, 0,      0.333,  0.667,  1,
                      1.333,  1.667,   2.333,  3.333,  4.667,  7,      10.333, 15};
  return s;
}

SensorSpec vlp16() {
  SensorSpec s;
  for (int i = 0; i < 16; ++i) s.elevations_deg.push_back(-15.0 + 2.0 * i);
  return s;
}

Eigen::Matrix3d facing_sensor(const Eigen::Vector3d& center, double roll_deg, double yaw_deg) {
  // x toward the sensor (horizontal), z up, y = z cross x; then yaw about z, roll about x.
  Eigen::Vector3d x = -center;
  x.z() = 0;
  x.normalize();
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r << x, y, z;
  const double d2r = std::numbers::pi / 180.0;
  return Eigen::AngleAxisd(yaw_deg * d2r, Eigen::Vector3d::UnitZ()).toRotationMatrix() * r *
         Eigen::AngleAxisd(roll_deg * d2r, Eigen::Vector3d::UnitX()).toRotationMatrix();
}

double angle_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle() * 180.0 / std::numbers::pi;
}

void render_scene(const SyntheticScene& scene, const SensorSpec& sensor, Scan& out) {
  const int rings = static_cast<int>(sensor.elevations_deg.size());
  out.reserve(rings, 1, sensor.columns);
  out.columns = sensor.columns;
  std::mt19937 rng(scene.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const double d2r = std::numbers::pi / 180.0;
  std::vector<std::vector<uint8_t>> images;
  for (const auto& t : scene.tags) {
    auto img = t.family->render(t.family->codes[static_cast<size_t>(t.id)]);
    for (int c : t.flipped_cells) img[static_cast<size_t>(c)] ^= 1;
    images.push_back(std::move(img));
  }
  for (int c = 0; c < sensor.columns; ++c) {
    const double az = 360.0 * c / sensor.columns;
    out.column_azimuth_deg[static_cast<size_t>(c)] = static_cast<float>(az);
    out.column_time_s[static_cast<size_t>(c)] = 0.1 * c / sensor.columns;
    for (int ring = 0; ring < rings; ++ring) {
      const double e = sensor.elevations_deg[static_cast<size_t>(ring)] * d2r;
      const Eigen::Vector3d d(std::cos(e) * std::cos(az * d2r), -std::cos(e) * std::sin(az * d2r),
                              std::sin(e));
      double best = std::numeric_limits<double>::infinity();
      uint8_t inten = 0;
      for (size_t k = 0; k < scene.tags.size(); ++k) {
        const auto& t = scene.tags[k];
        const Eigen::Vector3d n = t.rotation.col(0);
        const double den = n.dot(d);
        if (std::abs(den) < 1e-9) continue;
        const double s = n.dot(t.center) / den;
        if (s <= 0 || s >= best) continue;
        const Eigen::Vector3d q = t.rotation.transpose() * (s * d - t.center);
        if (std::abs(q.y()) > t.size / 2 || std::abs(q.z()) > t.size / 2) continue;
        const int w = t.family->total_width;
        const int col = std::clamp(static_cast<int>((q.y() + t.size / 2) / t.size * w), 0, w - 1);
        const int row = std::clamp(static_cast<int>((t.size / 2 - q.z()) / t.size * w), 0, w - 1);
        best = s;
        inten = images[k][static_cast<size_t>(row * w + col)] ? scene.white : scene.black;
      }
      if (scene.wall && d.x() > 1e-9) {
        const double s = scene.wall_x / d.x();
        const Eigen::Vector3d p = s * d;
        if (s < best && std::abs(p.y()) < 15.0 && p.z() > scene.floor_z) {
          best = s;
          inten = scene.wall_intensity;
        }
      }
      if (scene.floor && d.z() < -1e-9) {
        const double s = scene.floor_z / d.z();
        if (s < best && s < 60.0) {
          best = s;
          inten = scene.floor_intensity;
        }
      }
      for (const auto& [lo, hi] : scene.boxes) {  // slab test
        double t0 = 0, t1 = best;
        bool hit = true;
        for (int a = 0; a < 3 && hit; ++a) {
          if (std::abs(d(a)) < 1e-12) {
            hit = lo(a) <= 0 && 0 <= hi(a);
            continue;
          }
          double ta = lo(a) / d(a), tb = hi(a) / d(a);
          if (ta > tb) std::swap(ta, tb);
          t0 = std::max(t0, ta);
          t1 = std::min(t1, tb);
          hit = t0 <= t1;
        }
        if (hit && t0 > 0 && t0 < best) {
          best = t0;
          inten = scene.box_intensity;
        }
      }
      const size_t i = out.at(0, ring, c);
      if (!std::isfinite(best) || best > 100.0) {
        out.range[i] = 0.0f;
        out.return_type[i] = ReturnType::kNone;
        continue;
      }
      const double r = best + scene.range_noise_m * noise(rng);
      const Eigen::Vector3d p = r * d;
      out.x[i] = static_cast<float>(p.x());
      out.y[i] = static_cast<float>(p.y());
      out.z[i] = static_cast<float>(p.z());
      out.range[i] = static_cast<float>(r);
      out.azimuth_deg[i] = static_cast<float>(az);
      out.intensity[i] = inten;
      out.return_type[i] = ReturnType::kStrongest;
    }
  }
  out.complete = out.starts_at_cut = out.ends_at_cut = true;
}

}  // namespace lidartag::test
