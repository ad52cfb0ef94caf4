// One sensor's pipeline in process, on an in-process LCM bus (memq://): the demo capture replayed
// with and without the visualisation messages, checked against the same capture decoded and
// detected here.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <thread>

#include "lcm_bytes.hpp"
#include "lidartag/daemon/sensor_pipeline.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

const std::string kDemoConfig = LIDARTAG_SOURCE_DIR "/config/demo.yaml";
const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";

#define REQUIRE_DEMO()                                                                        \
  if (!std::filesystem::exists(kDemo)) {                                                      \
    GTEST_SKIP() << "no " << kDemo << ": make it with lidartag sim pcaps/demo.yaml (see the " \
                 << "README)";                                                                \
  }

// Every message of every channel, in the order published.
struct Recorder {
  std::vector<std::string> channels;
  std::vector<std::vector<uint8_t>> messages;
  void handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    const auto* p = static_cast<const uint8_t*>(rbuf->data);
    channels.push_back(channel);
    messages.emplace_back(p, p + rbuf->data_size);
  }
};

using lcm_test::decode;

DaemonOptions demo_options(const std::vector<std::string>& settings) {
  std::vector<std::string> overrides = {"sensors[0].source.file=" + kDemo,
                                        "sensors[0].source.rate=0", "lcm.url=memq://"};
  overrides.insert(overrides.end(), settings.begin(), settings.end());
  return load_config(kDemoConfig, overrides);
}

// Replays the demo through a SensorPipeline with two workers; returns what it published. With
// `stop_after` the pipeline is stopped then (a looping replay), and `last` gets its final status.
Recorder run_pipeline(const DaemonOptions& options,
                      std::chrono::milliseconds stop_after = std::chrono::milliseconds::zero(),
                      SensorStatus* last = nullptr) {
  LcmBus bus(options.lcm.url);
  Recorder recorder;
  bus.lcm().subscribe(".*", &Recorder::handle, &recorder);  // memq:// keeps subscribed channels
  // As the daemon: the arena's threads are all workers.
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 3);
  tbb::task_arena arena(2, 0);
  {
    SensorPipeline pipeline(options.sensors[0], options, bus, arena, 2, nullptr, nullptr);
    pipeline.start();
    const auto start = std::chrono::steady_clock::now();
    const auto deadline = start + 120s;
    while (!pipeline.finished() && std::chrono::steady_clock::now() < deadline) {
      if (stop_after.count() > 0 && std::chrono::steady_clock::now() - start > stop_after) {
        pipeline.stop();
      }
      std::this_thread::sleep_for(10ms);
    }
    EXPECT_TRUE(pipeline.finished());
    EXPECT_EQ(pipeline.error(), "");
    pipeline.join();
    if (last != nullptr) *last = pipeline.status(steady_ns());
  }
  while (bus.lcm().handleTimeout(0) > 0) {
  }
  return recorder;
}

// The demo decoded and detected here, one rotation at a time.
struct Reference {
  struct Rotation {
    uint64_t sequence = 0;
    int columns = 0;
    std::vector<float> x, y, z;  // every k-th column's returns, as point_cloud_t orders them
    std::vector<uint8_t> intensity, ring;
    detector::ScanResult detection;
  };
  std::vector<Rotation> rotations;
};

Reference reference(const DaemonOptions& options, int k) {
  const SensorOptions& sensor = options.sensors[0];
  velodyne::CaptureReaderOptions ro;
  ro.model = sensor.model;
  ro.decoder = sensor.decoder;
  ro.batcher = sensor.batcher;
  velodyne::CaptureReader reader(kDemo, ro);
  detector::Detector detector(options.detector);
  Reference ref;
  while (const Scan* scan = reader.next()) {
    auto& r = ref.rotations.emplace_back();
    r.sequence = scan->sequence;
    r.columns = scan->columns;
    for (int c = 0; c < scan->columns; c += k)
      for (int ret = 0; ret < scan->returns; ++ret)
        for (int ring = 0; ring < scan->rings; ++ring) {
          const size_t i = scan->at(ret, ring, c);
          if (scan->range[i] <= 0) continue;
          r.x.push_back(scan->x[i]);
          r.y.push_back(scan->y[i]);
          r.z.push_back(scan->z[i]);
          r.intensity.push_back(scan->intensity[i]);
          r.ring.push_back(static_cast<uint8_t>(ring));
        }
    detector.detect(*scan, r.detection);
  }
  return ref;
}

