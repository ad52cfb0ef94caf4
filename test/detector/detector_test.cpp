// End to end on synthetic scans: the whole pipeline, its outputs and its accounting.
#include "lidartag/detector/detector.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <string>

#include "count_allocations.hpp"
#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

using test::angle_deg;
using test::facing_sensor;

struct Case {
  double distance;
  double roll_deg;  // 45: diamond, 0: square
  double yaw_deg;
  int id;
};

class DetectorScenes : public ::testing::TestWithParam<Case> {};

TEST_P(DetectorScenes, FindsTheTagWithItsIdPoseAndCorners) {
  const Case c = GetParam();
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.id = c.id;
  tag.center = Eigen::Vector3d(c.distance * std::cos(0.3), c.distance * std::sin(0.3), 0.1);
  tag.rotation = facing_sensor(tag.center, c.roll_deg, c.yaw_deg);
  scene.tags.push_back(tag);
  scene.wall_x = c.distance + 4.0;
  scene.range_noise_m = 0.005;
  Scan scan;
  test::render_scene(scene, test::vlp32c(), scan);

  // A square mount's place along the rings is searched; by default one rotation of it needs a
  // larger margin (decode.min_margin_bits_searched, docs/tracking.md "Square mounts"): here it is
  // decoded with a diamond's margin, the pose and corners being what is tested.
  DetectorOptions options;
  if (c.roll_deg == 0.0) options.decode.min_margin_bits_searched = options.decode.min_margin_bits;
  Detector det(options);
  ScanResult res;
  det.detect(scan, res);
  ASSERT_EQ(res.detections.size(), 1u)
      << "features " << res.features << " clusters " << res.clusters;
  const Detection& d = res.detections[0];
  EXPECT_EQ(d.id, c.id);
  EXPECT_EQ(d.family, "tag16h5");
  EXPECT_DOUBLE_EQ(d.size_m, 1.2);
  EXPECT_LT((d.position - tag.center).norm(), 0.03);
  EXPECT_LT(angle_deg(d.orientation.toRotationMatrix(), tag.rotation), 1.5);
  const double h = 0.75 * 1.2 / 2;
  const std::array<Eigen::Vector2d, 4> yz = {Eigen::Vector2d(-h, -h), Eigen::Vector2d(h, -h),
                                             Eigen::Vector2d(h, h), Eigen::Vector2d(-h, h)};
  for (size_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d truth =
        tag.center + tag.rotation * Eigen::Vector3d(0, yz[k].x(), yz[k].y());
    EXPECT_LT((d.corners[k] - truth).norm(), 0.04) << "corner " << k;
  }
  EXPECT_GT(d.score, 0.5);
  EXPECT_GE(d.margin, 1.0);
  EXPECT_GT(d.points, 100);
  EXPECT_GE(d.orientation.w(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Placements, DetectorScenes,
                         ::testing::Values(Case{4, 45, 0, 0}, Case{8, 45, 0, 7},
                                           Case{8, 45, 45, 12}, Case{12, 45, 0, 29},
                                           Case{6, 0, 0, 3}, Case{6, 30, 20, 5},
                                           Case{5, 135, 0, 9}));

TEST(Detector, TwoSizesAndTwoFamiliesInOneScan) {
  const auto& f16 = tags::builtin_family("tag16h5");
  const auto& f25 = tags::builtin_family("tag25h9");
  test::SyntheticScene scene;
  test::SyntheticTag a;
  a.family = &f16;
  a.id = 4;
  a.size = 1.2;
  a.center = Eigen::Vector3d(6, 2.5, 0);
  a.rotation = facing_sensor(a.center, 45);
  test::SyntheticTag b;
  b.family = &f25;
  b.id = 17;
  b.size = 0.8;
  b.center = Eigen::Vector3d(4, -2.5, -0.2);
  b.rotation = facing_sensor(b.center, 45);
  scene.tags = {a, b};
  Scan scan;
  test::render_scene(scene, test::vlp32c(), scan);
  DetectorOptions opt;
  opt.tag_sizes_m = {0.8, 1.2};
  opt.families = {"tag16h5", "tag25h9"};
  Detector det(opt);
  ScanResult res;
  det.detect(scan, res);
  std::string why;
  for (const auto& c : res.diagnostics)
    if (c.points > 50)
      why += std::string(rejection_name(c.rejection)) + " (score " + std::to_string(c.score) +
             ", margin " + std::to_string(c.margin) + ", side " + std::to_string(c.side_m) + ") ";
  ASSERT_EQ(res.detections.size(), 2u) << why;
  for (const auto& d : res.detections) {
    if (d.family == "tag16h5") {
      EXPECT_EQ(d.id, 4);
      EXPECT_DOUBLE_EQ(d.size_m, 1.2);
      EXPECT_LT((d.position - a.center).norm(), 0.03);
    } else {
      EXPECT_EQ(d.family, "tag25h9");
      EXPECT_EQ(d.id, 17);
      EXPECT_DOUBLE_EQ(d.size_m, 0.8);
      EXPECT_LT((d.position - b.center).norm(), 0.03);
    }
  }
}

// Two tags of different sizes and families (one a diamond, one turned 20 degrees), a box beside.
struct TwoTags {
  test::SyntheticTag a, b;
  Scan scan;
  DetectorOptions options;
  TwoTags() {
    a.family = &tags::builtin_family("tag16h5");
    a.id = 4;
    a.size = 1.2;
    a.center = Eigen::Vector3d(6, 2.5, 0);
    a.rotation = facing_sensor(a.center, 45);
    b.family = &tags::builtin_family("tag25h9");
    b.id = 17;
    b.size = 0.8;
    b.center = Eigen::Vector3d(4, -2.5, -0.2);
    b.rotation = facing_sensor(b.center, 20, 15);
    test::SyntheticScene scene;
    scene.tags = {a, b};
    scene.boxes = {{Eigen::Vector3d(3, 3, -1.5), Eigen::Vector3d(4, 4, 0.5)}};
    scene.range_noise_m = 0.005;
    test::render_scene(scene, test::vlp32c(), scan);
    options.tag_sizes_m = {0.8, 1.2};
    options.families = {"tag16h5", "tag25h9"};
  }
};

// One rotation through a Detector built with `options`.
ScanResult detect_once(const Scan& scan, const DetectorOptions& options) {
  Detector det(options);
  ScanResult res;
  det.detect(scan, res);
  return res;
}

TEST(Detector, TagPointsOnlyWhenAskedFor) {
  const TwoTags s;
  Detector det(s.options);
  ScanResult res;
  det.detect(s.scan, res);
  ASSERT_EQ(res.detections.size(), 2u);
  EXPECT_TRUE(res.tag_points.empty());
  for (const auto& d : res.detections) {
    EXPECT_EQ(d.first_point, -1);
    EXPECT_GT(d.points, 50);
    EXPECT_TRUE(res.points_of(d).empty());
  }
}

TEST(Detector, TagPointsAreEachDetectionsClusterOnItsPlaneInsideItsSquare) {
  const TwoTags s;
  DetectorOptions with = s.options;
  with.keep_tag_points = true;
  Detector plain(s.options), keeping(with);
  ScanResult without_points, res;
  plain.detect(s.scan, without_points);
  keeping.detect(s.scan, res);
  ASSERT_EQ(res.detections.size(), 2u);
  ASSERT_EQ(without_points.detections.size(), 2u);
  size_t next = 0;
  for (size_t i = 0; i < res.detections.size(); ++i) {
    const Detection& d = res.detections[i];
    SCOPED_TRACE(std::string(d.family) + ":" + std::to_string(d.id));
    // Keeping the points changes nothing else.
    EXPECT_EQ(d.position, without_points.detections[i].position);
    EXPECT_EQ(d.points, without_points.detections[i].points);
    // One detection after the other, Detection::points of each.
    EXPECT_EQ(d.first_point, static_cast<int>(next));
    const auto points = res.points_of(d);
    ASSERT_EQ(points.size(), static_cast<size_t>(d.points));
    next += points.size();
    const test::SyntheticTag& truth = d.family == "tag16h5" ? s.a : s.b;
    ASSERT_EQ(d.id, truth.id);
    // In the detected tag's frame: on its plane (x) and inside its square (y, z), with the range
    // noise and a beam's footprint of slack.
    const Eigen::Matrix3d r = d.orientation.toRotationMatrix();
    int black = 0, white = 0;
    for (const ClusterPoint& p : points) {
      const Eigen::Vector3d q = r.transpose() * (Eigen::Vector3d(p.x, p.y, p.z) - d.position);
      EXPECT_LT(std::abs(q.x()), 0.03) << q.transpose();
      EXPECT_LE(std::abs(q.y()), d.size_m / 2 + 0.03) << q.transpose();
      EXPECT_LE(std::abs(q.z()), d.size_m / 2 + 0.03) << q.transpose();
      // Each is a return of the scan, with its ring and intensity.
      ASSERT_GE(p.ring, 0);
      ASSERT_LT(p.ring, s.scan.rings);
      ASSERT_GE(p.col, 0);
      ASSERT_LT(p.col, s.scan.columns);
      const size_t cell = s.scan.at(0, p.ring, p.col);
      EXPECT_EQ(p.x, s.scan.x[cell]);
      EXPECT_EQ(p.y, s.scan.y[cell]);
      EXPECT_EQ(p.z, s.scan.z[cell]);
      EXPECT_EQ(p.intensity, static_cast<float>(s.scan.intensity[cell]));
      black += p.intensity < 100 ? 1 : 0;
      white += p.intensity > 150 ? 1 : 0;
    }
    EXPECT_GT(black, 10);  // both colours of the marker: the points the code was read from
    EXPECT_GT(white, 10);
  }
  EXPECT_EQ(res.tag_points.size(), next);
  // The next rotation starts afresh.
  ScanResult again = res;
  keeping.detect(Scan{}, again);
  EXPECT_TRUE(again.tag_points.empty());
}

TEST(Detector, TagPointsAddNoAllocationOnceGrown) {
  const TwoTags s;
  DetectorOptions with = s.options;
  with.keep_tag_points = true;
  Detector det(with);
  ScanResult res;
  det.detect(s.scan, res);  // grows the buffers and the result
  ASSERT_EQ(res.detections.size(), 2u);
  const ClusterPoint* storage = res.tag_points.data();
  const long before = testing::heap_allocations();
  det.detect(s.scan, res);
  const long during = testing::heap_allocations() - before;
  EXPECT_EQ(during, 0);
  ASSERT_EQ(res.detections.size(), 2u);
  EXPECT_EQ(res.tag_points.data(), storage);
  EXPECT_EQ(res.points_of(res.detections[1]).size(), static_cast<size_t>(res.detections[1].points));
}

// Every cluster that reached decoding is a candidate: a detection's, with its index, and one
// rejected at the decode stage, with its pose and the evidence of every code (for a tracker).
TEST(Detector, CandidatesCarryThePoseAndTheEvidenceOfEveryCode) {
  const TwoTags s;
  Detector det(s.options);
  ScanResult res;
  det.detect(s.scan, res);
  ASSERT_EQ(res.detections.size(), 2u);
  ASSERT_GE(res.candidates.size(), 2u);
  int accepted = 0;
  for (const Candidate& k : res.candidates) {
    if (k.rejection != Rejection::kNone) continue;
    ++accepted;
    ASSERT_GE(k.detection, 0);
    const Detection& d = res.detections[static_cast<size_t>(k.detection)];
    EXPECT_EQ(k.family_index, d.family_index);
    EXPECT_EQ(k.id, d.id);
    EXPECT_EQ(k.position, d.position);
    EXPECT_EQ(k.orientation.coeffs(), d.orientation.coeffs());
    EXPECT_EQ(k.score, d.score);
    EXPECT_EQ(k.margin, d.margin);
    EXPECT_EQ(k.points, d.points);
    // The decoded frame is the undecoded one turned by the quarter turns about its normal.
    const Eigen::Matrix3d u = k.undecoded_orientation.toRotationMatrix();
    const Eigen::Matrix3d r = k.orientation.toRotationMatrix();
    EXPECT_LT((u.col(0) - r.col(0)).norm(), 1e-9);
    // One evidence block per configured family; the detection's family's best function is its
    // code at its quarter turns, scored as the detection.
    const auto evidence = res.evidence_of(k);
    ASSERT_EQ(evidence.size(), s.options.families.size());
    for (size_t f = 0; f < evidence.size(); ++f) {
      EXPECT_EQ(evidence[f].family_index, static_cast<int>(f));
      const auto scores = res.scores_of(evidence[f]);
      ASSERT_EQ(scores.size(), static_cast<size_t>(det.dictionaries()[f].functions()));
      EXPECT_GT(evidence[f].cells_per_score, 0.0f);
      if (static_cast<int>(f) != k.family_index) continue;
      const auto best = std::max_element(scores.begin(), scores.end()) - scores.begin();
      EXPECT_EQ(best, 4 * k.id + k.quarter_turns);
      EXPECT_FLOAT_EQ(scores[static_cast<size_t>(best)], static_cast<float>(k.score));
    }
    // The decoded grid of the detection's family.
    EXPECT_EQ(k.grid_width, det.dictionaries()[static_cast<size_t>(k.family_index)].width());
    EXPECT_EQ(res.cells_of(k).size(), static_cast<size_t>(k.grid_width * k.grid_width));
    EXPECT_EQ(res.votes_of(k).size(), res.cells_of(k).size());
    const auto counts = res.vote_counts_of(k);
    ASSERT_EQ(counts.size(), res.cells_of(k).size());
    EXPECT_GT(std::accumulate(counts.begin(), counts.end(), 0.0f), 50.0f);
    // The points behind the votes, in the candidate's frame: voted again with the same layout
    // and inset, they give its votes, cell for cell (what a tracker re-votes in its own frame).
    const auto vp = res.vote_points_of(k);
    ASSERT_EQ(vp.size(), static_cast<size_t>(k.vote_point_count));
    const int w = k.grid_width;
    const double inset = s.options.decode.vote_inset_cells;
    std::vector<float> again(counts.size(), 0.0f), again_n(counts.size(), 0.0f);
    for (const VotePoint& p : vp) {
      const double fc = (p.y / k.size_m + 0.5) * w, fr = (0.5 - p.z / k.size_m) * w;
      if (!(fc >= 0.0 && fc < w && fr >= 0.0 && fr < w)) continue;
      const double uc = fc - std::floor(fc), ur = fr - std::floor(fr);
      if (uc < inset || uc > 1.0 - inset || ur < inset || ur > 1.0 - inset) continue;
      const auto i = static_cast<size_t>(static_cast<int>(fr) * w + static_cast<int>(fc));
      again[i] += std::clamp(2.0f * p.label - 1.0f, -1.0f, 1.0f);
      again_n[i] += 1.0f;
    }
    for (size_t i = 0; i < again.size(); ++i) {
      EXPECT_EQ(again_n[i], counts[i]) << "cell " << i;
      EXPECT_NEAR(again[i], res.votes_of(k)[i], 1e-3) << "cell " << i;
    }
    EXPECT_GE(k.other_family_score, 0.0);  // decoys are on by default
    EXPECT_LT(k.other_family_score, k.score);
    // Linked to its cluster's diagnostic.
    ASSERT_GE(k.cluster, 0);
    EXPECT_EQ(res.diagnostics[static_cast<size_t>(k.cluster)].candidate,
              static_cast<int>(&k - res.candidates.data()));
  }
  EXPECT_EQ(accepted, 2);

  // With an impossible margin gate both tags are rejected as ambiguous, and stay candidates with
  // the same pose and evidence.
  DetectorOptions strict = s.options;
  strict.decode.min_margin_bits = 1e6;
  Detector strict_det(strict);
  ScanResult rej;
  strict_det.detect(s.scan, rej);
  EXPECT_TRUE(rej.detections.empty());
  ASSERT_EQ(rej.candidates.size(), res.candidates.size());
  for (size_t i = 0; i < res.candidates.size(); ++i) {
    const Candidate &a = res.candidates[i], &b = rej.candidates[i];
    if (a.rejection != Rejection::kNone) continue;
    EXPECT_EQ(b.rejection, Rejection::kAmbiguous);
    EXPECT_EQ(b.detection, -1);
    EXPECT_EQ(b.other_family_score, a.other_family_score);
    EXPECT_EQ(b.position, a.position);
    EXPECT_EQ(b.id, a.id);
    const auto ea = res.evidence_of(a), eb = rej.evidence_of(b);
    ASSERT_EQ(ea.size(), eb.size());
    for (size_t f = 0; f < ea.size(); ++f) {
      const auto sa = res.scores_of(ea[f]), sb = rej.scores_of(eb[f]);
      EXPECT_TRUE(std::equal(sa.begin(), sa.end(), sb.begin(), sb.end()));
    }
  }
}

// A cluster of more than pose.polish_max_points points is decoded on the subsample's fit and
// polished on every point only once it scores as a tag: the detections are those of the polish
// on every point before decoding (pose.polish_max_points 0), to a fraction of a millimetre.
TEST(Detector, ALargeClusterIsPolishedOnEveryPointOnceItScoresAsATag) {
  const TwoTags s;
  DetectorOptions every = s.options, few = s.options;
  every.pose.polish_max_points = 0;
  few.pose.polish_max_points = 100;  // below both tags' point counts
  const ScanResult a = detect_once(s.scan, every), b = detect_once(s.scan, few);
  ASSERT_EQ(a.detections.size(), 2u);
  ASSERT_EQ(b.detections.size(), a.detections.size());
  for (size_t i = 0; i < a.detections.size(); ++i) {
    const Detection &x = a.detections[i], &y = b.detections[i];
    EXPECT_GT(y.points, 100);
    EXPECT_EQ(y.id, x.id);
    EXPECT_EQ(y.family_index, x.family_index);
    EXPECT_LT((y.position - x.position).norm(), 5e-4) << i;
    EXPECT_LT(y.orientation.angularDistance(x.orientation), 0.1 * std::numbers::pi / 180.0) << i;
  }
}

// Eq. (3)'s bound above both tags' points, the tracks' (track_returns_per_cell) below: the same
// candidates, track-only, their clusters counted as validation/too_few_points; the tracks' bound
// at eq. (3)'s: those clusters stop at validation.
TEST(Detector, ClustersBelowThePointBoundButAboveTheTracksAreTrackOnlyCandidates) {
  const TwoTags s;
  const ScanResult res = detect_once(s.scan, s.options);
  ASSERT_EQ(res.detections.size(), 2u);
  int most = 0;
  for (const Candidate& k : res.candidates)
    if (k.detection >= 0)
      most = std::max(most, res.diagnostics[static_cast<size_t>(k.cluster)].points);
  DetectorOptions o = s.options;
  o.validation.min_returns_per_cell = static_cast<float>(most + 1) / 64.0f;  // tag16h5: 8 x 8
  o.validation.track_returns_per_cell = 0.5f;
  const ScanResult weak = detect_once(s.scan, o);
  EXPECT_TRUE(weak.detections.empty());
  int track_only = 0;
  for (const Candidate& k : weak.candidates) {
    if (!k.track_only || k.rejection != Rejection::kNone) continue;
    ++track_only;
    EXPECT_EQ(weak.diagnostics[static_cast<size_t>(k.cluster)].rejection, Rejection::kTooFewPoints);
    EXPECT_TRUE(std::any_of(res.detections.begin(), res.detections.end(), [&](const Detection& x) {
      return x.id == k.id && x.position == k.position;
    }));
  }
  EXPECT_EQ(track_only, 2);
  o.validation.track_returns_per_cell = o.validation.min_returns_per_cell;
  const ScanResult off = detect_once(s.scan, o);
  for (const Candidate& k : off.candidates) EXPECT_FALSE(k.track_only);
  EXPECT_EQ(off.candidates.size() + 2, weak.candidates.size());
}

TEST(Detector, ClustersBelowTheBoundaryBoundButAboveTheTracksAreTrackOnlyCandidates) {
  const TwoTags s;
  const ScanResult res = detect_once(s.scan, s.options);
  ASSERT_EQ(res.detections.size(), 2u);
  int fewest = 1 << 30, most = 0;  // boundary points of the two tags' clusters
  for (const Candidate& k : res.candidates) {
    EXPECT_FALSE(k.track_only);
    if (k.detection < 0) continue;
    const int n = res.diagnostics[static_cast<size_t>(k.cluster)].boundary_points;
    fewest = std::min(fewest, n);
    most = std::max(most, n);
  }
  // eq. (6)'s bound (scale x 12, tag16h5's 2 (d + 2), the smaller of the two families) above
  // both tags, the tracks' below both: the same candidates, none of them a detection, the two
  // tags' track-only, and their clusters counted as validation/few_boundary_points.
  DetectorOptions o = s.options;
  o.validation.boundary_scale = (static_cast<float>(most) + 0.5f) / 12.0f;
  o.validation.track_boundary_scale = (static_cast<float>(fewest) - 0.5f) / 12.0f;
  const ScanResult weak = detect_once(s.scan, o);
  EXPECT_TRUE(weak.detections.empty());
  std::vector<const Candidate*> tags;
  for (const Candidate& k : weak.candidates)
    if (k.track_only && k.rejection == Rejection::kNone) tags.push_back(&k);
  ASSERT_EQ(tags.size(), 2u);
  for (const Candidate* k : tags) {
    EXPECT_EQ(k->detection, -1);
    const ClusterDiagnostic& d = weak.diagnostics[static_cast<size_t>(k->cluster)];
    EXPECT_EQ(d.rejection, Rejection::kFewBoundaryPoints);
    EXPECT_TRUE(std::any_of(res.detections.begin(), res.detections.end(), [&](const Detection& x) {
      return x.id == k->id && x.family_index == k->family_index && x.position == k->position;
    }));
  }
  EXPECT_GE(weak.rejected[static_cast<size_t>(Rejection::kFewBoundaryPoints)],
            res.rejected[static_cast<size_t>(Rejection::kFewBoundaryPoints)] + 2);
  // The tracks' bound at the detections' bound: those clusters stop at validation.
  o.validation.track_boundary_scale = o.validation.boundary_scale;
  const ScanResult off = detect_once(s.scan, o);
  EXPECT_TRUE(off.detections.empty());
  for (const Candidate& k : off.candidates) EXPECT_FALSE(k.track_only);
  EXPECT_EQ(off.candidates.size() + 2, weak.candidates.size());
}

TEST(Detector, TooFewReturnsPerCellForOneRotationIsSparseNotADetection) {
  const TwoTags s;
  Detector det(s.options);
  ScanResult res;
  det.detect(s.scan, res);
  ASSERT_EQ(res.detections.size(), 2u);
  double fewest = 1e9, most = 0.0;  // returns per cell of the two tags
  for (const Candidate& k : res.candidates) {
    if (k.detection < 0) continue;
    const int w = det.dictionaries()[static_cast<size_t>(k.family_index)].width();
    fewest = std::min(fewest, static_cast<double>(k.points) / (w * w));
    most = std::max(most, static_cast<double>(k.points) / (w * w));
  }
  // Above both: two candidates rejected as sparse, with the detections' IDs and poses.
  DetectorOptions o = s.options;
  o.decode.min_returns_per_cell = most + 0.01;
  const ScanResult sparse = detect_once(s.scan, o);
  EXPECT_TRUE(sparse.detections.empty());
  EXPECT_EQ(sparse.rejected[static_cast<size_t>(Rejection::kSparse)], 2u);
  int matched = 0;
  for (const Candidate& k : sparse.candidates) {
    if (k.rejection != Rejection::kSparse) continue;
    EXPECT_EQ(k.detection, -1);
    matched += std::any_of(res.detections.begin(), res.detections.end(),
                           [&](const Detection& x) {
                             return x.id == k.id && x.family_index == k.family_index &&
                                    x.position == k.position;
                           })
                   ? 1
                   : 0;
  }
  EXPECT_EQ(matched, 2);
  // Just below the sparser one: both detected as before.
  o.decode.min_returns_per_cell = fewest - 0.01;
  const ScanResult dense = detect_once(s.scan, o);
  EXPECT_EQ(dense.detections.size(), 2u);
  EXPECT_EQ(dense.rejected[static_cast<size_t>(Rejection::kSparse)], 0u);
}

TEST(Detector, ClusterPointsOnlyWhenAskedForAsEachClusterWasLeft) {
  const TwoTags s;
  DetectorOptions with = s.options;
  with.keep_cluster_points = true;
  with.keep_tag_points = true;
  Detector plain(s.options), keeping(with);
  ScanResult without_points, res;
  plain.detect(s.scan, without_points);
  EXPECT_TRUE(without_points.cluster_points.empty());
  for (const auto& c : without_points.diagnostics) EXPECT_TRUE(without_points.points_of(c).empty());
  keeping.detect(s.scan, res);
  ASSERT_EQ(res.diagnostics.size(), without_points.diagnostics.size());
  size_t total = 0;
  for (const auto& c : res.diagnostics) {
    const auto pts = res.points_of(c);
    total += pts.size();
    if (c.rejection == Rejection::kFewFeatures || c.rejection == Rejection::kTooLarge) {
      // Never filled in: its edge features stand for its points.
      EXPECT_EQ(c.points, 0);
      EXPECT_EQ(pts.size(), static_cast<size_t>(c.features));
      for (const auto& p : pts) EXPECT_TRUE(p.edge);
      continue;
    }
    // Before the plane fit, every point of the fill-in; after it, at most that many.
    if (stage_of(c.rejection) == Stage::kValidation) {
      EXPECT_EQ(pts.size(), static_cast<size_t>(c.points));
    } else {
      EXPECT_FALSE(pts.empty()) << rejection_name(c.rejection);
      EXPECT_LE(pts.size(), static_cast<size_t>(c.points));
    }
  }
  EXPECT_EQ(total, res.cluster_points.size());
  // A detection's candidate holds the points its pose was fitted to.
  for (const auto& k : res.candidates) {
    if (k.detection < 0) continue;
    const auto a = res.points_of(k);
    const auto b = res.points_of(res.detections[static_cast<size_t>(k.detection)]);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].col, b[i].col);
  }
  // Nothing else changes, and the next rotation does not allocate.
  ASSERT_EQ(res.detections.size(), without_points.detections.size());
  for (size_t i = 0; i < res.detections.size(); ++i)
    EXPECT_EQ(res.detections[i].position, without_points.detections[i].position);
  const long before = testing::heap_allocations();
  keeping.detect(s.scan, res);
  EXPECT_EQ(testing::heap_allocations() - before, 0);
}

