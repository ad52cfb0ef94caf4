// Stage 6 for one cluster: pull-back, shift search, arbitration, other-family check, evidence.
#include "lidartag/detector/decode_cluster.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

namespace lidartag::detector {
namespace {

// Noise-free points of a t x t marker in its own frame (x normal, y right, z up): `per_cell`
// points per cell and axis, the image turned `q` times clockwise, only rows with z in [z0, z1].
std::vector<ClusterPoint> marker_points(const tags::TagFamily& fam, int id, int q, double t,
                                        int per_cell, double z0 = -1, double z1 = 1) {
  const int w = fam.total_width;
  auto img = fam.render(fam.codes[static_cast<size_t>(id)]);
  for (int k = 0; k < q; ++k) {
    std::vector<uint8_t> rot(img.size());
    for (int r = 0; r < w; ++r)
      for (int c = 0; c < w; ++c)
        rot[static_cast<size_t>(c * w + (w - 1 - r))] = img[static_cast<size_t>(r * w + c)];
    img.swap(rot);
  }
  std::vector<ClusterPoint> out;
  const int n = w * per_cell;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      ClusterPoint p;
      p.y = static_cast<float>(t * ((c + 0.5) / n - 0.5));
      p.z = static_cast<float>(t * (0.5 - (r + 0.5) / n));
      if (p.z < z0 * t || p.z > z1 * t) continue;
      p.intensity = img[static_cast<size_t>((r / per_cell) * w + c / per_cell)] ? 200.0f : 30.0f;
      out.push_back(p);
    }
  return out;
}

// The tag placed in the sensor frame: x_sensor = R x_tag + c; the pull-back that undoes it.
struct Placed {
  std::vector<ClusterPoint> points;
  RigidPose pull_back;
};
Placed place(std::vector<ClusterPoint> tag, const Eigen::Matrix3d& R, const Eigen::Vector3d& c) {
  Placed out;
  for (auto& p : tag) {
    const Eigen::Vector3d s = R * Eigen::Vector3d(p.x, p.y, p.z) + c;
    p.x = static_cast<float>(s.x());
    p.y = static_cast<float>(s.y());
    p.z = static_cast<float>(s.z());
  }
  out.points = std::move(tag);
  out.pull_back.R = R.transpose();
  out.pull_back.p = -R.transpose() * c;
  return out;
}

Eigen::Matrix3d facing() {
  // The tag's normal (x) toward a sensor at the origin from (6, 1, 0), turned 20 degrees.
  return (Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

TEST(DecodeCluster, FindsTheCodeAndKeepsEachFamilysEvidence) {
  const auto& f16 = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(f16),
                                             RkhsDictionary(tags::builtin_family("tag25h9"))};
  const Placed tag = place(marker_points(f16, 7, 1, 1.2, 3), facing(), {6, 1, 0});
  ClusterDecodeWorkspace ws;
  DecodeOptions every_point;  // all 576 points decoded (the default takes every other one)
  every_point.max_points = 1000;
  const ClusterDecode d = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2,
                                         dicts, {}, every_point, ws);
  EXPECT_EQ(d.best.rejection, Rejection::kNone);
  EXPECT_EQ(d.family, 0);
  EXPECT_EQ(d.best.code_index, 7);
  EXPECT_EQ(d.best.quarter_turns, 1);
  EXPECT_EQ(d.shift, 0.0);
  EXPECT_EQ(d.other_family_score, -1.0);  // no decoys
  ASSERT_EQ(ws.families.size(), 2u);
  // The chosen family's evidence: its best entry is the decision's function and score.
  const FamilyDecode& e = ws.families[0];
  ASSERT_TRUE(e.scored);
  ASSERT_EQ(e.scores.size(), static_cast<size_t>(dicts[0].functions()));
  const auto best = std::max_element(e.scores.begin(), e.scores.end()) - e.scores.begin();
  EXPECT_EQ(best, 4 * 7 + 1);
  EXPECT_FLOAT_EQ(e.scores[static_cast<size_t>(best)], static_cast<float>(d.best.score));
  // Its runner-up over the one shift, in cells, is the margin.
  std::vector<float> sorted = e.scores;
  std::sort(sorted.rbegin(), sorted.rend());
  EXPECT_NEAR((sorted[0] - sorted[1]) * e.result.cells_per_score, d.best.margin_bits, 1e-3);
  // The grid: W x W cells, white where the marker (turned once) is white.
  ASSERT_EQ(e.cells.size(), 64u);
  const float* signs = dicts[0].signs(4 * 7 + 1);
  int agree = 0;
  for (size_t i = 0; i < 64; ++i) agree += (e.cells[i] > 0) == (signs[i] > 0) ? 1 : 0;
  EXPECT_EQ(agree, 64);
  // Cell votes: every cell holds 3 x 3 points well inside it, voting for its colour.
  ASSERT_EQ(ws.votes.size(), 64u);
  ASSERT_EQ(ws.vote_counts.size(), 64u);
  for (size_t i = 0; i < 64; ++i) {
    EXPECT_EQ(ws.vote_counts[i], 9.0f) << i;
    EXPECT_NEAR(ws.votes[i], signs[i] > 0 ? 9.0f : -9.0f, 1e-3) << i;
  }
  EXPECT_FALSE(d.shift_searched);
  // The other family was scored too, lower.
  ASSERT_TRUE(ws.families[1].scored);
  EXPECT_LT(ws.families[1].result.score, d.best.score);
  EXPECT_EQ(ws.families[1].scores.size(), static_cast<size_t>(dicts[1].functions()));
}

TEST(DecodeCluster, ShiftSearchPlacesATagAlongTheAxisTheOutlineMissed) {
  // Rings only across the middle 60 % of the tag (a square mount: no top or bottom edge), and the
  // fitted frame 0.1 m too low: the points sit 0.1 m above its centre.
  const auto& fam = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(fam)};
  const Eigen::Matrix3d R = facing();
  const Eigen::Vector3d c(6, 1, 0);
  Placed tag = place(marker_points(fam, 12, 0, 1.2, 3, -0.3, 0.3), R, c);
  const Eigen::Vector3d up = R.col(2);  // the tag's z in the sensor frame
  tag.pull_back.p = -R.transpose() * (c - 0.1 * up);
  // The search itself, with a diamond's margin (the default for a searched place is stricter,
  // below).
  DecodeOptions loose;
  loose.min_margin_bits_searched = loose.min_margin_bits;
  ClusterDecodeWorkspace ws;
  const ClusterDecode d = decode_cluster(tag.points, tag.pull_back, up, 1.2, dicts, {}, loose, ws);
  EXPECT_EQ(d.best.rejection, Rejection::kNone);
  EXPECT_EQ(d.best.code_index, 12);
  EXPECT_NEAR(d.shift, 0.1, 0.02);
  // By default a square mount's searched place needs min_margin_bits_searched: this one rotation,
  // two rows unvoted, leads by less and is ambiguous (the tracker sums rotations), never another
  // code.
  ClusterDecodeWorkspace strict_ws;
  const ClusterDecode strict =
      decode_cluster(tag.points, tag.pull_back, up, 1.2, dicts, {}, DecodeOptions{}, strict_ws);
  EXPECT_EQ(strict.best.code_index, 12);
  EXPECT_LT(strict.best.margin_bits, DecodeOptions{}.min_margin_bits_searched);
  EXPECT_EQ(strict.best.rejection, Rejection::kAmbiguous);
  EXPECT_GT(ws.shifts.size(), 3u);
  EXPECT_NEAR(ws.families[0].shift, d.shift, 1e-12);
  EXPECT_TRUE(d.shift_searched);
  // Votes at the best shift: the rows the rings crossed vote, the top and bottom ones do not.
  ASSERT_EQ(ws.vote_counts.size(), 64u);
  float top = 0, middle = 0;
  for (size_t col = 0; col < 8; ++col) {
    top += ws.vote_counts[col];
    middle += ws.vote_counts[4 * 8 + col];
  }
  EXPECT_EQ(top, 0.0f);
  EXPECT_GT(middle, 0.0f);
  // Without the search (every side seen) the same points decode worse.
  ClusterDecodeWorkspace ws0;
  const ClusterDecode d0 = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2,
                                          dicts, {}, DecodeOptions{}, ws0);
  EXPECT_LT(d0.best.score, d.best.score);
}

