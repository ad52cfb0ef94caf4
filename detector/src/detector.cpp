// The orchestrator: the paper's stages in order, each timed; every rejected cluster is counted
// under the reason (and stage) that dropped it.
#include "lidartag/detector/detector.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

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

std::span<const ClusterPoint> ScanResult::points_of(const Detection& d) const {
  if (d.first_point < 0 || d.points < 0 ||
      static_cast<size_t>(d.first_point) + static_cast<size_t>(d.points) > tag_points.size()) {
    return {};
  }
  return std::span<const ClusterPoint>(tag_points)
      .subspan(static_cast<size_t>(d.first_point), static_cast<size_t>(d.points));
}

uint32_t ScanResult::rejected_at(Stage s) const {
  uint32_t n = 0;
  for (int r = 1; r < kRejectionCount; ++r)
    if (stage_of(static_cast<Rejection>(r)) == s) n += rejected[static_cast<size_t>(r)];
  return n;
}

void validate_options(const DetectorOptions& o) {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw OptionsError(std::string("detector options: ") + what);
  };
  need(!o.tag_sizes_m.empty(), "tag_sizes_m needs at least one size");
  for (double t : o.tag_sizes_m) need(t > 0.0 && t < 20.0, "tag sizes must be in (0, 20) m");
  need(!o.families.empty(), "families needs at least one family");
  need(o.features.ell >= 1, "features.ell must be >= 1");
  need(o.features.n >= 0, "features.n must be >= 0");
  need(o.features.max_gap >= 0, "features.max_gap must be >= 0");
  need(o.features.zeta_m > 0.0f, "features.zeta_m must be > 0");
  need(o.features.max_range_m > o.features.min_range_m, "features: max_range_m <= min_range_m");
  need(o.cluster.linkage_scale > 0.0f, "cluster.linkage_scale must be > 0");
  need(o.cluster.ring_gap >= 1, "cluster.ring_gap must be >= 1");
  need(o.validation.min_returns_per_cell >= 0.0f, "validation.min_returns_per_cell must be >= 0");
  need(o.validation.max_points_scale > 0.0f, "validation.max_points_scale must be > 0");
  need(o.validation.gi_ell >= 1, "validation.gi_ell must be >= 1");
  need(o.validation.min_ring_width >= 0.0f && o.validation.min_ring_width < 1.0f,
       "validation.min_ring_width must be in [0, 1)");
  need(o.plane.inlier_m > 0.0f, "plane.inlier_m must be > 0");
  need(o.plane.max_outlier_ratio >= 0.0f && o.plane.max_outlier_ratio < 1.0f,
       "plane.max_outlier_ratio must be in [0, 1)");
  need(o.plane.iterations >= 1, "plane.iterations must be >= 1");
  need(o.corners.line_inlier_m > 0.0f, "corners.line_inlier_m must be > 0");
  need(o.corners.min_line_points >= 2, "corners.min_line_points must be >= 2");
  need(o.corners.size_tolerance > 0.0f, "corners.size_tolerance must be > 0");
  need(o.pose.translation_bound_m > 0 && o.pose.rotation_bound_rad > 0, "pose bounds must be > 0");
  need(o.pose.max_evaluations >= 1, "pose.max_evaluations must be >= 1");
  need(o.pose.xtol_rel >= 0 && o.pose.xtol_abs >= 0, "pose tolerances must be >= 0");
  need(o.pose.min_coverage >= 0 && o.pose.min_coverage <= 1, "pose.min_coverage in [0, 1]");
  need(o.pose.max_points >= 8, "pose.max_points must be >= 8");
  need(o.decode.max_points >= 16, "decode.max_points must be >= 16");
  need(o.plane.score_points >= 0, "plane.score_points must be >= 0");
  need(o.decode.samples_per_cell >= 1 && o.decode.samples_per_cell <= 8,
       "decode.samples_per_cell must be 1..8");
  need(o.decode.length_scale_cells > 0 && o.decode.intensity_length_scale > 0,
       "decode length scales must be > 0");
  need(o.decode.min_margin_bits >= 0, "decode.min_margin_bits must be >= 0");
}