// Memory running out part-way is said, not hidden: the result is flagged, never a crash, and
// whatever was found before stands.
TEST(Detector, AnAllocationFailureTruncatesTheRotationAndSaysSo) {
  const TwoTags s;
  ScanResult clean;
  Detector(s.options).detect(s.scan, clean);
  ASSERT_EQ(clean.detections.size(), 2u);
  EXPECT_FALSE(clean.truncated);
  int truncated = 0;
  for (long n : {0L, 3L, 10L, 30L, 100L, 300L}) {
    Detector det(s.options);  // fresh buffers: the first rotation allocates
    ScanResult res;
    res.detections.reserve(4);
    testing::fail_allocation_after(n);
    det.detect(s.scan, res);
    testing::fail_allocation_after(-1);
    truncated += res.truncated ? 1 : 0;
    EXPECT_LE(res.detections.size(), 2u);
    if (!res.truncated) {
      EXPECT_EQ(res.detections.size(), 2u) << n;
    }
    for (const auto& d : res.detections) EXPECT_TRUE(d.position.allFinite());
    // The same detector works on the next rotation.
    det.detect(s.scan, res);
    EXPECT_FALSE(res.truncated);
    EXPECT_EQ(res.detections.size(), 2u);
  }
  EXPECT_GT(truncated, 0);
}

