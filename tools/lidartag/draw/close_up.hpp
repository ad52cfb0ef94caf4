// The close-up of one tag, or of a cluster that could have been one, in its own plane: the
// points coloured by intensity over the decoded grid (black and white cells of the code read),
// the fitted square, a scale bar and a legend.
#pragma once

#include <Eigen/Core>
#include <array>
#include <span>
#include <string>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/types.hpp"

namespace lidartag::draw {

struct CloseUp {
  std::vector<std::string> title;
  std::span<const detector::ClusterPoint> points;  // sensor frame
  // The plane's frame (tag frame -> sensor frame): x the normal toward the sensor, y to the
  // right of the printed image, z to its top; `centre` its origin.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  double size_m = 0;  // the marker (white ring included)
  // The decoded grid: `family`'s image of `code`, drawn under the points.
  const tags::TagFamily* family = nullptr;
  uint64_t code = 0;
  // The fitted black square's corners (sensor frame, from a pose); without them a dashed marker
  // of size_m is drawn at the centre for scale.
  bool fitted = false;
  std::array<Eigen::Vector3d, 4> corners;
  // Without a pose: the side the corner stage measured (dashed too), -1 when unknown.
  double measured_side_m = -1;
  // What the points read: per cell, white minus black evidence (> 0 reads white), row-major,
  // upright in this picture (row 0 at the top), cells_width across; drawn as an inset at the
  // top right, each cell's square as large as its evidence. Empty: no inset.
  std::vector<float> cells_read;
  int cells_width = 0;
};

// Where a point of the plane lands: pixel x = centre_x + y_tag * px_per_m, pixel y = centre_y -
// z_tag * px_per_m.
struct CloseUpMapping {
  double px_per_m = 0, centre_x = 0, centre_y = 0;
};

// The inset's cells upright: `cells` (row-major, `width` across) turned `quarter_turns` times
// counter-clockwise.
std::vector<float> turn_counter_clockwise(std::span<const float> cells, int width,
                                          int quarter_turns);

// A plane frame for points without a pose: the normal of least variance turned toward the
// sensor; in the plane, z as close to up (sensor z) as the plane allows, then turned by up to 45
// degrees to the smallest square around the points, whose centre is the origin.
void plane_frame(std::span<const detector::ClusterPoint> points, Eigen::Vector3d& centre,
                 Eigen::Matrix3d& rotation);

// Draws and writes a square PNG of `size_px`; throws std::runtime_error on failure.
CloseUpMapping write_close_up(const CloseUp& view, int size_px, const std::string& path);

}  // namespace lidartag::draw
