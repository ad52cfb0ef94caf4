// Evidence over rotations (issue 11, item 3): the clusters that reached decoding are associated
// across rotations by position and orientation; the votes of a tag's cells are summed (each
// rotation's points, ScanResult::vote_points, voted in the track's frame at that rotation), so
// that a tag whose single rotations are ambiguous gets an ID once the summed evidence tells its
// code apart from every other. A sensor that moves moves every tag through its frame: each track
// follows its tag with a constant turn rate and velocity (track_motion.hpp, issue 33), and a new
// track takes the motion of the others. A candidate farther than the association gates from
// where its track was predicted starts a new one: evidence is never mixed between two places. Pure:
// ScanResults in, tracks out; no I/O, no allocation once its buffers have grown (the tracks are a
// fixed pool sized at construction). docs/detector.md, "Evidence over rotations".
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "lidartag/detector/ego_motion.hpp"
#include "lidartag/detector/options.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/track_motion.hpp"

namespace lidartag::detector {

// Every setting of the tracker, with its default, unit and effect; the rules are in
// visit_tracker_options below.
struct TrackerOptions {
  // Run the tracker (lidartagd, `lidartag detect`). Default true. Off: every rotation is reported
  // alone, as the detector gives it.
  bool enabled = true;
  // Association gates, against a track's pose predicted to the candidate's time (the window's
  // model: its mean while the tag stands still in the sensor's frame, else a constant turn rate
  // and velocity fitted to it): a candidate joins a track when its centre is within the distance
  // gate and its orientation within the angle gate of it (up to quarter turns about the normal,
  // which the code decides). Each gate is the larger of its floor here and gate_sigmas standard
  // deviations of the difference that the pose noise explains (pose_noise_* below, and the
  // window's own spread about its model when larger), at most half the tag's size (two tags
  // cannot be closer than their size) and 30 degrees (quarter turns must stay apart). Floors
  // 0.1 m and 10 degrees: single-rotation poses of a 1.2 m tag scatter by a few millimetres and
  // well below a degree near the sensor (1-3 mm and 0.4 deg at 6 m on a VLP-16), where the floors
  // decide. A tag that leaves its predicted path by more than this (moved by hand, or another tag)
  // starts a new track. A track-only candidate (Candidate::track_only: fewer boundary points than
  // eq. (6) asks for a detection of one rotation) is evidence like any other: it joins or starts a
  // track and adds its votes, and the confirmation gates below decide (a VLP-16 at 10 m sees a
  // 1.2 m tag at 45 degrees with 9-11 boundary points in most rotations of some heights:
  // docs/detector.md).
  double max_distance_m = 0.1;
  double max_angle_deg = 10.0;
  // The pose noise of one rotation: its centre scatters by about pose_noise_m_points and its
  // orientation by pose_noise_deg_points over the number of points of the pose fit (RMS of the
  // 3-D offset and of the angle; metres x points, degrees x points). Defaults 1.5 and 200, an upper
  // envelope of the simulator's 1.2 m tag16h5 at 0 and 45 degrees (RMS offset x points 0.6-0.9 on
  // a VLP-16 at 5-10 m with 96-530 points, 1.1-1.4 on a VLP-32C at 24-32 m with 42-73 points;
  // RMS angle x points 60-130 and 130-190): a far tag at 45 degrees (a VLP-32C at 28 m, 45-70
  // points) scatters by 2-3 cm and 3 degrees RMS, up to 9 degrees, from one rotation to the next.
  // The same noise decides when a track moves (follow_motion): only a turn rate 4 standard errors
  // from zero and a drift beyond it are taken for motion.
  double pose_noise_m_points = 1.5;
  double pose_noise_deg_points = 200.0;
  // Standard deviations of the expected pose difference inside the gates. Default 3.
  double gate_sigmas = 3.0;
  // Follow a moving sensor (or tag): each track's window is fitted with a constant turn rate and
  // velocity when that explains its poses better than standing still, and predicted to each new
  // rotation. Default true. Off: tracks are the window's mean, and a sensor that moves more than
  // the gates per rotation starts a new track every rotation.
  bool follow_motion = true;
  // How fast the sensor may move, for a track seen once while no other track knows the motion:
  // its gates grow by max_speed_mps and max_turn_deg_s times the time since (the turn moving the
  // tag by its range times the angle), at most half the tag's size (two tags are at least their
  // size apart). Defaults 2 m/s and 45 deg/s (a robot driving and turning briskly; a VLP-16's tag
  // at 7 m then moves up to 0.75 m a rotation, capped at 0.6 m for a 1.2 m tag).
  double max_speed_mps = 2.0;
  double max_turn_deg_s = 45.0;
  // Confirmation. The evidence of a track is, per cell of the marker, the votes of the points
  // that fell well inside the cell (decode.vote_inset_cells from its borders) of the track's mean
  // pose over the window (not the rotation's own, which scatters more) over every rotation:
  // +1 white, -1 black, by the point's intensity between the cluster's black and white levels.
  // Each cell's mean vote (its sum over max(votes, full_cell_votes)) scores every function; the
  // leading function (code and quarter turns) must beat the best other one by min_margin_cells
  // cells, over at least min_rotations rotations (one more when none of them validated: every
  // candidate track-only, Candidate::track_only), and its mean normalised decoding score must
  // reach the detector's decode.min_score (and beat the families that are not configured). Once
  // confirmed, a track stays confirmed while the same function leads by the margin (the other
  // families' checks asked again), whatever its scores: the scores confirm, the lead keeps. Cells
  // no point fell well inside have no vote: codes that differ only there are never told apart,
  // however many rotations are summed (a static VLP-16 at 6 m sees only half the payload cells
  // of a diamond-mounted 1.2 m tag, and some codes differ only on the other half). Defaults:
  // 0.75 cells (about one cell voted consistently; over 10,000 simulated rotations of 30 codes,
  // VLP-16 at 5-9 m and VLP-32C at 14-26 m, 0-45 degrees, a wrong leading code never reached
  // 0.25; at 10 m on a VLP-16, with the tag's height spread over a beam spacing, one reached 0.33
  // in 30 runs), 4 votes, 3 rotations.
  double min_margin_cells = 0.75;
  // The margin for a track that searches its tag's place along an unseen axis (a square mount,
  // Candidate::shift_searched, square_mount_axis), cells. Default 1.5: such a track compares
  // codes at 9 shifts; over 61 runs of a square-mounted VLP-16 1.2 m tag16h5 at 5-7 m a wrong
  // leader held 0.97-0.99 cells for whole runs, none reached 1.5.
  double min_margin_cells_searched = 1.5;
  double full_cell_votes = 4.0;
  int min_rotations = 3;
  // The far edge's confirmation (fused_grid.hpp), for a track whose rotations' mean score stays
  // below decode.min_score: the fused grid's score of the leading function (the votes of every
  // rotation against its code, every cell of the marker, on the leader's grid) must reach
  // max(decode.min_score, fused_min_score), normalised score, and its margin
  // fused_min_margin_cells, cells (stricter than min_margin_cells). Defaults 0.88 and 1.0: the
  // right leaders of a VLP-32C's 1.2 m tag at 28-32 m and 45 degrees end at 0.88-0.94 after 20
  // rotations; the wrong leaders of a far tag of another family (tracker_e2e_test) reached 0.855
  // with a margin of 0.92 cells and up to 0.94 only with margins below 0.75, and the boards and
  // clutter of the tests stay below 0.66. Raising either trades far tags for caution. Only for a
  // track at least half of whose rotations sampled the tag anew (a static sensor firing at the
  // same angles every rotation, such as an Ouster, adds no finer sampling over rotations).
  double fused_min_score = 0.88;
  double fused_min_margin_cells = 1.0;
  // The far edge's wide margin: a fused grid that scores below fused_min_score but at least
  // max(decode.min_score, wide_min_score) still confirms when its leader leads by
  // wide_min_margin_cells or more (and by fused_min_margin_cells), on rotations that sampled the
  // tag anew, and no other built-in family fits its votes as well (no tolerance). Defaults 0.84
  // and 1.25 cells: a VLP-32C's 1.2 m tag16h5 cut to its size at 32 m and 45 degrees had its right
  // leader in every run, and 8 of 30 runs never confirmed with margins past 1.25 cells and fused
  // scores below fused_min_score (median 0.87; docs/tracking.md, the far edge's item 11). A
  // margin above any a track reaches (e.g. 100) turns it off.
  double wide_min_score = 0.84;
  double wide_min_margin_cells = 1.25;
  // The beam's full divergence across the scan (horizontal on a spinning sensor) and along it,
  // milliradians: each vote is weighted by how purely its return is its cell's colour, the share
  // of its footprint, laid on the tag, that stays on its side of the cell's nearest border (1 for
  // a footprint inside the cell, 0 on a border; a cell's mean vote is the weighted mean, its
  // number of votes unchanged). Defaults 3 and 1.5 (Velodyne's VLP-16 and VLP-32C; an Ouster
  // OS1's is about 3 both ways). At 28 m and 45 degrees a VLP-32C's footprint is 0.8 of a 1.2 m
  // tag16h5's cell wide: a ring crossing a white cell only at its corner among black neighbours
  // reads it black, a bias that no number of rotations averages out. 0 and 0: every vote counts
  // fully (before 2026-12-05).
  double beam_divergence_h_mrad = 3.0;
  double beam_divergence_v_mrad = 1.5;
  // Rotations (the latest) in the smoothed pose and its spread. Default 10 (1 s at 600 rpm).
  int window = 10;
  // A track not seen for longer than this is dropped, seconds of scan time (at most 1e6). Default
  // 0.5 (5 rotations at 600 rpm): a tag hidden by someone walking past keeps its evidence.
  double max_age_s = 0.5;
  // Tracks kept at once (memory is allocated for this many at construction). Default 64; when
  // full, the track seen longest ago makes room for a new one.
  int max_tracks = 64;
};

// The rule table of TrackerOptions, in the form of the detector's visit_options (options.hpp):
// every field with its key (the daemon's `tracker:` section), its rule and its unit. The daemon's
// YAML reader, checker and printer visit it, and so does validate_tracker_options.
template <class V>
void visit_tracker_options(V& v, TrackerOptions& o) {
  using namespace rules;
  v.field("enabled", o.enabled, Any{}, "");
  v.field("max_distance_m", o.max_distance_m, above(0.0), "m");
  // Below 45 degrees: quarter turns about the normal must stay apart.
  v.field("max_angle_deg", o.max_angle_deg, open(0.0, 45.0), "deg");
  v.field("pose_noise_m_points", o.pose_noise_m_points, at_least(0.0), "m*points");
  v.field("pose_noise_deg_points", o.pose_noise_deg_points, at_least(0.0), "deg*points");
  v.field("gate_sigmas", o.gate_sigmas, open_closed(0.0, 100.0), "");
  v.field("follow_motion", o.follow_motion, Any{}, "");
  v.field("max_speed_mps", o.max_speed_mps, closed(0.0, 100.0), "m/s");
  v.field("max_turn_deg_s", o.max_turn_deg_s, closed(0.0, 3600.0), "deg/s");
  v.field("min_margin_cells", o.min_margin_cells, above(0.0), "cells");
  v.field("min_margin_cells_searched", o.min_margin_cells_searched, above(0.0), "cells");
  v.field("full_cell_votes", o.full_cell_votes, at_least(1.0), "votes");
  v.field("min_rotations", o.min_rotations, at_least(1), "rotations");
  v.field("fused_min_score", o.fused_min_score, closed(0.5, 1.0), "");
  v.field("fused_min_margin_cells", o.fused_min_margin_cells, above(0.0), "cells");
  v.field("wide_min_score", o.wide_min_score, closed(0.5, 1.0), "");
  v.field("wide_min_margin_cells", o.wide_min_margin_cells, above(0.0), "cells");
  v.field("beam_divergence_h_mrad", o.beam_divergence_h_mrad, closed(0.0, 100.0), "mrad");
  v.field("beam_divergence_v_mrad", o.beam_divergence_v_mrad, closed(0.0, 100.0), "mrad");
  v.field("window", o.window, closed(1, 1000), "rotations");
  v.field("max_age_s", o.max_age_s, open_closed(0.0, 1e6), "s");
  v.field("max_tracks", o.max_tracks, closed(1, 4096), "tracks");
}

// Every rule of visit_tracker_options. Throws OptionsError naming the first bad option
// ("tracker.window").
void validate_tracker_options(const TrackerOptions& options);

// What the tracker knows about the tag behind one detection or candidate of the rotation.
struct TrackInfo {
  int track_id = -1;  // unique for the Tracker's life, increasing; -1: not tracked
  int rotations = 0;  // rotations that gave the track a candidate (this one included)
  // The leading function's code passed the gates (TrackerOptions), or passed them earlier and
  // still leads by the margin; the track's ID is `id`.
  bool confirmed = false;
  int family_index = 0;       // of the track's evidence
  int id = -1;                // the code of the leading function
  double margin_cells = 0.0;  // summed margin of the leading function over the best other one
  double mean_score = 0.0;    // mean normalised score of the leading function
  // The window's pose at this rotation's candidate time (tag frame -> sensor frame, the leading
  // function's quarter turns): its mean, or its fitted motion's pose when it moves; and the
  // spread about that: standard deviation of the centre per sensor axis, metres, and RMS angle of
  // the orientations, degrees. window_rotations of them.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d position_std_m = Eigen::Vector3d::Zero();
  double angle_std_deg = 0.0;
  int window_rotations = 0;
  // The tag moves through the sensor's frame (TrackerOptions::follow_motion): at `velocity_mps`
  // (its centre's, now) and turning at `turn_deg_s` (about the sensor's axes): the sensor's own
  // motion, reversed, when the tag stands still.
  bool moving = false;
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d turn_deg_s = Eigen::Vector3d::Zero();
  // The size check over the track: the mean of its candidates' measured sizes
  // (Detection::measured_size_m; -1: none measured), and whether it differs from the configured
  // size by more than the detector's pose.size_warning_ratio.
  double measured_size_m = -1.0;
  bool size_warning = false;
  // With an ego-motion input (Tracker::update's `ego`) that placed every candidate of the window
  // in one odometry frame: the tag's pose there (tag frame -> odometry frame, the leading
  // function's quarter turns; a static tag's mean over the window), and `position` and
  // `orientation` above are that pose seen from the sensor at this rotation's candidate time.
  bool odometry = false;
  Eigen::Vector3d odometry_position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond odometry_orientation = Eigen::Quaterniond::Identity();
};

// One tag of a rotation as reported with the tracker: every detection of the rotation, as the
// detector gave it (`decoded` true), then each confirmed track whose candidate of this rotation
// was not a detection (decoded false: ambiguous alone; the detection's pose is this rotation's,
// with the track's code and quarter turns; score and margin those of that function in this
// rotation alone, so the margin may be negative).
struct TrackedDetection {
  Detection detection;
  bool decoded = true;
  TrackInfo track;
};

struct TrackerResult {
  std::vector<TrackedDetection> tags;
  // Every track that took a candidate in this rotation, confirmed or not (for diagnostics).
  std::vector<TrackInfo> seen;
  int tracks = 0;            // live tracks after this rotation
  int confirmed_tracks = 0;  // of which confirmed
  double time_ms = 0.0;      // wall time of update()
  // With an ego-motion input: candidates of this rotation placed in the odometry frame, and those
  // it had no pose for (tracked in the sensor's frame, the no-ego-motion model), with the reason
  // of the last of them (EgoLookup::kOk when none).
  int ego_placed = 0;
  int ego_missing = 0;
  EgoLookup ego_last_miss = EgoLookup::kOk;
  // Memory ran out while tracking this rotation: the report is incomplete.
  bool truncated = false;
};

class Tracker {
 public:
  // Validates the options and resolves the detector's families (their code counts size the
  // evidence). Throws OptionsError.
  Tracker(TrackerOptions options, const DetectorOptions& detector);

