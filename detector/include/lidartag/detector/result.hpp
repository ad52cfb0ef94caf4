// What the detector reports for one rotation: detections, the candidates that reached decoding
// (with their decoding evidence, for a tracker), per-cluster diagnostics, timing and rejection
// counts. Plain structs of reused vectors: detect() does not allocate once they have grown.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

enum class Stage : uint8_t {
  kFeatures,    // Sec. IV-A, eq. (1)
  kClustering,  // Sec. IV-B, eq. (2)
  kValidation,  // Sec. IV-C: fill-in, eqs. (3)-(6)
  kPlane,       // Sec. IV-C: RANSAC plane, kappa
  kCorners,     // Sec. V-B remark: edge lines and intersections
  kPose,        // Sec. V: eq. (10), eq. (9), coverage
  kDecode,      // Sec. VI: RKHS decoding
  kCount
};
inline constexpr int kStageCount = static_cast<int>(Stage::kCount);
std::string_view stage_name(Stage s);

// The stage a rejection reason belongs to.
Stage stage_of(Rejection r);

// The size check's rule: a size measured (> 0; -1 when the points do not tell it) that is more
// than `ratio` off the configured `size_m` (Detection::size_warning, the tracker's, and a tag on a
// board beyond corners.size_tolerance).
inline bool size_contradicts(double measured_m, double size_m, double ratio) {
  return measured_m > 0.0 && std::abs(measured_m / size_m - 1.0) > ratio;
}

struct Detection {
  int family_index = 0;                                // into DetectorOptions::families
  std::string_view family;                             // the family's name (owned by the Detector)
  int id = 0;                                          // index of the code in the family
  double size_m = 0.0;                                 // the tag size t that matched
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // tag centre, sensor frame, metres
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // tag frame -> sensor frame
  // Corners of the black square in the sensor frame: bottom-left, bottom-right, top-right,
  // top-left, as seen from the front.
  std::array<Eigen::Vector3d, 4> corners;
  double score = 0.0;     // RKHS decoding score, <= 1
  double margin = 0.0;    // over the second best function, in cells' worth of evidence
  int points = 0;         // points of the cluster used for the pose
  double fit_cost = 0.0;  // eq. (8) at the optimum, metres summed over the points
  // When the beams crossed the tag, seconds from the rotation's first firing (Scan::stamp_ns): its
  // first and last points, and the point nearest its centre (what a moving sensor's pose is
  // interpolated at; a rotation lasts 100 ms at 600 rpm).
  double time_first_s = 0.0, time_center_s = 0.0, time_last_s = 0.0;
  // The size check (issue 33): the marker's size its points measure (its black square fitted
  // freely to where the rings step from the white ring to the black border, then scaled by the
  // family's layout), metres; -1 when the points do not tell it (steps on fewer than two
  // opposite sides, or pose.border_refine off). size_warning: it differs from size_m, the
  // configured size that matched, by more than pose.size_warning_ratio (the pose and the cells
  // are placed with the configured size: a wrong one biases them).
  double measured_size_m = -1.0;
  bool size_warning = false;
  // What its points were moved to time_center_s with before the fits (DeskewOptions::enabled):
  // kNone when they were fitted as fired.
  DeskewSource deskew = DeskewSource::kNone;
  // Its `points` points in ScanResult::tag_points start here; -1 without keep_tag_points.
  int first_point = -1;
};

// What happened to one cluster.
struct ClusterDiagnostic {
  int features = 0;
  int points = 0;  // after fill-in
  int boundary_points = 0;
  Rejection rejection = Rejection::kNone;
  float min_x = 0, max_x = 0, min_y = 0, max_y = 0;
  int min_ring = 0, max_ring = 0;
  // What the later stages measured, -1 when the cluster did not get that far.
  double outlier_ratio = -1;  // plane fit
  double side_m = -1;         // corners: measured side length
  double mean_cost_m = -1;    // pose: eq. (8) per point after the fit
  double coverage = -1;       // pose: convex hull / t^2 (its upper bound when that rejected)
  double score = -1;          // decode: best normalised score
  double margin = -1;         // decode: best minus second best, payload cells
  int candidate = -1;         // index into ScanResult::candidates when it reached decoding
  // With keep_cluster_points: its points in ScanResult::cluster_points, as they were when it was
  // accepted or dropped (after fill-in; after the plane fit only the plane's inliers, without
  // the narrow top and bottom rings; dropped at clustering, its edge features). -1 / 0
  // otherwise.
  int first_point = -1;
  int point_count = 0;
};

