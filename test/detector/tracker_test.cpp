// The tracker on hand-made decoding candidates: association by pose, votes summed in each track's
// frame, confirmation, motion starting new tracks, the window's mean pose and spread, ageing,
// capacity, the options' rule table, and no allocation in steady state.
#include "lidartag/detector/tracker.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <optional>
#include <vector>

#include "count_allocations.hpp"

namespace lidartag::detector {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int64_t kPeriod = 100'000'000;  // ns: 600 rpm

Eigen::Matrix3d quarter(int q) {
  return Eigen::AngleAxisd(q * kPi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
}

// A tag facing the sensor (its x, the normal, along -x of the sensor; its z up).
Eigen::Matrix3d facing() {
  Eigen::Matrix3d m;
  m.col(0) = -Eigen::Vector3d::UnitX();
  m.col(2) = Eigen::Vector3d::UnitZ();
  m.col(1) = m.col(2).cross(m.col(0));
  return m;
}

struct Cand {
  int code = 3;
  int q = 0;  // quarter turns of the function that fits, in `frame`
  Eigen::Vector3d position{6.0, 0.0, 0.0};
  Eigen::Matrix3d frame = facing();  // before the quarter turns
  std::vector<bool> observed;        // cells with points (empty: all)
  int votes = 5;                     // points per observed cell
  Rejection rejection = Rejection::kAmbiguous;
  double other_family_score = -1.0;
  bool shift_searched = false;
  bool track_only = false;
  double size = 1.2;
  double measured = -1.0;   // the size its points measure (-1: not told)
  int points = 500;         // of the pose fit (its expected noise)
  float fit_score = 0.95f;  // the fitting function's normalised score (the others 0.6)
  // Where the tag showing the fitting function really is (in `frame`); unset: at `position`. The
  // candidate's points are given in its own frame, as the detector gives them, so a tag that is
  // not where the candidate's pose says puts its points in other cells of that frame.
  std::optional<Eigen::Vector3d> tag_at;
  // Returns near a cell's corner whose footprints lie mostly on its neighbours: in each cell
  // `blurred` marks, `blurred_votes` points 0.06 cell inside its upper left corner, labelled with
  // function `blurred_function`'s colour of the cell (what a far beam reads there).
  std::vector<bool> blurred;
  int blurred_votes = 0;
  int blurred_function = -1;
  // Where the points sit in their cells: moved this share of a cell along the tag's y from the
  // centre (a sensor whose firings drift from one rotation to the next samples other places).
  double sample_shift = 0.0;
};

// Appends a candidate as the detector reports one: the normalised score of every function (the
// fitting one 0.95, the others 0.6), and the points decoding read: `votes` at the centre of each
// observed cell of the tag, labelled with the fitting function's image. (Its grid of cell votes,
// which the tracker does not read, stays zero.)
void add(ScanResult& r, const RkhsDictionary& dict, const Cand& c) {
  Candidate& d = r.candidates.emplace_back();
  const int f = 4 * c.code + c.q;
  d.rejection = c.rejection;
  d.family_index = 0;
  d.id = c.code;
  d.quarter_turns = c.q;
  d.size_m = c.size;
  d.position = c.position;
  d.undecoded_orientation = Eigen::Quaterniond(c.frame);
  d.orientation = Eigen::Quaterniond(c.frame * quarter(-c.q));
  d.score = 0.95;
  d.margin = c.rejection == Rejection::kNone ? 3.0 : 0.5;
  d.other_family_score = c.other_family_score;
  d.points = c.points;
  d.fit_cost = 1.0;
  d.shift_searched = c.shift_searched;
  if (c.shift_searched) d.unseen_axis = c.frame.col(2);  // the tag's z: a square mount's vertical
  d.track_only = c.track_only;
  d.measured_size_m = c.measured;
  d.first_evidence = static_cast<int>(r.family_evidence.size());
  d.evidence_count = 1;
  FamilyEvidence& e = r.family_evidence.emplace_back();
  e.family_index = 0;
  e.first = static_cast<int>(r.evidence_scores.size());
  e.functions = dict.functions();
  e.cells_per_score = 10.0f;
  for (int g = 0; g < dict.functions(); ++g)
    r.evidence_scores.push_back(g == f ? c.fit_score : 0.6f);
  const int W = dict.width();
  d.grid_width = W;
  d.first_cell = static_cast<int>(r.cell_votes.size());
  for (int i = 0; i < W * W; ++i) r.cell_evidence.push_back(dict.signs(f)[i]);
  r.cell_votes.resize(r.cell_votes.size() + static_cast<size_t>(W * W), 0.0f);
  r.cell_vote_counts.resize(r.cell_vote_counts.size() + static_cast<size_t>(W * W), 0.0f);
  d.first_vote_point = static_cast<int>(r.vote_points.size());
  const Eigen::Vector3d centre = c.tag_at.value_or(c.position);
  for (int i = 0; i < W * W; ++i) {
    if (!c.observed.empty() && !c.observed[static_cast<size_t>(i)]) continue;
    const double y = ((i % W + 0.5 + c.sample_shift) / W - 0.5) * c.size,
                 z = (0.5 - (i / W + 0.5) / W) * c.size;
    const Eigen::Vector3d p = centre + c.frame * Eigen::Vector3d(0.0, y, z);
    const Eigen::Vector3d q = c.frame.transpose() * (p - c.position);
    const float label = dict.signs(f)[i] > 0 ? 1.0f : 0.0f;
    for (int k = 0; k < c.votes; ++k)
      r.vote_points.push_back(
          {static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()), label});
  }
  for (int i = 0; i < W * W && c.blurred_function >= 0; ++i) {
    if (c.blurred.empty() || !c.blurred[static_cast<size_t>(i)]) continue;
    const double y = ((i % W + 0.06) / W - 0.5) * c.size, z = (0.5 - (i / W + 0.06) / W) * c.size;
    const Eigen::Vector3d q =
        c.frame.transpose() * (centre + c.frame * Eigen::Vector3d(0.0, y, z) - c.position);
    const float label = dict.signs(c.blurred_function)[i] > 0 ? 1.0f : 0.0f;
    for (int k = 0; k < c.blurred_votes; ++k)
      r.vote_points.push_back(
          {static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()), label});
  }
  d.vote_point_count = static_cast<int>(r.vote_points.size()) - d.first_vote_point;
  if (c.rejection == Rejection::kNone && !c.track_only) {
    Detection det;
    det.id = c.code;
    det.position = c.position;
    det.orientation = d.orientation;
    det.size_m = c.size;
    det.points = d.points;
    d.detection = static_cast<int>(r.detections.size());
    r.detections.push_back(det);
  }
}

