#include "lidartag/sim/geometry.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace lidartag::sim {
namespace {

constexpr double kEps = 1e-9;

// Cheap rejection before the exact test: does the ray pass within `b.radius` of `b.center`
// somewhere in front of the origin and before t_max?
template <typename B>
bool may_hit(const B& b, const Ray& ray, double t_max) {
  const Eigen::Vector3d oc = b.center - ray.origin;
  const double tca = oc.dot(ray.dir);
  if (tca < -b.radius || tca - b.radius > t_max) return false;
  const double d2 = oc.squaredNorm() - tca * tca;
  return d2 <= b.radius * b.radius;
}

}  // namespace

bool PrintedPattern::reflectivity_at(double y, double z, double& r) const {
  const double hw = width / 2.0, hh = height / 2.0;
  if (std::abs(y) > hw || std::abs(z) > hh) return false;
  const int col = std::clamp(static_cast<int>(std::floor((y + hw) / (width / cols))), 0, cols - 1);
  const int row = std::clamp(static_cast<int>(std::floor((hh - z) / (height / rows))), 0, rows - 1);
  r = reflectivity[static_cast<size_t>(row) * static_cast<size_t>(cols) + static_cast<size_t>(col)];
  return true;
}

OrientedBox make_box(const Eigen::Vector3d& center, const Eigen::Vector3d& size, double yaw_deg,
                     double reflectivity) {
  OrientedBox b;
  b.center = center;
  b.rotation =
      Eigen::AngleAxisd(yaw_deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()).matrix();
  b.half = size / 2.0;
  b.reflectivity = reflectivity;
  return b;
}

bool intersect_box(const OrientedBox& box, const Ray& ray, double t_max, double& t,
                   Eigen::Vector3d& local, bool& face_x) {
  // Slab test in the box's own axes.
  const Eigen::Vector3d o = box.rotation.transpose() * (ray.origin - box.center);
  const Eigen::Vector3d d = box.rotation.transpose() * ray.dir;
  double t0 = kEps, t1 = t_max;
  int entry_axis = -1;
  double entry_sign = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-15) {
      if (std::abs(o[a]) > box.half[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double ta = (-box.half[a] - o[a]) * inv;
    double tb = (box.half[a] - o[a]) * inv;
    double sign = -1.0;  // entering through the -a face
    if (ta > tb) {
      std::swap(ta, tb);
      sign = 1.0;
    }
    if (ta > t0) {
      t0 = ta;
      entry_axis = a;
      entry_sign = sign;
    }
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  if (entry_axis < 0) return false;  // origin inside the box: the sensor sees no inner faces
  t = t0;
  local = o + t * d;
  face_x = entry_axis == 0 && entry_sign > 0.0;
  return true;
}

bool intersect_cylinder(const VerticalCylinder& cyl, const Ray& ray, double t_max, double& t) {
  const Eigen::Vector3d o = ray.origin - cyl.base;
  const Eigen::Vector3d& d = ray.dir;
  double best = std::numeric_limits<double>::infinity();
  // Side: (ox + t dx)^2 + (oy + t dy)^2 = r^2.
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-15) {
    const double b = o.x() * d.x() + o.y() * d.y();
    const double c = o.x() * o.x() + o.y() * o.y() - cyl.radius * cyl.radius;
    const double disc = b * b - a * c;
    if (disc >= 0.0) {
      const double s = std::sqrt(disc);
      for (double ts : {(-b - s) / a, (-b + s) / a}) {
        if (ts <= kEps || ts >= t_max) continue;
        const double z = o.z() + ts * d.z();
        if (z >= 0.0 && z <= cyl.height) {
          best = std::min(best, ts);
          break;
        }
      }
    }
  }
  // Caps.
  if (std::abs(d.z()) > 1e-15) {
    for (double zc : {0.0, cyl.height}) {
      const double tc = (zc - o.z()) / d.z();
      if (tc <= kEps || tc >= t_max || tc >= best) continue;
      const double x = o.x() + tc * d.x(), y = o.y() + tc * d.y();
      if (x * x + y * y <= cyl.radius * cyl.radius) best = tc;
    }
  }
  if (best == std::numeric_limits<double>::infinity()) return false;
  t = best;
  return true;
}

void World::set_ground(bool enabled, double reflectivity) {
  ground_ = enabled;
  ground_reflectivity_ = reflectivity;
}

void World::add_box(const OrientedBox& box) {
  boxes_.push_back(box);
  box_bounds_.push_back({box.center, box.half.norm()});
}

void World::add_cylinder(const VerticalCylinder& cyl) {
  cylinders_.push_back(cyl);
  const double hh = cyl.height / 2.0;
  cylinder_bounds_.push_back(
      {cyl.base + Eigen::Vector3d(0, 0, hh), std::sqrt(hh * hh + cyl.radius * cyl.radius)});
}

int World::add_pattern(PrintedPattern pattern) {
  patterns_.push_back(std::move(pattern));
  return static_cast<int>(patterns_.size()) - 1;
}

Hit World::cast(const Ray& ray, double t_max) const {
  Hit best;
  double limit = t_max;
  if (ground_ && ray.dir.z() < -1e-12 && ray.origin.z() > 0.0) {
    const double t = -ray.origin.z() / ray.dir.z();
    if (t < limit) {
      best.t = limit = t;
      best.reflectivity = ground_reflectivity_;
    }
  }
  for (size_t i = 0; i < boxes_.size(); ++i) {
    if (!may_hit(box_bounds_[i], ray, limit)) continue;
    double t = 0;
    Eigen::Vector3d local;
    bool face_x = false;
    const OrientedBox& box = boxes_[i];
    if (!intersect_box(box, ray, limit, t, local, face_x)) continue;
    if (!box.holes.empty() && std::abs(std::abs(local.x()) - box.half.x()) < 1e-6 &&
        std::any_of(box.holes.begin(), box.holes.end(), [&](const Hole& h) {
          const double dy = local.y() - h.y, dz = local.z() - h.z;
          return dy * dy + dz * dz < h.radius * h.radius;
        }))
      continue;  // through a hole
    best.t = limit = t;
    best.reflectivity = box.reflectivity;
    best.tag = -1;
    if (face_x && box.pattern >= 0) {
      const PrintedPattern& p = patterns_[static_cast<size_t>(box.pattern)];
      double r = 0;
      if (p.reflectivity_at(local.y(), local.z(), r)) {
        best.reflectivity = r;
        best.tag = p.tag;
      }
    }
  }
  for (size_t i = 0; i < cylinders_.size(); ++i) {
    if (!may_hit(cylinder_bounds_[i], ray, limit)) continue;
    double t = 0;
    if (!intersect_cylinder(cylinders_[i], ray, limit, t)) continue;
    best.t = limit = t;
    best.reflectivity = cylinders_[i].reflectivity;
    best.tag = -1;
  }
  return best;
}

}  // namespace lidartag::sim