  const TrackerOptions& options() const { return opt_; }

  // One rotation, in rotation order: the detector's result for the scan stamped `stamp_ns` (first
  // firing, ns). Fills `out` (cleared first). A stamp older than the previous one (a replay
  // starting again) drops every track. Never throws; no allocation once warmed up.
  // `ego` (optional): the sensor's poses in an odometry frame, on the stamps' clock. Each candidate
  // is placed there at its own time (stamp_ns + time_center_s); a track whose window is all in one
  // odometry frame associates and averages there (a static tag: its mean), else in the sensor's
  // frame with its own motion model, as without `ego` (a candidate the poses do not cover: before
  // them, in a gap, stale; counted in `out`).
  void update(const ScanResult& result, int64_t stamp_ns, TrackerResult& out,
              const EgoMotion* ego = nullptr) noexcept;

  // The apparent motion of the static world in the sensor's frame after the last update (the
  // track with the longest window's constant-velocity model; unknown without one): what the
  // detector's deskew uses for the next scan when no odometry covers it (SensorMotion::model).
  const Motion& motion() const noexcept { return fleet_; }

  // Drops every track (ids keep increasing).
  void reset();

  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;
  ~Tracker();

 private:
  struct Track;
  struct Family {
    RkhsDictionary dict;
    int functions = 0;              // 4 x codes
    double black_half_ratio = 0.0;  // (width_at_border / total_width) / 2
  };
  // A track's association gates for one candidate (TrackerOptions, "Association gates").
  struct Gates {
    double distance_m = 0.0, angle_rad = 0.0;
  };
  struct Pair {
    double cost;  // distance and angle, each in units of its gate
    int candidate, track, delta;
  };
  // A candidate of the rotation placed in the odometry frame.
  struct Placed {
    bool ok = false;
    EgoPose ego;  // the sensor's pose at the candidate's time
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    Eigen::Matrix3d frame = Eigen::Matrix3d::Identity();  // undecoded, in the odometry frame
  };
  void track(const ScanResult& result, int64_t stamp_ns, TrackerResult& out, const EgoMotion* ego);
  // The candidate's time on the tracker's clock (its centre's firing time), seconds.
  double time_of(const Candidate& c, int64_t stamp_ns) const;
  Gates gates(const Track& t, const Candidate& c) const;
  void update_fleet();
  // The candidate's evidence for its family, when it is complete and consistent; else null.
  const FamilyEvidence* evidence(const Candidate& c, const ScanResult& result) const;
  void start(Track& t, const Candidate& c);
  void add(Track& t, const Candidate& c, const ScanResult& result, int64_t stamp_ns);
  void add_evidence(Track& t, const Candidate& c, const ScanResult& result);
  // The best fused grid score (fused_grid_score) of any decoy family's function on the track's
  // votes at its leading grid's place, the leader's own pattern (function `lead` of `own`: a
  // family that shares codes ties there) excluded; -1 with no decoy or no vote. Overwrites the
  // scoring scratch.
  double best_decoy_score(const Track& t, const RkhsDictionary& own, int lead);
  void fill_info(const Track& t, TrackInfo& info) const;
  void report(const ScanResult& result, TrackerResult& out) const;

