// Data passed between the detector's stages. Plain structs, reused across rotations.
#pragma once

#include <cstdint>
#include <string_view>

namespace lidartag::detector {

// Why a cluster was dropped; one counter per reason in ScanResult (the paper's Table III).
enum class Rejection : uint8_t {
  kNone = 0,           // accepted: a detection
  kFewFeatures,        // too few features or rings to span a tag
  kTooLarge,           // the x-y box is larger than the largest tag could be
  kTooFewPoints,       // fill-in: fewer points than the family's lower bound (eta)
  kTooManyPoints,      // fill-in: more points than a tag can return at that distance
  kFewBoundaryPoints,  // eq. (5): fewer payload boundary points than psi
  kPlaneOutliers,      // plane fit: outlier ratio above kappa
  kCorners,            // no four edge lines (too few edge points on the sides)
  kSize,               // side length far from every configured tag size
  kFitCost,            // eq. (8) gate: mean fitting cost too high
  kCoverage,           // convex hull of the pulled-back points below the coverage ratio
  kLowContrast,        // no two intensity levels to decode
  kLowScore,           // RKHS decoding: best score below the threshold
  kAmbiguous,          // RKHS decoding: best and second best too close
  kOtherFamily,        // RKHS decoding: a built-in family that is not configured fits better
  kSparse,  // too few returns per cell for an ID from one rotation (a tracker's evidence)
  kCount
};
inline constexpr int kRejectionCount = static_cast<int>(Rejection::kCount);

// The pipeline stage a rejection belongs to (what `lidartag detect --json` reports).
std::string_view rejection_name(Rejection r);
std::string_view rejection_stage(Rejection r);

// What moved a cluster's points to its centre time before the fits (deskew.hpp; a Detection's
// and a Candidate's `deskew`).
enum class DeskewSource : unsigned char {
  kNone,   // not deskewed (the deskew off, or nothing known of the motion): the points as fired
  kEgo,    // the odometry's interpolated poses
  kModel,  // the tracker's constant-velocity model
};

// "none", "ego", "model": what `lidartag detect --json` and Python report.
std::string_view deskew_source_name(DeskewSource s);

// An edge feature of eq. (1): a point of the scan where the distance jumps.
struct Feature {
  int ring = 0;
  int col = 0;
  float x = 0, y = 0, z = 0;  // metres, sensor frame
  float range = 0;            // metres
  // -1: the surface starts here (the jump is before it, in column order); +1: it ends here.
  int8_t side = 0;
  // For side +1: index (in the feature list) of the side -1 feature that opens the same
  // continuous run of the ring, when the run is short enough to lie on one tag; -1 otherwise.
  int partner = -1;
};

// A point of a cluster after the fill-in from the scan.
struct ClusterPoint {
  float x = 0, y = 0, z = 0;  // metres, sensor frame
  float intensity = 0;        // 0..255
  int ring = 0;
  int col = 0;
  bool edge = false;  // first or last point of its ring inside the cluster (the tag's outline)
};

}  // namespace lidartag::detector