// The decoding evidence of one candidate for one configured family, at the shift of that family's
// best hypothesis: the normalised score (eq. (18) over its largest possible value, <= 1) of every
// function of the family's dictionary, function f = 4 * code + quarter_turns.
// (score_f - score_g) * cells_per_score is the margin between f and g in payload cells' worth of
// evidence (the unit of decode.min_margin_bits).
struct FamilyEvidence {
  int family_index = 0;  // into DetectorOptions::families
  int first = 0;         // into ScanResult::evidence_scores
  int functions = 0;     // 4 x codes; 0 when nothing could be scored (no contrast)
  float cells_per_score = 0.0f;
  float shift_m = 0.0f;  // along the candidate's unseen axis (0 when every side was seen)
};

// A point that decoding read, in its candidate's undecoded tag frame (metres; x along the normal)
// at the best shift, with its intensity label (0 black, 1 white, between the cluster's levels;
// not clamped): what a tracker votes again in the frame of a track.
struct VotePoint {
  float x = 0.0f, y = 0.0f, z = 0.0f;
  float label = 0.0f;
};

// A cluster that reached decoding (Sec. VI), accepted or not: its pose, what decoding found and
// the evidence for every code, so that a tracker can add evidence up over rotations.
struct Candidate {
  Rejection rejection = Rejection::kNone;  // kNone: accepted; else a decode-stage reason
  int detection = -1;                      // index into ScanResult::detections when accepted
  int cluster = -1;       // index into ScanResult::diagnostics (with cluster_diagnostics)
  int family_index = -1;  // family of the best hypothesis (-1: nothing could be scored)
  int id = -1;            // its best code
  int quarter_turns = 0;  // its best function's quarter turns (function = 4 id + quarter_turns)
  double size_m = 0.0;    // the tag size t that matched
  // Tag centre (sensor frame, metres) at the best hypothesis' shift.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  // Firing times of its points, as Detection's (first, nearest the centre, last).
  double time_first_s = 0.0, time_center_s = 0.0, time_last_s = 0.0;
  // The size its points measure, as Detection's (-1: not told).
  double measured_size_m = -1.0;
  DeskewSource deskew = DeskewSource::kNone;  // as Detection's
  // The fitted frame before the quarter turns are known (eq. (9) is blind to them): the tag frame
  // of function f = 4 k + q is undecoded_orientation * Rx(-q * 90 deg) (x the tag's normal).
  Eigen::Quaterniond undecoded_orientation = Eigen::Quaterniond::Identity();
  // That frame turned by the best function's quarter turns (what a detection reports).
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  double score = -1.0;   // best normalised score of the configured families
  double margin = -1.0;  // its margin, payload cells (over every shift, as the decision uses it)
  // Best score of a built-in family that is not configured (decode.reject_other_families), over
  // every shift (below min_score: at the best shift only); -1 when not decoded (check off, score
  // below decode.other_family_min_score, or nothing could be scored).
  double other_family_score = -1.0;
  // The built-in family that scored other_family_score (Detector::other_family_of); -1 none.
  int other_family = -1;
  // The outline placed the tag along one axis only (a square mount): decoding chose the shift
  // along the other, so votes and scores agree with the decoder by construction there.
  bool shift_searched = false;
  // That axis (sensor frame, unit; zero when every side was seen): a tracker searches along it
  // again over the evidence of every rotation.
  Eigen::Vector3d unseen_axis = Eigen::Vector3d::Zero();
  // Fewer boundary points than eq. (6) asks but at least the tracks' bound (track_boundary_bound),
  // or fewer points than eq. (3) asks but at least validation.track_returns_per_cell of them:
  // never a detection (its diagnostic says validation/few_boundary_points or
  // validation/too_few_points), but evidence for a tracker like any other candidate (its own gates
  // confirm an ID over rotations).
  bool track_only = false;
  int points = 0;         // points of the pose fit
  double fit_cost = 0.0;  // eq. (8) at the optimum
  double coverage = 0.0;  // convex hull / t^2
  // ScanResult::family_evidence[first_evidence, first_evidence + evidence_count): one per
  // configured family.
  int first_evidence = 0;
  int evidence_count = 0;
  // The decoded grid, W x W cells of the best hypothesis' family, row-major in the undecoded frame
  // at the best shift, row 0 at its top (+z), column 0 at its -y: the marker as the points show
  // it, which the best code's image turned quarter_turns times clockwise matches. At first_cell
  // in three parallel vectors of ScanResult: cell_evidence (white minus black kernel sums: > 0
  // reads white), cell_votes (sum over the points at least decode.vote_inset_cells inside the
  // cell of clamp(2 label - 1, -1, 1), label 0 black, 1 white) and cell_vote_counts (their
  // number).
  int first_cell = 0;
  int grid_width = 0;
  // The points decoding read (its best hypothesis' family was scored): ScanResult::vote_points
  // [first_vote_point, first_vote_point + vote_point_count).
  int first_vote_point = 0;
  int vote_point_count = 0;
  // With keep_cluster_points: its points in ScanResult::cluster_points (-1 / 0 otherwise).
  int first_point = -1;
  int point_count = 0;
};

