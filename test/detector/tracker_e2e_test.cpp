// The tracker end to end: simulated rotations -> Decoder/ScanBatcher -> Detector -> Tracker,
// against the simulator's truth. A static sensor whose single rotations are ambiguous gets the ID
// confirmed from the 4th rotation on; a moving sensor never mixes evidence between places; the
// boards of pcaps/boards.pcap and the clutter of pcaps/clutter.pcap give no tag at all.
#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "../../bench/sim_scans.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::detector {
namespace {

const std::string kPcaps = LIDARTAG_SOURCE_DIR "/pcaps/";

// What the tracker reported about the truth tag in one rotation.
struct Seen {
  bool right = false;    // an entry at the tag with the tag's ID
  bool wrong = false;    // an entry at the tag with another ID
  bool decoded = false;  // the right ID decoded by this rotation alone
  bool tracked = false;  // the right ID reported by its track only
  int track = -1;        // the right entry's track
  Eigen::Vector3d tag;   // the tag's centre in the sensor's frame (truth)
};

std::vector<Seen> run(const sim::Scene& scene, int rotations, uint64_t seed,
                      const DetectorOptions& options = {}) {
  const sim::Simulator simulator(scene);
  eval::SimScans scans(simulator);
  Detector det(options);
  Tracker tracker({}, options);
  ScanResult result;
  TrackerResult tracked;
  std::vector<TrackerResult> all;
  std::vector<int64_t> stamps;
  const sim::Truth truth = scans.run(rotations, seed, [&](const Scan& scan, size_t) {
    det.detect(scan, result);
    // The detector's evidence for the tracker: every candidate has its grid of votes.
    for (const Candidate& c : result.candidates) {
      if (c.family_index < 0) continue;
      EXPECT_EQ(result.votes_of(c).size(), static_cast<size_t>(c.grid_width * c.grid_width));
      float counted = 0.0f;
      for (float n : result.vote_counts_of(c)) counted += n;
      EXPECT_GT(counted, 0.0f);
    }
    tracker.update(result, scan.stamp_ns, tracked);
    all.push_back(tracked);
  });
  std::vector<Seen> out;
  for (size_t k = 0; k < all.size() && k < truth.rotations.size(); ++k) {
    const sim::TagTruth& tag = truth.rotations[k].tags.front();
    Seen s;
    s.tag = tag.position;
    for (const TrackedDetection& t : all[k].tags) {
      if (!eval::at_tag(t.detection, tag)) continue;
      if (t.detection.id != tag.id || t.detection.family != tag.family) {
        s.wrong = true;
        continue;
      }
      s.right = true;
      s.decoded = s.decoded || t.decoded;
      s.tracked = s.tracked || !t.decoded;
      s.track = t.track.track_id;
    }
    out.push_back(s);
  }
  return out;
}

// VLP-16, 1.2 m tag16h5 at 7 m face-on (the paper's Table I protocol): the rings miss payload
// cells, so that most rotations are ambiguous alone (decode/ambiguous); their votes, summed while
// the tag stays put, tell the code apart.
TEST(TrackerEndToEnd, StaticSensorAmbiguousAloneIsConfirmedFromTheFourthRotation) {
  const int code = 21;
  const auto seen = run(eval::accuracy_scene(velodyne::Model::kVLP16, 7.0, 0, code), 12, 100);
  ASSERT_EQ(seen.size(), 12u);
  int right = 0, decoded = 0, tracked = 0, wrong = 0;
  for (size_t k = 0; k < seen.size(); ++k) {
    wrong += seen[k].wrong ? 1 : 0;
    if (k < 3) continue;
    right += seen[k].right ? 1 : 0;
    decoded += seen[k].decoded ? 1 : 0;
    tracked += seen[k].tracked ? 1 : 0;
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(right, 9);    // >= 95 % of the 9 rotations from the 4th on: all of them
  EXPECT_LE(decoded, 6);  // alone, a third of them or more are ambiguous
  EXPECT_GE(tracked, 3);  // ... and reported by the track
  std::set<int> tracks;
  for (size_t k = 3; k < seen.size(); ++k) tracks.insert(seen[k].track);
  EXPECT_EQ(tracks.size(), 1u);  // one track for the tag that stays put
}

// Sensors that move: slowly (the tag drifts through the sensor's frame by 1-2 cm a rotation:
// its track follows it, and evidence from several distances is summed) and fast (1 m/s or
// turning 10 deg/s: 10 cm a rotation at the tag, the association gate: a new track every
// rotation). A rotation's cluster joins a track only within max_distance_m of the mean of the
// track's window; no ID is ever wrong.
TEST(TrackerEndToEnd, MovingSensorNeverMixesEvidenceNorGivesAWrongId) {
  struct Motion {
    velodyne::Model model;
    double distance;
    int angle;
    int code;
    std::array<double, 3> velocity;  // m/s, world
    double turn_deg_s;               // about the vertical
    int min_right;                   // rotations of 20 with the right ID
  };
  const Motion motions[] = {
      {velodyne::Model::kVLP16, 7.0, 0, 5, {0.1, 0.0, 0.0}, 0.0, 12},
      {velodyne::Model::kVLP16, 6.0, 45, 11, {0.0, 0.5, 0.0}, 0.0, 0},
      {velodyne::Model::kVLP32C, 10.0, 0, 17, {-1.0, 0.5, 0.0}, 0.0, 18},
      {velodyne::Model::kVLP32C, 6.0, 45, 23, {0.0, 0.0, 0.0}, 10.0, 18},
      {velodyne::Model::kVLP32C, 5.0, 0, 29, {0.0, 0.0, 0.0}, 2.0, 18},
  };
  const TrackerOptions o;
  for (const Motion& m : motions) {
    SCOPED_TRACE(std::string(velodyne::model_spec(m.model).name) + " " +
                 std::to_string(m.distance) + " m");
    sim::Scene scene = eval::accuracy_scene(m.model, m.distance, m.angle, m.code);
    scene.sensor.velocity = m.velocity;
    scene.sensor.angular_velocity = {0.0, 0.0, m.turn_deg_s};
    const auto seen = run(scene, 20, 7);
    ASSERT_EQ(seen.size(), 20u);
    int right = 0;
    std::map<int, std::vector<int>> rotations_of;  // per track, the rotations it reported
    for (int k = 0; k < 20; ++k) {
      const Seen& s = seen[static_cast<size_t>(k)];
      EXPECT_FALSE(s.wrong) << "rotation " << k;
      right += s.right ? 1 : 0;
      if (s.right && s.track >= 0) rotations_of[s.track].push_back(k);
    }
    EXPECT_GE(right, m.min_right);
    for (const auto& [id, ks] : rotations_of) {
      // Each rotation of the track within the gate of the mean of the track's window before it
      // (truth positions; 3 cm for the poses' own error).
      for (size_t i = 1; i < ks.size(); ++i) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        const auto window = static_cast<size_t>(o.window);
        const size_t first = i > window ? i - window : 0;
        for (size_t j = first; j < i; ++j) mean += seen[static_cast<size_t>(ks[j])].tag;
        mean /= static_cast<double>(i - first);
        EXPECT_LE((seen[static_cast<size_t>(ks[i])].tag - mean).norm(), o.max_distance_m + 0.03)
            << "track " << id << " rotation " << ks[i];
      }
    }
    // How far the tag moves in the sensor's frame per rotation (0.1 s).
    const double step = 0.1 * Eigen::Vector3d(m.velocity[0], m.velocity[1], m.velocity[2]).norm() +
                        m.distance * 0.1 * m.turn_deg_s * std::numbers::pi / 180;
    if (step >= o.max_distance_m) {
      EXPECT_EQ(rotations_of.size(), static_cast<size_t>(right));  // a new track every rotation
    } else {
      EXPECT_LT(rotations_of.size(), 4u);  // it follows a slow drift
    }
  }
}

// Every detection and every confirmed track in these captures is a false positive.
void expect_no_tag(const std::string& capture, const DetectorOptions& options,
                   bool reaches_decoding) {
  SCOPED_TRACE(capture);
  velodyne::CaptureReader reader(kPcaps + capture, {});
  Detector det(options);
  Tracker tracker({}, options);
  ScanResult result;
  TrackerResult tracked;
  int rotations = 0, candidates = 0;
  while (const Scan* scan = reader.next()) {
    det.detect(*scan, result);
    tracker.update(result, scan->stamp_ns, tracked);
    ++rotations;
    candidates += static_cast<int>(result.candidates.size());
    EXPECT_TRUE(result.detections.empty()) << "rotation " << rotations;
    EXPECT_TRUE(tracked.tags.empty()) << "rotation " << rotations;
    EXPECT_EQ(tracked.confirmed_tracks, 0) << "rotation " << rotations;
  }
  EXPECT_GE(rotations, 10);
  // The boards look enough like tags to be decoded (and rejected): the test is not empty.
  if (reaches_decoding) {
    EXPECT_GT(candidates, 0);
  }
}

TEST(TrackerEndToEnd, CalibrationBoardsAndSignsGiveNoTagNorConfirmedTrack) {
  expect_no_tag("boards.pcap", DetectorOptions{}, true);
  DetectorOptions all;  // three families and sizes, 0.6 m next to the 0.61 m checkerboards
  all.tag_sizes_m = {1.2, 0.8, 0.6};
  all.families = {"tag16h5", "tag25h9", "tag36h11"};
  expect_no_tag("boards.pcap", all, true);
  expect_no_tag("clutter.pcap", all, false);
}

}  // namespace
}  // namespace lidartag::detector