struct Detector::Buffers {
  std::vector<Feature> features;
  std::vector<float> edge_buffer;  // detect_edge_features' work buffer
  std::vector<Cluster> clusters;
  std::vector<int> labels, offsets, order, ring_cols;
  std::vector<ClusterPoint> points, subset, pulled;
  std::vector<float> weights;
  struct Hypothesis {
    DecodeResult d;
    int family = 0;
    double shift = 0.0;
  };
  std::vector<Hypothesis> hypotheses;
  std::vector<double> shifts;  // tried along an unseen axis
  CornerWorkspace corners;
  std::vector<Eigen::Vector2d> hull_in, hull;
  DecodeWorkspace decode;
  PoseSolver solver;
  explicit Buffers(PoseAlgorithm a) : solver(a) {}
};

Detector::Detector(DetectorOptions options) : opt_(std::move(options)) {
  validate_options(opt_);
  try {
    for (const auto& f : opt_.families) dicts_.emplace_back(tags::resolve_family(f));
    if (opt_.decode.reject_other_families) {
      for (const auto& name : tags::builtin_family_names()) {
        const bool configured = std::any_of(dicts_.begin(), dicts_.end(),
                                            [&](const auto& d) { return d.family().name == name; });
        if (!configured) decoys_.emplace_back(tags::builtin_family(name));
      }
    }
  } catch (const tags::FamilyError& e) {
    throw OptionsError(std::string("detector options: ") + e.what());
  }
  t_max_ = *std::max_element(opt_.tag_sizes_m.begin(), opt_.tag_sizes_m.end());
  min_points_ = 1 << 30;
  min_boundary_ = 1 << 30;
  for (const auto& d : dicts_) {
    const auto& fam = d.family();
    min_points_ = std::min(
        min_points_,
        static_cast<int>(std::ceil(opt_.validation.min_returns_per_cell *
                                   static_cast<float>(fam.total_width * fam.total_width))));
    // eq. (psi): at least 2 (d + 2) payload boundary points.
    min_boundary_ =
        std::min(min_boundary_,
                 static_cast<int>(std::ceil(opt_.validation.boundary_scale *
                                            static_cast<float>(2 * (fam.payload_width() + 2)))));
  }
  min_ring_width_m_ =
      opt_.validation.min_ring_width *
      static_cast<float>(*std::min_element(opt_.tag_sizes_m.begin(), opt_.tag_sizes_m.end()));
  buf_ = std::make_unique<Buffers>(opt_.pose.algorithm);
  opt_.features.max_pair_chord_m = static_cast<float>(t_max_ * std::numbers::sqrt2 * 1.1);
  opt_.cluster.max_extent_m = static_cast<float>(t_max_ * std::numbers::sqrt2 * 1.25);
}

Detector::~Detector() = default;

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point& t0) {
  const auto t1 = Clock::now();
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  t0 = t1;
  return ms;
}

// Mean azimuth step of the rotation (the horizontal resolution theta).
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

}  // namespace