class TrackerTest : public ::testing::Test {
 protected:
  DetectorOptions det_opt;  // tag16h5, decode.min_score 0.8
  RkhsDictionary dict{tags::builtin_family("tag16h5")};
  ScanResult result;
  TrackerResult out;
  int64_t stamp = 1'700'000'000'000'000'000;

  // One rotation with these candidates.
  void step(Tracker& t, const std::vector<Cand>& cands) {
    result.clear();
    for (const Cand& c : cands) add(result, dict, c);
    t.update(result, stamp, out);
    stamp += kPeriod;
  }
  const TrackInfo* seen_at(const Eigen::Vector3d& p) const {
    for (const TrackInfo& i : out.seen)
      if ((i.position - p).norm() < 0.2) return &i;
    return nullptr;
  }
  // The function of the family that differs from function `f` in the fewest cells.
  int closest_other(int f) const {
    int rival = -1, fewest = 1 << 30;
    for (int g = 0; g < dict.functions(); ++g) {
      if (g == f) continue;
      int differ = 0;
      for (int i = 0; i < 64; ++i) differ += dict.signs(f)[i] != dict.signs(g)[i] ? 1 : 0;
      if (differ < fewest) fewest = differ, rival = g;
    }
    return rival;
  }
};

TEST_F(TrackerTest, CandidatesAtTwoPlacesKeepTheirOwnTracksOverRotations) {
  Tracker tracker({}, det_opt);
  Cand a, b;
  b.code = 7;
  b.position = {4.0, 2.0, 0.0};
  for (int k = 0; k < 5; ++k) {
    a.position.x() = 6.0 + 0.005 * (k % 2);  // a few mm of scatter
    step(tracker, {a, b});
    ASSERT_EQ(out.seen.size(), 2u);
    const TrackInfo* ta = seen_at(a.position);
    const TrackInfo* tb = seen_at(b.position);
    ASSERT_TRUE(ta && tb);
    EXPECT_EQ(ta->track_id, 0);
    EXPECT_EQ(tb->track_id, 1);
    EXPECT_EQ(ta->rotations, k + 1);
    EXPECT_EQ(tb->id, 7);
    EXPECT_EQ(out.tracks, 2);
  }
}

TEST_F(TrackerTest, VotesAccumulateAndConfirmAfterMinRotations) {
  TrackerOptions o;
  o.min_rotations = 3;
  Tracker tracker(o, det_opt);
  Cand c;       // ambiguous alone every rotation
  c.votes = 2;  // half of full_cell_votes (4) per rotation
  for (int k = 0; k < 4; ++k) {
    step(tracker, {c});
    ASSERT_EQ(out.seen.size(), 1u);
    const TrackInfo& t = out.seen[0];
    EXPECT_EQ(t.id, 3);
    EXPECT_EQ(t.confirmed, k >= 2) << "rotation " << k;
    // Confirmed tracks of ambiguous rotations are reported with the track's ID.
    EXPECT_EQ(out.tags.size(), k >= 2 ? 1u : 0u);
  }
  // Every cell observed with full votes: the margin is the number of cells in which the closest
  // other function differs. A single rotation of half-weight votes gives half of it.
  const double whole = out.seen[0].margin_cells;
  EXPECT_GE(whole, 1.0);
  EXPECT_EQ(whole, std::round(whole));
  Tracker fresh(o, det_opt);
  step(fresh, {c});
  EXPECT_NEAR(out.seen[0].margin_cells, whole / 2, 1e-5);
}

TEST_F(TrackerTest, EachRotationsPointsAreVotedInTheTracksMeanFrame) {
  Tracker tracker({}, det_opt);
  Cand c;
  for (int k = 0; k < 9; ++k) step(tracker, {c});
  ASSERT_EQ(out.seen.size(), 1u);
  ASSERT_TRUE(out.seen[0].confirmed);
  const double margin = out.seen[0].margin_cells;
  // One rotation whose pose is 0.09 m (0.6 cell) off along the tag, inside the association gate:
  // in its own frame each of its points reads the cell beside its own, in the track's mean frame
  // (0.009 m off) its own cell.
  c.position += c.frame * Eigen::Vector3d(0.0, 0.09, 0.0);
  step(tracker, {c});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].rotations, 10);
  EXPECT_EQ(out.seen[0].id, 3);
  EXPECT_GE(out.seen[0].margin_cells, margin - 1e-9);
}

TEST_F(TrackerTest, CodesThatDifferOnlyOnUnobservedCellsAreNeverConfirmed) {
  // The closest other function of code 3 (quarter turn 0): observe every cell but those where the
  // two differ, as a sparse sensor's rings miss them.
  const int f = 12;
  const int rival = closest_other(f);
  ASSERT_GE(rival, 0);
  Cand c;
  c.observed = std::vector<bool>(64);  // each set below (assign() trips GCC 12 at -O3)
  for (int i = 0; i < 64; ++i)
    c.observed[static_cast<size_t>(i)] = dict.signs(f)[i] == dict.signs(rival)[i];
  c.votes = 20;
  Tracker tracker({}, det_opt);
  for (int k = 0; k < 50; ++k) step(tracker, {c});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].rotations, 50);
  EXPECT_NEAR(out.seen[0].margin_cells, 0.0, 1e-6);
  EXPECT_FALSE(out.seen[0].confirmed);
  EXPECT_TRUE(out.tags.empty());
}

