// The tracker: association by pose, cell votes summed in each track's own frame, confirmation by
// the margin of the leading function over the votes, and the mean pose and spread over a window.
#include "lidartag/detector/tracker.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <span>
#include <string_view>
#include <type_traits>

#include "lidartag/detector/decode_cluster.hpp"
#include "lidartag/detector/fused_grid.hpp"
#include "lidartag/detector/tag_family.hpp"

namespace lidartag::detector {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Every function's inner product with per-cell values on the dictionary's varying cells (the
// other cells add the same to every function), by tables of the 256 sign patterns of each group
// of 8 cells, as decode_prepared scores the kernel evidence.
void score_functions(const RkhsDictionary& dict, const std::vector<float>& values,
                     std::vector<float>& tables, std::vector<float>& scores) {
  const size_t groups = dict.chunk_count();
  tables.resize(groups * 256);
  for (size_t g = 0; g < groups; ++g) {
    float* table = tables.data() + g * 256;
    const size_t n = std::min<size_t>(8, values.size() - 8 * g);
    table[0] = 0.0f;
    for (size_t i = 0; i < n; ++i) table[0] -= values[8 * g + i];
    for (unsigned m = 1; m < 256; ++m) {
      const unsigned low = static_cast<unsigned>(std::countr_zero(m));
      table[m] = low < n ? table[m & (m - 1)] + 2.0f * values[8 * g + low] : 0.0f;
    }
  }
  const int nf = dict.functions();
  scores.resize(static_cast<size_t>(nf));
  for (int f = 0; f < nf; ++f) {
    const uint8_t* idx = dict.chunks(f);
    float sum = 0.0f;
    for (size_t g = 0; g < groups; ++g) sum += tables[g * 256 + idx[g]];
    scores[static_cast<size_t>(f)] = sum;
  }
}

// Rx(q pi / 2): a quarter turn about the tag's normal (x).
Eigen::Matrix3d quarter_turn(int q) {
  return Eigen::AngleAxisd(q * std::numbers::pi / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
}

// A square-mounted tag's track searches where the tag sits along its unseen axis over the votes of
// every rotation: kShifts grids of cell votes, grid g shifted by (g - kCentre) quarter cells along
// that axis from the track's pose (a cell either way, as decoding searches one rotation). Grid
// kCentre is the track's pose itself, the only one of a track whose tags were seen on every side.
constexpr int kShifts = 9;
constexpr int kCentre = kShifts / 2;

// How much better another built-in family must fit a track's fused votes (best_decoy_score)
// to keep it from confirming: far tags of another family, cut to their size, whose votes led a
// tag16h5 code by 0.75 cells or more (tag25h9 and tag36h11 at 24-32 m and 45 degrees, 90 runs
// each) fitted their own family better in 463 of 469 rotations, by up to 0.15; the right tag16h5
// codes fitted worse than some other family's best in 7 of 1,361 (by up to 0.03), and a sparse
// grid lets a large family (tag36h11's 2,348 functions) come close to a fit by chance: at 0.01
// an OS1-64's tags at 20 m face-on lost 4.3 points (71.2 -> 66.9 %, 30 runs), at 0.02 none, and
// the far tag25h9 that had been confirmed as tag16h5 is refused at 0.01, 0.02 and 0.03 alike.
// Only a track that fits its own code well gets it: its rotations' mean score or its fused grid's
// at max(decode.min_score, fused_min_score) or more. The right tracks that needed it scored
// 0.94-0.98 / 0.91-0.95 there (mean / fused: an OS1-64 at 20 m face-on), and 0.92-0.94 / 0.88
// (an OS1-128 at 28 m face-on); a tag36h11 printed at 28 m and 45 degrees was confirmed as
// tag16h5 code 27 at 0.81 / 0.85, tag36h11's best fitting its votes better by 0.009.
constexpr double kDecoyTolerance = 0.02;

// The least position scatter the motion fit assumes, metres (a near tag's: 1-3 mm at 6 m on a
// VLP-16).
constexpr double kMinNoiseM = 0.002;

// The widest angle gate that the pose noise opens (quarter turns, 90 degrees apart, stay apart).
constexpr double kMaxGateDeg = 30.0;

// The most vote points of a rotation whose directions a track keeps to tell whether the next
// rotation samples its tag anew (the sparse far tags the fused grid is for have 30-160).
constexpr size_t kSampleDirections = 256;

// A rotation samples its tag anew when its points fall between the previous rotation's by at
// least this share of their own spacing (resampling()): measured, 0.0001-0.0004 for a static
// OS1-64 or OS1-128 at 20-24 m, 0.45-0.55 for a VLP-16 or VLP-32C at 600 rpm (0.1 against the
// rotation before the previous one).
constexpr double kResampledShare = 0.05;

// Directions closer than this (radians) are one beam's: a dual return's two points.
constexpr float kSameDirection = 5e-4f;

// The points of a rotation resampling() measures, at most (each against every point of both).
constexpr size_t kResamplingProbes = 32;

// How far a rotation's samples fall from the previous rotation's, as a share of their own
// spacing: over the points of `now` (unit directions from the sensor), the median chord to the
// nearest direction of `before`, over the median chord to the nearest other direction of `now`.
// About 0 when the sensor fires at the same angles in every rotation (an Ouster's columns sit at
// fixed encoder angles; a static sensor); a Velodyne's firings drift by a fraction of their step
// from one rotation to the next. `scratch` holds 2 kResamplingProbes floats.
double resampling(std::span<const Eigen::Vector3f> now, std::span<const Eigen::Vector3f> before,
                  std::vector<float>& scratch) {
  if (now.size() < 2 || before.empty()) return 1.0;
  // Up to kResamplingProbes of the points, spread over them: the two figures are far apart.
  const size_t step = (now.size() + kResamplingProbes - 1) / kResamplingProbes;
  const size_t probes = (now.size() + step - 1) / step;
  scratch.resize(2 * probes);
  for (size_t j = 0; j < probes; ++j) {
    const Eigen::Vector3f& d = now[j * step];
    float to_before = std::numeric_limits<float>::infinity(), to_own = to_before;
    for (const Eigen::Vector3f& b : before) to_before = std::min(to_before, (d - b).norm());
    for (const Eigen::Vector3f& o : now) {
      const float e = (d - o).norm();
      if (e > kSameDirection) to_own = std::min(to_own, e);
    }
    scratch[j] = to_before;
    scratch[probes + j] = to_own;
  }
  const auto n = static_cast<std::ptrdiff_t>(probes);
  const auto mid = scratch.begin() + n / 2;
  std::nth_element(scratch.begin(), mid, scratch.begin() + n);
  std::nth_element(scratch.begin() + n, mid + n, scratch.end());
  const float own = *(mid + n);
  return std::isfinite(own) ? *mid / own : 1.0;
}

// A beam's footprint on the tag, in cells of the track's grid: its half-extent across a column
// border (along the track frame's y) and across a row border (along its z). 0: a point.
struct Footprint {
  double across_column = 0.0, across_row = 0.0;
};

// The footprint of the beam to `point` (sensor's frame; an ellipse of full divergences div_h_rad
// across the scan and div_v_rad along it) laid on the tag's plane (normal `normal`) and turned
// into the track's frame (`to_track`; cells_per_m the grid's cells per metre). Across a border its
// half-extent is the ellipse's support along the border's normal. At 28 m and 45 degrees a
// VLP-32C's 3 mrad footprint is 0.12 m wide on the tag, 0.8 of a 1.2 m tag16h5's cell.
Footprint footprint_on_tag(const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                           const Eigen::Matrix3d& to_track, double div_h_rad, double div_v_rad,
                           double cells_per_m) {
  const double r = point.norm();
  if (!(r > 0.0) || !(div_h_rad > 0.0 || div_v_rad > 0.0)) return {};
  const Eigen::Vector3d b = point / r;
  Eigen::Vector3d h = Eigen::Vector3d::UnitZ().cross(b);
  if (!(h.norm() > 1e-9)) return {};
  h.normalize();
  const Eigen::Vector3d v = b.cross(h);
  // A ray offset by e from the beam's axis meets the plane at e - b (e . n) / (b . n) from the
  // point (grazing incidence capped at about 87 degrees).
  const double bn =
      b.dot(normal) < 0.0 ? std::min(b.dot(normal), -0.05) : std::max(b.dot(normal), 0.05);
  const Eigen::Vector3d eh =
      to_track * (h - b * (h.dot(normal) / bn)) * (r * div_h_rad / 2.0 * cells_per_m);
  const Eigen::Vector3d ev =
      to_track * (v - b * (v.dot(normal) / bn)) * (r * div_v_rad / 2.0 * cells_per_m);
  return {std::hypot(eh.y(), ev.y()), std::hypot(eh.z(), ev.z())};
}

// How purely a return's intensity is its cell's colour, from its footprint and its place in its
// cell (uc, ur: fractions of the cell along the grid's columns and rows): a footprint of
// half-extent e centred d inside a border covers the cell with (e + d) / 2e of its width, and its
// return is the cell's colour less the neighbour's share, min(1, d / e) over both axes: 1 for a
// footprint inside its cell, 0 on a border. A ring that crosses a cell only at its corner reads
// mostly its neighbours.
double footprint_purity(const Footprint& fp, double uc, double ur) {
  double purity = 1.0;
  if (fp.across_column > 0.0) purity = std::min(purity, std::min(uc, 1.0 - uc) / fp.across_column);
  if (fp.across_row > 0.0) purity = std::min(purity, std::min(ur, 1.0 - ur) / fp.across_row);
  return std::clamp(purity, 0.0, 1.0);
}

// A cell's mean vote for the scores: its votes weighted by their purity (footprint_purity), over
// their weight, times min(votes, full_cell_votes) / full_cell_votes (a cell with fewer votes
// counts proportionally less). 0 for a cell whose returns all straddle its borders.
float cell_value(float votes, float purity, float counts, float full) {
  return purity > 0.0f ? votes / purity * (counts / std::max(counts, full)) : 0.0f;
}

// A grid's votes for fused_grid_score: each cell's purity-weighted mean vote times its number of
// votes (`votes`, `purity` and `counts` of one grid, `out` resized to them).
void fused_votes(std::span<const float> votes, std::span<const float> purity,
                 std::span<const float> counts, std::vector<float>& out) {
  out.resize(counts.size());
  for (size_t i = 0; i < counts.size(); ++i)
    out[i] = cell_value(votes[i], purity[i], counts[i], 0.0f) * counts[i];
}

}  // namespace

namespace {

// Throws the detector's error for the first tracker option that breaks its rule.
void fail(const std::string& key, const std::string& value, const std::string& reason) {
  throw OptionsError(key, value, reason);
}

}  // namespace

void validate_tracker_options(const TrackerOptions& options) {
  TrackerOptions copy = options;  // the visitor takes fields by reference
  rules::RuleChecker checker("tracker.", fail);
  visit_tracker_options(checker, copy);
}

struct Tracker::Track {
  bool live = false;
  bool seen_now = false;  // took a candidate in the current update
  int id = -1;
  int family = 0;
  double size_m = 0.0;
  int rotations = 0;  // rotations seen
  int validated = 0;  // of those, rotations whose candidate passed validation (not track-only)
  // Of the rotations after the first, those that sampled the tag anew (resampling(); a rotation
  // with more than kSampleDirections points counts as anew), and the directions of the last
  // rotation's vote points from the sensor (kSampleDirections at most; empty: more).
  int resampled = 0;
  std::vector<Eigen::Vector3f> last_directions;
  int64_t last_seen_ns = 0;
  // Per function of the family in the track's frame (4 code + quarter turns): summed normalised
  // scores. Per cell of the marker in the track's frame: the votes (+1 white, -1 black) of the
  // points well inside it, each times its purity (footprint_purity), summed; their purities
  // summed; and their number.
  std::vector<double> score_sum;
  std::vector<float> votes, purity, counts;  // kShifts grids of W x W cells (kCentre unshifted)
  // The same on each decoy family's grid (Tracker::decoys_), kShifts of them: shift g's grids
  // from g x decoy_cells_ on.
  std::vector<float> decoy_votes, decoy_purity, decoy_counts;
  // The axis of the track's frame along which its tag's place is searched (1: y, 2: z; 0: none,
  // every side seen), from its first candidate whose shift decoding searched; the extent of the
  // voted points along it (track frame, metres), and the grid that leads.
  int axis = 0;
  bool square = false;  // the axis lies along or across the rings (square_mount_axis)
  double lo = 0.0, hi = 0.0;
  int shift = kCentre;
  // Over the rotations in which the families not configured were decoded: their best score and
  // the configured family's best score, summed, and the number of those rotations.
  double other_sum = 0.0, own_sum = 0.0;
  int other_count = 0;
  // The window: the candidates' poses at their times, frames turned into the track's frame
  // (quarter turns taken out); a ring of opt_.window.
  std::vector<TimedPose> window;
  std::vector<int> window_points;  // the candidates' pose-fit points (their expected noise)
  int window_count = 0, window_next = 0;
  // The expected scatter of one candidate's pose over the window (TrackerOptions::pose_noise_*,
  // RMS over its candidates): metres and degrees.
  double noise_m = 0.0, noise_deg = 0.0;
  // The window's model: the pose at the newest candidate's time, and how it moves from there.
  double ref_t_s = 0.0;
  Eigen::Vector3d ref_position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond ref_frame = Eigen::Quaterniond::Identity();
  Motion motion;
  bool moving = false;
  // The same window in the odometry frame, where the ego-motion placed its candidates
  // (odometry[i] valid when placed[i], of odometry frame segment[i]); its model, valid when every
  // pose of the window is placed in one frame, and the sensor's pose at the newest candidate.
  std::vector<TimedPose> odometry;
  std::vector<uint8_t> placed;
  std::vector<uint32_t> segment;
  bool odom_valid = false;
  TimedPose odom_ref;
  Motion odom_motion;
  EgoPose ego_now;
  // The size check: measured sizes of its candidates, summed, and how many.
  double size_sum = 0.0;
  int size_count = 0;
  Eigen::Vector3d position_std = Eigen::Vector3d::Zero();
  double angle_std_deg = 0.0;
  int leader = -1;
  double margin = 0.0, mean_score = 0.0;
  bool confirmed = false;
  int confirmed_leader = -1;  // the leader of its last confirmation, while it keeps leading
  // This rotation's candidate: its index and the quarter turns from its frame to the track's.
  int candidate = -1;
  int delta = 0;
};

Tracker::Tracker(TrackerOptions options, const DetectorOptions& detector)
    : opt_(std::move(options)),
      min_score_(detector.decode.min_score),
      size_warning_ratio_(detector.pose.size_warning_ratio),
      vote_inset_(detector.decode.vote_inset_cells) {
  validate_tracker_options(opt_);
  int most = 0, cells = 0;
  try {
    for (const auto& name : detector.families) {
      const tags::TagFamily fam = tags::resolve_family(name);
      families_.push_back({RkhsDictionary(fam), 4 * fam.ncodes(),
                           static_cast<double>(fam.width_at_border) / fam.total_width / 2.0});
      most = std::max(most, 4 * fam.ncodes());
      cells = std::max(cells, fam.total_width * fam.total_width);
    }
    if (detector.decode.reject_other_families) {
      std::vector<std::string> configured;
      for (const Family& f : families_) configured.push_back(f.dict.family().name);
      decoys_ = other_builtin_dictionaries(configured);
    }
  } catch (const tags::FamilyError& e) {
    throw OptionsError("families", "", e.what());
  }
  for (const auto& d : decoys_) {
    decoy_offsets_.push_back(decoy_cells_);
    decoy_cells_ += static_cast<size_t>(d.width() * d.width());
    most = std::max(most, d.functions());
    cells = std::max(cells, d.width() * d.width());
  }
  tracks_.resize(static_cast<size_t>(opt_.max_tracks));
  scores_.reserve(static_cast<size_t>(most));
  best_.reserve(static_cast<size_t>(most));
  best_grid_.reserve(static_cast<size_t>(most));
  values_.reserve(static_cast<size_t>(cells));
  fused_votes_.reserve(static_cast<size_t>(cells));
  tables_.reserve(static_cast<size_t>(cells / 8 + 1) * 256);
  for (Track& t : tracks_) {
    t.score_sum.assign(static_cast<size_t>(most), 0.0);
    t.votes.assign(static_cast<size_t>(kShifts * cells), 0.0f);
    t.purity.assign(static_cast<size_t>(kShifts * cells), 0.0f);
    t.counts.assign(static_cast<size_t>(kShifts * cells), 0.0f);
    t.decoy_votes.assign(kShifts * decoy_cells_, 0.0f);
    t.decoy_purity.assign(kShifts * decoy_cells_, 0.0f);
    t.decoy_counts.assign(kShifts * decoy_cells_, 0.0f);
    t.window.resize(static_cast<size_t>(opt_.window));
    t.window_points.assign(static_cast<size_t>(opt_.window), 0);
    t.odometry.resize(static_cast<size_t>(opt_.window));
    t.placed.assign(static_cast<size_t>(opt_.window), 0);
    t.segment.assign(static_cast<size_t>(opt_.window), 0);
    t.last_directions.reserve(kSampleDirections);
  }
  directions_.reserve(kSampleDirections);
  resampling_scratch_.reserve(2 * kResamplingProbes);
  ordered_.reserve(static_cast<size_t>(opt_.window));
  pairs_.reserve(64);
  assigned_.reserve(64);
  placed_.reserve(64);
}

Tracker::~Tracker() = default;

void Tracker::reset() {
  for (Track& t : tracks_) t.live = false;
  have_stamp_ = false;
  fleet_ = {};
}

namespace {

// The quarter turns delta (0..3) that bring `frame` closest to `ref` (frame * Rx(delta pi/2) ~
// ref), and the angle left, radians. The trace of ref^T frame Rx(phi) is
// M00 + cos(phi) (M11 + M22) + sin(phi) (M12 - M21).
double aligned_angle(const Eigen::Matrix3d& ref, const Eigen::Matrix3d& frame, int& delta) {
  const Eigen::Matrix3d m = ref.transpose() * frame;
  const double a = m(1, 1) + m(2, 2), b = m(1, 2) - m(2, 1);
  const double traces[4] = {m(0, 0) + a, m(0, 0) + b, m(0, 0) - a, m(0, 0) - b};
  delta = static_cast<int>(std::max_element(traces, traces + 4) - traces);
  return std::acos(std::clamp((traces[delta] - 1.0) / 2.0, -1.0, 1.0));
}

}  // namespace

void Tracker::update(const ScanResult& result, int64_t stamp_ns, TrackerResult& out,
                     const EgoMotion* ego) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  out.tags.clear();
  out.seen.clear();
  out.tracks = out.confirmed_tracks = 0;
  out.truncated = false;
  out.ego_placed = out.ego_missing = 0;
  out.ego_last_miss = EgoLookup::kOk;
  try {
    track(result, stamp_ns, out, ego);
  } catch (...) {
    // Only allocation failure can get here (the buffers grow to the scene): the report of this
    // rotation is incomplete and says so.
    out.truncated = true;
  }
  out.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::track(const ScanResult& result, int64_t stamp_ns, TrackerResult& out,
                    const EgoMotion* ego) {
  if (have_stamp_ && stamp_ns < last_stamp_ns_) reset();
  if (!have_stamp_) epoch_ns_ = stamp_ns;
  have_stamp_ = true;
  last_stamp_ns_ = stamp_ns;
  // Stamps never decrease from here, so last_seen_ns <= stamp_ns: the unsigned difference is
  // exact whatever the stamps (max_age_s <= 1e6 s).
  const auto max_age_ns = static_cast<uint64_t>(opt_.max_age_s * 1e9);
  for (Track& t : tracks_) {
    t.seen_now = false;
    t.candidate = -1;
    if (t.live &&
        static_cast<uint64_t>(stamp_ns) - static_cast<uint64_t>(t.last_seen_ns) > max_age_ns)
      t.live = false;
  }

  update_fleet();

  // Every (candidate, track) pair inside both gates, cheapest first; each takes at most one. A
  // track is met where its motion puts it at the candidate's time.
  const auto& cands = result.candidates;
  pairs_.clear();
  assigned_.assign(cands.size(), -1);
  // Each candidate in the odometry frame, at its own time, where the ego-motion has a pose.
  placed_.assign(cands.size(), Placed{});
  for (size_t c = 0; c < cands.size() && ego != nullptr; ++c) {
    const Candidate& cand = cands[c];
    if (evidence(cand, result) == nullptr) continue;
    // Its firing time after the scan's stamp (a rotation lasts well under a second; anything
    // else is no time and takes the stamp's).
    const double dt = std::abs(cand.time_center_s) < 10.0 ? cand.time_center_s : 0.0;
    Placed& p = placed_[c];
    const EgoLookup found = ego->at(stamp_ns + static_cast<int64_t>(std::llround(dt * 1e9)), p.ego);
    if (found != EgoLookup::kOk) {
      ++out.ego_missing;
      out.ego_last_miss = found;
      continue;
    }
    ++out.ego_placed;
    p.ok = true;
    p.position = p.ego.orientation * cand.position + p.ego.position;
    p.frame = p.ego.orientation.toRotationMatrix() *
              cand.undecoded_orientation.normalized().toRotationMatrix();
  }
  for (size_t c = 0; c < cands.size(); ++c) {
    const Candidate& cand = cands[c];
    if (evidence(cand, result) == nullptr) continue;
    const Eigen::Matrix3d frame = cand.undecoded_orientation.normalized().toRotationMatrix();
    const double t_c = time_of(cand, stamp_ns);
    const Placed& pl = placed_[c];
    for (size_t k = 0; k < tracks_.size(); ++k) {
      const Track& t = tracks_[k];
      if (!t.live || t.family != cand.family_index || std::abs(t.size_m - cand.size_m) > 1e-9)
        continue;
      const Gates g = gates(t, cand);
      if (pl.ok && t.odom_valid && t.ego_now.segment == pl.ego.segment) {
        // Both in one odometry frame: the track's model there (a static tag stands still).
        const TimedPose at = predict(t.odom_ref, t.odom_motion, t_c - t.odom_ref.t_s);
        const double d = (pl.position - at.position).norm();
        if (d > g.distance_m) continue;
        int delta = 0;
        const double angle = aligned_angle(at.frame.toRotationMatrix(), pl.frame, delta);
        if (angle > g.angle_rad) continue;
        pairs_.push_back({d / g.distance_m + angle / g.angle_rad, static_cast<int>(c),
                          static_cast<int>(k), delta});
        continue;
      }
      // A track seen once has no motion of its own: the other tags' when they show it, else
      // gates as wide as the sensor's motion allows.
      const Motion& m = t.window_count == 1 && fleet_.known ? fleet_ : t.motion;
      const double dt = t_c - t.ref_t_s;
      const TimedPose at = predict({t.ref_t_s, t.ref_position, t.ref_frame}, m, dt);
      double max_distance = g.distance_m, max_angle = g.angle_rad;
      if (opt_.follow_motion && !m.known) {
        const double turned = opt_.max_turn_deg_s * kDeg * std::abs(dt);
        max_distance +=
            std::min(opt_.max_speed_mps * std::abs(dt) + turned * at.position.norm(), t.size_m / 2);
        max_angle += std::min(turned, 30.0 * kDeg);
      }
      const double d = (cand.position - at.position).norm();
      if (d > max_distance) continue;
      int delta = 0;
      const double angle = aligned_angle(at.frame.toRotationMatrix(), frame, delta);
      if (angle > max_angle) continue;
      pairs_.push_back(
          {d / max_distance + angle / max_angle, static_cast<int>(c), static_cast<int>(k), delta});
    }
  }
  std::sort(pairs_.begin(), pairs_.end(),
            [](const Pair& a, const Pair& b) { return a.cost < b.cost; });
  for (const Pair& p : pairs_) {
    Track& t = tracks_[static_cast<size_t>(p.track)];
    if (t.seen_now || assigned_[static_cast<size_t>(p.candidate)] >= 0) continue;
    t.seen_now = true;
    t.candidate = p.candidate;
    t.delta = p.delta;
    assigned_[static_cast<size_t>(p.candidate)] = p.track;
  }
  // The others start tracks: a free slot, else the one seen longest ago (not in this rotation).
  for (size_t c = 0; c < cands.size(); ++c) {
    if (assigned_[c] >= 0 || evidence(cands[c], result) == nullptr) continue;
    int slot = -1;
    for (size_t k = 0; k < tracks_.size() && slot < 0; ++k)
      if (!tracks_[k].live) slot = static_cast<int>(k);
    for (size_t k = 0; k < tracks_.size() && slot < 0; ++k)
      if (!tracks_[k].seen_now)
        if (slot < 0 || tracks_[k].last_seen_ns < tracks_[static_cast<size_t>(slot)].last_seen_ns)
          slot = static_cast<int>(k);
    if (slot < 0) continue;  // more candidates than tracks: this one stays untracked
    Track& t = tracks_[static_cast<size_t>(slot)];
    start(t, cands[c]);
    t.seen_now = true;
    t.candidate = static_cast<int>(c);
    t.delta = 0;
    assigned_[c] = slot;
  }
  for (Track& t : tracks_) {
    if (!t.seen_now) continue;
    add(t, cands[static_cast<size_t>(t.candidate)], result, stamp_ns);
  }
  report(result, out);
}

Tracker::Gates Tracker::gates(const Track& t, const Candidate& c) const {
  // The difference between a candidate and its track's prediction: the candidate's own scatter
  // and the track's, which averages its window's (both at least what the window showed about its
  // model).
  const double points = std::max(c.points, 1);
  const double spread_m = t.position_std.norm(), spread_deg = t.angle_std_deg;
  const double n = std::max(t.window_count, 1);
  const double own_m = std::max(opt_.pose_noise_m_points / points, spread_m);
  const double own_deg = std::max(opt_.pose_noise_deg_points / points, spread_deg);
  const double track_m = std::max(t.noise_m, spread_m),
               track_deg = std::max(t.noise_deg, spread_deg);
  const double sigma_m = std::sqrt(own_m * own_m + track_m * track_m / n);
  const double sigma_deg = std::sqrt(own_deg * own_deg + track_deg * track_deg / n);
  Gates g;
  g.distance_m = std::min(std::max(opt_.max_distance_m, opt_.gate_sigmas * sigma_m),
                          std::max(opt_.max_distance_m, t.size_m / 2));
  g.angle_rad = kDeg * std::min(std::max(opt_.max_angle_deg, opt_.gate_sigmas * sigma_deg),
                                std::max(opt_.max_angle_deg, kMaxGateDeg));
  return g;
}

double Tracker::time_of(const Candidate& c, int64_t stamp_ns) const {
  const double t = static_cast<double>(stamp_ns - epoch_ns_) * 1e-9 + c.time_center_s;
  return std::isfinite(t) ? t : static_cast<double>(stamp_ns - epoch_ns_) * 1e-9;
}

void Tracker::update_fleet() {
  // The track with the longest window that fits its own motion tells how the world moves
  // through the sensor's frame; a tie goes to a tag standing still.
  fleet_ = {};
  if (!opt_.follow_motion) return;
  int best = 2;
  bool best_moving = true;
  for (const Track& t : tracks_) {
    if (!t.live || t.window_count < 3) continue;
    if (t.window_count > best || (t.window_count == best && best_moving && !t.moving)) {
      best = t.window_count;
      best_moving = t.moving;
      fleet_ = t.motion;
    }
  }
}

const FamilyEvidence* Tracker::evidence(const Candidate& c, const ScanResult& result) const {
  if (c.family_index < 0 || static_cast<size_t>(c.family_index) >= families_.size()) return nullptr;
  const Family& fam = families_[static_cast<size_t>(c.family_index)];
  const auto all = result.evidence_of(c);
  if (static_cast<size_t>(c.family_index) >= all.size()) return nullptr;
  const FamilyEvidence& e = all[static_cast<size_t>(c.family_index)];
  const int w = fam.dict.width();
  const bool ok =
      e.family_index == c.family_index && e.functions == fam.functions &&
      result.scores_of(e).size() == static_cast<size_t>(fam.functions) &&
      std::isfinite(e.cells_per_score) && e.cells_per_score > 0.0f && c.grid_width == w &&
      result.vote_points_of(c).size() == static_cast<size_t>(std::max(c.vote_point_count, 0)) &&
      c.position.allFinite() && c.undecoded_orientation.coeffs().allFinite() &&
      c.undecoded_orientation.norm() > 0.5;
  return ok ? &e : nullptr;
}

void Tracker::start(Track& t, const Candidate& c) {
  t.live = true;
  t.id = next_id_++;
  t.family = c.family_index;
  t.size_m = c.size_m;
  t.rotations = 0;
  t.validated = 0;
  const size_t n = static_cast<size_t>(families_[static_cast<size_t>(c.family_index)].functions);
  std::fill(t.score_sum.begin(), t.score_sum.begin() + static_cast<std::ptrdiff_t>(n), 0.0);
  std::fill(t.votes.begin(), t.votes.end(), 0.0f);
  std::fill(t.purity.begin(), t.purity.end(), 0.0f);
  std::fill(t.counts.begin(), t.counts.end(), 0.0f);
  std::fill(t.decoy_votes.begin(), t.decoy_votes.end(), 0.0f);
  std::fill(t.decoy_purity.begin(), t.decoy_purity.end(), 0.0f);
  std::fill(t.decoy_counts.begin(), t.decoy_counts.end(), 0.0f);
  t.axis = 0;
  t.resampled = 0;
  t.last_directions.clear();
  t.square = false;
  t.lo = t.hi = 0.0;
  t.shift = kCentre;
  t.other_sum = t.own_sum = 0.0;
  t.other_count = 0;
  t.window_count = t.window_next = 0;
  t.ref_position = c.position;
  t.ref_frame = c.undecoded_orientation.normalized();
  t.motion = {};
  t.moving = false;
  t.odom_valid = false;
  t.size_sum = 0.0;
  t.size_count = 0;
  t.leader = -1;
  t.confirmed = false;
  t.confirmed_leader = -1;
}

void Tracker::add(Track& t, const Candidate& c, const ScanResult& result, int64_t stamp_ns) {
  ++t.rotations;
  t.validated += c.track_only ? 0 : 1;
  t.last_seen_ns = stamp_ns;
  if (c.measured_size_m > 0.0) {
    t.size_sum += c.measured_size_m;
    ++t.size_count;
  }
  // The window: the frame turned into the track's frame, at the candidate's time.
  const auto w = static_cast<size_t>(t.window_next);
  t.window[w] = {time_of(c, stamp_ns), c.position,
                 Eigen::Quaterniond(c.undecoded_orientation.normalized().toRotationMatrix() *
                                    quarter_turn(t.delta))};
  const Placed& pl = placed_[static_cast<size_t>(&c - result.candidates.data())];
  t.placed[w] = pl.ok ? 1 : 0;
  if (pl.ok) {
    t.odometry[w] = {t.window[w].t_s, pl.position,
                     Eigen::Quaterniond(pl.frame * quarter_turn(t.delta)).normalized()};
    t.segment[w] = pl.ego.segment;
    t.ego_now = pl.ego;
  }
  t.window_points[w] = std::max(c.points, 1);
  t.window_next = (t.window_next + 1) % opt_.window;
  t.window_count = std::min(t.window_count + 1, opt_.window);
  double inverse2 = 0.0;  // mean of 1 / points^2 over the window
  for (int i = 0; i < t.window_count; ++i) {
    const double p = t.window_points[static_cast<size_t>(i)];
    inverse2 += 1.0 / (p * p);
  }
  inverse2 = std::sqrt(inverse2 / t.window_count);
  t.noise_m = opt_.pose_noise_m_points * inverse2;
  t.noise_deg = opt_.pose_noise_deg_points * inverse2;
  ordered_.clear();
  for (int i = t.window_count; i > 0; --i)
    ordered_.push_back(
        t.window[static_cast<size_t>((t.window_next - i + opt_.window) % opt_.window)]);
  // Its model: the mean, or a constant motion when that explains it clearly better.
  // Motion is followed only once it is significant against the poses' noise: a turn rate 4
  // standard errors from zero, a drift beyond the scatter (fit_motion); the static world first.
  const MotionFit fit =
      opt_.follow_motion
          ? fit_motion(ordered_, fleet_, 4.0, std::max(kMinNoiseM, t.noise_m), t.noise_deg * kDeg)
          : fit_motion(ordered_, Motion{}, std::numeric_limits<double>::infinity());
  t.ref_t_s = fit.pose.t_s;
  t.ref_position = fit.pose.position;
  t.ref_frame = fit.pose.frame;
  t.motion = fit.motion;
  t.moving = fit.moving;
  t.position_std = fit.position_std_m;
  t.angle_std_deg = fit.angle_std_deg;
  // In the odometry frame, when the whole window is in one: a static tag's mean (or its own
  // motion, a tag carried), the sensor's motion taken out by the ego-motion.
  t.odom_valid = pl.ok;
  ordered_.clear();
  for (int i = t.window_count; i > 0 && t.odom_valid; --i) {
    const auto k = static_cast<size_t>((t.window_next - i + opt_.window) % opt_.window);
    t.odom_valid = t.placed[k] != 0 && t.segment[k] == pl.ego.segment;
    ordered_.push_back(t.odometry[k]);
  }
  if (t.odom_valid) {
    const MotionFit odom = fit_motion(ordered_, Motion{});
    t.odom_ref = odom.pose;
    t.odom_motion = odom.motion;
    t.position_std = odom.position_std_m;
    t.angle_std_deg = odom.angle_std_deg;
  }
  // Then the evidence, voted in the window's frame at this candidate's time. A track-only
  // candidate (too few boundary points for a detection of its own, eq. (6)) is evidence like any
  // other: the track's own gates decide.
  add_evidence(t, c, result);
}

void Tracker::add_evidence(Track& t, const Candidate& c, const ScanResult& result) {
  // Normalised scores, for the mean score of the leading function: function (code k, quarter
  // turns q) of the candidate's frame is (k, q + delta) of the track's frame (its tag frame is
  // frame Rx(-q pi/2) = aligned Rx(-(q + delta) pi/2)).
  const Family& fam = families_[static_cast<size_t>(t.family)];
  const auto s = result.scores_of(*evidence(c, result));
  const int n = fam.functions;
  for (int f = 0; f < n; ++f)
    t.score_sum[static_cast<size_t>((f & ~3) | (((f & 3) + t.delta) & 3))] +=
        s[static_cast<size_t>(f)];
  if (c.other_family_score >= 0.0) {
    t.other_sum += c.other_family_score;
    t.own_sum += c.score;
    ++t.other_count;
  }
  // Cell votes: the points decoding read, voted again in the track's mean frame (a rotation's own
  // pose scatters by 4-12 mm and 0.4-1.4 degrees at 10 m on a VLP-16, the mean of the window by a
  // few millimetres and tenths of a degree, and the cells crossed near their borders are the ones
  // that tell codes apart there). A cluster whose place along an unseen axis decoding searched (a
  // square mount: the rings run along its top and bottom edges) was placed where its best code
  // fits: its votes at that place agree with the decoder by construction. Its track searches
  // again, as decoding does for one rotation, over the votes of every rotation: every grid of
  // kShifts along that axis, where the points stay inside the tag, and the margin is taken
  // against the best other function at any of them.
  const int W = fam.dict.width();
  const auto cells = static_cast<size_t>(W * W);
  const double step = t.size_m / W / 4.0;
  // The track's frame and the candidate's pose, both in the odometry frame when the track is
  // there, else in the sensor's.
  const Placed& pl = placed_[static_cast<size_t>(&c - result.candidates.data())];
  const bool odom = t.odom_valid && pl.ok;
  const Eigen::Matrix3d to_track =
      (odom ? t.odom_ref.frame : t.ref_frame).toRotationMatrix().transpose();
  const Eigen::Matrix3d u =
      odom ? pl.frame : c.undecoded_orientation.normalized().toRotationMatrix();
  const Eigen::Vector3d offset =
      to_track * (odom ? pl.position - t.odom_ref.position : c.position - t.ref_position);
  const Eigen::Matrix3d m = to_track * u;
  if (c.shift_searched && t.axis == 0 && c.unseen_axis.allFinite() &&
      c.unseen_axis.squaredNorm() > 0.25) {
    const Eigen::Vector3d a =
        m * c.undecoded_orientation.normalized().toRotationMatrix().transpose() * c.unseen_axis;
    t.axis = std::abs(a.y()) >= std::abs(a.z()) ? 1 : 2;
    t.square = square_mount_axis(c.unseen_axis, a);
    t.lo = std::numeric_limits<double>::infinity();
    t.hi = -t.lo;
  }
  const int first_grid = t.axis == 0 ? kCentre : 0, last_grid = t.axis == 0 ? kCentre : kShifts - 1;
  // Each vote weighted by how purely its return is its cell's colour (footprint_purity; the
  // beam's footprint from the candidate's own pose in the sensor's frame, seen in the track's).
  const Eigen::Matrix3d frame = c.undecoded_orientation.normalized().toRotationMatrix();
  const Eigen::Matrix3d sensor_to_track = m * frame.transpose();
  const double div_h = opt_.beam_divergence_h_mrad * 1e-3,
               div_v = opt_.beam_divergence_v_mrad * 1e-3;
  const double cells_per_m = W / t.size_m;
  // The points' directions from the sensor, for whether this rotation sampled the tag anew (the
  // fused grid's premise, below): kept for up to kSampleDirections points.
  const auto vote_points = result.vote_points_of(c);
  const bool keep_directions = vote_points.size() <= kSampleDirections;
  directions_.clear();
  {
    for (const VotePoint& p : vote_points) {
      const Eigen::Vector3d local(p.x, p.y, p.z);
      const Eigen::Vector3d q = m * local + offset;
      const Eigen::Vector3d sensor = frame * local + c.position;
      if (keep_directions) directions_.push_back(sensor.normalized().cast<float>());
      const Footprint fp =
          footprint_on_tag(sensor, frame.col(0), sensor_to_track, div_h, div_v, cells_per_m);
      if (t.axis != 0) {
        t.lo = std::min(t.lo, q[t.axis]);
        t.hi = std::max(t.hi, q[t.axis]);
      }
      const float vote = point_vote(p.label);
      for (int g = first_grid; g <= last_grid; ++g) {
        const double sh = (g - kCentre) * step;
        const double y = q.y() - (t.axis == 1 ? sh : 0.0), z = q.z() - (t.axis == 2 ? sh : 0.0);
        const int i = vote_cell(y / t.size_m, z / t.size_m, W, vote_inset_);
        if (i >= 0) {
          const double fc = (y / t.size_m + 0.5) * W, fr = (0.5 - z / t.size_m) * W;
          const auto w =
              static_cast<float>(footprint_purity(fp, fc - std::floor(fc), fr - std::floor(fr)));
          const size_t k = static_cast<size_t>(g) * cells + static_cast<size_t>(i);
          t.votes[k] += w * vote;
          t.purity[k] += w;
          t.counts[k] += 1.0f;
        }
        // The decoy families' grids at the same shift: the footprint scales with their cells.
        for (size_t d = 0; d < decoys_.size(); ++d) {
          const int Wd = decoys_[d].width();
          const int j = vote_cell(y / t.size_m, z / t.size_m, Wd, vote_inset_);
          if (j < 0) continue;
          const double sc = static_cast<double>(Wd) / W;
          const double dc = (y / t.size_m + 0.5) * Wd, dr = (0.5 - z / t.size_m) * Wd;
          const auto wd =
              static_cast<float>(footprint_purity({fp.across_column * sc, fp.across_row * sc},
                                                  dc - std::floor(dc), dr - std::floor(dr)));
          const size_t kd =
              static_cast<size_t>(g) * decoy_cells_ + decoy_offsets_[d] + static_cast<size_t>(j);
          t.decoy_votes[kd] += wd * vote;
          t.decoy_purity[kd] += wd;
          t.decoy_counts[kd] += 1.0f;
        }
      }
    }
  }
  if (t.rotations > 1 &&
      (directions_.empty() || t.last_directions.empty() ||
       resampling(directions_, t.last_directions, resampling_scratch_) >= kResampledShare))
    ++t.resampled;
  t.last_directions.assign(directions_.begin(), directions_.end());
  // The decision: every function scored on the cells that tell functions apart, each cell's votes
  // averaged (a cell with fewer than full_cell_votes votes counts proportionally less), in each
  // grid whose shift keeps the points inside the tag (and the track's pose); each function's best
  // grid. The margin is in cells: the leading function beats the best other one on that many.
  const auto& vary = fam.dict.varying_cells();
  values_.resize(vary.size());
  const auto full = static_cast<float>(opt_.full_cell_votes);
  best_.assign(static_cast<size_t>(n), -1e30f);
  best_grid_.assign(static_cast<size_t>(n), kCentre);
  for (int g = first_grid; g <= last_grid; ++g) {
    const double sh = (g - kCentre) * step, slack = step / 2;
    if (g != kCentre && (sh < t.hi - t.size_m / 2 - slack || sh > t.lo + t.size_m / 2 + slack))
      continue;
    const size_t base = static_cast<size_t>(g) * cells;
    for (size_t k = 0; k < vary.size(); ++k) {
      const auto i = base + static_cast<size_t>(vary[k]);
      values_[k] = cell_value(t.votes[i], t.purity[i], t.counts[i], full);
    }
    score_functions(fam.dict, values_, tables_, scores_);
    for (int f = 0; f < n; ++f) {
      const auto k = static_cast<size_t>(f);
      if (scores_[k] > best_[k]) {
        best_[k] = scores_[k];
        best_grid_[k] = g;
      }
    }
  }
  int lead = 0;
  for (int f = 1; f < n; ++f)
    if (best_[static_cast<size_t>(f)] > best_[static_cast<size_t>(lead)]) lead = f;
  float rival = -1e30f;
  for (int f = 0; f < n; ++f)
    if (f != lead) rival = std::max(rival, best_[static_cast<size_t>(f)]);
  t.leader = lead;
  t.shift = best_grid_[static_cast<size_t>(lead)];
  t.margin = n > 1 ? (best_[static_cast<size_t>(lead)] - rival) / 2.0 : 1e9;
  t.mean_score = t.score_sum[static_cast<size_t>(lead)] / t.rotations;
  // The score: the rotations' mean, or the fused grid's under a stricter margin (the far edge,
  // where each rotation's own fit scores low: fused_grid_confirms), on the leader's own grid (the
  // unshifted one unless the track searches its place).
  const size_t lead_base = static_cast<size_t>(t.shift) * cells;
  const auto lead_counts = std::span<const float>(t.counts).subspan(lead_base, cells);
  fused_votes(std::span<const float>(t.votes).subspan(lead_base, cells),
              std::span<const float>(t.purity).subspan(lead_base, cells), lead_counts,
              fused_votes_);
  const auto lead_grid = std::span<const float>(fused_votes_);
  // The fused grid stands for finer sampling than any one rotation's only when the rotations
  // sampled the tag at different places (at least half of them anew): a static Ouster's columns
  // fall on the same spots in every rotation, its fused grid is one rotation's with less noise,
  // and an OS1-128's tag at 24 m and 45 degrees was confirmed through it as code 3 for 10 (margin
  // 1.1 cells, fused score 0.90, mean score 0.79) and as code 9 for 29.
  const bool resampled = 2 * t.resampled >= t.rotations - 1;
  const bool fused_path =
      resampled &&
      fused_grid_confirms(fam.dict, lead, lead_grid, lead_counts, opt_.full_cell_votes, t.margin,
                          min_score_, opt_.fused_min_score, opt_.fused_min_margin_cells);
  const double min_margin = t.square ? opt_.min_margin_cells_searched : opt_.min_margin_cells;
  // A track that no rotation validated (track-only candidates alone: too few points or boundary
  // points to stand alone, every rotation) confirms one rotation later: its first rotations are
  // sparse and biased alike (an OS1-128's tag at 20 m and 45 degrees confirmed code 15 for 17
  // after 3 such rotations, margin 0.82 cells, mean score 0.835; 17 led by 1.44 after 20).
  const int min_rotations = opt_.min_rotations + (t.validated == 0 ? 1 : 0);
  // Such a track's two views of its evidence must name the same function: the votes' leader also
  // leads the rotations' summed scores. An OS1-128's tag at 24 m and 45 degrees (fixed columns:
  // every rotation samples the same spots, 36-50 points, none validated) confirmed code 3 for 10
  // from its votes (margin 0.80-0.94 cells, mean score 0.83) while the rotations' own scores
  // favoured another. Not asked of a track with validated rotations: a static VLP-16's summed
  // scores are biased where its votes are not (docs/detector.md), and asking it there cost 3-6
  // points at 7-10 m.
  const auto sums = std::span<const double>(t.score_sum).first(static_cast<size_t>(n));
  const bool views_agree =
      t.validated > 0 || std::max_element(sums.begin(), sums.end()) - sums.begin() == lead;
  // The far edge's wide margin (TrackerOptions::wide_min_margin_cells): a fused grid below
  // fused_min_score still confirms when its leader stands out by a wider margin and no other
  // family fits its votes as well (below). A VLP-32C's 1.2 m tag16h5 cut to its size at 32 m and
  // 45 degrees, 30 runs: 37.3 -> 49.6 %.
  const double fused =
      fused_grid_score(fam.dict, lead, lead_grid, lead_counts, opt_.full_cell_votes);
  const bool wide_margin =
      resampled && !fused_path && t.mean_score < min_score_ &&
      t.margin >= std::max(opt_.wide_min_margin_cells, opt_.fused_min_margin_cells) &&
      fused >= std::max(min_score_, opt_.wide_min_score);
  // The score gates confirm a track; its lead keeps it: once a function confirmed, the track is
  // confirmed in every rotation where that function, in the lead ever since, leads by min_margin
  // (and both views agree), whatever its scores. A far tag's mean and fused scores wander about
  // their gates from one rotation to the next (a VLP-32C's 1.2 m tag16h5 cut to its size at 32 m
  // and 45 degrees: 3 of 30 runs confirmed, then dropped for a few rotations with the same leader
  // and margins of 0.86-1.25 cells).
  if (t.confirmed_leader != lead) t.confirmed_leader = -1;
  const bool kept = t.confirmed_leader == lead && t.margin >= min_margin && views_agree;
  t.confirmed = kept || (t.rotations >= min_rotations && t.margin >= min_margin &&
                         (t.mean_score >= min_score_ || fused_path || wide_margin) && views_agree);
  if (!t.confirmed) return;
  // Another family fitting better makes it that family's tag (as the detector's
  // decode/other_family for one rotation). Over the rotations whose candidates were decoded
  // against the other families, best against best as there: the leading function's own score is
  // lower in the rotations another function of the family led, and the decoys' best would beat
  // it by that alone (a VLP-32C's 1.2 m tag16h5 at 24 m and 45 degrees, whose codes tag16h6
  // shares, was never confirmed). And over the fused votes, on every other built-in family's own
  // grid at the leader's place (best_decoy_score): far tags' candidates are mostly too poor to
  // be decoded against the other families, and a 1.2 m tag25h9 at 24 m and 45 degrees, cut to
  // its size, was confirmed as a tag16h5 code by its rotations' mean score (0.823, margin 0.90
  // cells) while its fused votes fitted tag25h9 better. A track that fits its own code poorly
  // gets no tolerance (kDecoyTolerance): so also every track confirmed by the wide margin alone,
  // whose foreign tags of that test's kind (tag25h9, tag36h11 printed) reach its margin and score
  // in some rotations (with the tolerance one more was read as a tag16h5 code over 90 runs).
  const bool other_mean = t.other_count > 0 && t.other_sum > t.own_sum + 1e-6 * t.other_count;
  const double decoy = best_decoy_score(t, fam.dict, lead);
  const bool strong = std::max(t.mean_score, fused) >= std::max(min_score_, opt_.fused_min_score);
  t.confirmed = !other_mean && decoy < fused + (strong ? kDecoyTolerance : 0.0);
  if (t.confirmed) t.confirmed_leader = lead;
}

double Tracker::best_decoy_score(const Track& t, const RkhsDictionary& own, int lead) {
  double best = -1.0;
  const auto full = static_cast<float>(opt_.full_cell_votes);
  const auto own_cells = static_cast<size_t>(own.width() * own.width());
  for (size_t d = 0; d < decoys_.size(); ++d) {
    const RkhsDictionary& dict = decoys_[d];
    const auto cells = static_cast<size_t>(dict.width() * dict.width());
    const size_t base = static_cast<size_t>(t.shift) * decoy_cells_ + decoy_offsets_[d];
    const auto& vary = dict.varying_cells();
    values_.resize(vary.size());
    for (size_t k = 0; k < vary.size(); ++k) {
      const size_t i = base + static_cast<size_t>(vary[k]);
      values_[k] = cell_value(t.decoy_votes[i], t.decoy_purity[i], t.decoy_counts[i], full);
    }
    score_functions(dict, values_, tables_, scores_);
    // Its best function, other than the leader's own pattern (families that share codes, such as
    // tag16h5 and tag16h6, tie there and stay with the configured one).
    int f = -1;
    for (int k = 0; k < dict.functions(); ++k) {
      if (f >= 0 && scores_[static_cast<size_t>(k)] <= scores_[static_cast<size_t>(f)]) continue;
      if (cells == own_cells && std::equal(dict.signs(k), dict.signs(k) + cells, own.signs(lead)))
        continue;
      f = k;
    }
    if (f < 0) continue;
    const auto counts = std::span<const float>(t.decoy_counts).subspan(base, cells);
    fused_votes(std::span<const float>(t.decoy_votes).subspan(base, cells),
                std::span<const float>(t.decoy_purity).subspan(base, cells), counts, fused_votes_);
    best = std::max(best, fused_grid_score(dict, f, fused_votes_, counts, opt_.full_cell_votes));
  }
  return best;
}

void Tracker::fill_info(const Track& t, TrackInfo& info) const {
  info.track_id = t.id;
  info.rotations = t.rotations;
  info.confirmed = t.confirmed;
  info.family_index = t.family;
  info.id = t.leader / 4;
  info.margin_cells = t.margin;
  info.mean_score = t.mean_score;
  // The track's pose, moved along the searched axis to the leading grid.
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  if (t.axis != 0)
    shift[t.axis] = (t.shift - kCentre) * t.size_m /
                    families_[static_cast<size_t>(t.family)].dict.width() / 4.0;
  info.position = t.ref_position + t.ref_frame * shift;
  Eigen::Quaterniond o(t.ref_frame.toRotationMatrix() * quarter_turn(-(t.leader & 3)));
  info.odometry = t.odom_valid;
  if (t.odom_valid) {
    // The odometry frame's pose, seen from the sensor at the newest candidate's time.
    info.odometry_position = t.odom_ref.position + t.odom_ref.frame * shift;
    Eigen::Quaterniond w(t.odom_ref.frame.toRotationMatrix() * quarter_turn(-(t.leader & 3)));
    if (w.w() < 0) w.coeffs() *= -1.0;
    info.odometry_orientation = w;
    const Eigen::Quaterniond back = t.ego_now.orientation.conjugate();
    info.position = back * (info.odometry_position - t.ego_now.position);
    o = back * w;
  }
  if (o.w() < 0) o.coeffs() *= -1.0;
  info.orientation = o;
  info.position_std_m = t.position_std;
  info.angle_std_deg = t.angle_std_deg;
  info.window_rotations = t.window_count;
  info.measured_size_m = t.size_count > 0 ? t.size_sum / t.size_count : -1.0;
  info.size_warning = size_contradicts(info.measured_size_m, t.size_m, size_warning_ratio_);
  info.moving = t.moving;
  if (t.moving) {
    // The centre's velocity now: the turn moving it, and the drift.
    info.velocity_mps = t.motion.turn.cross(t.ref_position) + t.motion.velocity;
    info.turn_deg_s = t.motion.turn / kDeg;
  } else {
    info.velocity_mps.setZero();
    info.turn_deg_s.setZero();
  }
}

void Tracker::report(const ScanResult& result, TrackerResult& out) const {
  const auto& cands = result.candidates;
  // Every detection of the rotation, as the detector gave it, with its track.
  for (size_t i = 0; i < result.detections.size(); ++i) {
    TrackedDetection td;
    td.detection = result.detections[i];
    td.decoded = true;
    for (size_t c = 0; c < cands.size(); ++c) {
      if (cands[c].detection != static_cast<int>(i) || assigned_[c] < 0) continue;
      const Track& t = tracks_[static_cast<size_t>(assigned_[c])];
      fill_info(t, td.track);
      // Confirmed means: the track's evidence confirms this detection's ID.
      td.track.confirmed =
          t.confirmed && t.family == td.detection.family_index && t.leader / 4 == td.detection.id;
    }
    out.tags.push_back(td);
  }
  // Confirmed tracks whose candidate of this rotation did not decode alone.
  for (const Track& t : tracks_) {
    if (!t.live) continue;
    ++out.tracks;
    out.confirmed_tracks += t.confirmed ? 1 : 0;
    if (!t.seen_now) continue;
    out.seen.emplace_back();
    fill_info(t, out.seen.back());
    if (!t.confirmed) continue;
    const Candidate& c = cands[static_cast<size_t>(t.candidate)];
    if (c.detection >= 0) continue;
    const Family& fam = families_[static_cast<size_t>(t.family)];
    TrackedDetection td;
    td.decoded = false;
    fill_info(t, td.track);
    Detection& d = td.detection;
    d.family_index = t.family;
    d.family = fam.dict.family().name;
    d.id = t.leader / 4;
    d.size_m = c.size_m;
    d.position = c.position;
    d.time_first_s = c.time_first_s;
    d.time_center_s = c.time_center_s;
    d.time_last_s = c.time_last_s;
    d.measured_size_m = c.measured_size_m;
    d.deskew = c.deskew;
    d.size_warning = size_contradicts(c.measured_size_m, c.size_m, size_warning_ratio_);
    // The track's function in the candidate's frame: quarter turns q - delta.
    const int q = ((t.leader & 3) - t.delta) & 3;
    const Eigen::Matrix3d r =
        c.undecoded_orientation.normalized().toRotationMatrix() * quarter_turn(-q);
    d.orientation = Eigen::Quaterniond(r);
    if (d.orientation.w() < 0) d.orientation.coeffs() *= -1.0;
    const double h = fam.black_half_ratio * c.size_m;
    const double yz[4][2] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
    for (size_t k = 0; k < 4; ++k)
      d.corners[k] = c.position + r * Eigen::Vector3d(0.0, yz[k][0], yz[k][1]);
    const FamilyEvidence& e = *evidence(c, result);
    const auto s = result.scores_of(e);
    const auto f = static_cast<size_t>((t.leader & ~3) | q);
    float rival = -1e30f;
    for (size_t g = 0; g < s.size(); ++g)
      if (g != f) rival = std::max(rival, s[g]);
    d.score = s[f];
    d.margin = (static_cast<double>(s[f]) - rival) * e.cells_per_score;
    d.points = c.points;
    d.fit_cost = c.fit_cost;
    d.first_point = -1;
    out.tags.push_back(td);
  }
}

}  // namespace lidartag::detector