TEST(Detector, NothingInATaglessClutteredScene) {
  test::SyntheticScene scene;
  scene.boxes = {{Eigen::Vector3d(3, -1, -1.5), Eigen::Vector3d(3.8, -0.2, 0.3)},
                 {Eigen::Vector3d(5, 1, -1.5), Eigen::Vector3d(6.2, 2.2, 0.0)},
                 {Eigen::Vector3d(-4, -3, -1.5), Eigen::Vector3d(-3, -2, 1.0)},
                 {Eigen::Vector3d(7, -4, -1.5), Eigen::Vector3d(7.5, -2.8, -0.3)}};
  scene.range_noise_m = 0.01;
  Scan scan;
  test::render_scene(scene, test::vlp32c(), scan);
  Detector det(DetectorOptions{});
  ScanResult res;
  det.detect(scan, res);
  EXPECT_TRUE(res.detections.empty());
  EXPECT_GT(res.clusters, 0);
}

TEST(Detector, EveryClusterIsAccountedForAndTimed) {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.center = Eigen::Vector3d(5, 0, 0);
  tag.rotation = facing_sensor(tag.center, 45);
  scene.tags.push_back(tag);
  scene.boxes = {{Eigen::Vector3d(3, 3, -1.5), Eigen::Vector3d(4, 4, 0.5)}};
  Scan scan;
  test::render_scene(scene, test::vlp32c(), scan);
  Detector det(DetectorOptions{});
  ScanResult res;
  det.detect(scan, res);
  uint32_t rejected = 0;
  for (auto n : res.rejected) rejected += n;
  EXPECT_EQ(rejected + res.detections.size(), static_cast<size_t>(res.clusters));
  EXPECT_EQ(res.diagnostics.size(), static_cast<size_t>(res.clusters));
  uint32_t by_stage = 0;
  for (int s = 0; s < kStageCount; ++s) by_stage += res.rejected_at(static_cast<Stage>(s));
  EXPECT_EQ(by_stage, rejected);
  EXPECT_GT(res.timing_ms[static_cast<size_t>(Stage::kFeatures)], 0.0);
  EXPECT_GT(res.timing_ms[static_cast<size_t>(Stage::kDecode)], 0.0);
  // A second rotation through the same detector gives the same answer (buffers are reused).
  ScanResult again;
  det.detect(scan, again);
  ASSERT_EQ(again.detections.size(), res.detections.size());
  EXPECT_EQ(again.detections[0].position, res.detections[0].position);
}