  TrackerOptions opt_;
  double min_score_ = 0.8;            // the detector's decode.min_score
  double size_warning_ratio_ = 0.03;  // the detector's pose.size_warning_ratio
  double vote_inset_ = 0.05;          // the detector's decode.vote_inset_cells
  std::vector<Family> families_;
  // The built-in families not configured (the detector's decode.reject_other_families): each
  // track's votes are also summed on their grids, so that a track whose fused evidence fits
  // another family better is never confirmed as a tag of its own family. Each decoy's grid starts
  // at decoy_offsets_[k] of a track's decoy_* arrays.
  std::vector<RkhsDictionary> decoys_;
  std::vector<size_t> decoy_offsets_;
  size_t decoy_cells_ = 0;     // the cells of every decoy's grid, one shift
  std::vector<Track> tracks_;  // the pool, max_tracks of them
  std::vector<Pair> pairs_;
  std::vector<int> assigned_;   // per candidate of the rotation: the track it joined, or -1
  std::vector<Placed> placed_;  // per candidate of the rotation
  std::vector<float> values_, tables_, scores_;  // scoring scratch
  std::vector<float> fused_votes_;  // the leading grid's votes for fused_grid_score (or a decoy's)
  std::vector<Eigen::Vector3f> directions_;  // a candidate's vote points' directions (resampling)
  std::vector<float> resampling_scratch_;
  std::vector<float> best_;         // per function: its best score over the grids
  std::vector<int> best_grid_;      // ... and that grid
  std::vector<TimedPose> ordered_;  // a window, oldest first
  Motion fleet_;          // the motion of the tags that show it best (the sensor's, reversed)
  int64_t epoch_ns_ = 0;  // the tracker's clock starts at the first stamp
  int64_t last_stamp_ns_ = 0;
  bool have_stamp_ = false;
  int next_id_ = 0;
};

}  // namespace lidartag::detector
