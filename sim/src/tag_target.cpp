#include "lidartag/sim/tag_target.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace lidartag::sim {

double TagTarget::black_half() const {
  return static_cast<double>(width_at_border) / total_width * options.size / 2.0;
}

std::array<Eigen::Vector3d, 4> TagTarget::corners_tag() const {
  const double s = black_half();
  return {Eigen::Vector3d(0, -s, -s), Eigen::Vector3d(0, s, -s), Eigen::Vector3d(0, s, s),
          Eigen::Vector3d(0, -s, s)};
}

bool TagTarget::white_at(double y, double z) const {
  const double h = options.size / 2.0;
  if (std::abs(y) > h || std::abs(z) > h) return false;
  const double cell = options.size / total_width;
  const int col = std::min(static_cast<int>(std::floor((y + h) / cell)), total_width - 1);
  const int row = std::min(static_cast<int>(std::floor((h - z) / cell)), total_width - 1);
  return image[static_cast<size_t>(row * total_width + col)] != 0;
}

Eigen::Matrix3d tag_rotation(const Eigen::Vector3d& normal, double rotation_deg) {
  const Eigen::Vector3d x = normal.normalized();
  // The image's "up" before the rotation about the normal: world up projected on the face.
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ() - x.z() * x;
  if (up.norm() < 1e-6) up = Eigen::Vector3d::UnitX() - x.x() * x;
  up.normalize();
  const Eigen::Vector3d z =
      Eigen::AngleAxisd(rotation_deg * std::numbers::pi / 180.0, x).matrix() * up;
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return r;
}

TagTarget make_tag(const TagOptions& options, const Eigen::Vector3d& sensor_position,
                   const std::string& key) {
  TagTarget tag;
  tag.options = options;
  tags::TagFamily family;
  try {
    family = tags::resolve_family(options.family);
  } catch (const tags::FamilyError& e) {
    throw SceneError(key + ".family: " + e.what());
  }
  if (options.id < 0 || options.id >= family.ncodes())
    throw SceneError(key + ".id: " + std::to_string(options.id) + " is not a code of " +
                     family.name + " (0.." + std::to_string(family.ncodes() - 1) + ")");
  tag.family_name = family.name;
  tag.total_width = family.total_width;
  tag.width_at_border = family.width_at_border;
  tag.code = family.codes[static_cast<size_t>(options.id)];
  tag.image = family.render(tag.code);
  tag.center = Eigen::Vector3d(options.center[0], options.center[1], options.center[2]);
  Eigen::Vector3d n(options.normal[0], options.normal[1], options.normal[2]);
  if (n.norm() < 1e-9) {
    n = sensor_position - tag.center;
    n.z() = 0.0;
    if (n.norm() < 1e-9)
      throw SceneError(key +
                       ".normal: the tag is straight above or below the sensor; give a normal");
  }
  tag.rotation = tag_rotation(n, options.rotation_deg);
  return tag;
}

void add_tag(World& world, const TagTarget& tag, int index) {
  const TagOptions& o = tag.options;
  PrintedPattern p;
  p.tag = index;
  p.width = p.height = o.size;
  p.cols = p.rows = tag.total_width;
  for (uint8_t white : tag.image)
    p.reflectivity.push_back(white ? o.white_reflectivity : o.black_reflectivity);
  OrientedBox board;
  board.rotation = tag.rotation;
  const double half = o.size / 2.0 + o.board.margin;
  board.half = Eigen::Vector3d(o.board.thickness / 2.0, half, half);
  // The printed face (box +x face) lies in the tag's x = 0 plane.
  board.center = tag.center - tag.rotation.col(0) * (o.board.thickness / 2.0);
  board.reflectivity = o.board.reflectivity;
  board.pattern = world.add_pattern(std::move(p));
  world.add_box(board);

  if (o.stand.enabled) {
    // A post from the ground up to the board's centre, just behind the board.
    const Eigen::Vector3d behind =
        tag.center - tag.rotation.col(0) * (o.board.thickness + o.stand.width / 2.0 + 1e-3);
    const double top = tag.center.z();
    if (top > 0.0) {
      Eigen::Vector3d n = tag.rotation.col(0);
      const double yaw = std::atan2(n.y(), n.x()) * 180.0 / std::numbers::pi;
      world.add_box(make_box(Eigen::Vector3d(behind.x(), behind.y(), top / 2.0),
                             Eigen::Vector3d(o.stand.width, o.stand.width, top), yaw,
                             o.stand.reflectivity));
    }
  }
}

}  // namespace lidartag::sim