TEST_F(TrackerTest, MovingBeyondTheGatesStartsANewTrackWithoutTheOldEvidence) {
  TrackerOptions o;  // 0.1 m, 10 degrees
  Tracker tracker(o, det_opt);
  Cand c;
  for (int k = 0; k < 3; ++k) step(tracker, {c});
  ASSERT_TRUE(out.seen[0].confirmed);
  const int first = out.seen[0].track_id;
  // 5 cm from the track's mean: the same track.
  c.position.y() += 0.05;
  step(tracker, {c});
  EXPECT_EQ(out.seen[0].track_id, first);
  EXPECT_EQ(out.seen[0].rotations, 4);
  // 0.2 m away from the mean: a new track, unconfirmed, with one rotation of evidence, and another
  // code: the evidence of the old place is not mixed in.
  c.position.y() += 0.2;
  c.code = 9;
  step(tracker, {c});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_NE(out.seen[0].track_id, first);
  EXPECT_EQ(out.seen[0].rotations, 1);
  EXPECT_EQ(out.seen[0].id, 9);
  EXPECT_FALSE(out.seen[0].confirmed);
  // Turned 15 degrees about the vertical at the same place: new track too.
  c.frame =
      Eigen::AngleAxisd(15 * kPi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() * c.frame;
  const int second = out.seen[0].track_id;
  step(tracker, {c});
  EXPECT_NE(out.seen[0].track_id, second);
  EXPECT_EQ(out.tracks, 3);  // the old ones live until max_age_s
}

// The gates follow the expected pose noise (TrackerOptions::pose_noise_*): a far tag's candidates
// of 40 points (5 cm and 5 degrees RMS from one rotation to the next) stay one track 15 degrees
// and 0.12 m off its mean, where a near tag's of 500 points start a new one; 35 degrees is beyond
// any noise (the gates stop at 30 degrees).
TEST_F(TrackerTest, TheGatesWidenWithTheExpectedPoseNoiseOfSparseCandidates) {
  for (const int points : {40, 500}) {
    SCOPED_TRACE(points);
    Tracker tracker({}, det_opt);
    Cand c;
    c.position = {20.0, 20.0, 0.0};
    c.points = points;
    for (int k = 0; k < 3; ++k) step(tracker, {c});
    const int first = out.seen[0].track_id;
    Cand off = c;
    off.frame =
        Eigen::AngleAxisd(15 * kPi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() * c.frame;
    step(tracker, {off});
    EXPECT_EQ(out.seen[0].track_id == first, points == 40);
    if (points == 500) continue;
    off = c;
    off.position.z() += 0.12;
    step(tracker, {off});
    EXPECT_EQ(out.seen[0].track_id, first);
    off.frame =
        Eigen::AngleAxisd(35 * kPi / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() * c.frame;
    step(tracker, {off});
    EXPECT_NE(out.seen[0].track_id, first);
  }
}

// The far edge: every rotation's own fit scores 0.75 for the right code (below decode.min_score,
// 0.8), while its points' votes, fused in the track's frame, agree with it in every cell: the
// fused grid (its leader's own, the unshifted grid of a tag seen on every side) confirms it from
// the 3rd rotation, unless its options ask for a margin it does not have.
TEST_F(TrackerTest, TheFusedGridConfirmsATagWhoseRotationsScoreLow) {
  Cand c;
  c.fit_score = 0.75f;
  c.position = {22.0, 22.0, 0.0};
  c.points = 60;
  // Each rotation samples the cells at other places (a Velodyne's firings drift).
  auto at = [&](int k) {
    Cand r = c;
    r.sample_shift = 0.2 * (k % 2) - 0.1;
    return r;
  };
  {
    Tracker tracker({}, det_opt);
    for (int k = 0; k < 3; ++k) step(tracker, {at(k)});
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_LT(out.seen[0].mean_score, det_opt.decode.min_score);
    EXPECT_TRUE(out.seen[0].confirmed);
    EXPECT_EQ(out.seen[0].id, c.code);
  }
  // Without the fused grid's confirmation (nor its wide margin, which asks as much): none.
  TrackerOptions strict;
  strict.fused_min_margin_cells = 100.0;
  Tracker tracker(strict, det_opt);
  for (int k = 0; k < 5; ++k) step(tracker, {at(k)});
  EXPECT_FALSE(out.seen[0].confirmed);
}

// The same tag sampled at the same places in every rotation (an Ouster's columns at fixed encoder
// angles, a static sensor): its fused grid is one rotation's with less noise, not a finer one, and
// never confirms what the rotations' own scores do not. Half the rotations sampling anew is
// enough. (128 points a rotation: a far tag's; a tag of more than 256 is taken as sampled anew.)
TEST_F(TrackerTest, TheFusedGridNeedsRotationsThatSampleTheTagAnew) {
  Cand c;
  c.fit_score = 0.75f;
  c.position = {22.0, 22.0, 0.0};
  c.points = 60;
  c.votes = 2;
  {
    Tracker tracker({}, det_opt);
    for (int k = 0; k < 8; ++k) {
      step(tracker, {c});
      ASSERT_EQ(out.seen.size(), 1u);
      EXPECT_EQ(out.seen[0].id, c.code);
      EXPECT_GE(out.seen[0].margin_cells, 1.0);
      EXPECT_FALSE(out.seen[0].confirmed) << k;
    }
  }
  Tracker tracker({}, det_opt);
  for (int k = 0; k < 5; ++k) {
    Cand r = c;
    r.sample_shift = k % 4 == 1 || k % 4 == 2 ? 0.2 : 0.0;  // anew in rotations 2 and 4
    step(tracker, {r});
    EXPECT_EQ(out.seen[0].confirmed, k >= 2) << k;
  }
}

// A tag `p0` (frame `f0`) fixed in the world, seen after the sensor turned `deg` about its z.
Cand turned(Cand c, const Eigen::Vector3d& p0, const Eigen::Matrix3d& f0, double deg) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(-deg * kPi / 180, Eigen::Vector3d::UnitZ())
                                .toRotationMatrix();  // the world turns the other way
  c.position = r * p0;
  c.frame = r * f0;
  return c;
}

// A sensor yawing at 30 deg/s moves two tags at 7 m by 0.37 m and 3 degrees a rotation, beyond
// both gates: each track follows its tag with the motion of its window, the evidence of every
// rotation is summed, and the tracks say how the world turns (the sensor's turn, reversed).
TEST_F(TrackerTest, ATurningSensorKeepsOneTrackPerTagAndConfirmsIt) {
  Tracker tracker({}, det_opt);
  Cand a, b;
  b.code = 9;
  const Eigen::Vector3d pa{7.0, 1.5, 0.0}, pb{6.5, -2.0, 0.2};
  for (int k = 0; k < 12; ++k) {
    step(tracker, {turned(a, pa, a.frame, 3.0 * k), turned(b, pb, b.frame, 3.0 * k)});
    ASSERT_EQ(out.seen.size(), 2u) << k;
    EXPECT_EQ(out.tracks, 2) << k;
    for (const TrackInfo& t : out.seen) {
      EXPECT_LT(t.track_id, 2) << k;  // the first two tracks, never a new one
      EXPECT_EQ(t.rotations, k + 1);
      EXPECT_EQ(t.confirmed, k >= 2) << k;
      if (k >= 2) {
        EXPECT_TRUE(t.moving);
        EXPECT_NEAR(t.turn_deg_s.z(), -30.0, 1e-6) << k;
      }
    }
    ASSERT_EQ(out.tags.size(), k >= 2 ? 2u : 0u);
    for (const TrackedDetection& t : out.tags)
      EXPECT_EQ(t.detection.id, t.track.track_id == 0 ? 3 : 9);
  }
  // The track's pose is the tag where it is now, not the mean of where it was.
  const TrackInfo* t = seen_at(turned(a, pa, a.frame, 33.0).position);
  ASSERT_NE(t, nullptr);
  EXPECT_NEAR((t->position - turned(a, pa, a.frame, 33.0).position).norm(), 0.0, 1e-6);
  EXPECT_NEAR(t->velocity_mps.norm(), 30.0 * kPi / 180 * pa.norm(), 1e-6);
}

// Without tracker.follow_motion, the same sensor starts a new track every rotation (the tag is
// 0.37 m from the window's mean) and never confirms the ambiguous tag.
TEST_F(TrackerTest, WithoutFollowMotionATurningSensorStartsATrackEveryRotation) {
  TrackerOptions o;
  o.follow_motion = false;
  Tracker tracker(o, det_opt);
  Cand a;
  const Eigen::Vector3d pa{7.0, 1.5, 0.0};
  for (int k = 0; k < 6; ++k) {
    step(tracker, {turned(a, pa, a.frame, 3.0 * k)});
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_EQ(out.seen[0].track_id, k);
    EXPECT_FALSE(out.seen[0].moving);
    EXPECT_TRUE(out.tags.empty());
  }
}

// While the sensor turns, a tag that leaves its predicted path (moved by hand, or another tag of
// the same code) starts a new track: evidence of two places is never summed.
TEST_F(TrackerTest, ATagThatLeavesItsPredictedPathStartsANewTrack) {
  Tracker tracker({}, det_opt);
  Cand a;
  const Eigen::Vector3d pa{7.0, 1.5, 0.0};
  for (int k = 0; k < 6; ++k) step(tracker, {turned(a, pa, a.frame, 3.0 * k)});
  ASSERT_EQ(out.seen[0].track_id, 0);
  // 0.25 m off where the turn puts it.
  Cand moved = turned(a, pa, a.frame, 18.0);
  moved.position.z() += 0.25;
  moved.code = 9;
  step(tracker, {moved});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].track_id, 1);
  EXPECT_EQ(out.seen[0].rotations, 1);
  EXPECT_EQ(out.seen[0].id, 9);
}

