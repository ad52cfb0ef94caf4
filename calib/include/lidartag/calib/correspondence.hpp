// Correspondences between a tag seen by the LiDAR and the same tag seen by the camera.
//
// The calibration's corner order (corner k, k = 0..3) is defined on the marker itself, so that it
// survives any in-plane rotation of the tag: the outer corners of the black border square of the
// marker held upright as printed (row 0 of the family's code image, TagFamily::render, at the
// top), seen from its front:
//   k = 0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left.
// In the detector's tag frame (x the normal out of the front, y right, z up; Detection::
// orientation maps it to the sensor frame) corner k is (0, -h, -h), (0, h, -h), (0, h, h),
// (0, -h, h), h = half the black square (width_at_border / total_width times half the tag size):
// exactly Detection::corners. AprilTag 3's detection p[i] (apriltag.c: the decoded homography
// projects tag coordinates (x right, y down the printed code, +-1 at the black square's corners)
// (-1, 1), (1, 1), (1, -1), (-1, -1) for i = 0..3) is, on the upright marker, bottom-left,
// bottom-right, top-right, top-left: p[k] is corner k (apriltag_corner_of below). Both sides name
// corners by the code, not by where they fall in the image or the scan, so a tag turned by any
// number of quarter turns still pairs the same physical corners.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/detector/result.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::calib {

// Index into AprilTag's p[] of calibration corner k (the identity, written down once: see above).
constexpr int apriltag_corner_of(int k) {
  constexpr std::array<int, 4> kMap = {0, 1, 2, 3};
  return kMap[static_cast<std::size_t>(k & 3)];
}

// Corner k of the black square in the tag frame (x normal, y right, z up), metres; h = half side.
Eigen::Vector3d tag_frame_corner(int k, double h);

// Half the black square's side of a marker of size `size_m` (the whole marker, white ring
// included, as the detector's tag size) of `family`.
double black_half_side(const tags::TagFamily& family, double size_m);

// One tag as the LiDAR saw it: its corners in the calibration order, sensor frame, with their
// joint covariance (12 x 12, metres^2, corner-major: x0 y0 z0 x1 ...; the corners of one pose
// move together, so their errors are correlated).
struct LidarTag {
  std::string family;
  int id = -1;
  double size_m = 0.0;  // the whole marker, as the detector's tag size
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // tag frame -> LiDAR frame
  std::array<Eigen::Vector3d, 4> corners;
  Eigen::Matrix<double, 12, 12> corner_cov = Eigen::Matrix<double, 12, 12>::Identity() * 1e-4;
};

// The corners' covariance of a tag pose known to `position_cov` (3 x 3, m^2, LiDAR frame) and an
// isotropic orientation error of `angle_sigma_rad` per axis: corner k moves by dc - [R r_k]x
// dtheta.
Eigen::Matrix<double, 12, 12> pose_corner_covariance(const LidarTag& tag,
                                                     const Eigen::Matrix3d& position_cov,
                                                     double angle_sigma_rad);

// How uncertain a LiDAR tag's corners are taken to be. Defaults: 3 mm and 0.2 degrees per axis
// for one rotation's detection (a 1.2 m tag at 5 m on a VLP-32C scatters by 1-3 mm and a few
// tenths of a degree: docs/accuracy.md); floor_m is added to every corner in every axis for what
// averaging over rotations does not remove (beam-range biases, the tag's flatness), default 2 mm.
struct LidarCornerNoise {
  double position_sigma_m = 0.003;
  double angle_sigma_deg = 0.2;
  double floor_m = 0.002;
};

// A tag from one rotation's detection (its corners and the noise above).
LidarTag lidar_tag_from_detection(const detector::Detection& det, const tags::TagFamily& family,
                                  const LidarCornerNoise& noise = {});

// A tag from the tracker's window over a static tag (evidence over its rotations): the window's
// mean pose, the corners' covariance from its spread (per-rotation standard deviations over
// window_rotations: the mean's is that over sqrt(N); the RMS angle split over three axes), plus
// the floor. `family` and `size_m` are the detection's (TrackInfo does not carry them).
LidarTag lidar_tag_from_track(const detector::TrackInfo& track, const tags::TagFamily& family,
                              double size_m, const LidarCornerNoise& noise = {});

// Adds to `tag.corner_cov` the error the LiDAR's ring spacing leaves in the tag's pose, which no
// averaging over rotations removes: a static tag is cut by the same rings every rotation, so the
// tracker's spread does not show it. When the tag's edges run nearly along the rings (a square
// mount), its top and bottom edges lie somewhere in the gap g = range x (the angle between the
// rings about the tag's elevation, `ring_elevations_rad` of the sensor's rings in any order) and
// the tag's position across the rings is known to about g / sqrt(12) (uniform over the gap). An
// edge turned by phi from the rings spans s sin(phi) across them (s the black square's side) and
// locates the corners once that exceeds the gap: the term is scaled by max(0, 1 - s sin(phi) /
// g), zero for a diamond. It moves the four corners together, in the tag's plane, across the
// rings. Simulated tag36h11 tags on a VLP-16 (2 degree gap): square tags at 2.6 and 7.1 m were
// 13 and 25 mm off across the rings with a window spread of 0.2-1.7 mm (this term: 26 and 71 mm);
// tags turned 20-60 degrees were within 1 mm (this term: 0). The sensor is at the origin of the
// LiDAR frame.
void add_ring_spacing_uncertainty(LidarTag& tag, const tags::TagFamily& family,
                                  std::span<const double> ring_elevations_rad);

// The elevation of each ring of `scan` that has returns (first return), radians: the mean of its
// returns' atan2(z, hypot(x, y)), rings without a return left out. What `lidartag calibrate` passes
// to add_ring_spacing_uncertainty for a capture (its last rotation's rings).
std::vector<double> ring_elevations_rad(const Scan& scan);

// One tag as the camera saw it: AprilTag's family name, ID and p[0..3] (pixels, CameraModel's
// convention: (0, 0) the centre of the top-left pixel), and how well its corners are known.
// size_m: the marker's size when the user gave it (whole marker, as LidarTag), 0 when unknown.
struct ImageTagCorners {
  std::string family;
  int id = -1;
  std::array<Eigen::Vector2d, 4> apriltag_p;
  double sigma_px = 0.5;
  double size_m = 0.0;
};

// Image corners in the calibration order (apriltag_corner_of).
std::array<Eigen::Vector2d, 4> calibration_order(const std::array<Eigen::Vector2d, 4>& apriltag_p);

// One tag pose seen by both sensors: corner k of `pixels` is corner k of `lidar`.
struct TagPose {
  std::string label;  // names the pose in reports ("pair 3 tag36h11:7")
  LidarTag lidar;
  std::array<Eigen::Vector2d, 4> pixels;
  double sigma_px = 0.5;
};

// A tag that found no partner, and why.
struct Unpaired {
  std::string label;
  std::string reason;
};

struct Pairing {
  std::vector<TagPose> poses;
  std::vector<Unpaired> unpaired;
};

// Pairs the tags of one scene (an image and a capture of it) by family and ID, and size where the
// image side knows it (within size_tolerance, relative; default 3 %, the detector's size check).
// A family and ID seen twice on either side is ambiguous and not paired. `scene` prefixes labels.
Pairing pair_tags(std::span<const LidarTag> lidar, std::span<const ImageTagCorners> image,
                  std::string_view scene, double size_tolerance = 0.03);

}  // namespace lidartag::calib