void Detector::detect(const Scan& scan, ScanResult& out) noexcept {
  out.detections.clear();
  out.diagnostics.clear();
  out.tag_points.clear();
  out.timing_ms.fill(0.0);
  out.rejected.fill(0);
  out.features = out.clusters = 0;
  if (scan.rings <= 0 || scan.columns <= 0) return;
  // A Scan is a plain struct: sizes that disagree with its storage would make every stage read
  // past the arrays. Only return 0 is read (cells [0, rings x column_capacity)).
  const size_t cells = static_cast<size_t>(scan.rings) * static_cast<size_t>(scan.column_capacity);
  if (scan.returns < 1 || scan.columns > scan.column_capacity || scan.x.size() < cells ||
      scan.y.size() < cells || scan.z.size() < cells || scan.range.size() < cells ||
      scan.intensity.size() < cells ||
      scan.column_azimuth_deg.size() < static_cast<size_t>(scan.columns))
    return;
  try {
    Buffers& b = *buf_;
    auto t0 = Clock::now();
    // eq. (GD) per ring, with the "one edge among n+1" rule.
    detect_edge_features(scan, opt_.features, b.features, b.edge_buffer);
    out.features = static_cast<int>(b.features.size());
    out.timing_ms[static_cast<size_t>(Stage::kFeatures)] += ms_since(t0);

    // eq. (linkage) with tau = t sqrt(2) / 4 for the largest configured size.
    const auto tau =
        static_cast<float>(opt_.cluster.linkage_scale * t_max_ * std::numbers::sqrt2 / 4);
    cluster_features(b.features, tau, opt_.cluster, b.clusters, b.labels);
    // Group the features by cluster (counting sort) for the fill-in.
    b.offsets.assign(b.clusters.size() + 1, 0);
    for (int l : b.labels) ++b.offsets[static_cast<size_t>(l) + 1];
    for (size_t c = 0; c < b.clusters.size(); ++c) b.offsets[c + 1] += b.offsets[c];
    b.order.resize(b.labels.size());
    b.ring_cols.assign(b.offsets.begin(), b.offsets.end() - 1);  // insertion cursors
    for (size_t k = 0; k < b.labels.size(); ++k)
      b.order[static_cast<size_t>(b.ring_cols[static_cast<size_t>(b.labels[k])]++)] =
          static_cast<int>(k);
    out.timing_ms[static_cast<size_t>(Stage::kClustering)] += ms_since(t0);

    const double res = horizontal_resolution(scan);
    for (size_t c = 0; c < b.clusters.size(); ++c) {
      if (b.clusters[c].parent >= 0) continue;
      ++out.clusters;
      process_cluster(scan, static_cast<int>(c), res, out);
    }
  } catch (...) {
    // Only allocation failure can get here; the rotation yields what was found so far.
  }
}