// A track seen once, with no other track that knows the motion, meets its next candidate within
// gates grown by the sensor's largest motion (2 m/s and 45 deg/s: 0.75 m at 7 m in 0.1 s), at
// most half the tag's size: a 1.2 m tag 0.5 m on is the same track, a 0.2 m tag 0.3 m on is not.
TEST_F(TrackerTest, AYoungTracksGatesGrowWithTheSensorsMotionUpToHalfTheTagsSize) {
  det_opt.tag_sizes_m = {1.2, 0.2};
  Tracker tracker({}, det_opt);
  Cand big, small;
  big.position = {7.0, 2.0, 0.0};
  small.position = {7.0, -2.0, 0.0};
  small.size = 0.2;
  small.code = 9;
  step(tracker, {big, small});
  ASSERT_EQ(out.seen.size(), 2u);
  big.position.y() += 0.5;
  small.position.y() += 0.3;
  step(tracker, {big, small});
  const TrackInfo* b = seen_at(big.position);
  const TrackInfo* s = seen_at(small.position);
  ASSERT_TRUE(b && s);
  EXPECT_EQ(b->track_id, 0);
  EXPECT_EQ(b->rotations, 2);
  EXPECT_EQ(s->track_id, 2);  // a new one
  EXPECT_EQ(s->rotations, 1);
  // 0.7 m on for the big tag: beyond half its size, a new track too.
  big.position.y() += 0.7;
  step(tracker, {big});
  EXPECT_EQ(out.seen[0].track_id, 3);
}

