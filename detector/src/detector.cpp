// The orchestrator: the paper's steps in order, each timed; every rejected cluster is counted
// under the reason (and stage) that dropped it. The steps themselves are the stage files' free
// functions.
#include "lidartag/detector/detector.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "lidartag/detector/detection.hpp"
#include "lidartag/detector/square_fit.hpp"

namespace lidartag::detector {

struct Detector::Buffers {
  std::vector<Feature> features;
  std::vector<float> edge_buffer;  // detect_edge_features' work buffer
  std::vector<Cluster> clusters;
  std::vector<int> labels, offsets, order, ring_cols;
  std::vector<ClusterPoint> points;
  CornerWorkspace corners;
  TagPoseWorkspace pose;
  std::vector<Eigen::Vector2d> hull_in, hull;
  BorderWorkspace border;
  ClusterDecodeWorkspace decode;
  PoseSolver solver;
  explicit Buffers(PoseAlgorithm a) : solver(a) {}
};

DetectorLimits derive_limits(const DetectorOptions& o,
                             std::span<const RkhsDictionary> dictionaries) {
  DetectorLimits l;
  l.t_max = *std::max_element(o.tag_sizes_m.begin(), o.tag_sizes_m.end());
  l.tau_m = static_cast<float>(o.cluster.linkage_scale * l.t_max * std::numbers::sqrt2 / 4);
  // The largest object a tag can be: its board, with the largest margin (corners.board_margin_m).
  l.board_max = l.t_max + 2.0 * o.corners.board_margin_m;
  l.max_pair_chord_m = static_cast<float>(l.board_max * std::numbers::sqrt2 * 1.1);
  l.max_extent_m = static_cast<float>(l.board_max * std::numbers::sqrt2 * 1.25);
  l.min_points = l.min_track_points = 1 << 30;
  int psi = 1 << 30;  // eq. (6): at least 2 (d + 2) payload boundary points, smallest family
  for (const auto& d : dictionaries) {
    const auto& fam = d.family();
    // eq. (3) with min_returns_per_cell returns per cell (the paper: 5).
    l.min_points = std::min(
        l.min_points,
        static_cast<int>(std::ceil(o.validation.min_returns_per_cell *
                                   static_cast<float>(fam.total_width * fam.total_width))));
    l.min_track_points = std::min(
        l.min_track_points,
        static_cast<int>(std::ceil(o.validation.track_returns_per_cell *
                                   static_cast<float>(fam.total_width * fam.total_width))));
    psi = std::min(psi, 2 * (fam.payload_width() + 2));
  }
  l.min_track_points = std::min(l.min_track_points, l.min_points);
  l.psi = psi;
  l.min_boundary_points = l.min_track_boundary_points = psi;
  if (!dictionaries.empty()) {
    l.min_boundary_points =
        static_cast<int>(std::ceil(o.validation.boundary_scale * static_cast<float>(psi)));
    l.min_track_boundary_points = std::min(
        l.min_boundary_points,
        static_cast<int>(std::ceil(o.validation.track_boundary_scale * static_cast<float>(psi))));
  }
  l.min_ring_width_m =
      o.validation.min_ring_width *
      static_cast<float>(*std::min_element(o.tag_sizes_m.begin(), o.tag_sizes_m.end()));
  return l;
}

std::string_view Detector::other_family_of(const ScanResult& result,
                                           const ClusterDiagnostic& c) const {
  if (c.rejection != Rejection::kOtherFamily || c.candidate < 0 ||
      static_cast<size_t>(c.candidate) >= result.candidates.size()) {
    return {};
  }
  const int k = result.candidates[static_cast<size_t>(c.candidate)].other_family;
  if (k < 0 || static_cast<size_t>(k) >= decoys_.size()) return {};
  return decoys_[static_cast<size_t>(k)].family().name;
}

Detector::Detector(DetectorOptions options) : opt_(std::move(options)) {
  validate_options(opt_);
  try {
    for (const auto& f : opt_.families) dicts_.emplace_back(tags::resolve_family(f));
    if (opt_.decode.reject_other_families) {
      std::vector<std::string> configured;
      for (const auto& d : dicts_) configured.push_back(d.family().name);
      decoys_ = other_builtin_dictionaries(configured);
    }
  } catch (const tags::FamilyError& e) {
    throw OptionsError("families", "", e.what());
  }
  limits_ = derive_limits(opt_, dicts_);
  buf_ = std::make_unique<Buffers>(opt_.pose.algorithm);
}

Detector::~Detector() = default;

namespace {

using Clock = std::chrono::steady_clock;

// Adds the time since the last lap to a stage's total.
class StageClock {
 public:
  explicit StageClock(std::array<double, kStageCount>& timing) : timing_(timing) {}
  void lap(Stage s) {
    const auto t1 = Clock::now();
    timing_[static_cast<size_t>(s)] += std::chrono::duration<double, std::milli>(t1 - t0_).count();
    t0_ = t1;
  }