TEST(DecodeCluster, TheMarginCountsEveryShiftsRivals) {
  const auto& fam = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(fam)};
  const Eigen::Matrix3d R = facing();
  const Placed tag = place(marker_points(fam, 3, 2, 1.2, 2, -0.35, 0.35), R, {6, 1, 0});
  ClusterDecodeWorkspace ws;
  const ClusterDecode d =
      decode_cluster(tag.points, tag.pull_back, R.col(2), 1.2, dicts, {}, DecodeOptions{}, ws);
  ASSERT_GT(ws.hypotheses.size(), 1u);
  // Never more than the best shift's own margin, which only knows that shift's runner-up.
  EXPECT_LE(d.best.margin_bits, ws.families[0].result.margin_bits + 1e-9);
  double rival = -1;
  for (const auto& h : ws.hypotheses)
    if (h.result.function != d.best.function) rival = std::max(rival, h.result.score);
  EXPECT_LE(d.best.margin_bits, (d.best.score - rival) * d.best.cells_per_score + 1e-9);
}

TEST(DecodeCluster, ATagOfAFamilyNotConfiguredIsRejected) {
  const auto& f25 = tags::builtin_family("tag25h9");
  const std::vector<RkhsDictionary> configured = {RkhsDictionary(tags::builtin_family("tag16h5"))};
  std::vector<RkhsDictionary> decoys;
  for (const char* name : {"tag25h9", "tag36h11", "tag36h10"})
    decoys.emplace_back(tags::builtin_family(name));
  const Placed tag = place(marker_points(f25, 5, 0, 1.2, 3), facing(), {6, 1, 0});
  ClusterDecodeWorkspace ws;
  DecodeOptions lenient;  // so that the configured family's best code would pass on its own
  lenient.min_score = 0.0;
  lenient.min_margin_bits = 0.0;
  const ClusterDecode without = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(),
                                               1.2, configured, {}, lenient, ws);
  EXPECT_EQ(without.best.rejection, Rejection::kNone);
  const ClusterDecode with = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2,
                                            configured, decoys, lenient, ws);
  EXPECT_EQ(with.best.rejection, Rejection::kOtherFamily);
  EXPECT_GT(with.other_family_score, with.best.score);
  EXPECT_EQ(with.best.code_index, without.best.code_index);
  // Rejected by the decision itself, the decoys are still decoded (evidence over rotations needs
  // them): ambiguous, and below min_score at the best shift.
  DecodeOptions strict;
  strict.min_margin_bits = 1e6;
  const ClusterDecode ambiguous = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(),
                                                 1.2, configured, decoys, strict, ws);
  EXPECT_EQ(ambiguous.best.rejection, Rejection::kAmbiguous);
  EXPECT_GT(ambiguous.other_family_score, ambiguous.best.score);
  strict.min_score = 1.0;
  const ClusterDecode low = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2,
                                           configured, decoys, strict, ws);
  EXPECT_EQ(low.best.rejection, Rejection::kLowScore);
  EXPECT_GT(low.other_family_score, low.best.score);
  // ... but not below other_family_min_score: no tag of any family, the check is skipped.
  strict.other_family_min_score = std::nextafter(low.best.score, 2.0);
  const ClusterDecode hopeless = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(),
                                                1.2, configured, decoys, strict, ws);
  EXPECT_EQ(hopeless.best.rejection, Rejection::kLowScore);
  EXPECT_EQ(hopeless.best.function, low.best.function);
  EXPECT_EQ(hopeless.other_family_score, -1.0);
}