// The size check over a track: the mean of its candidates' measured sizes (those that measured
// one), warned about beyond pose.size_warning_ratio; a tag reported by its track alone carries
// its rotation's measure and warning.
TEST_F(TrackerTest, ATracksMeasuredSizeIsTheMeanOfItsCandidatesAndWarnedAboutWhenOff) {
  Tracker tracker({}, det_opt);  // pose.size_warning_ratio 0.03
  Cand c;                        // 1.2 m, ambiguous alone: reported by its track once confirmed
  const double measured[] = {1.25, -1.0, 1.27, 1.26};
  for (double m : measured) {
    c.measured = m;
    step(tracker, {c});
  }
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_NEAR(out.seen[0].measured_size_m, 1.26, 1e-12);
  EXPECT_TRUE(out.seen[0].size_warning);
  ASSERT_EQ(out.tags.size(), 1u);
  EXPECT_FALSE(out.tags[0].decoded);
  EXPECT_EQ(out.tags[0].detection.measured_size_m, 1.26);
  EXPECT_TRUE(out.tags[0].detection.size_warning);
  // Within 3 %: no warning.
  Tracker right({}, det_opt);
  c.position.y() += 3.0;
  for (double m : {1.21, 1.19, 1.22}) {
    c.measured = m;
    step(right, {c});
  }
  EXPECT_FALSE(out.seen[0].size_warning);
  EXPECT_FALSE(out.tags[0].detection.size_warning);
  EXPECT_NEAR(out.seen[0].measured_size_m, 1.2066666666666666, 1e-9);
}

TEST_F(TrackerTest, QuarterTurnsOfTheEstimatedFrameAreAlignedToTheTrack) {
  Tracker tracker({}, det_opt);
  Cand c;
  c.q = 1;
  // The tag itself is fixed; the detector's frame before the quarter turns differs by one turn
  // every other rotation (its corners came out in another order), so the fitting function does
  // too: frame * Rx(-q pi / 2) is the same tag frame.
  const Eigen::Matrix3d tag = c.frame * quarter(-1);
  for (int k = 0; k < 6; ++k) {
    const int turn = k % 2;
    c.frame = tag * quarter(1 + turn);
    c.q = 1 + turn;
    step(tracker, {c});
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_EQ(out.seen[0].track_id, 0);
    EXPECT_EQ(out.seen[0].id, 3);
    EXPECT_LT(out.seen[0].angle_std_deg, 1e-6);
    EXPECT_LT(Eigen::Quaterniond(tag).angularDistance(out.seen[0].orientation), 1e-9);
  }
  EXPECT_TRUE(out.seen[0].confirmed);
  // The tag reported for an ambiguous rotation has the tag's frame and corners of its black
  // square (bottom-left first) in it.
  ASSERT_EQ(out.tags.size(), 1u);
  const TrackedDetection& t = out.tags[0];
  EXPECT_FALSE(t.decoded);
  EXPECT_EQ(t.detection.id, 3);
  EXPECT_EQ(t.detection.family, "tag16h5");
  EXPECT_LT(Eigen::Quaterniond(tag).angularDistance(t.detection.orientation), 1e-9);
  const double h = 0.375 * 1.2;
  EXPECT_LT((t.detection.corners[0] - (c.position + tag * Eigen::Vector3d(0, -h, -h))).norm(),
            1e-9);
  EXPECT_NEAR(t.detection.score, 0.95, 1e-6);
  EXPECT_NEAR(t.detection.margin, (0.95 - 0.6) * 10.0, 1e-5);
}

TEST_F(TrackerTest, MeanPoseAndSpreadOverTheWindow) {
  TrackerOptions o;
  o.window = 4;
  Tracker tracker(o, det_opt);
  Cand c;
  // Over the last 4: x alternates 6.00 / 6.02 (std 1 cm), y fixed, z 0, 0, 0.04, 0.
  const double xs[] = {4.5, 6.0, 6.02, 6.0, 6.02};
  const double zs[] = {0.0, 0.0, 0.0, 0.04, 0.0};
  // The first is 1.5 m from the others (farther than a young track's gates reach): they start
  // another track. Its frames alternate +-1 degree about the normal. Scatter, not motion: the
  // mean.
  for (int k = 0; k < 5; ++k) {
    c.position = {xs[k], 0.0, zs[k]};
    c.frame = facing() * Eigen::AngleAxisd((k % 2 ? 1 : -1) * kPi / 180, Eigen::Vector3d::UnitX())
                             .toRotationMatrix();
    step(tracker, {c});
  }
  ASSERT_EQ(out.seen.size(), 1u);
  const TrackInfo& t = out.seen[0];
  EXPECT_EQ(t.rotations, 4);
  EXPECT_EQ(t.window_rotations, 4);
  EXPECT_NEAR(t.position.x(), 6.01, 1e-9);
  EXPECT_NEAR(t.position.z(), 0.01, 1e-9);
  EXPECT_NEAR(t.position_std_m.x(), 0.01, 1e-9);
  EXPECT_NEAR(t.position_std_m.y(), 0.0, 1e-12);
  EXPECT_NEAR(t.position_std_m.z(), std::sqrt(3 * 0.0001 + 0.0009) / 2, 1e-9);
  EXPECT_NEAR(t.angle_std_deg, 1.0, 1e-6);
  EXPECT_FALSE(t.moving);
}

TEST_F(TrackerTest, TracksAgeOutAndAReplayStartingAgainResetsThem) {
  TrackerOptions o;
  o.max_age_s = 0.25;
  Tracker tracker(o, det_opt);
  Cand c;
  step(tracker, {c});
  step(tracker, {});
  step(tracker, {});
  EXPECT_EQ(out.tracks, 1);  // 0.2 s unseen
  step(tracker, {});
  EXPECT_EQ(out.tracks, 0);  // 0.3 s
  step(tracker, {c});
  EXPECT_EQ(out.seen[0].track_id, 1);
  EXPECT_EQ(out.seen[0].rotations, 1);
  step(tracker, {c});
  EXPECT_EQ(out.seen[0].rotations, 2);
  stamp -= 100 * kPeriod;  // the capture starts again
  step(tracker, {c});
  EXPECT_EQ(out.seen[0].track_id, 2);
  EXPECT_EQ(out.seen[0].rotations, 1);
}

