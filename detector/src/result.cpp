// What a rotation's detection reports: names of stages and reasons, and the result's accessors.
#include "lidartag/detector/result.hpp"

namespace lidartag::detector {

std::string_view rejection_name(Rejection r) {
  switch (r) {
    case Rejection::kNone:
      return "accepted";
    case Rejection::kFewFeatures:
      return "few_features";
    case Rejection::kTooLarge:
      return "too_large";
    case Rejection::kTooFewPoints:
      return "too_few_points";
    case Rejection::kTooManyPoints:
      return "too_many_points";
    case Rejection::kFewBoundaryPoints:
      return "few_boundary_points";
    case Rejection::kPlaneOutliers:
      return "plane_outliers";
    case Rejection::kCorners:
      return "no_corners";
    case Rejection::kSize:
      return "wrong_size";
    case Rejection::kFitCost:
      return "fit_cost";
    case Rejection::kCoverage:
      return "coverage";
    case Rejection::kLowContrast:
      return "low_contrast";
    case Rejection::kLowScore:
      return "low_score";
    case Rejection::kAmbiguous:
      return "ambiguous";
    case Rejection::kOtherFamily:
      return "other_family";
    case Rejection::kSparse:
      return "sparse";
    case Rejection::kCount:
      break;
  }
  return "?";
}

Stage stage_of(Rejection r) {
  switch (r) {
    case Rejection::kFewFeatures:
    case Rejection::kTooLarge:
      return Stage::kClustering;
    case Rejection::kTooFewPoints:
    case Rejection::kTooManyPoints:
    case Rejection::kFewBoundaryPoints:
      return Stage::kValidation;
    case Rejection::kPlaneOutliers:
      return Stage::kPlane;
    case Rejection::kCorners:
    case Rejection::kSize:
      return Stage::kCorners;
    case Rejection::kFitCost:
    case Rejection::kCoverage:
      return Stage::kPose;
    default:
      return Stage::kDecode;
  }
}

std::string_view stage_name(Stage s) {
  switch (s) {
    case Stage::kFeatures:
      return "features";
    case Stage::kClustering:
      return "clustering";
    case Stage::kValidation:
      return "validation";
    case Stage::kPlane:
      return "plane";
    case Stage::kCorners:
      return "corners";
    case Stage::kPose:
      return "pose";
    case Stage::kDecode:
      return "decode";
    case Stage::kCount:
      break;
  }
  return "?";
}

std::string_view rejection_stage(Rejection r) {
  return stage_name(stage_of(r));
}

double ScanResult::total_ms() const {
  double t = 0.0;
  for (double v : timing_ms) t += v;
  return t;
}

namespace {

// [first, first + count) of `v`, or nothing when that is not inside it.
template <class T>
std::span<const T> slice(const std::vector<T>& v, int first, int count) {
  if (first < 0 || count < 0 || static_cast<size_t>(first) + static_cast<size_t>(count) > v.size())
    return {};
  return std::span<const T>(v).subspan(static_cast<size_t>(first), static_cast<size_t>(count));
}

}  // namespace

std::span<const ClusterPoint> ScanResult::points_of(const Detection& d) const {
  return slice(tag_points, d.first_point, d.points);
}

std::span<const ClusterPoint> ScanResult::points_of(const ClusterDiagnostic& c) const {
  return slice(cluster_points, c.first_point, c.point_count);
}

std::span<const ClusterPoint> ScanResult::points_of(const Candidate& c) const {
  return slice(cluster_points, c.first_point, c.point_count);
}

std::span<const FamilyEvidence> ScanResult::evidence_of(const Candidate& c) const {
  return slice(family_evidence, c.first_evidence, c.evidence_count);
}

std::span<const float> ScanResult::scores_of(const FamilyEvidence& e) const {
  return slice(evidence_scores, e.first, e.functions);
}

std::span<const float> ScanResult::cells_of(const Candidate& c) const {
  return slice(cell_evidence, c.first_cell, c.grid_width * c.grid_width);
}

std::span<const float> ScanResult::votes_of(const Candidate& c) const {
  return slice(cell_votes, c.first_cell, c.grid_width * c.grid_width);
}

std::span<const float> ScanResult::vote_counts_of(const Candidate& c) const {
  return slice(cell_vote_counts, c.first_cell, c.grid_width * c.grid_width);
}

std::span<const VotePoint> ScanResult::vote_points_of(const Candidate& c) const {
  return slice(vote_points, c.first_vote_point, c.vote_point_count);
}

uint32_t ScanResult::rejected_at(Stage s) const {
  uint32_t n = 0;
  for (int r = 1; r < kRejectionCount; ++r)
    if (stage_of(static_cast<Rejection>(r)) == s) n += rejected[static_cast<size_t>(r)];
  return n;
}

void ScanResult::clear() {
  detections.clear();
  timing_ms.fill(0.0);
  rejected.fill(0);
  features = clusters = 0;
  deskewed_ego = deskewed_model = deskew_without_motion = 0;
  truncated = refused = false;
  diagnostics.clear();
  candidates.clear();
  family_evidence.clear();
  evidence_scores.clear();
  cell_evidence.clear();
  cell_votes.clear();
  cell_vote_counts.clear();
  vote_points.clear();
  tag_points.clear();
  cluster_points.clear();
}

}  // namespace lidartag::detector