TEST(Detector, BadOptionsThrowATypedError) {
  DetectorOptions o;
  o.tag_sizes_m.clear();
  EXPECT_THROW(Detector{o}, OptionsError);
  o = DetectorOptions{};
  o.families = {"tag99h1"};
  EXPECT_THROW(Detector{o}, OptionsError);
  o = DetectorOptions{};
  o.plane.max_outlier_ratio = 1.5f;
  EXPECT_THROW(Detector{o}, OptionsError);
  o = DetectorOptions{};
  o.features.ell = 0;
  EXPECT_THROW(Detector{o}, OptionsError);
}

TEST(Detector, EmptyScanGivesNothing) {
  Scan scan;
  Detector det(DetectorOptions{});
  ScanResult res;
  det.detect(scan, res);
  EXPECT_TRUE(res.detections.empty());
  EXPECT_EQ(res.clusters, 0);
}

// ---- Hostile scans: whatever the cells hold, no crash, no non-finite output, nothing invented.

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A scan with one tag16h5 (id 3) 5 m ahead, on a wall and a floor.
Scan tag_scan() {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.id = 3;
  tag.center = Eigen::Vector3d(5, 0.5, 0);
  tag.rotation = facing_sensor(tag.center, 45);
  scene.tags.push_back(tag);
  scene.wall_x = 9.0;
  Scan scan;
  test::render_scene(scene, test::vlp32c(), scan);
  return scan;
}