TEST_F(TrackerTest, MoreCandidatesThanTracksStayUntrackedAndTheOldestMakesRoom) {
  TrackerOptions o;
  o.max_tracks = 2;
  Tracker tracker(o, det_opt);
  Cand a, b, c;
  b.position.y() = 2.0;
  c.position.y() = -2.0;
  a.rejection = b.rejection = c.rejection = Rejection::kNone;
  step(tracker, {a, b, c});
  EXPECT_EQ(out.tracks, 2);
  ASSERT_EQ(out.tags.size(), 3u);  // every detection is reported, tracked or not
  int untracked = 0;
  for (const auto& t : out.tags) untracked += t.track.track_id < 0 ? 1 : 0;
  EXPECT_EQ(untracked, 1);
  step(tracker, {b});
  step(tracker, {c});  // a (seen longest ago) makes room
  EXPECT_EQ(out.tracks, 2);
  EXPECT_EQ(out.seen[0].rotations, 1);
}

TEST_F(TrackerTest, AnotherFamilyFittingBetterOnAverageBlocksConfirmation) {
  Tracker tracker({}, det_opt);
  Cand c;
  c.other_family_score = 0.97;  // the decoys beat the leading function's 0.95
  for (int k = 0; k < 5; ++k) step(tracker, {c});
  EXPECT_FALSE(out.seen[0].confirmed);
  Tracker tie({}, det_opt);
  c.other_family_score = 0.95;  // identical patterns (tag16h6 shares tag16h5's codes) tie
  for (int k = 0; k < 5; ++k) step(tie, {c});
  EXPECT_TRUE(out.seen[0].confirmed);
}

TEST_F(TrackerTest, OtherFamiliesAreComparedBestAgainstBestInEachRotation) {
  // Four rotations lead with code 3; in a fifth another code leads (no votes), where code 3
  // scores 0.6: code 3's mean score is 0.88. The decoys tie with the best of every rotation
  // (0.95), as identical patterns do: that is no better fit, and the track confirms.
  Tracker tracker({}, det_opt);
  Cand c;
  c.other_family_score = 0.95;
  Cand other = c;
  other.code = 5;
  other.observed = std::vector<bool>(64, false);
  for (int k = 0; k < 5; ++k) step(tracker, {k == 2 ? other : c});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].id, 3);
  EXPECT_NEAR(out.seen[0].mean_score, (4 * 0.95 + 0.6) / 5, 1e-6);
  EXPECT_TRUE(out.seen[0].confirmed);
  // Decoys above the best of every rotation still block it.
  Tracker blocked({}, det_opt);
  c.other_family_score = other.other_family_score = 0.96;
  for (int k = 0; k < 5; ++k) step(blocked, {k == 2 ? other : c});
  EXPECT_FALSE(out.seen[0].confirmed);
}

TEST_F(TrackerTest, ClustersWhosePositionWasSearchedByDecodingAreSearchedAgainOverTheirVotes) {
  // Decoding placed these candidates half a cell too low along the unseen axis (the tag's z): at
  // the candidates' own place every point sits on a cell border and votes nowhere. The track
  // searches the axis over its summed votes, confirms the code half a cell up and reports the
  // tag near there.
  const double cell = 1.2 / 8;
  Tracker tracker({}, det_opt);
  Cand c;
  c.shift_searched = true;
  c.tag_at = c.position + facing() * Eigen::Vector3d(0.0, 0.0, cell / 2);
  for (int k = 0; k < 3; ++k) step(tracker, {c});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].rotations, 3);
  EXPECT_EQ(out.seen[0].id, 3);
  EXPECT_TRUE(out.seen[0].confirmed);
  EXPECT_GE(out.seen[0].margin_cells, 4.0);
  // Within the search's step, a quarter cell (the points at cell centres vote alike a quarter
  // cell either way); the candidates' own place is twice that off.
  EXPECT_LE((out.seen[0].position - *c.tag_at).norm(), cell / 4 + 1e-6);
  // Not searched, the same points vote nowhere: no margin, never confirmed.
  Tracker plain({}, det_opt);
  c.shift_searched = false;
  for (int k = 0; k < 5; ++k) step(plain, {c});
  EXPECT_FALSE(out.seen[0].confirmed);
  EXPECT_NEAR(out.seen[0].margin_cells, 0.0, 1e-9);
  // A searched track whose candidates disagree on the code, each at its own place along the
  // axis, is confirmed for neither while their evidence is even.
  Tracker mixed({}, det_opt);
  Cand a;
  a.shift_searched = true;
  Cand b = a;
  b.code = 9;
  b.tag_at = b.position + facing() * Eigen::Vector3d(0.0, 0.0, cell / 4);
  for (int k = 0; k < 6; ++k) step(mixed, {k % 2 == 0 ? a : b});
  EXPECT_FALSE(out.seen[0].confirmed);
}