struct ScanResult {
  std::vector<Detection> detections;
  std::array<double, kStageCount> timing_ms{};       // wall time per stage in this rotation
  std::array<uint32_t, kRejectionCount> rejected{};  // clusters dropped, by reason
  int features = 0;
  int clusters = 0;
  // With DeskewOptions::enabled: clusters whose points were moved to their centre time by the
  // odometry (SensorMotion::ego), by the constant-velocity model, and by nothing (no motion known
  // for them: fitted as fired).
  int deskewed_ego = 0, deskewed_model = 0, deskew_without_motion = 0;
  // The scan's sizes disagree with its storage: nothing was read (a caller's bug, not data).
  bool refused = false;
  // Memory ran out part-way through the rotation: what was found before is kept, the rest of
  // the clusters were not looked at.
  bool truncated = false;
  std::vector<ClusterDiagnostic> diagnostics;  // when DetectorOptions::cluster_diagnostics
  // Every cluster that reached decoding, in the order processed.
  std::vector<Candidate> candidates;
  std::vector<FamilyEvidence> family_evidence;
  std::vector<float> evidence_scores;
  std::vector<float> cell_evidence, cell_votes, cell_vote_counts;
  std::vector<VotePoint> vote_points;
  // When DetectorOptions::keep_tag_points: the points each detection's pose was fitted to (sensor
  // frame), one detection after the other; one vector for all, so that it is reused.
  std::vector<ClusterPoint> tag_points;
  // When DetectorOptions::keep_cluster_points: every cluster's points (past the fill-in, or its
  // edge features when it was dropped at clustering).
  std::vector<ClusterPoint> cluster_points;

  double total_ms() const;
  // The points of `d` in tag_points (empty without keep_tag_points).
  std::span<const ClusterPoint> points_of(const Detection& d) const;
  // The points of a cluster or candidate in cluster_points (empty without keep_cluster_points).
  std::span<const ClusterPoint> points_of(const ClusterDiagnostic& c) const;
  std::span<const ClusterPoint> points_of(const Candidate& c) const;
  // A candidate's evidence, one entry per configured family, and one family's scores.
  std::span<const FamilyEvidence> evidence_of(const Candidate& c) const;
  std::span<const float> scores_of(const FamilyEvidence& e) const;
  // A candidate's decoded grid, votes and vote counts (grid_width^2 cells each).
  std::span<const float> cells_of(const Candidate& c) const;
  std::span<const float> votes_of(const Candidate& c) const;
  std::span<const float> vote_counts_of(const Candidate& c) const;
  // The points a candidate's decoding read (Candidate::first_vote_point).
  std::span<const VotePoint> vote_points_of(const Candidate& c) const;
  // Clusters rejected at a stage (sum over that stage's reasons).
  uint32_t rejected_at(Stage s) const;
  // Empties every list and counter (keeps the capacity).
  void clear();
};

}  // namespace lidartag::detector