// Every number a detection carries is finite, and its ID is the scene's.
void expect_sane(const ScanResult& res, const std::string& what, int true_id) {
  EXPECT_GE(res.features, 0) << what;
  EXPECT_GE(res.clusters, 0) << what;
  for (double ms : res.timing_ms) EXPECT_TRUE(std::isfinite(ms) && ms >= 0.0) << what;
  for (const Detection& d : res.detections) {
    bool finite = d.position.allFinite() && d.orientation.coeffs().allFinite() &&
                  std::isfinite(d.score) && std::isfinite(d.margin) && std::isfinite(d.fit_cost);
    for (const auto& c : d.corners) finite = finite && c.allFinite();
    EXPECT_TRUE(finite) << what << ": a detection with a non-finite value";
    EXPECT_EQ(d.id, true_id) << what;
    EXPECT_EQ(d.family, "tag16h5") << what;
  }
}

// Cells of the scan's filled columns, return 0.
template <class F>
void for_each_cell(Scan& s, F&& f) {
  for (int ring = 0; ring < s.rings; ++ring)
    for (int c = 0; c < s.columns; ++c) f(s.at(0, ring, c), ring, c);
}

// One cell of `from` written over cell `to` of `into` (position, range, intensity, return).
void copy_cell(const Scan& from, size_t at, Scan& into, size_t to) {
  into.x[to] = from.x[at];
  into.y[to] = from.y[at];
  into.z[to] = from.z[at];
  into.range[to] = from.range[at];
  into.intensity[to] = from.intensity[at];
  into.return_type[to] = from.return_type[at];
}

