// Stage 6 for one cluster (paper Sec. VI): its points pulled back into the fitted tag frame,
// decoded against every configured dictionary (eqs. (18), (19), (21), (22)) at one or several
// shifts along an axis the outline could not place, the hypotheses arbitrated, and the built-in
// families that are not configured tried, so that a tag of another family is not read as one of
// ours.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

// One decoded (shift, family) pair.
struct DecodeHypothesis {
  DecodeResult result;
  int family = 0;      // index of the configured family
  double shift = 0.0;  // metres along the unseen axis
};

// The best hypothesis of one configured family and its evidence (FamilyEvidence in ScanResult).
struct FamilyDecode {
  bool scored = false;  // some shift gave a score (else: no contrast)
  DecodeResult result;  // at its best shift (its margin only over that shift's functions)
  double shift = 0.0;
  std::vector<float> scores;  // normalised score of every function at that shift
  std::vector<float> cells;   // W x W cell evidence at that shift (decode_evidence_cells)
};

// Scratch memory of decode_cluster, kept by the caller between clusters.
struct ClusterDecodeWorkspace {
  std::vector<ClusterPoint> pulled;  // the points in the tag frame, at the current shift
  std::vector<ClusterPoint> inside;  // those inside the tag's square (a board's levels)
  std::vector<DecodeHypothesis> hypotheses;
  std::vector<double> shifts;  // tried along the unseen axis, in order
  std::vector<FamilyDecode> families;
  // The best hypothesis' cell votes (W x W of its family, row-major as the cell evidence): per
  // cell the sum of clamp(2 label - 1, -1, 1) of the decoded points at least
  // DecodeOptions::vote_inset_cells inside it, and their number.
  std::vector<float> votes, vote_counts;
  DecodeWorkspace decode;
};

struct ClusterDecode {
  // The best hypothesis over every family and shift, its margin taken against the best other
  // function of its family at any shift, and the decision (rejection kNone, kLowContrast,
  // kLowScore, kAmbiguous, kOtherFamily or kSparse).
  DecodeResult best;
  int family = 0;      // index of its configured family
  double shift = 0.0;  // metres along the unseen axis (0 when every side was seen)
  // The best score of a built-in family that is not configured, over every shift (for a best
  // hypothesis below min_score, at its shift only); -1 when not decoded (no decoys, or nothing
  // could be scored).
  double other_family_score = -1.0;
  int other_family = -1;  // the decoy (index into the decoys given) that scored it; -1: none
  // The shift was searched (an unseen axis): decoding chose where the tag sits.
  bool shift_searched = false;
};

// `points`: the cluster (sensor frame); `pose` pulls them back into the fitted tag frame; t the
// tag size; `unseen_axis` (sensor frame, unit, or zero) the axis along which the outline could not
// place the tag (TagOutline::unseen_axis). At most opt.max_points points (evenly spaced) are
// decoded. The evidence of each configured family's best hypothesis is left in ws.families, the
// best hypothesis' cell votes in ws.votes and ws.vote_counts. `on_board` (a tag on a larger
// board, whose points reach past it): the black and white levels from the points inside the
// tag's square (board_levels), and shifts along the unseen axis up to `board_slack_m` either way
// (else only where the points stay inside the tag).
// The black and white levels of a tag on a board: from its points inside the tag's square of
// side t (pulled back by `pose`), since a board's bare margin, most of the points around a small
// tag, would count as white and pull the split between the levels; from every point when fewer
// than 16 are inside. `inside` is scratch.
IntensityLevels board_levels(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                             std::vector<ClusterPoint>& inside, DecodeWorkspace& ws);

// Whether a tag whose place along an unseen axis is searched is square-mounted: the axis is one
// of the tag's edges (`in_tag`: the axis in the tag's frame, whose plane is y-z) and lies along or
// across the rings (`in_sensor`: within 22.5 degrees of level or vertical). Such a tag's rows that
// no ring crosses never vote and its place is searched over several cells; a sparse
// diamond-mounted tag's unseen axis is a diagonal of the tag (the square fitted to ring ends) or
// an edge at 45 degrees to the rings, searched over a short span. The stricter margins
// (DecodeOptions::min_margin_bits_searched, TrackerOptions::min_margin_cells_searched) are for
// the first.
inline bool square_mount_axis(const Eigen::Vector3d& in_sensor, const Eigen::Vector3d& in_tag) {
  constexpr double kCos22 = 0.9239, kSin22 = 0.3827;  // cos and sin of 22.5 degrees
  const double ns = in_sensor.norm(), nt = in_tag.norm();
  if (!(ns > 0.0) || !(nt > 0.0)) return false;
  const double vertical = std::abs(in_sensor.z()) / ns;
  const double edge = std::max(std::abs(in_tag.y()), std::abs(in_tag.z())) / nt;
  return (vertical < kSin22 || vertical > kCos22) && edge > kCos22;
}

ClusterDecode decode_cluster(std::span<const ClusterPoint> points, const RigidPose& pose,
                             const Eigen::Vector3d& unseen_axis, double t,
                             std::span<const RkhsDictionary> dictionaries,
                             std::span<const RkhsDictionary> decoys, const DecodeOptions& opt,
                             ClusterDecodeWorkspace& ws, bool on_board = false,
                             double board_slack_m = 0.0);

}  // namespace lidartag::detector