TEST_F(TrackerTest, TrackOnlyCandidatesAreEvidenceButNeverDetectionsOfTheirOwn) {
  Tracker tracker({}, det_opt);
  Cand weak;  // decodes code 3 well, but too few boundary points for a detection of its own
  weak.rejection = Rejection::kNone;
  weak.track_only = true;
  // They start a track and confirm it like any candidate, one rotation later than min_rotations
  // (3) when no rotation of the track validated; the track's tag is reported, never as a
  // detection of the rotation.
  for (int k = 0; k < 4; ++k) {
    step(tracker, {weak});
    ASSERT_EQ(out.seen.size(), 1u) << "rotation " << k;
    EXPECT_EQ(out.seen[0].track_id, 0);
    EXPECT_EQ(out.seen[0].rotations, k + 1);
    EXPECT_EQ(out.seen[0].confirmed, k == 3) << "rotation " << k;
    EXPECT_TRUE(result.detections.empty());
  }
  ASSERT_EQ(out.tags.size(), 1u);
  EXPECT_FALSE(out.tags[0].decoded);
  EXPECT_EQ(out.tags[0].detection.id, 3);
  EXPECT_EQ(out.tags[0].detection.position, weak.position);
  // Their votes count: track-only candidates of another code at the same place first lower the
  // margin of code 3, then take the lead.
  const double margin = out.seen[0].margin_cells;
  weak.code = 9;
  weak.position.x() += 0.01;
  step(tracker, {weak});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].rotations, 5);
  EXPECT_EQ(out.seen[0].id, 3);
  EXPECT_LT(out.seen[0].margin_cells, margin);
  for (int k = 0; k < 5; ++k) step(tracker, {weak});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].track_id, 0);
  EXPECT_EQ(out.seen[0].id, 9);
  // Beyond the gates one starts a track of its own.
  weak.position.x() += 1.0;
  step(tracker, {weak});
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].track_id, 1);
  EXPECT_EQ(out.tracks, 2);
}

// Track-only rotations alone confirm at min_rotations + 1; one validated rotation among them (a
// candidate that passed validation, here ambiguous in its own decoding) confirms at
// min_rotations, as before.
TEST_F(TrackerTest, ATrackOfTrackOnlyRotationsAloneConfirmsOneRotationLater) {
  Cand weak;
  weak.rejection = Rejection::kNone;
  weak.track_only = true;
  Cand validated = weak;
  validated.track_only = false;
  validated.rejection = Rejection::kAmbiguous;
  for (const bool with_validated : {false, true}) {
    SCOPED_TRACE(with_validated ? "one validated rotation" : "track-only rotations alone");
    Tracker tracker({}, det_opt);
    for (int k = 0; k < 4; ++k) {
      step(tracker, {with_validated && k == 1 ? validated : weak});
      ASSERT_EQ(out.seen.size(), 1u) << "rotation " << k;
      EXPECT_EQ(out.seen[0].rotations, k + 1);
      EXPECT_EQ(out.seen[0].id, 3);
      EXPECT_EQ(out.seen[0].confirmed, k >= (with_validated ? 2 : 3)) << "rotation " << k;
    }
  }
}

TEST_F(TrackerTest, DetectionsKeepTheirOwnFieldsAndGetTheirTrack) {
  Tracker tracker({}, det_opt);
  Cand c;
  c.rejection = Rejection::kNone;
  for (int k = 0; k < 3; ++k) step(tracker, {c});
  ASSERT_EQ(out.tags.size(), 1u);
  EXPECT_TRUE(out.tags[0].decoded);
  EXPECT_EQ(out.tags[0].detection.points, result.detections[0].points);
  EXPECT_EQ(out.tags[0].detection.position, result.detections[0].position);
  EXPECT_EQ(out.tags[0].track.track_id, 0);
  EXPECT_TRUE(out.tags[0].track.confirmed);
  // A detection whose ID is not the track's is reported as decoded, not confirmed.
  c.code = 4;
  step(tracker, {c});
  ASSERT_EQ(out.tags.size(), 1u);
  EXPECT_EQ(out.tags[0].detection.id, 4);
  EXPECT_EQ(out.tags[0].track.track_id, 0);
  EXPECT_FALSE(out.tags[0].track.confirmed);
}

TEST_F(TrackerTest, SteadyStateDoesNotAllocate) {
  Tracker tracker({}, det_opt);
  Cand a, b;
  b.position.y() = 2.0;
  b.rejection = Rejection::kNone;
  const ScanResult first = [&] {
    ScanResult r;
    add(r, dict, a);
    add(r, dict, b);
    return r;
  }();
  for (int k = 0; k < 5; ++k) {
    tracker.update(first, stamp, out);
    stamp += kPeriod;
  }
  const long before = testing::heap_allocations();
  for (int k = 0; k < 50; ++k) {
    tracker.update(first, stamp, out);
    stamp += kPeriod;
  }
  EXPECT_EQ(testing::heap_allocations() - before, 0);
  EXPECT_EQ(out.tags.size(), 2u);
}

TEST_F(TrackerTest, WithEgoMotionATagIsAveragedInTheOdometryFrameWithoutAllocating) {
  // The sensor yaws at 30 deg/s; the tag stands at (6, 0, 0) in the odometry frame, so each
  // rotation's candidate is there seen from the sensor's pose at the candidate's time.
  const double w = 30.0 * kPi / 180.0;
  EgoMotionOptions keep;
  keep.capacity = 1000;  // the whole test's 7 s at 100 Hz
  EgoMotion ego(keep);
  const int64_t start = stamp;
  auto yaw = [&](int64_t t) {
    return Eigen::AngleAxisd(w * static_cast<double>(t - start) * 1e-9, Eigen::Vector3d::UnitZ())
        .toRotationMatrix();
  };
  for (int64_t t = start - 50'000'000; t < start + 70 * kPeriod; t += 10'000'000)
    ASSERT_EQ(ego.add_pose(t, Eigen::Vector3d(0.5, 0.0, 0.0), Eigen::Quaterniond(yaw(t))),
              EgoSample::kAccepted);
  const Eigen::Vector3d world(6.0, 0.0, 0.0);
  Tracker tracker({}, det_opt);
  auto rotation = [&](int64_t t) {
    ScanResult r;
    Cand c;
    c.frame = yaw(t).transpose() * facing();
    c.position = yaw(t).transpose() * (world - Eigen::Vector3d(0.5, 0.0, 0.0));
    add(r, dict, c);
    return r;
  };
  for (int k = 0; k < 5; ++k) {
    const ScanResult r = rotation(stamp);
    tracker.update(r, stamp, out, &ego);
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_EQ(out.seen[0].track_id, 0);
    EXPECT_EQ(out.ego_placed, 1);
    EXPECT_TRUE(out.seen[0].odometry);
    EXPECT_LT((out.seen[0].odometry_position - world).norm(), 1e-9);
    // Seen from the sensor now: where the candidate is.
    EXPECT_LT((out.seen[0].position - r.candidates[0].position).norm(), 1e-9);
    stamp += kPeriod;
  }
  EXPECT_TRUE(out.seen[0].confirmed);
  // Steady state: the same rotations again (their candidates at the same place in the world).
  std::vector<ScanResult> later;
  std::vector<int64_t> stamps;
  for (int k = 0; k < 50; ++k) {
    later.push_back(rotation(stamp));
    stamps.push_back(stamp);
    stamp += kPeriod;
  }
  const long before = testing::heap_allocations();
  for (size_t k = 0; k < later.size(); ++k) tracker.update(later[k], stamps[k], out, &ego);
  EXPECT_EQ(testing::heap_allocations() - before, 0);
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_EQ(out.seen[0].track_id, 0);
  // Two seconds on, past the poses (stale): tracked in the sensor's frame, counted.
  const ScanResult stale = rotation(stamp + 20 * kPeriod);
  tracker.update(stale, stamp + 20 * kPeriod, out, &ego);
  EXPECT_EQ(out.ego_missing, 1);
  EXPECT_EQ(out.ego_last_miss, EgoLookup::kStale);
  ASSERT_EQ(out.seen.size(), 1u);
  EXPECT_FALSE(out.seen[0].odometry);
}