TEST(DetectorHostileScans, NonFiniteAndHugeValuesInATagScanAreNeverPassedOn) {
  const Scan clean = tag_scan();
  Detector det(DetectorOptions{});
  ScanResult res;
  det.detect(clean, res);
  ASSERT_EQ(res.detections.size(), 1u);
  ASSERT_EQ(res.detections[0].id, 3);

  struct Damage {
    std::string name;
    std::function<void(Scan&, size_t)> apply;
  };
  const std::vector<Damage> damages = {
      {"NaN x", [](Scan& s, size_t i) { s.x[i] = kNaN; }},
      {"NaN xyz", [](Scan& s, size_t i) { s.x[i] = s.y[i] = s.z[i] = kNaN; }},
      {"Inf z", [](Scan& s, size_t i) { s.z[i] = kInf; }},
      {"-Inf y", [](Scan& s, size_t i) { s.y[i] = -kInf; }},
      {"huge xyz", [](Scan& s, size_t i) { s.x[i] = s.y[i] = s.z[i] = 1e30f; }},
      {"NaN range", [](Scan& s, size_t i) { s.range[i] = kNaN; }},
      {"Inf range", [](Scan& s, size_t i) { s.range[i] = kInf; }},
      {"negative range", [](Scan& s, size_t i) { s.range[i] = -5.0f; }},
      {"huge range", [](Scan& s, size_t i) { s.range[i] = 3e38f; }},
      {"NaN azimuth and time", [](Scan& s, size_t i) { s.azimuth_deg[i] = s.time_s[i] = kNaN; }},
      {"extreme intensity", [](Scan& s, size_t i) { s.intensity[i] = i % 2 ? 255 : 0; }},
  };
  std::mt19937 rng(5);
  for (const Damage& dmg : damages) {
    for (const int every : {1, 3, 50}) {  // every cell, a third, one in fifty
      Scan s = clean;
      for_each_cell(s, [&](size_t i, int, int) {
        if (rng() % static_cast<unsigned>(every) == 0) dmg.apply(s, i);
      });
      const std::string what = dmg.name + " in 1/" + std::to_string(every) + " of the cells";
      det.detect(s, res);
      expect_sane(res, what, 3);
      if (every == 1 && dmg.name != "extreme intensity" && dmg.name != "NaN azimuth and time") {
        EXPECT_TRUE(res.detections.empty()) << what;
      }
    }
  }
  // NaN column azimuths (the horizontal resolution and the wrap test read them).
  Scan s = clean;
  for (auto& a : s.column_azimuth_deg) a = kNaN;
  for (auto& t : s.column_time_s) t = std::numeric_limits<double>::quiet_NaN();
  det.detect(s, res);
  expect_sane(res, "NaN column azimuths", 3);
  // The same detector still finds the tag in the clean scan afterwards.
  det.detect(clean, res);
  ASSERT_EQ(res.detections.size(), 1u);
  EXPECT_EQ(res.detections[0].id, 3);
}

