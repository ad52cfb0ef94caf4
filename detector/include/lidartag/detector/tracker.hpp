// Evidence over rotations (issue 11, item 3): the clusters that reached decoding are associated
// across rotations by position and orientation; while a tag stays put, the votes of its cells
// are summed (each rotation's points, ScanResult::vote_points, voted in the track's mean frame),
// so that a tag whose single rotations are ambiguous gets an
// ID once the summed evidence tells its code apart from every other. A candidate that moved
// farther than the association gates from a track starts a new one: evidence is never mixed
// between two places. Pure: ScanResults in, tracks out; no I/O, no allocation once its buffers
// have grown (the tracks are a fixed pool sized at construction). docs/detector.md, "Evidence over
// rotations".
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "lidartag/detector/options.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"

namespace lidartag::detector {

// Every setting of the tracker, with its default, unit and effect; the rules are in
// visit_tracker_options below.
struct TrackerOptions {
  // Run the tracker (lidartagd, `lidartag detect`). Default true. Off: every rotation is reported
  // alone, as the detector gives it.
  bool enabled = true;
  // Association gates, against a track's reference pose (the mean of its window): a candidate
  // joins a track when its centre is within max_distance_m and its orientation within
  // max_angle_deg of it (up to quarter turns about the normal, which the code decides). Defaults
  // 0.1 m and 10 degrees: single-rotation poses of a 1.2 m tag scatter by a few millimetres and
  // well below a degree (1-3 mm and 0.4 deg at 6 m on a VLP-16), and two tags cannot be closer
  // than their size. A tag or sensor that moves more than this from where the track has been (the
  // mean of its window) starts a new track; a slow drift is followed. A track-only candidate
  // (Candidate::track_only: fewer boundary points than eq. (6) asks for a detection of one
  // rotation) is evidence like any other: it joins or starts a track and adds its votes, and the
  // confirmation gates below decide (a VLP-16 at 10 m sees a 1.2 m tag at 45 degrees with 9-11
  // boundary points in most rotations of some heights: docs/detector.md).
  double max_distance_m = 0.1;
  double max_angle_deg = 10.0;
  // Confirmation. The evidence of a track is, per cell of the marker, the votes of the points
  // that fell well inside the cell (decode.vote_inset_cells from its borders) of the track's mean
  // pose over the window (not the rotation's own, which scatters more) over every rotation:
  // +1 white, -1 black, by the point's intensity between the cluster's black and white levels.
  // Each cell's mean vote (its sum over max(votes, full_cell_votes)) scores every function; the
  // leading function (code and quarter turns) must beat the best other one by min_margin_cells
  // cells, over at least min_rotations rotations, and its mean normalised decoding score must
  // reach the detector's decode.min_score (and beat the families that are not configured). Cells
  // no point fell well inside have no vote: codes that differ only there are never told apart,
  // however many rotations are summed (a static VLP-16 at 6 m sees only half the payload cells
  // of a diamond-mounted 1.2 m tag, and some codes differ only on the other half). Defaults:
  // 0.75 cells (about one cell voted consistently; over 10,000 simulated rotations of 30 codes,
  // VLP-16 at 5-9 m and VLP-32C at 14-26 m, 0-45 degrees, a wrong leading code never reached
  // 0.25; at 10 m on a VLP-16, with the tag's height spread over a beam spacing, one reached 0.33
  // in 30 runs), 4 votes, 3 rotations.
  double min_margin_cells = 0.75;
  double full_cell_votes = 4.0;
  int min_rotations = 3;
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
  v.field("min_margin_cells", o.min_margin_cells, above(0.0), "cells");
  v.field("full_cell_votes", o.full_cell_votes, at_least(1.0), "votes");
  v.field("min_rotations", o.min_rotations, at_least(1), "rotations");
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
  // The leading function's code passed the gates (TrackerOptions); the track's ID is `id`.
  bool confirmed = false;
  int family_index = 0;       // of the track's evidence
  int id = -1;                // the code of the leading function
  double margin_cells = 0.0;  // summed margin of the leading function over the best other one
  double mean_score = 0.0;    // mean normalised score of the leading function
  // Mean pose over the window (tag frame -> sensor frame, the leading function's quarter turns)
  // and its spread: standard deviation of the centre per sensor axis, metres, and RMS angle of the
  // orientations from their mean, degrees. window_rotations of them.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d position_std_m = Eigen::Vector3d::Zero();
  double angle_std_deg = 0.0;
  int window_rotations = 0;
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
  void update(const ScanResult& result, int64_t stamp_ns, TrackerResult& out) noexcept;

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
  struct Pair {
    double cost;  // distance and angle, each in units of its gate
    int candidate, track, delta;
  };
  void track(const ScanResult& result, int64_t stamp_ns, TrackerResult& out);
  // The candidate's evidence for its family, when it is complete and consistent; else null.
  const FamilyEvidence* evidence(const Candidate& c, const ScanResult& result) const;
  void start(Track& t, const Candidate& c);
  void add(Track& t, const Candidate& c, const ScanResult& result, int64_t stamp_ns);
  void add_evidence(Track& t, const Candidate& c, const ScanResult& result);
  void fill_info(const Track& t, TrackInfo& info) const;
  void report(const ScanResult& result, TrackerResult& out) const;

  TrackerOptions opt_;
  double min_score_ = 0.8;    // the detector's decode.min_score
  double vote_inset_ = 0.05;  // the detector's decode.vote_inset_cells
  std::vector<Family> families_;
  std::vector<Track> tracks_;  // the pool, max_tracks of them
  std::vector<Pair> pairs_;
  std::vector<int> assigned_;  // per candidate of the rotation: the track it joined, or -1
  std::vector<float> values_, tables_, scores_;  // scoring scratch
  int64_t last_stamp_ns_ = 0;
  bool have_stamp_ = false;
  int next_id_ = 0;
};

}  // namespace lidartag::detector
