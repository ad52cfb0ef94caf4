#include "lidartag/sim/clutter.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "lidartag/sim/random.hpp"

namespace lidartag::sim {
namespace {

double segment_distance(const Eigen::Vector2d& p, const KeepOut& k) {
  const Eigen::Vector2d ab = k.b - k.a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - k.a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (k.a + s * ab)).norm();
}

// Objects placed so far, as footprint circles.
class Placer {
 public:
  Placer(const ClutterOptions& o, std::span<const KeepOut> keep_out) : o_(o), keep_out_(keep_out) {}

  // True (and remembered) when a footprint of radius r at p fits.
  bool try_place(const Eigen::Vector2d& p, double r) {
    if (p.x() - r < o_.region[0] || p.x() + r > o_.region[1] || p.y() - r < o_.region[2] ||
        p.y() + r > o_.region[3])
      return false;
    for (const KeepOut& k : keep_out_)
      if (segment_distance(p, k) < k.radius + r + o_.clearance) return false;
    for (const auto& [q, rq] : placed_)
      if ((p - q).norm() < r + rq + 0.1) return false;
    placed_.emplace_back(p, r);
    return true;
  }

 private:
  const ClutterOptions& o_;
  std::span<const KeepOut> keep_out_;
  std::vector<std::pair<Eigen::Vector2d, double>> placed_;
};

void add_box(Clutter& out, const Eigen::Vector2d& p, double sx, double sy, double sz, double yaw,
             double refl) {
  out.boxes.push_back({{p.x(), p.y(), sz / 2.0}, {sx, sy, sz}, yaw, refl});
}

void add_cylinder(Clutter& out, const Eigen::Vector2d& p, double r, double h, double refl) {
  out.cylinders.push_back({{p.x(), p.y(), 0.0}, r, h, refl});
}

Eigen::Vector2d random_point(Rng& rng, const ClutterOptions& o) {
  return {rng.uniform(o.region[0], o.region[1]), rng.uniform(o.region[2], o.region[3])};
}

// One object of an indoor lab or an outdoor space: kind picked by cumulative weights.
void place_scattered(const ClutterOptions& o, Rng& rng, Placer& placer, Clutter& out) {
  const bool lab = o.kind == ClutterKind::kLab;
  int placed = 0;
  for (int attempt = 0; attempt < 100 * o.count && placed < o.count; ++attempt) {
    const double pick = rng.uniform();
    const Eigen::Vector2d p = random_point(rng, o);
    const double yaw = rng.uniform(0.0, 360.0);
    double sx = 0, sy = 0, sz = 0, radius = 0, height = 0, refl = 0;
    bool cylinder = false;
    if (lab) {
      refl = rng.uniform(10.0, 70.0);
      if (pick < 0.3) {  // table
        sx = rng.uniform(1.2, 1.8), sy = rng.uniform(0.6, 0.8), sz = 0.75;
      } else if (pick < 0.5) {  // cabinet or shelf
        sx = rng.uniform(0.5, 1.2), sy = rng.uniform(0.4, 0.6), sz = rng.uniform(1.0, 2.0);
      } else if (pick < 0.7) {  // chair, bin, crate
        sx = sy = rng.uniform(0.4, 0.6), sz = rng.uniform(0.4, 0.9);
      } else if (pick < 0.9) {  // person
        cylinder = true, radius = rng.uniform(0.17, 0.25), height = rng.uniform(1.55, 1.9);
      } else {  // pole, tripod, coat stand
        cylinder = true, radius = rng.uniform(0.03, 0.08), height = rng.uniform(1.5, 3.0);
      }
    } else {
      refl = rng.uniform(5.0, 50.0);
      if (pick < 0.3) {  // tree trunk
        cylinder = true, radius = rng.uniform(0.1, 0.35), height = rng.uniform(3.0, 8.0);
      } else if (pick < 0.5) {  // pole, sign post
        cylinder = true, radius = rng.uniform(0.05, 0.12), height = rng.uniform(2.5, 6.0);
      } else if (pick < 0.75) {  // bush, hedge
        sx = rng.uniform(0.6, 2.0), sy = rng.uniform(0.6, 2.0), sz = rng.uniform(0.4, 1.2);
      } else if (pick < 0.9) {  // person
        cylinder = true, radius = rng.uniform(0.17, 0.25), height = rng.uniform(1.55, 1.9);
      } else {  // bench, rock
        sx = rng.uniform(0.3, 1.5), sy = rng.uniform(0.3, 0.8), sz = rng.uniform(0.2, 0.6);
      }
    }
    const double footprint = cylinder ? radius : std::hypot(sx, sy) / 2.0;
    if (!placer.try_place(p, footprint)) continue;
    if (cylinder)
      add_cylinder(out, p, radius, height, refl);
    else
      add_box(out, p, sx, sy, sz, yaw, refl);
    ++placed;
  }
}

// Rows of parking slots along x, 2.6 m wide and 5 m deep, aisles of 6 m between row pairs;
// `count` cars on randomly chosen free slots, then lamp posts and a few people in the aisles.
void place_parking(const ClutterOptions& o, Rng& rng, Placer& placer, Clutter& out) {
  constexpr double kSlotWidth = 2.6, kSlotDepth = 5.0, kAisle = 6.0;
  std::vector<Eigen::Vector2d> slots;
  auto add_row = [&](double y) {
    for (double x = o.region[0] + kSlotWidth / 2.0; x + kSlotWidth / 2.0 <= o.region[1];
         x += kSlotWidth)
      slots.emplace_back(x, y);
  };
  // Two rows back to back, then an aisle.
  for (double y = o.region[2] + kSlotDepth / 2.0; y + kSlotDepth / 2.0 <= o.region[3];
       y += 2.0 * kSlotDepth + kAisle) {
    add_row(y);
    if (y + 1.5 * kSlotDepth <= o.region[3]) add_row(y + kSlotDepth);
  }
  // Fisher-Yates with the portable generator.
  for (size_t i = slots.size(); i > 1; --i)
    std::swap(slots[i - 1],
              slots[static_cast<size_t>(rng.uniform_int(0, static_cast<int>(i) - 1))]);
  int cars = 0;
  for (const Eigen::Vector2d& s : slots) {
    if (cars >= o.count) break;
    const double len = rng.uniform(4.2, 4.9), wid = rng.uniform(1.7, 1.9);
    const double h = rng.uniform(1.4, 1.7), refl = rng.uniform(5.0, 90.0);
    const double yaw = 90.0 + rng.uniform(-3.0, 3.0);
    const Eigen::Vector2d p = s + Eigen::Vector2d(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2));
    if (!placer.try_place(p, std::hypot(len, wid) / 2.0)) continue;
    add_box(out, p, len, wid, h, yaw, refl);
    ++cars;
  }
  const int posts = std::max(1, o.count / 5), people = std::max(1, o.count / 6);
  for (int i = 0, attempt = 0; i < posts && attempt < 100 * posts; ++attempt) {
    const Eigen::Vector2d p = random_point(rng, o);
    if (!placer.try_place(p, 0.12)) continue;
    add_cylinder(out, p, 0.12, rng.uniform(6.0, 8.0), 30.0);
    ++i;
  }
  for (int i = 0, attempt = 0; i < people && attempt < 100 * people; ++attempt) {
    const Eigen::Vector2d p = random_point(rng, o);
    const double r = rng.uniform(0.17, 0.25);
    if (!placer.try_place(p, r)) continue;
    add_cylinder(out, p, r, rng.uniform(1.55, 1.9), rng.uniform(10.0, 60.0));
    ++i;
  }
}

}  // namespace

Clutter generate_clutter(const ClutterOptions& options, std::span<const KeepOut> keep_out) {
  Clutter out;
  if (!options.enabled || options.count <= 0) return out;
  Rng rng(options.seed);
  Placer placer(options, keep_out);
  if (options.kind == ClutterKind::kParking)
    place_parking(options, rng, placer, out);
  else
    place_scattered(options, rng, placer, out);
  return out;
}

}  // namespace lidartag::sim