TEST(DetectorHostileScans, DegenerateScansGiveNoDetection) {
  Detector det(DetectorOptions{});
  ScanResult res;
  const Scan clean = tag_scan();
  struct Shape {
    std::string name;
    std::function<Scan()> make;
  };
  const std::vector<Shape> shapes = {
      {"all zero",
       [] {
         Scan s;
         s.reserve(32, 1, 1800);
         s.columns = 1800;
         return s;
       }},
      {"every point identical",
       [&] {
         Scan s = clean;
         for_each_cell(s, [&](size_t i, int, int) {
           s.x[i] = 5.0f;
           s.y[i] = 0.5f;
           s.z[i] = 0.0f;
           s.range[i] = std::sqrt(25.25f);
           s.intensity[i] = static_cast<uint8_t>(i % 2 ? 220 : 20);
           s.return_type[i] = ReturnType::kStrongest;
         });
         return s;
       }},
      {"every range identical, points scattered",
       [&] {
         Scan s = clean;
         for_each_cell(s, [&](size_t i, int, int) { s.range[i] = 5.0f; });
         return s;
       }},
      {"one column",
       [&] {
         Scan s = clean;
         s.columns = 1;
         return s;
       }},
      {"two columns",
       [&] {
         Scan s = clean;
         s.columns = 2;
         return s;
       }},
      {"a single ring (through the tag)",
       [&] {
         Scan s;
         s.reserve(1, 1, clean.column_capacity);
         s.columns = clean.columns;
         s.column_azimuth_deg = clean.column_azimuth_deg;
         for (int c = 0; c < clean.columns; ++c) {
           copy_cell(clean, clean.at(0, 16, c), s, s.at(0, 0, c));
         }
         return s;
       }},
      {"every ring a copy of one ring",
       [&] {
         Scan s = clean;
         for_each_cell(s,
                       [&](size_t i, int, int c) { copy_cell(clean, clean.at(0, 16, c), s, i); });
         return s;
       }},
      {"uniform random garbage",
       [&] {
         Scan s = clean;
         std::mt19937 rng(9);
         std::uniform_real_distribution<float> u(-50.0f, 50.0f);
         for_each_cell(s, [&](size_t i, int, int) {
           s.x[i] = u(rng);
           s.y[i] = u(rng);
           s.z[i] = u(rng);
           s.range[i] = std::fabs(u(rng));
           s.intensity[i] = static_cast<uint8_t>(rng());
         });
         return s;
       }},
      {"all NaN",
       [&] {
         Scan s = clean;
         for_each_cell(s,
                       [&](size_t i, int, int) { s.x[i] = s.y[i] = s.z[i] = s.range[i] = kNaN; });
         return s;
       }},
      {"a zero-sized tag: every point of the tag at its centre",
       [&] {
         Scan s = clean;
         for_each_cell(s, [&](size_t i, int, int) {
           if (std::fabs(s.x[i] - 5.0f) < 0.5f && std::fabs(s.y[i] - 0.5f) < 0.8f) {
             s.x[i] = 5.0f;
             s.y[i] = 0.5f;
             s.z[i] = 0.0f;
           }
         });
         return s;
       }},
  };
  for (const Shape& shape : shapes) {
    const Scan s = shape.make();
    det.detect(s, res);
    expect_sane(res, shape.name, 3);
    EXPECT_TRUE(res.detections.empty()) << shape.name;
  }
}