TEST(Pipeline, TagPointsAndCloudFollowEachRotationsDetections) {
  REQUIRE_DEMO();
  constexpr int k = 7;
  const DaemonOptions options =
      demo_options({"lcm.publish_tag_points=true", "lcm.cloud_decimation=" + std::to_string(k)});
  ASSERT_TRUE(options.detector.keep_tag_points);
  const Recorder got = run_pipeline(options);
  const Reference ref = reference(options, k);
  ASSERT_GE(ref.rotations.size(), 10u);

  // Per rotation, in rotation order: its detections, its tag points when it has detections, its
  // cloud. Nothing else.
  size_t m = 0, with_tags = 0;
  for (const auto& want : ref.rotations) {
    SCOPED_TRACE("rotation " + std::to_string(want.sequence));
    ASSERT_LT(m, got.channels.size());
    ASSERT_EQ(got.channels[m], "LIDARTAG_DETECTIONS");
    const auto det = decode<lidartag::tag_detections_t>(got.messages[m++]);
    ASSERT_EQ(det.sequence, static_cast<int64_t>(want.sequence));
    ASSERT_EQ(det.ndetections, static_cast<int32_t>(want.detection.detections.size()));

    if (det.ndetections > 0) {
      ++with_tags;
      ASSERT_LT(m, got.channels.size());
      ASSERT_EQ(got.channels[m], "LIDARTAG_TAG_POINTS");
      const auto pts = decode<lidartag::tag_points_t>(got.messages[m++]);
      EXPECT_EQ(pts.utime, det.utime);
      EXPECT_EQ(pts.sequence, det.sequence);
      EXPECT_EQ(pts.sensor, "demo");
      EXPECT_EQ(pts.frame_id, "velodyne");
      ASSERT_EQ(pts.ntags, det.ndetections);
      int32_t first = 0;
      for (int32_t i = 0; i < pts.ntags; ++i) {
        const auto& d = det.detections[static_cast<size_t>(i)];
        EXPECT_EQ(pts.family[static_cast<size_t>(i)], d.family);
        EXPECT_EQ(pts.id[static_cast<size_t>(i)], d.id);
        EXPECT_EQ(pts.first_point[static_cast<size_t>(i)], first);
        ASSERT_EQ(pts.tag_npoints[static_cast<size_t>(i)], d.points);
        // The points on the published tag's plane, inside its square: all of them within 5 sigma
        // of the simulated range noise (1.5 cm) and the beam footprint, 3 in 4 within 2 sigma.
        const Eigen::Quaterniond q(d.orientation[0], d.orientation[1], d.orientation[2],
                                   d.orientation[3]);
        const Eigen::Matrix3d rt = q.toRotationMatrix().transpose();
        const Eigen::Vector3d centre(d.position[0], d.position[1], d.position[2]);
        int close = 0;
        for (int32_t j = first; j < first + d.points; ++j) {
          const auto u = static_cast<size_t>(j);
          const Eigen::Vector3d p =
              rt * (Eigen::Vector3d(pts.x[u], pts.y[u], pts.z[u]).cast<double>() - centre);
          const double outside = std::max(std::abs(p.y()), std::abs(p.z())) - d.size_m / 2;
          EXPECT_LT(std::abs(p.x()), 0.075) << p.transpose();
          EXPECT_LT(outside, 0.075) << p.transpose();
          close += std::abs(p.x()) < 0.03 && outside < 0.03 ? 1 : 0;
        }
        EXPECT_GT(close, d.points * 3 / 4);
        first += d.points;
      }
      ASSERT_EQ(pts.npoints, first);
      // The very points the detector found them from.
      const auto& want_points = want.detection.tag_points;
      ASSERT_EQ(want_points.size(), static_cast<size_t>(pts.npoints));
      for (size_t j = 0; j < want_points.size(); ++j) {
        ASSERT_EQ(pts.x[j], want_points[j].x);
        ASSERT_EQ(pts.y[j], want_points[j].y);
        ASSERT_EQ(pts.z[j], want_points[j].z);
        ASSERT_EQ(pts.intensity[j], static_cast<uint8_t>(want_points[j].intensity));
        ASSERT_EQ(pts.ring[j], want_points[j].ring);
      }
    }

    ASSERT_LT(m, got.channels.size());
    ASSERT_EQ(got.channels[m], "LIDARTAG_CLOUD");
    const auto cloud = decode<lidartag::point_cloud_t>(got.messages[m++]);
    EXPECT_EQ(cloud.utime, det.utime);
    EXPECT_EQ(cloud.sequence, det.sequence);
    EXPECT_EQ(cloud.sensor, "demo");
    EXPECT_EQ(cloud.frame_id, "velodyne");
    EXPECT_EQ(cloud.decimation, k);
    EXPECT_EQ(det.columns, want.columns);
    EXPECT_EQ(cloud.columns, (want.columns + k - 1) / k);
    ASSERT_EQ(cloud.npoints, static_cast<int32_t>(want.x.size()));
    EXPECT_EQ(cloud.x, want.x);
    EXPECT_EQ(cloud.y, want.y);
    EXPECT_EQ(cloud.z, want.z);
    EXPECT_EQ(cloud.intensity, want.intensity);
    EXPECT_EQ(cloud.ring, want.ring);
  }
  EXPECT_EQ(m, got.channels.size());
  EXPECT_GE(with_tags, ref.rotations.size() - 2);  // all but the partial first and last
}

