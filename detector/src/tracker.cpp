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
#include <string_view>
#include <type_traits>

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
  int64_t last_seen_ns = 0;
  // Per function of the family in the track's frame (4 code + quarter turns): summed normalised
  // scores. Per cell of the marker in the track's frame: summed votes (+1 white, -1 black) of the
  // points well inside it, and their number.
  std::vector<double> score_sum;
  std::vector<float> votes, counts;
  // Over the rotations in which the families not configured were decoded: their best score and
  // the configured family's best score, summed, and the number of those rotations.
  double other_sum = 0.0, own_sum = 0.0;
  int other_count = 0;
  // The window: the candidates' poses at their times, frames turned into the track's frame
  // (quarter turns taken out); a ring of opt_.window.
  std::vector<TimedPose> window;
  int window_count = 0, window_next = 0;
  // The window's model: the pose at the newest candidate's time, and how it moves from there.
  double ref_t_s = 0.0;
  Eigen::Vector3d ref_position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond ref_frame = Eigen::Quaterniond::Identity();
  Motion motion;
  bool moving = false;
  // The size check: measured sizes of its candidates, summed, and how many.
  double size_sum = 0.0;
  int size_count = 0;
  Eigen::Vector3d position_std = Eigen::Vector3d::Zero();
  double angle_std_deg = 0.0;
  int leader = -1;
  double margin = 0.0, mean_score = 0.0;
  bool confirmed = false;
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
  } catch (const tags::FamilyError& e) {
    throw OptionsError("families", "", e.what());
  }
  tracks_.resize(static_cast<size_t>(opt_.max_tracks));
  scores_.reserve(static_cast<size_t>(most));
  values_.reserve(static_cast<size_t>(cells));
  tables_.reserve(static_cast<size_t>(cells / 8 + 1) * 256);
  for (Track& t : tracks_) {
    t.score_sum.assign(static_cast<size_t>(most), 0.0);
    t.votes.assign(static_cast<size_t>(cells), 0.0f);
    t.counts.assign(static_cast<size_t>(cells), 0.0f);
    t.window.resize(static_cast<size_t>(opt_.window));
  }
  ordered_.reserve(static_cast<size_t>(opt_.window));
  pairs_.reserve(64);
  assigned_.reserve(64);
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