void Detector::process_cluster(const Scan& scan, int ci, double res, ScanResult& out) {
  Buffers& b = *buf_;
  const Cluster& cl = b.clusters[static_cast<size_t>(ci)];
  ClusterDiagnostic diag;
  diag.features = cl.features;
  diag.min_x = cl.min_x;
  diag.max_x = cl.max_x;
  diag.min_y = cl.min_y;
  diag.max_y = cl.max_y;
  diag.min_ring = cl.min_ring;
  diag.max_ring = cl.max_ring;
  auto finish = [&](Rejection r) {
    diag.rejection = r;
    if (r != Rejection::kNone) ++out.rejected[static_cast<size_t>(r)];
    if (opt_.cluster_diagnostics) out.diagnostics.push_back(diag);
  };
  auto t0 = Clock::now();
  auto lap = [&](Stage s) { out.timing_ms[static_cast<size_t>(s)] += ms_since(t0); };

  // Fill-in, then eta: family lower bound, M t sqrt(2) / (D sin theta) upper bound.
  const auto members = std::span<const int>(b.order).subspan(
      static_cast<size_t>(b.offsets[static_cast<size_t>(ci)]),
      static_cast<size_t>(b.offsets[static_cast<size_t>(ci) + 1] -
                          b.offsets[static_cast<size_t>(ci)]));
  const auto max_extent = opt_.cluster.max_extent_m;
  Rejection r = fill_cluster(scan, b.features, members, cl, opt_.validation, max_extent, b.points,
                             b.ring_cols);
  if (r != Rejection::kNone) {
    diag.points = static_cast<int>(b.points.size());
    lap(Stage::kClustering);
    return finish(r);
  }
  diag.points = static_cast<int>(b.points.size());
  if (diag.points < min_points_) {
    lap(Stage::kValidation);
    return finish(Rejection::kTooFewPoints);
  }
  if (diag.points > opt_.validation.max_points_scale * max_tag_points(b.points, t_max_, res)) {
    lap(Stage::kValidation);
    return finish(Rejection::kTooManyPoints);
  }
  // eq. (GI): payload boundary points, psi >= 2 (d + 2).
  diag.boundary_points = count_boundary_points(b.points, opt_.validation);
  lap(Stage::kValidation);
  if (diag.boundary_points < min_boundary_) return finish(Rejection::kFewBoundaryPoints);

  // Plane fit, outlier ratio kappa.
  Plane plane;
  const bool planar =
      fit_plane(b.points, opt_.plane, 0x9e3779b9u ^ static_cast<uint32_t>(ci), plane);
  lap(Stage::kPlane);
  diag.outlier_ratio = plane.outlier_ratio;
  if (!planar) return finish(Rejection::kPlaneOutliers);
  // Posts and poles above or below the tag are in its plane but not part of it; so are the few
  // ground points where the plane meets the ground.
  trim_narrow_rings(b.points, min_ring_width_m_);

  // Corners: edge lines and their intersections; the side length picks the tag size.
  TagOutline outline;
  r = find_corners(b.points, plane, opt_.tag_sizes_m, opt_.corners, b.corners, outline);
  lap(Stage::kCorners);
  diag.side_m = outline.side_m;
  if (r != Rejection::kNone) return finish(r);

  // eq. (procrustes) initial guess, then eq. (Pose) minimising eq. (JKHcost).
  const double t = outline.size_m;
  const RigidPose init = procrustes_initial_guess(outline.corners, t);
  const double eps = std::max(opt_.pose.min_depth_epsilon_m, plane.depth_sigma);
  // The template of the fit is the outline actually seen when it is larger than the marker: a
  // board with a bare margin around the print. With the marker's size, the margin's points would
  // all cost, and the fit would slide toward the side with more rings (a bias of centimetres).
  const double t_fit = std::max(t, outline.side_m);
  // The outline (each ring's end points) and evenly spaced interior points, at most max_points.
  b.subset.clear();
  size_t edges = 0;
  for (const auto& p : b.points) edges += p.edge ? 1 : 0;
  const size_t cap = static_cast<size_t>(std::max(opt_.pose.max_points, 8));
  const size_t interior = b.points.size() - edges;
  const size_t keep = cap > edges ? cap - edges : 0;
  const size_t stride = keep > 0 ? std::max<size_t>(1, (interior + keep - 1) / keep) : 0;
  b.weights.clear();
  size_t n_interior = 0;
  for (const auto& p : b.points) {
    if (p.edge || (stride > 0 && n_interior++ % stride == 0)) {
      b.subset.push_back(p);
      b.weights.push_back(p.edge ? 1.0f : 0.0f);
    }
  }
  // Each kept interior point stands for the interior points it replaces, so that the depth term
  // keeps its weight against the outline (else the fit tilts the plane to pull edge points in).
  const size_t kept = b.subset.size() - edges;
  const float interior_weight =
      kept > 0 ? static_cast<float>(interior) / static_cast<float>(kept) : 0.0f;
  for (size_t i = 0; i < b.subset.size(); ++i)
    if (!b.subset[i].edge) b.weights[i] = interior_weight;
  PoseFitResult fit = b.solver.fit(b.subset, t_fit, eps, init, opt_.pose, b.weights);
  if (b.subset.size() < b.points.size() && opt_.pose.polish_evaluations > 0) {
    // A few evaluations on every point from there: the depth term of the subsample is noisier.
    PoseOptions polish = opt_.pose;
    polish.max_evaluations = opt_.pose.polish_evaluations;
    polish.translation_bound_m = 0.02;
    polish.rotation_bound_rad = 0.02;
    fit = b.solver.fit(b.points, t_fit, eps, fit.pose, polish);
  }
  const double mean_cost = fit.cost / static_cast<double>(b.points.size());
  diag.mean_cost_m = mean_cost;
  if (mean_cost > opt_.pose.max_mean_cost_m) {
    lap(Stage::kPose);
    return finish(Rejection::kFitCost);
  }
  // Coverage: convex hull of the pull-back, surveyor's formula, >= 75 % of t^2.
  const double cover = coverage_ratio(b.subset, fit.pose, t, b.hull_in, b.hull);
  lap(Stage::kPose);
  diag.coverage = cover;
  if (cover < opt_.pose.min_coverage) return finish(Rejection::kCoverage);

  // Decoding: the points pulled back into the template frame, against every dictionary. When a
  // pair of sides was not seen (square mount), the tag may sit anywhere along that axis where the
  // points stay inside it: try shifts of 1/8 cell and keep the one that decodes best.
  const Eigen::Vector3d axis = fit.pose.R * outline.unseen_axis;  // in the tag frame
  double lo = 0.0, hi = 0.0;
  const size_t dstride = std::max<size_t>(
      1, (b.points.size() + static_cast<size_t>(std::max(opt_.decode.max_points, 16)) - 1) /
             static_cast<size_t>(std::max(opt_.decode.max_points, 16)));
  b.pulled.clear();
  for (size_t i = 0; i < b.points.size(); i += dstride) {
    const auto& p = b.points[i];
    const Eigen::Vector3d q = fit.pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    ClusterPoint c = p;
    c.x = static_cast<float>(q.x());
    c.y = static_cast<float>(q.y());
    c.z = static_cast<float>(q.z());
    b.pulled.push_back(c);
    const double a = q.dot(axis);
    lo = i == 0 ? a : std::min(lo, a);
    hi = i == 0 ? a : std::max(hi, a);
  }
  // Along an unseen axis, shifts of half a cell first, then halved twice around the best one.
  const double cell = t / dicts_.front().width();
  const bool search = !outline.unseen_axis.isZero();
  const double s0 = search ? std::min(0.0, hi - t / 2) : 0.0;
  const double s1 = search ? std::max(0.0, lo + t / 2) : 0.0;
  // Every (shift, family) is a hypothesis: the best one must beat the best *other* function of its
  // family at any shift (another code or rotation) by the margin, so that searching more shifts
  // does not make a wrong ID more likely. Families are chosen between by score alone.
  b.hypotheses.clear();
  b.shifts.clear();
  double applied = 0.0;
  const IntensityLevels levels = intensity_levels(b.pulled, b.decode);
  auto move_to = [&](double shift) {
    for (auto& q : b.pulled) {  // move the points by -(shift - applied) along the axis
      q.x -= static_cast<float>((shift - applied) * axis.x());
      q.y -= static_cast<float>((shift - applied) * axis.y());
      q.z -= static_cast<float>((shift - applied) * axis.z());
    }
    applied = shift;
    prepare_decode(b.pulled, levels, t, b.decode);  // the same for every family
  };
  auto try_shift = [&](double shift) {
    // The refinement's steps are clamped to [s0, s1]: a shift tried before would only add the
    // same hypotheses again.
    for (double s : b.shifts)
      if (std::abs(s - shift) < 1e-9 * t) return;
    b.shifts.push_back(shift);
    move_to(shift);
    for (size_t f = 0; f < dicts_.size(); ++f) {
      const DecodeResult d = decode_prepared(dicts_[f], opt_.decode, b.decode);
      if (d.function >= 0) b.hypotheses.push_back({d, static_cast<int>(f), shift});
    }
  };
  auto best_so_far = [&]() {
    size_t k = 0;
    for (size_t i = 1; i < b.hypotheses.size(); ++i)
      if (b.hypotheses[i].d.score > b.hypotheses[k].d.score) k = i;
    return k;
  };
  if (!search) {
    try_shift(0.0);
  } else {
    for (double shift = s0; shift <= s1 + 1e-9; shift += cell / 2) try_shift(shift);
    for (double step = cell / 4; step > cell / 10 && !b.hypotheses.empty(); step /= 2) {
      const double centre = b.hypotheses[best_so_far()].shift;
      try_shift(std::max(s0, centre - step));
      try_shift(std::min(s1, centre + step));
    }
  }
  DecodeResult best;  // kLowContrast unless some hypothesis could be scored
  int best_family = 0;
  double best_shift = 0.0;
  if (!b.hypotheses.empty()) {
    const auto& h = b.hypotheses[best_so_far()];
    double rival = -1e30;
    for (const auto& o : b.hypotheses) {
      if (o.family != h.family) continue;  // normalised scores of two families do not compare
      if (o.d.function != h.d.function) rival = std::max(rival, o.d.score);
      if (o.d.second_function >= 0 && o.d.second_function != h.d.function)
        rival = std::max(rival, o.d.second_score);
    }
    best = h.d;
    best_family = h.family;
    best_shift = h.shift;
    best.margin_bits = rival > -1e29 ? (h.d.score - rival) * h.d.cells_per_score : 1e9;
    best.rejection = best.score < opt_.decode.min_score               ? Rejection::kLowScore
                     : best.margin_bits < opt_.decode.min_margin_bits ? Rejection::kAmbiguous
                                                                      : Rejection::kNone;
  }
  // A tag of a family that is not configured still has a best code in the configured ones (the
  // margin only compares codes of one family): the built-in families left out are decoded at the
  // same shifts, and one that fits strictly better makes it another family's tag. Identical
  // patterns tie and stay with the configured family.
  for (size_t si = 0;
       !decoys_.empty() && si < b.shifts.size() && best.rejection == Rejection::kNone; ++si) {
    move_to(b.shifts[si]);
    for (const auto& decoy : decoys_) {
      const DecodeResult d = decode_prepared(decoy, opt_.decode, b.decode);
      if (d.function >= 0 && d.score > best.score) {
        best.rejection = Rejection::kOtherFamily;
        break;
      }
    }
  }
  lap(Stage::kDecode);
  diag.score = best.score;
  diag.margin = best.margin_bits;
  if (best.rejection != Rejection::kNone) return finish(best.rejection);

  // The pose: H_L^T is the inverse of the pull-back; the decoded quarter turns fix the rotation
  // about the normal (the marker image turned q times clockwise is what the points show, so the
  // tag frame is the estimated one turned by -q quarter turns about x).
  const Eigen::Matrix3d r_se = fit.pose.R.transpose();
  const Eigen::Vector3d center = -r_se * fit.pose.p + best_shift * outline.unseen_axis;
  const Eigen::Matrix3d r_st =
      r_se * Eigen::AngleAxisd(-best.quarter_turns * std::numbers::pi / 2, Eigen::Vector3d::UnitX())
                 .toRotationMatrix();
  const auto& fam = dicts_[static_cast<size_t>(best_family)].family();
  Detection det;
  det.family_index = best_family;
  det.family = fam.name;
  det.id = best.code_index;
  det.size_m = t;
  det.position = center;
  det.orientation = Eigen::Quaterniond(r_st).normalized();
  if (det.orientation.w() < 0) det.orientation.coeffs() *= -1.0;
  const double h = static_cast<double>(fam.width_at_border) / fam.total_width * t / 2;
  const std::array<Eigen::Vector2d, 4> yz = {Eigen::Vector2d(-h, -h), Eigen::Vector2d(h, -h),
                                             Eigen::Vector2d(h, h), Eigen::Vector2d(-h, h)};
  for (size_t k = 0; k < 4; ++k)
    det.corners[k] = center + r_st * Eigen::Vector3d(0.0, yz[k].x(), yz[k].y());
  det.score = best.score;
  det.margin = best.margin_bits;
  det.points = static_cast<int>(b.points.size());
  det.fit_cost = fit.cost;
  if (opt_.keep_tag_points) {
    det.first_point = static_cast<int>(out.tag_points.size());
    out.tag_points.insert(out.tag_points.end(), b.points.begin(), b.points.end());
  }
  out.detections.push_back(det);
  finish(Rejection::kNone);
}

}  // namespace lidartag::detector