// The function of `dict` nearest to function `a` (fewest cells of another colour), and that
// number of cells.
int nearest_other(const RkhsDictionary& dict, int a, int& cells) {
  const int W = dict.width();
  int b = -1;
  cells = 1 << 30;
  for (int f = 0; f < dict.functions(); ++f) {
    if (f == a) continue;
    int n = 0;
    for (int i = 0; i < W * W; ++i) n += dict.signs(a)[i] != dict.signs(f)[i] ? 1 : 0;
    if (n < cells) {
      cells = n;
      b = f;
    }
  }
  return b;
}

TEST(DecodeCluster, TheCellsSeenMustCarryTheirShareOfTheMargin) {
  // The margin counts the kernel's evidence in every cell, also in cells no return fell in; the
  // cells seen must lead by decode.min_seen_margin_cells on their own returns' votes.
  const auto& fam = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(fam)};
  const int W = fam.total_width, a = 4 * 7 + 1;
  std::vector<ClusterPoint> full = marker_points(fam, 7, 1, 1.2, 3);
  ClusterDecodeWorkspace ws;
  DecodeOptions opt;
  opt.max_points = 1000;
  opt.min_margin_bits = 0.0;
  // The nearest other function: it differs in `nearest` cells.
  int nearest = 0;
  const int b = nearest_other(dicts[0], a, nearest);
  // Every cell seen, each with returns of one clean colour: the cells seen lead by `nearest`
  // cells, and the gate is against that.
  const Placed all = place(full, facing(), {6, 1, 0});
  const ClusterDecode d =
      decode_cluster(all.points, all.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt, ws);
  ASSERT_EQ(d.best.rejection, Rejection::kNone);
  ASSERT_EQ(d.best.function, a);
  opt.min_seen_margin_cells = nearest - 0.01;
  EXPECT_EQ(
      decode_cluster(all.points, all.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt, ws)
          .best.rejection,
      Rejection::kNone);
  opt.min_seen_margin_cells = nearest + 0.01;
  EXPECT_EQ(
      decode_cluster(all.points, all.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt, ws)
          .best.rejection,
      Rejection::kAmbiguous);
  // No return in the cells where the nearest other code differs: only the kernel's spill from
  // the neighbours tells the two apart there.
  std::vector<ClusterPoint> blind;
  for (const ClusterPoint& p : full) {
    const int c = static_cast<int>((p.y / 1.2 + 0.5) * W),
              r = static_cast<int>((0.5 - p.z / 1.2) * W);
    const auto i = static_cast<size_t>(r * W + c);
    if (dicts[0].signs(a)[i] == dicts[0].signs(b)[i]) blind.push_back(p);
  }
  ASSERT_LT(blind.size(), full.size());
  const Placed tag = place(blind, facing(), {6, 1, 0});
  opt.min_seen_margin_cells = 0.0;
  const ClusterDecode tails =
      decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt, ws);
  EXPECT_EQ(tails.best.rejection, Rejection::kNone) << "a margin from the tails alone";
  opt.min_seen_margin_cells = DecodeOptions{}.min_seen_margin_cells;
  EXPECT_EQ(
      decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt, ws)
          .best.rejection,
      Rejection::kAmbiguous);
}