TEST(Pipeline, VisualisationMessagesAreOffByDefault) {
  REQUIRE_DEMO();
  const DaemonOptions options = demo_options({});
  EXPECT_FALSE(options.detector.keep_tag_points);
  const Recorder got = run_pipeline(options);
  const size_t rotations = reference(options, 1).rotations.size();
  ASSERT_GE(rotations, 10u);
  EXPECT_EQ(got.channels, std::vector<std::string>(rotations, "LIDARTAG_DETECTIONS"));
  size_t tags = 0;
  for (const auto& bytes : got.messages) {
    tags += static_cast<size_t>(decode<lidartag::tag_detections_t>(bytes).ndetections);
  }
  EXPECT_GT(tags, 0u);  // there were points to publish, and none were
}

TEST(Pipeline, TheTrackerFollowsEachTagAcrossRotationsUnlessTurnedOff) {
  REQUIRE_DEMO();
  // On by default: the demo's two static tags keep one track each, confirmed after a few
  // rotations, with the rotation count growing.
  const Recorder on = run_pipeline(demo_options({}));
  ASSERT_GE(on.messages.size(), 10u);
  std::map<int32_t, int32_t> rotations_of;  // track id -> highest track_rotations seen
  int confirmed = 0, last_tracks = 0;
  for (const auto& bytes : on.messages) {
    const auto m = decode<lidartag::tag_detections_t>(bytes);
    last_tracks = m.tracks;
    for (const auto& d : m.detections) {
      EXPECT_GE(d.track_id, 0);
      EXPECT_GT(d.track_rotations, rotations_of[d.track_id] - 1) << "track " << d.track_id;
      rotations_of[d.track_id] = std::max(rotations_of[d.track_id], d.track_rotations);
      confirmed += d.confirmed ? 1 : 0;
    }
  }
  EXPECT_EQ(rotations_of.size(), 2u);  // two tags, one track each
  EXPECT_EQ(last_tracks, 2);
  for (const auto& [id, n] : rotations_of) EXPECT_GE(n, 8) << "track " << id;
  EXPECT_GT(confirmed, 0);
  // Off: the same detections, every one untracked.
  const Recorder off = run_pipeline(demo_options({"tracker.enabled=false"}));
  ASSERT_EQ(off.messages.size(), on.messages.size());
  for (const auto& bytes : off.messages) {
    const auto m = decode<lidartag::tag_detections_t>(bytes);
    EXPECT_EQ(m.tracks, 0);
    for (const auto& d : m.detections) {
      EXPECT_EQ(d.track_id, -1);
      EXPECT_TRUE(d.decoded);
    }
  }
}