 private:
  std::array<double, kStageCount>& timing_;
  Clock::time_point t0_ = Clock::now();
};

// Mean azimuth step of the rotation (the horizontal resolution theta of eq. (4)).
double horizontal_resolution(const Scan& s) {
  if (s.columns < 2) return 2 * std::numbers::pi / 1800.0;
  double sum = 0.0;
  int n = 0;
  for (int c = 1; c < s.columns; ++c) {
    double d = s.column_azimuth_deg[static_cast<size_t>(c)] -
               s.column_azimuth_deg[static_cast<size_t>(c - 1)];
    if (d < 0) d += 360.0;
    if (d > 0 && d < 5.0) {
      sum += d;
      ++n;
    }
  }
  const double deg = n > 0 ? sum / n : 360.0 / s.columns;
  return deg * std::numbers::pi / 180.0;
}

// A Scan is a plain struct: sizes that disagree with its storage would make every stage read past
// the arrays. Only return 0 is read (cells [0, rings x column_capacity)).
bool storage_matches(const Scan& scan) {
  const size_t cells = static_cast<size_t>(scan.rings) * static_cast<size_t>(scan.column_capacity);
  return scan.returns >= 1 && scan.columns <= scan.column_capacity && scan.x.size() >= cells &&
         scan.y.size() >= cells && scan.z.size() >= cells && scan.range.size() >= cells &&
         scan.intensity.size() >= cells &&
         scan.column_azimuth_deg.size() >= static_cast<size_t>(scan.columns);
}

// A cluster's edge features as points (every one on the outline; the intensity of the return).
void features_as_points(const Scan& scan, std::span<const Feature> features,
                        std::span<const int> members, std::vector<ClusterPoint>& out) {
  out.clear();
  for (int m : members) {
    const Feature& f = features[static_cast<size_t>(m)];
    ClusterPoint p;
    p.x = f.x;
    p.y = f.y;
    p.z = f.z;
    p.intensity = scan.intensity[scan.at(0, f.ring, f.col)];
    p.ring = f.ring;
    p.col = f.col;
    p.edge = true;
    out.push_back(p);
  }
}

ClusterDiagnostic diagnostic_of(const Cluster& cl) {
  ClusterDiagnostic d;
  d.features = cl.features;
  d.min_x = cl.min_x;
  d.max_x = cl.max_x;
  d.min_y = cl.min_y;
  d.max_y = cl.max_y;
  d.min_ring = cl.min_ring;
  d.max_ring = cl.max_ring;
  return d;
}

}  // namespace

void Detector::detect(const Scan& scan, ScanResult& out) noexcept {
  detect(scan, out, SensorMotion{});
}

void Detector::detect(const Scan& scan, ScanResult& out, const SensorMotion& motion) noexcept {
  out.clear();
  if (scan.rings <= 0 || scan.columns <= 0) return;
  if (!storage_matches(scan)) {
    out.refused = true;
    return;
  }
  try {
    detect_clusters(scan, out, motion);
  } catch (...) {
    // Only allocation failure can get here (the stages throw nothing else).
    out.truncated = true;
  }
}

void Detector::detect_clusters(const Scan& scan, ScanResult& out, const SensorMotion& motion) {
  Buffers& b = *buf_;
  StageClock clock(out.timing_ms);
  // Sec. IV-A: eq. (1) per ring, with the "one edge among n+1" rule.
  detect_edge_features(scan, opt_.features, limits_.max_pair_chord_m, b.features, b.edge_buffer);
  out.features = static_cast<int>(b.features.size());
  clock.lap(Stage::kFeatures);
  // Sec. IV-B: eq. (2) with tau for the largest configured size; the features grouped by cluster
  // for the fill-in.
  cluster_features(b.features, limits_.tau_m, limits_.max_extent_m, opt_.cluster, b.clusters,
                   b.labels);
  group_by_cluster(b.labels, b.clusters.size(), b.offsets, b.order);
  clock.lap(Stage::kClustering);
  const double res = horizontal_resolution(scan);
  for (size_t c = 0; c < b.clusters.size(); ++c) {
    if (b.clusters[c].parent >= 0) continue;
    ++out.clusters;
    process_cluster(scan, static_cast<int>(c), res, motion, out);
  }
}

void Detector::process_cluster(const Scan& scan, int ci, double res, const SensorMotion& motion,
                               ScanResult& out) {
  Buffers& b = *buf_;
  const auto c = static_cast<size_t>(ci);
  StageClock clock(out.timing_ms);
  ClusterDiagnostic diag = diagnostic_of(b.clusters[c]);
  // Every exit: the time to its stage, the reason counted, the points and the diagnostic kept.
  // A cluster below eq. (3)'s or eq. (6)'s bound but above the tracks' is looked at to the end for
  // a track (Candidate::track_only); whatever the later stages say, the bound it missed is why it
  // is no detection.
  bool track_only = false;
  Rejection track_only_reason = Rejection::kFewBoundaryPoints;
  auto finish = [&](Stage s, Rejection r) {
    clock.lap(s);
    if (track_only) r = track_only_reason;
    diag.rejection = r;
    if (r != Rejection::kNone) ++out.rejected[static_cast<size_t>(r)];
    if (opt_.keep_cluster_points && !b.points.empty()) {
      diag.first_point = static_cast<int>(out.cluster_points.size());
      diag.point_count = static_cast<int>(b.points.size());
      out.cluster_points.insert(out.cluster_points.end(), b.points.begin(), b.points.end());
      if (diag.candidate >= 0) {
        out.candidates[static_cast<size_t>(diag.candidate)].first_point = diag.first_point;
        out.candidates[static_cast<size_t>(diag.candidate)].point_count = diag.point_count;
      }
    }
    if (!opt_.cluster_diagnostics) return;
    if (diag.candidate >= 0)
      out.candidates[static_cast<size_t>(diag.candidate)].cluster =
          static_cast<int>(out.diagnostics.size());
    out.diagnostics.push_back(diag);
  };

  // Sec. IV-C: the fill-in from the scan; the point counts, eqs. (3) and (4); the payload boundary
  // points, eqs. (5) and (6).
  const auto members = std::span<const int>(b.order).subspan(
      static_cast<size_t>(b.offsets[c]), static_cast<size_t>(b.offsets[c + 1] - b.offsets[c]));
  Rejection r = fill_cluster(scan, b.features, members, b.clusters[c], opt_.validation,
                             limits_.max_extent_m, b.points, b.ring_cols);
  diag.points = static_cast<int>(b.points.size());
  if (r != Rejection::kNone) {
    // Dropped before the fill-in: its edge features are all it has, kept as its points so that a
    // tag too far or too sparse still shows where it was (render, detect --clusters).
    if (opt_.keep_cluster_points) features_as_points(scan, b.features, members, b.points);
    return finish(Stage::kClustering, r);
  }
  // The tracks' bounds (issue 33's far edge): eq. (3) with track_returns_per_cell, and eq. (6)
  // scaled to the points where eq. (5) can fire (track_boundary_bound) when the track tier is
  // on; a cluster between them and the detection bounds is evidence for a track only.
  r = check_point_counts(b.points, limits_.min_track_points, limits_.board_max, res,
                         opt_.validation);
  if (r != Rejection::kNone) return finish(Stage::kValidation, r);
  diag.boundary_points = count_boundary_points(b.points, opt_.validation);
  const int track_bound =
      limits_.min_track_boundary_points < limits_.min_boundary_points
          ? track_boundary_bound(testable_points(b.points, opt_.validation), rings_in(b.points),
                                 limits_.psi, limits_.min_track_boundary_points, opt_.validation)
          : limits_.min_track_boundary_points;
  if (diag.boundary_points < track_bound)
    return finish(Stage::kValidation, Rejection::kFewBoundaryPoints);
  if (static_cast<int>(b.points.size()) < limits_.min_points) {
    track_only = true;
    track_only_reason = Rejection::kTooFewPoints;
  } else {
    track_only = diag.boundary_points < limits_.min_boundary_points;
  }
  clock.lap(Stage::kValidation);

  // Issue 33: the points moved to the cluster's centre time with the sensor's motion, so that the
  // fits see the tag as from one pose (timed with the plane fit).
  Deskewed deskewed;
  if (opt_.deskew.enabled) {
    deskewed = deskew_cluster(b.points, scan, motion);
    switch (deskewed.source) {
      case DeskewSource::kEgo:
        ++out.deskewed_ego;
        break;
      case DeskewSource::kModel:
        ++out.deskewed_model;
        break;
      case DeskewSource::kNone:
        ++out.deskew_without_motion;
        break;
    }
  }

  // Sec. IV-C: the plane and its outlier ratio kappa. Posts and poles above or below the tag are
  // in its plane but not part of it; so are the few ground points where it meets the ground.
  Plane plane;
  const bool planar =
      fit_plane(b.points, opt_.plane, 0x9e3779b9u ^ static_cast<uint32_t>(ci), plane);
  diag.outlier_ratio = plane.outlier_ratio;
  if (!planar) return finish(Stage::kPlane, Rejection::kPlaneOutliers);
  clock.lap(Stage::kPlane);
  trim_narrow_rings(b.points, limits_.min_ring_width_m);

  // Sec. V-B remark: the outline's corners; the side length picks the tag size t.
  TagOutline outline;
  r = find_corners(b.points, plane, opt_.tag_sizes_m, opt_.corners, b.corners, outline);
  diag.side_m = outline.side_m;
  if (r != Rejection::kNone) return finish(Stage::kCorners, r);
  clock.lap(Stage::kCorners);

  // Sec. V: eq. (10)'s initial guess from the corners, then eq. (9) minimising eq. (8), whose
  // epsilon is the plane's depth spread. The template is the outline seen when that is larger
  // than the marker (a board with a bare margin: with the marker's size, the margin's points
  // would all cost, and the fit would slide toward the side with more rings). Gates: the mean
  // cost, and the coverage of the pull-back's convex hull (surveyor's formula).
  const double t = outline.size_m;
  // The coverage gate's upper bound first: a cluster that cannot pass it is not fitted (most of
  // the boards and walls of a configured size that reach this stage).
  const double bound = coverage_bound(b.corners.hull, t);
  if (!track_only && bound < opt_.pose.min_coverage) {
    diag.coverage = bound;
    return finish(Stage::kPose, Rejection::kCoverage);
  }
  const double t_fit = std::max(t, outline.side_m);
  const double epsilon = std::max(opt_.pose.min_depth_epsilon_m, plane.depth_sigma);
  PoseFitResult fit = fit_tag_pose(b.solver, b.points, procrustes_initial_guess(outline.corners, t),
                                   t_fit, epsilon, opt_.pose, b.pose);
  diag.mean_cost_m = fit.cost / static_cast<double>(b.points.size());
  if (diag.mean_cost_m > opt_.pose.max_mean_cost_m)
    return finish(Stage::kPose, Rejection::kFitCost);
  diag.coverage = coverage_ratio(b.pose.subset, fit.pose, t, b.hull_in, b.hull);
  // A cluster for a track alone (the far edge) is held to the share of the gate that its sampling
  // lets a whole tag show: sparse rings and columns leave the hull of a whole tag well short of
  // t^2 (0.65 at a VLP-32C's 28 m and 45 degrees), and only a board's margin made up for it; less
  // a ring that one rotation's cluster may lack. Its pre-fit bound above is skipped for the same
  // reason.
  const double min_coverage =
      track_only
          ? opt_.pose.min_coverage * track_coverage_share(b.points, fit.pose, t, b.hull_in, b.hull)
          : opt_.pose.min_coverage;
  if (diag.coverage < min_coverage) return finish(Stage::kPose, Rejection::kCoverage);
  IntensityLevels levels;
  if (opt_.pose.border_refine)
    levels = outline.on_board
                 ? board_levels(b.points, fit.pose, t, b.decode.inside, b.decode.decode)
                 : intensity_levels(b.points, b.decode.decode);
  double measured_size_m = -1.0;          // the size check: what the black square's steps say
  bool along_y = false, along_z = false;  // the in-plane axes the black square placed
  auto place = [&] {
    if (!opt_.pose.border_refine) return;
    const BorderFit border =
        place_on_border(b.points, fit.pose, t, dicts_, levels, BorderFitOptions{}, b.border);
    if (border.ok) fit.pose = border.pose;
    measured_size_m = border.ok ? border.measured_size_m : -1.0;
    along_y = border.ok && border.along_y;
    along_z = border.ok && border.along_z;
  };
  place();
  // A tag on a board (an outline larger than the tag) is where its black square is: a board in
  // which no square of this size is measured (steps on two opposite sides or three) is not this
  // tag (blank boards, signs, other prints).
  if (outline.on_board &&
      (measured_size_m <= 0 || size_contradicts(measured_size_m, t, opt_.corners.size_tolerance)))
    return finish(Stage::kPose, Rejection::kSize);
  clock.lap(Stage::kPose);

  // Sec. VI: decoding, eqs. (18)-(22), over the shifts along an axis the outline did not place.
  // On a board, the board's outline places the board: along an axis the black square could not
  // place (a square mount's top and bottom, which horizontal rings do not cross), the tag is taken
  // to be printed at the board's centre, which the board's first and last rings place to within
  // half a ring spacing: decoding searches a cell either way. (Searching the whole slack of a
  // large margin, up to 2.3 cells of a 1.2 m tag16h5 on a 1.6 m board, read a VLP-16's tag as
  // another code once in 90 rotations.)
  Eigen::Vector3d unseen = outline.unseen_axis;
  double board_slack_m = 0.0;
  if (outline.on_board && along_y != along_z) {
    unseen =
        fit.pose.R.transpose() * (along_y ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY());
    board_slack_m = t / dicts_.front().width();
  }
  const ClusterDecode dec = decode_cluster(b.points, fit.pose, unseen, t, dicts_, decoys_,
                                           opt_.decode, b.decode, outline.on_board, board_slack_m);
  diag.score = dec.best.score;
  diag.margin = dec.best.margin_bits;
  clock.lap(Stage::kDecode);
  // A large cluster's polish, once it scores as a tag (a detection, or a candidate rejected only
  // for its margin, its sparse returns or its boundary): most such clusters are no tag.
  if (fit.polish_pending && dec.best.function >= 0 && dec.best.score >= opt_.decode.min_score) {
    fit = polish_tag_pose(b.solver, b.points, fit.pose, t_fit, epsilon, opt_.pose);
    place();
    clock.lap(Stage::kPose);
  }
  const TagFrame frame = tag_frame(fit.pose, unseen, dec.shift);
  const int points = static_cast<int>(b.points.size());
  diag.candidate =
      add_candidate(dec, frame.center, frame.undecoded, t, points, fit.cost, diag.coverage, out);
  Candidate& candidate = out.candidates[static_cast<size_t>(diag.candidate)];
  candidate.track_only = track_only;
  if (dec.shift_searched) candidate.unseen_axis = unseen.normalized();
  FiringTimes times = firing_times(b.points, scan, frame.center);
  // Deskewed points are all seen from the sensor's pose at the time they were moved to.
  if (deskewed.source != DeskewSource::kNone) times.center_s = deskewed.center_s;
  candidate.time_first_s = times.first_s;
  candidate.time_center_s = times.center_s;
  candidate.time_last_s = times.last_s;
  candidate.measured_size_m = measured_size_m;
  candidate.deskew = deskewed.source;
  if (dec.best.rejection != Rejection::kNone || track_only)
    return finish(Stage::kDecode, dec.best.rejection);

  // The detection: the pose with the decoded quarter turns (Sec. V remark).
  Detection det =
      assemble_detection(frame, dec.best, dec.family,
                         dicts_[static_cast<size_t>(dec.family)].family(), t, points, fit.cost);
  det.time_first_s = times.first_s;
  det.time_center_s = times.center_s;
  det.time_last_s = times.last_s;
  det.measured_size_m = measured_size_m;
  det.deskew = deskewed.source;
  det.size_warning = size_contradicts(measured_size_m, t, opt_.pose.size_warning_ratio);
  if (opt_.keep_tag_points) {
    det.first_point = static_cast<int>(out.tag_points.size());
    out.tag_points.insert(out.tag_points.end(), b.points.begin(), b.points.end());
  }
  candidate.detection = static_cast<int>(out.detections.size());
  out.detections.push_back(det);
  finish(Stage::kDecode, Rejection::kNone);
}

int Detector::add_candidate(const ClusterDecode& dec, const Eigen::Vector3d& center,
                            const Eigen::Matrix3d& undecoded, double t, int points, double fit_cost,
                            double coverage, ScanResult& out) {
  Candidate& k = out.candidates.emplace_back();
  const bool scored = dec.best.function >= 0;
  k.rejection = dec.best.rejection;
  k.family_index = scored ? dec.family : -1;
  k.id = scored ? dec.best.code_index : -1;
  k.quarter_turns = scored ? dec.best.quarter_turns : 0;
  k.size_m = t;
  k.position = center;
  k.undecoded_orientation = unit_quaternion(undecoded);
  k.orientation = unit_quaternion(decoded_rotation(undecoded, k.quarter_turns));
  k.score = dec.best.score;
  k.margin = dec.best.margin_bits;
  k.other_family_score = dec.other_family_score;
  k.other_family = dec.other_family;
  k.shift_searched = dec.shift_searched;
  k.points = points;
  k.fit_cost = fit_cost;
  k.coverage = coverage;
  // Each configured family's best hypothesis: its scores, and the decoded grid of the best one.
  k.first_evidence = static_cast<int>(out.family_evidence.size());
  k.evidence_count = static_cast<int>(dicts_.size());
  for (size_t f = 0; f < dicts_.size(); ++f) {
    const FamilyDecode& fd = buf_->decode.families[f];
    FamilyEvidence& e = out.family_evidence.emplace_back();
    e.family_index = static_cast<int>(f);
    e.first = static_cast<int>(out.evidence_scores.size());
    if (!fd.scored) continue;
    e.functions = static_cast<int>(fd.scores.size());
    e.cells_per_score = static_cast<float>(fd.result.cells_per_score);
    e.shift_m = static_cast<float>(fd.shift);
    out.evidence_scores.insert(out.evidence_scores.end(), fd.scores.begin(), fd.scores.end());
    if (scored && static_cast<int>(f) == dec.family) {
      k.first_cell = static_cast<int>(out.cell_evidence.size());
      k.grid_width = dicts_[f].width();
      const auto& ws = buf_->decode;
      out.cell_evidence.insert(out.cell_evidence.end(), fd.cells.begin(), fd.cells.end());
      out.cell_votes.insert(out.cell_votes.end(), ws.votes.begin(), ws.votes.end());
      out.cell_vote_counts.insert(out.cell_vote_counts.end(), ws.vote_counts.begin(),
                                  ws.vote_counts.end());
      // The points behind those votes (prepared at the best shift, in units of t).
      k.first_vote_point = static_cast<int>(out.vote_points.size());
      k.vote_point_count = static_cast<int>(ws.decode.prepared.size());
      for (const DecodePoint& q : ws.decode.prepared)
        out.vote_points.push_back({static_cast<float>(q.xn * t), static_cast<float>(q.yn * t),
                                   static_cast<float>(q.zn * t), static_cast<float>(q.label)});
    }
  }
  return static_cast<int>(out.candidates.size()) - 1;
}

}  // namespace lidartag::detector
