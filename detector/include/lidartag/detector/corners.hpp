// Stage 4 (paper Sec. V-B, remark): the tag's outline from the edge points of a cluster: a
// rectangle fit in the tag plane, a RANSAC line per side, intersections. Handles tags mounted as a
// diamond (the paper's case: every side is crossed by rings) and as a square (only the left and
// right sides are; the top and bottom are placed from the measured width).
#pragma once

#include <Eigen/Core>
#include <array>
#include <span>
#include <vector>

#include "lidartag/detector/plane_fit.hpp"
#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

struct CornerOptions {
  // RANSAC line fit of a side: inlier distance (metres, default 0.03), hypotheses (default 30),
  // fewest inliers for a side to count (default 3; the paper's "fewer than three" rule).
  float line_inlier_m = 0.03f;
  int line_iterations = 30;
  int min_line_points = 3;
  // Edge points within this fraction of the side length of two sides are left out of both line
  // fits (they sit at a corner). Default 0.08.
  float corner_exclusion = 0.08f;
  // Largest relative difference between the measured side length and the nearest configured tag
  // size. Default 0.2: ring crossings end up to one point spacing inside the true edge.
  float size_tolerance = 0.2f;
  // A tag on a larger board (issue 33): an outline larger than a configured size by up to twice
  // this (a bare margin on each side of the print), beyond size_tolerance, is taken as that tag on
  // its board, and the tag is placed inside it by its black square (pose.border_refine, which
  // must then find the square with the configured size, or the cluster is rejected as the wrong
  // size). Metres; default 0.2 (Tier IV's calibration targets: a 0.6 m tag on a 0.8 m board);
  // 0: the outline must be the tag's.
  float board_margin_m = 0.2f;
  // A fitted side must be within this angle (degrees) of the rectangle's side. Default 20.
  float max_side_angle_deg = 20.0f;
  // When no pair of opposite sides has a line (3-5 rings across a tag, or rings on two adjacent
  // sides only, as in a VLP-32C's sparse upper beams): fit a square to the outline points
  // directly, its size free within size_tolerance of the configured sizes. Default true.
  bool square_fit = true;
  // ... and accept it when the outline points' rms distance to it is at most this fraction of
  // its side. Default 0.05 (a ring's ends sit up to one point spacing inside the true edge).
  float square_fit_max_rms = 0.05f;
};

struct TagOutline {
  // Outer corners of the marker in the sensor frame, counter-clockwise seen from the front
  // (which corner comes first is only known modulo 90 degrees until decoding).
  std::array<Eigen::Vector3d, 4> corners;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double side_m = 0.0;      // measured side length
  int size_index = -1;      // index of the selected tag size
  double size_m = 0.0;      // the selected tag size t
  double angle_deg = 0;     // in-plane rotation of the outline modulo 90 degrees, [0, 90)
  int sides_fitted = 0;     // sides with a RANSAC line (4 for a diamond, 2 for a square)
  bool square_fit = false;  // placed by the square fit (CornerOptions::square_fit), not by lines
  bool on_board = false;    // larger than the tag beyond size_tolerance: a board with a margin
  // When neither side of a pair was seen (a square mount: top and bottom), the outline is placed
  // mid-way along this unit axis (sensor frame) and its position along it is uncertain; decoding
  // resolves it. Zero when every side was seen.
  Eigen::Vector3d unseen_axis = Eigen::Vector3d::Zero();
};

// Work buffers, kept by the caller between clusters.
struct CornerWorkspace {
  std::vector<Eigen::Vector2d> edge, hull, scratch;
  std::array<std::vector<Eigen::Vector2d>, 4> side;
};

// `points` are plane inliers in ring order with `edge` marking each ring's ends; `sizes` the
// configured tag sizes (metres). Returns kNone, kCorners or kSize.
Rejection find_corners(std::span<const ClusterPoint> points, const Plane& plane,
                       std::span<const double> sizes, const CornerOptions& opt, CornerWorkspace& ws,
                       TagOutline& out);

// The in-plane basis used for a tag plane: u (viewer's right), v (up), both unit, with u x v
// along the normal (toward the sensor).
void plane_basis(const Eigen::Vector3d& normal, Eigen::Vector3d& u, Eigen::Vector3d& v);

}  // namespace lidartag::detector