void Tracker::update(const ScanResult& result, int64_t stamp_ns, TrackerResult& out) noexcept {
  const auto t0 = std::chrono::steady_clock::now();
  out.tags.clear();
  out.seen.clear();
  out.tracks = out.confirmed_tracks = 0;
  out.truncated = false;
  try {
    track(result, stamp_ns, out);
  } catch (...) {
    // Only allocation failure can get here (the buffers grow to the scene): the report of this
    // rotation is incomplete and says so.
    out.truncated = true;
  }
  out.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::track(const ScanResult& result, int64_t stamp_ns, TrackerResult& out) {
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
  for (size_t c = 0; c < cands.size(); ++c) {
    const Candidate& cand = cands[c];
    if (evidence(cand, result) == nullptr) continue;
    const Eigen::Matrix3d frame = cand.undecoded_orientation.normalized().toRotationMatrix();
    const double t_c = time_of(cand, stamp_ns);
    for (size_t k = 0; k < tracks_.size(); ++k) {
      const Track& t = tracks_[k];
      if (!t.live || t.family != cand.family_index || std::abs(t.size_m - cand.size_m) > 1e-9)
        continue;
      // A track seen once has no motion of its own: the other tags' when they show it, else
      // gates as wide as the sensor's motion allows.
      const Motion& m = t.window_count == 1 && fleet_.known ? fleet_ : t.motion;
      const double dt = t_c - t.ref_t_s;
      const TimedPose at = predict({t.ref_t_s, t.ref_position, t.ref_frame}, m, dt);
      double max_distance = opt_.max_distance_m, max_angle = opt_.max_angle_deg * kDeg;
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
  const size_t n = static_cast<size_t>(families_[static_cast<size_t>(c.family_index)].functions);
  std::fill(t.score_sum.begin(), t.score_sum.begin() + static_cast<std::ptrdiff_t>(n), 0.0);
  std::fill(t.votes.begin(), t.votes.end(), 0.0f);
  std::fill(t.counts.begin(), t.counts.end(), 0.0f);
  t.other_sum = t.own_sum = 0.0;
  t.other_count = 0;
  t.window_count = t.window_next = 0;
  t.ref_position = c.position;
  t.ref_frame = c.undecoded_orientation.normalized();
  t.motion = {};
  t.moving = false;
  t.size_sum = 0.0;
  t.size_count = 0;
  t.leader = -1;
  t.confirmed = false;
}

void Tracker::add(Track& t, const Candidate& c, const ScanResult& result, int64_t stamp_ns) {
  ++t.rotations;
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
  t.window_next = (t.window_next + 1) % opt_.window;
  t.window_count = std::min(t.window_count + 1, opt_.window);
  ordered_.clear();
  for (int i = t.window_count; i > 0; --i)
    ordered_.push_back(
        t.window[static_cast<size_t>((t.window_next - i + opt_.window) % opt_.window)]);
  // Its model: the mean, or a constant motion when that explains it clearly better.
  const MotionFit fit =
      opt_.follow_motion ? fit_motion(ordered_, fleet_)
                         : fit_motion(ordered_, Motion{}, std::numeric_limits<double>::infinity());
  t.ref_t_s = fit.pose.t_s;
  t.ref_position = fit.pose.position;
  t.ref_frame = fit.pose.frame;
  t.motion = fit.motion;
  t.moving = fit.moving;
  t.position_std = fit.position_std_m;
  t.angle_std_deg = fit.angle_std_deg;
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
  // that tell codes apart there). None from a cluster whose position along an unseen axis was
  // searched by decoding: its votes would agree with the decoder by construction.
  const int W = fam.dict.width();
  if (!c.shift_searched) {
    const Eigen::Matrix3d u = c.undecoded_orientation.normalized().toRotationMatrix();
    const Eigen::Matrix3d to_track = t.ref_frame.toRotationMatrix().transpose();
    const Eigen::Vector3d offset = to_track * (c.position - t.ref_position);
    const Eigen::Matrix3d m = to_track * u;
    for (const VotePoint& p : result.vote_points_of(c)) {
      const Eigen::Vector3d q = m * Eigen::Vector3d(p.x, p.y, p.z) + offset;
      const int i = vote_cell(q.y() / t.size_m, q.z() / t.size_m, W, vote_inset_);
      if (i < 0) continue;
      t.votes[static_cast<size_t>(i)] += point_vote(p.label);
      t.counts[static_cast<size_t>(i)] += 1.0f;
    }
  }
  // The decision: every function scored on the cells that tell functions apart, each cell's votes
  // averaged (a cell with fewer than full_cell_votes votes counts proportionally less); the
  // margin is in cells: the leading function beats the best other one on that many cells.
  const auto& vary = fam.dict.varying_cells();
  values_.resize(vary.size());
  const auto full = static_cast<float>(opt_.full_cell_votes);
  for (size_t k = 0; k < vary.size(); ++k) {
    const auto i = static_cast<size_t>(vary[k]);
    values_[k] = t.votes[i] / std::max(t.counts[i], full);
  }
  score_functions(fam.dict, values_, tables_, scores_);
  int lead = 0;
  for (int f = 1; f < n; ++f)
    if (scores_[static_cast<size_t>(f)] > scores_[static_cast<size_t>(lead)]) lead = f;
  float rival = -1e30f;
  for (int f = 0; f < n; ++f)
    if (f != lead) rival = std::max(rival, scores_[static_cast<size_t>(f)]);
  t.leader = lead;
  t.margin = n > 1 ? (scores_[static_cast<size_t>(lead)] - rival) / 2.0 : 1e9;
  t.mean_score = t.score_sum[static_cast<size_t>(lead)] / t.rotations;
  // Another family fitting better on average makes it that family's tag (as the detector's
  // decode/other_family for one rotation), best against best as there: the leading function's own
  // score is lower in the rotations another function of the family led, and the decoys' best
  // would beat it by that alone (a VLP-32C's 1.2 m tag16h5 at 24 m and 45 degrees, whose codes
  // tag16h6 shares, was never confirmed).
  const bool other_better = t.other_count > 0 && t.other_sum > t.own_sum + 1e-6 * t.other_count;
  // The score: the rotations' mean, or the fused grid's under a stricter margin (the far edge,
  // where each rotation's own fit scores low: fused_grid_confirms).
  const bool scored =
      t.mean_score >= min_score_ || fused_grid_confirms(fam.dict, lead, t.votes, t.counts,
                                                        opt_.full_cell_votes, t.margin, min_score_);
  t.confirmed = t.rotations >= opt_.min_rotations && t.margin >= opt_.min_margin_cells && scored &&
                !other_better;
}

void Tracker::fill_info(const Track& t, TrackInfo& info) const {
  info.track_id = t.id;
  info.rotations = t.rotations;
  info.confirmed = t.confirmed;
  info.family_index = t.family;
  info.id = t.leader / 4;
  info.margin_cells = t.margin;
  info.mean_score = t.mean_score;
  info.position = t.ref_position;
  Eigen::Quaterniond o(t.ref_frame.toRotationMatrix() * quarter_turn(-(t.leader & 3)));
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