TEST(DetectorHostileScans, DuplicatedPointsFindTheTagOrNothing) {
  // Every column twice over (a batcher bug or a replayed packet): the same points, half the
  // azimuth step.
  const Scan clean = tag_scan();
  Scan s;
  s.reserve(clean.rings, 1, 2 * clean.columns);
  s.columns = 2 * clean.columns;
  for (int c = 0; c < s.columns; ++c) {
    s.column_azimuth_deg[static_cast<size_t>(c)] =
        clean.column_azimuth_deg[static_cast<size_t>(c / 2)];
    for (int ring = 0; ring < s.rings; ++ring) {
      const size_t from = clean.at(0, ring, c / 2), to = s.at(0, ring, c);
      s.x[to] = clean.x[from];
      s.y[to] = clean.y[from];
      s.z[to] = clean.z[from];
      s.range[to] = clean.range[from];
      s.intensity[to] = clean.intensity[from];
      s.return_type[to] = clean.return_type[from];
    }
  }
  Detector det(DetectorOptions{});
  ScanResult res;
  det.detect(s, res);
  expect_sane(res, "duplicated columns", 3);
}

TEST(DetectorHostileScans, ScanWhoseSizesDisagreeWithItsStorageGivesNothing) {
  // A Scan is a plain struct: a caller can get its sizes wrong. Reading past the storage would be
  // a crash or garbage; the detector refuses the scan instead.
  Detector det(DetectorOptions{});
  ScanResult res;
  Scan s = tag_scan();
  s.columns = s.column_capacity + 100;
  det.detect(s, res);
  EXPECT_TRUE(res.detections.empty());
  EXPECT_TRUE(res.refused);
  Scan t = tag_scan();
  t.rings = 64;  // storage for 32
  det.detect(t, res);
  EXPECT_TRUE(res.detections.empty());
  Scan u;
  u.rings = 32;
  u.columns = 1800;  // no storage at all
  u.column_capacity = 1800;
  det.detect(u, res);
  EXPECT_TRUE(res.detections.empty());
  Scan v = tag_scan();
  v.returns = 0;
  det.detect(v, res);
  EXPECT_TRUE(res.detections.empty());
  EXPECT_TRUE(res.refused);
  det.detect(tag_scan(), res);  // a sound scan is not
  EXPECT_FALSE(res.refused);
  EXPECT_EQ(res.detections.size(), 1u);
}

}  // namespace
}  // namespace lidartag::detector
