// Squares of known size fitted in the tag's plane (an extension of paper Sec. V):
// - the black square's outline, found along each ring where the intensity steps from the white
//   ring to the black border, places the tag in its plane (refine_on_border). Unlike the board's
//   outline it does not depend on a bare margin around the print or on the board's thickness,
//   whose side face a turned board shows on one side: both biased the L1 box fit of eq. (9),
//   whose cost is flat wherever the box covers the points, by up to a centimetre (docs/detector.md
//   "The 45° bias").
// - a square fitted directly to the outline points (fit_square_outline) gives corners when too
//   few rings cross each side for a line fit (3-5 rings across a tag).
#pragma once

#include <Eigen/Core>
#include <array>
#include <span>
#include <vector>

#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

// A square in a plane: centre, the angle of its first side (radians), half its side.
struct Square2 {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double angle = 0.0;
  double half = 0.5;
};

struct SquareFitOptions {
  double huber_m = 0.01;  // robust loss: quadratic within this distance of the square
  double gate_m = 0.1;    // points farther than this from the start square are ignored
  int iterations = 10;
  int min_points = 6;
  bool fit_size = false;  // fit the half size too (needs points on two opposite or three sides)
  // Points within this distance of a diagonal (where the nearest side is ambiguous) are left out:
  // near a square mount's top corners a point of its left side would pull the unseen height.
  double corner_m = 0.0;
};

struct SquareFit {
  bool ok = false;
  Square2 square;
  int points = 0;                 // points within the gate
  std::array<int, 4> per_side{};  // of them on the sides at -u, +u, -v, +v (u along `angle`)
  double rms_m = 0.0;             // their rms distance to the square
  bool along_u = false, along_v = false;  // the centre could be placed along u / v
  bool size_fitted = false;
};

// Gauss-Newton with Huber weights: `points` on the boundary of a square, from `start`. A direction
// with fewer than 2 points on either of its sides is held where it started (a square-mounted
// tag's top and bottom); the size is held unless opt.fit_size (and then needs points on two
// opposite or three sides). ok is false with fewer than min_points points within the gate.
SquareFit fit_square(std::span<const Eigen::Vector2d> points, const Square2& start,
                     const SquareFitOptions& opt);

// A square fitted to a tag's outline points (each ring's ends, in its plane) when too few rings
// cross each side for a line per side: several starting angles (15 degree steps), the size free
// in [min_half, max_half]; the fit with the smallest rms distance wins. False when none fits.
bool fit_square_outline(std::span<const Eigen::Vector2d> edge, double min_half, double max_half,
                        const SquareFitOptions& opt, SquareFit& best);

// A point of the black square's outline in the tag frame (y right, z up, metres).
struct BorderPoint {
  Eigen::Vector2d yz = Eigen::Vector2d::Zero();
  int ring = 0;
};

// Along each ring of `points` (ring by ring, by column, as fill_cluster emits them), from each end
// inward: the first step from the outer ring's colour (white; black for a reversed border) to the
// border's, where the intensity crosses half-way between `levels`, interpolated between the two
// points; pulled back into the tag frame by `pose`. A step more than `max_gap_m` long (a missing
// return) or not preceded by a point of the outer ring's colour is skipped.
void border_crossings(std::span<const ClusterPoint> points, const RigidPose& pose,
                      const IntensityLevels& levels, bool reversed_border, double max_gap_m,
                      std::vector<BorderPoint>& out);

struct BorderFit {
  bool ok = false;
  RigidPose pose;                         // the refined pull-back
  int points = 0;                         // border points used (within the gate)
  int sides = 0;                          // sides of the square with at least 2 of them
  double rms_m = 0.0;                     // their rms distance to the square after the fit
  bool along_y = false, along_z = false;  // the in-plane directions the fit could place
  // The black square's half side fitted freely to the same crossings (they lie on two opposite
  // sides or on three), metres; -1 when they do not tell it. place_on_border turns it into the
  // marker's size (measured_size_m): what the points say the printed tag measures.
  double measured_half_m = -1.0;
  double measured_size_m = -1.0;
};

struct BorderFitOptions {
  double half_size = 0.45;  // half the black square's side, metres
  double huber_m = 0.01;
  double gate_m = 0.1;
  double corner_m = 0.075;  // SquareFitOptions::corner_m
  int iterations = 10;
  int min_points = 6;
};

// Moves the pull-back `pose` in the tag's plane (a turn about its normal x and a shift along y and
// z) so that `border` (from border_crossings under `pose`) lies on a square of half-size
// opt.half_size centred on the origin; depth and normal are kept. A direction with no border point
// (the top and bottom of a square-mounted tag) is not moved: decoding places it. `buffer` is
// scratch memory.
BorderFit refine_on_border(std::span<const BorderPoint> border, const RigidPose& pose,
                           const BorderFitOptions& opt, std::vector<Eigen::Vector2d>& buffer);

struct BorderWorkspace {
  std::vector<BorderPoint> border;
  std::vector<Eigen::Vector2d> yz;
};

// refine_on_border for a tag of size t of one of `families` (the black square's size and colours
// depend on the family's layout): each distinct layout is tried, the fit with the smallest rms
// distance wins. `levels` are the cluster's black and white intensities.
BorderFit place_on_border(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                          std::span<const RkhsDictionary> families, const IntensityLevels& levels,
                          BorderFitOptions opt, BorderWorkspace& ws);

}  // namespace lidartag::detector