TEST(DecodeCluster, ADecidingCellCountsByItsOwnReturnsNotByItsNeighboursTails) {
  // Of the cells where the decoded function and the nearest other one differ, a single return
  // near the centre of one (the VLP-32C at 20 m, 45 degrees, that read code 8 as 15 with a margin
  // of 1.90 cells): a grey return leaning to the function's colour leads by 0.3 cell, short of
  // decode.min_seen_margin_cells, however much its neighbours' kernel tails agree; a clean one
  // leads by a whole cell.
  const auto& fam = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(fam)};
  const int W = fam.total_width, a = 4 * 7 + 1;
  int nearest = 0;
  const int b = nearest_other(dicts[0], a, nearest);
  std::vector<ClusterPoint> blind;
  int seen = -1;
  for (const ClusterPoint& p : marker_points(fam, 7, 1, 1.2, 3)) {
    const int c = static_cast<int>((p.y / 1.2 + 0.5) * W),
              r = static_cast<int>((0.5 - p.z / 1.2) * W);
    const auto i = static_cast<size_t>(r * W + c);
    if (dicts[0].signs(a)[i] == dicts[0].signs(b)[i])
      blind.push_back(p);
    else if (seen < 0)
      seen = static_cast<int>(i);
  }
  ASSERT_GE(seen, 0);
  const bool white = dicts[0].signs(a)[seen] > 0;
  ClusterPoint one{};
  one.y = static_cast<float>(((seen % W + 0.5) / W - 0.5) * 1.2);
  one.z = static_cast<float>((0.5 - (seen / W + 0.5) / W) * 1.2);
  DecodeOptions opt;
  opt.max_points = 1000;
  opt.min_margin_bits = 0.0;
  ClusterDecodeWorkspace ws;
  auto decode = [&](float label) {
    std::vector<ClusterPoint> pts = blind;
    one.intensity = 30.0f + 170.0f * (white ? label : 1.0f - label);  // levels 30 and 200
    pts.push_back(one);
    const Placed tag = place(pts, facing(), {6, 1, 0});
    return decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2, dicts, {}, opt,
                          ws);
  };
  const ClusterDecode grey = decode(0.65f);
  EXPECT_EQ(grey.best.function, a);
  EXPECT_EQ(grey.best.rejection, Rejection::kAmbiguous);
  const ClusterDecode clean = decode(1.0f);
  EXPECT_EQ(clean.best.function, a);
  EXPECT_EQ(clean.best.rejection, Rejection::kNone);
  opt.min_seen_margin_cells = 1.01;
  EXPECT_EQ(decode(1.0f).best.rejection, Rejection::kAmbiguous);
}

TEST(DecodeCluster, OneIntensityGivesNothingToDecode) {
  const auto& fam = tags::builtin_family("tag16h5");
  const std::vector<RkhsDictionary> dicts = {RkhsDictionary(fam)};
  auto pts = marker_points(fam, 0, 0, 1.2, 2);
  for (auto& p : pts) p.intensity = 100.0f;
  const Placed tag = place(pts, facing(), {6, 1, 0});
  ClusterDecodeWorkspace ws;
  const ClusterDecode d = decode_cluster(tag.points, tag.pull_back, Eigen::Vector3d::Zero(), 1.2,
                                         dicts, {}, DecodeOptions{}, ws);
  EXPECT_EQ(d.best.rejection, Rejection::kLowContrast);
  EXPECT_EQ(d.best.function, -1);
  EXPECT_FALSE(ws.families[0].scored);
}

}  // namespace
}  // namespace lidartag::detector
