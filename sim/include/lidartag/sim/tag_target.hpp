// A LiDARTag in the world: the printed marker of a family code on a board (and optional stand),
// its pose, and the ground-truth quantities (tag frame, black-square corners).
// Tag frame: origin at the marker centre, +x the normal out of the printed face, +z toward the
// top edge of the printed image, +y toward its right edge (seen from the front); y = z x x.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

struct TagTarget {
  TagOptions options;
  std::string family_name;
  int total_width = 0;      // cells across the printed marker
  int width_at_border = 0;  // cells across the black square
  uint64_t code = 0;
  std::vector<uint8_t> image;  // TagFamily::render(code): row 0 at the top, 1 = white
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // world <- tag
  Eigen::Vector3d center = Eigen::Vector3d::Zero();        // world

  // Half the side of the black square: (width_at_border / total_width) * t / 2.
  double black_half() const;
  // Black-square corners in the tag frame: bottom-left, bottom-right, top-right, top-left.
  std::array<Eigen::Vector3d, 4> corners_tag() const;
  // Whether the printed cell under tag-frame (y, z) is white; false outside the marker too.
  bool white_at(double y, double z) const;
};

// Tag frame in the world for a normal and a rotation about it: with rotation 0 the image's top
// edge points up (world +z projected on the face; world +x for a face looking straight up or
// down); positive angles turn the image counter-clockwise as seen from the front.
Eigen::Matrix3d tag_rotation(const Eigen::Vector3d& normal, double rotation_deg);

// Resolves the family and code and the pose; an unset normal faces `sensor_position`
// horizontally. Throws SceneError naming `key` (e.g. "tags[1]") on a bad family or id.
TagTarget make_tag(const TagOptions& options, const Eigen::Vector3d& sensor_position,
                   const std::string& key);

// Adds the board (printed face at the tag's x = 0), and the stand when enabled, to `world`.
void add_tag(World& world, const TagTarget& tag, int index);

}  // namespace lidartag::sim