// The size check through the daemon: the demo's 0.8 m tag configured as 0.75 m is published with
// size_warning and the size its points measure, and the final status names the mismatch; at the
// right sizes nothing is warned about.
TEST(Pipeline, ATagSizeTheTagsPointsContradictIsWarnedAboutInMessagesAndStatus) {
  REQUIRE_DEMO();
  SensorStatus last;
  const Recorder wrong = run_pipeline(demo_options({"detector.tag_sizes_m=[0.75, 0.6]"}),
                                      std::chrono::milliseconds::zero(), &last);
  int warned = 0, found = 0;
  for (size_t i = 0; i < wrong.messages.size(); ++i) {
    if (wrong.channels[i] != "LIDARTAG_DETECTIONS") continue;
    const auto m = decode<lidartag::tag_detections_t>(wrong.messages[i]);
    for (const auto& d : m.detections) {
      if (d.id != 0) continue;
      ++found;
      EXPECT_EQ(d.size_m, 0.75);
      EXPECT_NEAR(d.measured_size_m, 0.8, 0.016);  // within 2 %
      warned += d.size_warning ? 1 : 0;
    }
  }
  EXPECT_GE(found, 8);
  EXPECT_EQ(warned, found);
  EXPECT_EQ(last.health.state, HealthState::kEnded);
  EXPECT_NE(last.health.reason.find("measured another size than configured: tag16h5 id 0 "
                                    "measures 0.8"),
            std::string::npos)
      << last.health.reason;
  SensorStatus right_status;
  const Recorder right =
      run_pipeline(demo_options({}), std::chrono::milliseconds::zero(), &right_status);
  for (size_t i = 0; i < right.messages.size(); ++i) {
    if (right.channels[i] != "LIDARTAG_DETECTIONS") continue;
    const auto m = decode<lidartag::tag_detections_t>(right.messages[i]);
    for (const auto& d : m.detections) {
      EXPECT_FALSE(d.size_warning) << "id " << d.id << " measures " << d.measured_size_m;
      EXPECT_NEAR(d.measured_size_m, d.size_m, 0.02 * d.size_m);
    }
  }
  EXPECT_EQ(right_status.health.reason.find("another size"), std::string::npos)
      << right_status.health.reason;
}

TEST(Pipeline, LoopSeamPartialsAreCountedNotPublishedAndTheRateStaysTheSensors) {
  REQUIRE_DEMO();
  // The demo (10 whole rotations and a partial at each end, 600 rpm) looped at the recorded pace
  // for about three passes.
  const DaemonOptions options =
      demo_options({"sensors[0].source.rate=1", "sensors[0].source.loop=true"});
  SensorStatus last;
  const Recorder got = run_pipeline(options, 3200ms, &last);
  std::vector<lidartag::tag_detections_t> rotations;
  for (size_t i = 0; i < got.messages.size(); ++i) {
    if (got.channels[i] == "LIDARTAG_DETECTIONS") {
      rotations.push_back(decode<lidartag::tag_detections_t>(got.messages[i]));
    }
  }
  ASSERT_GE(rotations.size(), 25u);
  // Two seams at least, each two partial rotations: counted, not published.
  EXPECT_GE(last.rotations_seam, 4u);
  EXPECT_EQ(last.rotations_seam % 2, 0u);
  EXPECT_EQ(last.rotations_assembled, last.rotations_published + last.rotations_dropped);
  EXPECT_EQ(last.rotations_dropped, last.rotations_seam);
  EXPECT_EQ(last.rotations_published, rotations.size());
  // Only the stream's own ends are partial: the first rotation and the one flushed at the stop.
  for (size_t i = 1; i + 1 < rotations.size(); ++i) {
    EXPECT_TRUE(rotations[i].complete) << "rotation " << rotations[i].sequence;
  }
  // The pace stays the sensor's across the seams: 10 rotations a second (publishing the seam's two
  // partials too would make 12 per pass of 11 rotation periods, 10.9 a second), no pause (the
  // replay's clock runs on across the seam). Judged over the whole run, so that a rotation
  // published late on a loaded machine does not count.
  std::vector<double> gaps_ms;
  for (size_t i = 2; i + 1 < rotations.size(); ++i) {
    gaps_ms.push_back(
        static_cast<double>(rotations[i].publish_utime - rotations[i - 1].publish_utime) / 1000.0);
  }
  std::string all;
  for (double g : gaps_ms) all += std::to_string(static_cast<int>(g)) + " ";
  std::vector<double> sorted = gaps_ms;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_NEAR(sorted[sorted.size() / 2], 100.0, 15.0) << all;
  const double seconds = static_cast<double>(rotations[rotations.size() - 2].publish_utime -
                                             rotations[1].publish_utime) *
                         1e-6;
  EXPECT_NEAR(static_cast<double>(rotations.size() - 3) / seconds, 10.0, 0.4) << all;
}

}  // namespace
}  // namespace lidartag::daemon