// The beam's footprint (TrackerOptions::beam_divergence_*): a tag at 28 m whose cells that tell
// its code from the nearest other function are each read by 2 returns at their centre and by 6
// near a corner whose footprints (42 mm across, 0.28 of a 0.15 m cell) lie mostly on neighbours of
// the other function's colour there. Weighted by how much of each footprint stays in its cell
// (0.2 for the corner returns), the cell centres decide and the right code leads and confirms;
// with every vote counted fully (divergences 0) the corners outvote them and the other function
// leads, rotation after rotation.
TEST_F(TrackerTest, VotesAreWeightedByTheShareOfTheirFootprintInsideTheirCell) {
  const int f = 12;  // code 3, no quarter turn
  const int rival = closest_other(f);
  ASSERT_GE(rival, 0);
  Cand c;
  c.position = {28.0, 0.0, 0.0};
  c.points = 60;
  c.votes = 2;
  c.blurred = std::vector<bool>(64);  // each set below (assign() trips GCC 12 at -O3)
  for (int i = 0; i < 64; ++i)
    c.blurred[static_cast<size_t>(i)] = dict.signs(f)[i] != dict.signs(rival)[i];
  c.blurred_votes = 6;
  c.blurred_function = rival;
  {
    Tracker tracker({}, det_opt);
    for (int k = 0; k < 10; ++k) step(tracker, {c});
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_EQ(out.seen[0].id, c.code);
    EXPECT_GE(out.seen[0].margin_cells, TrackerOptions{}.min_margin_cells);
    EXPECT_TRUE(out.seen[0].confirmed);
  }
  TrackerOptions full;
  full.beam_divergence_h_mrad = full.beam_divergence_v_mrad = 0.0;
  Tracker tracker(full, det_opt);
  for (int k = 0; k < 10; ++k) {
    step(tracker, {c});
    ASSERT_EQ(out.seen.size(), 1u);
    EXPECT_NE(out.seen[0].id, c.code);
  }
}

TEST(TrackerOptionsTest, EveryRuleOfTheTableIsChecked) {
  const DetectorOptions det;
  EXPECT_NO_THROW(Tracker({}, det));
  auto broken = [&](auto change) {
    TrackerOptions o;
    change(o);
    EXPECT_THROW(validate_tracker_options(o), OptionsError);
    EXPECT_THROW(Tracker(o, det), OptionsError);
  };
  broken([](TrackerOptions& o) { o.max_distance_m = 0.0; });
  broken([](TrackerOptions& o) { o.max_angle_deg = 45.0; });
  broken([](TrackerOptions& o) { o.max_angle_deg = std::nan(""); });
  broken([](TrackerOptions& o) { o.min_margin_cells = -1.0; });
  broken([](TrackerOptions& o) { o.full_cell_votes = 0.5; });
  broken([](TrackerOptions& o) { o.min_rotations = 0; });
  broken([](TrackerOptions& o) { o.window = 0; });
  broken([](TrackerOptions& o) { o.window = 1001; });
  broken([](TrackerOptions& o) { o.max_age_s = 0.0; });
  broken([](TrackerOptions& o) { o.max_age_s = 1e300; });
  broken([](TrackerOptions& o) { o.max_tracks = 0; });
  broken([](TrackerOptions& o) { o.pose_noise_m_points = -1.0; });
  broken([](TrackerOptions& o) { o.pose_noise_deg_points = std::nan(""); });
  broken([](TrackerOptions& o) { o.gate_sigmas = 0.0; });
  broken([](TrackerOptions& o) { o.fused_min_score = 0.4; });
  broken([](TrackerOptions& o) { o.fused_min_score = 1.1; });
  broken([](TrackerOptions& o) { o.fused_min_margin_cells = 0.0; });
  broken([](TrackerOptions& o) { o.wide_min_score = 0.4; });
  broken([](TrackerOptions& o) { o.wide_min_margin_cells = std::nan(""); });
  broken([](TrackerOptions& o) { o.beam_divergence_h_mrad = -1.0; });
  broken([](TrackerOptions& o) { o.beam_divergence_v_mrad = 101.0; });
  try {
    TrackerOptions o;
    o.window = 0;
    validate_tracker_options(o);
    ADD_FAILURE() << "accepted";
  } catch (const OptionsError& e) {
    EXPECT_EQ(e.key(), "tracker.window");
    EXPECT_EQ(e.value(), "0");
    EXPECT_EQ(e.reason(), "must be in [1, 1000]");
  }
}

}  // namespace
}  // namespace lidartag::detector
