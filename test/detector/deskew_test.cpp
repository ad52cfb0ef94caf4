// The deskew (issue 33, item 1): a cluster's points moved to its centre time with the sensor's
// motion, from the odometry's interpolated poses or the tracker's constant-velocity model; and,
// end to end on the simulator, a VLP-16 turning at 30 deg/s: the tag's pose error with and
// without it.
#include "lidartag/detector/deskew.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "../../bench/sim_scans.hpp"
#include "count_allocations.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/ego_motion.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/sim/sensor_sim.hpp"

namespace lidartag::detector {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int64_t kT0 = 1'700'000'000'000'000'000;  // ns

Eigen::Quaterniond yaw(double rad) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ()));
}

// One ring of a scan: `n` columns 1 ms apart, each with one point of a static wall at x = 5 m seen
// by a sensor yawing at `w` rad/s (its pose at time t: yaw(w t)), so that each point is where the
// sensor saw it from at its own firing.
struct SkewedRing {
  Scan scan;
  std::vector<ClusterPoint> points;
  std::vector<Eigen::Vector3d> world;  // each point in the odometry frame
  double w = 0.0;
  SkewedRing(int n, double w_rad_s) : w(w_rad_s) {
    scan.reserve(1, 1, n);
    scan.columns = n;
    scan.stamp_ns = kT0;
    for (int c = 0; c < n; ++c) {
      const double t = 0.001 * c;
      const Eigen::Vector3d x(5.0, -0.5 + 0.05 * c, 0.2);
      world.push_back(x);
      const Eigen::Vector3d seen = yaw(w * t).conjugate() * x;  // in the sensor's frame at t
      scan.time_s[scan.at(0, 0, c)] = static_cast<float>(t);
      ClusterPoint p;
      p.x = static_cast<float>(seen.x());
      p.y = static_cast<float>(seen.y());
      p.z = static_cast<float>(seen.z());
      p.col = c;
      points.push_back(p);
    }
  }
  // The largest distance of a point from where the sensor at `t_s` sees its world point.
  double worst_off(double t_s) const {
    double most = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d want = yaw(w * t_s).conjugate() * world[i];
      const Eigen::Vector3d got(points[i].x, points[i].y, points[i].z);
      most = std::max(most, (got - want).norm());
    }
    return most;
  }
};

TEST(DeskewTest, OdometryPosesMoveEveryPointToTheClusterCentreTime) {
  SkewedRing ring(21, 90.0 * kPi / 180.0);
  EgoMotion ego;
  for (int k = -2; k <= 5; ++k)
    ASSERT_EQ(ego.add_pose(kT0 + k * 10'000'000, Eigen::Vector3d::Zero(), yaw(ring.w * 0.01 * k)),
              EgoSample::kAccepted);
  // As fired: the wall is sheared by the turn (about 3 cm at its ends).
  EXPECT_GT(ring.worst_off(0.010), 0.012);
  SensorMotion motion;
  motion.ego = &ego;
  const Deskewed d = deskew_cluster(ring.points, ring.scan, motion);
  ASSERT_EQ(d.source, DeskewSource::kEgo);
  EXPECT_NEAR(d.center_s, 0.010, 1e-6);  // the middle column is nearest the centroid
  EXPECT_LT(ring.worst_off(d.center_s), 1e-5);
}

TEST(DeskewTest, TheConstantVelocityModelMovesThePointsWhereNoOdometryCoversThem) {
  SkewedRing ring(21, 90.0 * kPi / 180.0);
  EgoMotion stale;  // poses that end long before the scan: not used
  ASSERT_EQ(stale.add_pose(kT0 - 2'000'000'000, Eigen::Vector3d::Zero(), yaw(0.0)),
            EgoSample::kAccepted);
  SensorMotion motion;
  motion.ego = &stale;
  motion.model.known = true;
  motion.model.turn = Eigen::Vector3d(0.0, 0.0, -ring.w);  // the world turns the other way
  const Deskewed d = deskew_cluster(ring.points, ring.scan, motion);
  ASSERT_EQ(d.source, DeskewSource::kModel);
  EXPECT_LT(ring.worst_off(d.center_s), 1e-5);
}

TEST(DeskewTest, WithoutAnyMotionThePointsStayAsFired) {
  SkewedRing ring(21, 90.0 * kPi / 180.0);
  const std::vector<ClusterPoint> before = ring.points;
  EXPECT_EQ(deskew_cluster(ring.points, ring.scan, SensorMotion{}).source, DeskewSource::kNone);
  EgoMotion empty;
  SensorMotion motion;
  motion.ego = &empty;
  EXPECT_EQ(deskew_cluster(ring.points, ring.scan, motion).source, DeskewSource::kNone);
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_EQ(ring.points[i].x, before[i].x);
    EXPECT_EQ(ring.points[i].y, before[i].y);
  }
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// A simulated VLP-16 turning at 30 deg/s about its vertical axis, the 1.2 m tag16h5 face-on at
// `distance`: every rotation detected with and without the deskew (the simulator's trajectory as
// the odometry, 100 Hz), each detection against the tag's truth at the detection's own time.
struct PoseErrors {
  std::vector<double> plain_mm, deskewed_mm, plain_deg, deskewed_deg, plain_size, deskewed_size;
  // Deskewed with the tracker's constant-velocity model (no odometry), from the 4th rotation on.
  std::vector<double> model_mm, model_deg, model_size;
  int deskewed_clusters = 0, model_clusters = 0;
  // Detections whose Detection::deskew names the source that moved their points: as fired
  // (kNone) from the plain detector, kEgo from the odometry's; those that do not.
  int marked = 0, mismarked = 0;
};
PoseErrors turning_sensor(double distance, int angle, double deg_s, int runs, int rotations) {
  PoseErrors e;
  for (int run = 0; run < runs; ++run) {
    sim::Scene scene = eval::accuracy_scene(velodyne::Model::kVLP16, distance, angle, 3 + run);
    scene.sensor.angular_velocity = {0.0, 0.0, deg_s};
    const sim::Trajectory trajectory(scene.sensor);
    EgoMotion ego;
    const auto t0 = static_cast<int64_t>(scene.sensor.start_time_s * 1e9);
    for (int k = -5; k <= rotations * 10 + 10; ++k) {
      const sim::Pose p = trajectory.at(0.01 * k);
      (void)ego.add_pose(t0 + k * 10'000'000, p.position, Eigen::Quaterniond(p.rotation));
    }
    DetectorOptions plain_options;
    DetectorOptions deskew_options;
    deskew_options.deskew.enabled = true;
    Detector plain(plain_options), deskew(deskew_options), modelled(deskew_options);
    Tracker tracker({}, deskew_options);
    TrackerResult tracked;
    SensorMotion motion;
    motion.ego = &ego;
    std::vector<std::vector<Detection>> a, b, c;
    const sim::Simulator simulator(scene);
    eval::SimScans scans(simulator);
    ScanResult ra, rb, rc;
    const sim::Truth truth =
        scans.run(rotations, static_cast<uint64_t>(700 + run), [&](const Scan& scan, size_t) {
          plain.detect(scan, ra);
          deskew.detect(scan, rb, motion);
          SensorMotion model;
          model.model = tracker.motion();
          modelled.detect(scan, rc, model);
          tracker.update(rc, scan.stamp_ns, tracked);
          a.push_back(ra.detections);
          b.push_back(rb.detections);
          c.push_back(rc.detections);
          e.deskewed_clusters += rb.deskewed_ego;
          e.model_clusters += rc.deskewed_model;
          for (const Detection& d : ra.detections)
            ++(d.deskew == DeskewSource::kNone ? e.marked : e.mismarked);
          for (const Detection& d : rb.detections)
            ++(d.deskew == DeskewSource::kEgo ? e.marked : e.mismarked);
        });
    for (size_t k = 0; k < truth.rotations.size() && k < a.size(); ++k) {
      const sim::TagTruth& tag = truth.rotations[k].tags.front();
      auto score = [&](const std::vector<Detection>& ds, std::vector<double>& mm,
                       std::vector<double>& deg, std::vector<double>& size) {
        for (const Detection& d : ds) {
          const sim::TagTruth then =
              eval::tag_at_time(scene.sensor, truth.rotations[k], tag, d.time_center_s);
          if (!eval::at_tag(d, then) || d.id != tag.id) continue;
          mm.push_back(1e3 * (d.position - then.position).norm());
          deg.push_back(eval::rotation_error_deg(d.orientation, then.orientation));
          if (d.measured_size_m > 0)
            size.push_back(100.0 * std::abs(d.measured_size_m - tag.size) / tag.size);
        }
      };
      score(a[k], e.plain_mm, e.plain_deg, e.plain_size);
      score(b[k], e.deskewed_mm, e.deskewed_deg, e.deskewed_size);
      if (k >= 3) score(c[k], e.model_mm, e.model_deg, e.model_size);
    }
  }
  return e;
}

void print(const char* what, double distance, int angle, double rate, const PoseErrors& e) {
  std::printf(
      "%s: VLP-16 %.0f m %d deg, yawing %.0f deg/s: %zu / %zu detections; centre off %.2f -> "
      "%.2f mm, orientation off %.3f -> %.3f deg, measured size off %.2f -> %.2f %% (median, as "
      "fired -> deskewed); with the tracks' model from the 4th rotation: %.2f mm, %.3f deg, %.2f "
      "%% (%d clusters moved by it)\n",
      what, distance, angle, rate, e.plain_mm.size(), e.deskewed_mm.size(), median(e.plain_mm),
      median(e.deskewed_mm), median(e.plain_deg), median(e.deskewed_deg), median(e.plain_size),
      median(e.deskewed_size), median(e.model_mm), median(e.model_deg), median(e.model_size),
      e.model_clusters);
}

// Face-on, the turn stretches the tag along the rings by the angle turned while the beams
// crossed it (0.5 % at 30 deg/s: 1 cm of a 1.2 m tag at 7 m); its centre and normal hardly move.
// Deskewed, the black square measures its printed size (the size check's figure), and the pose
// is no worse.
TEST(DeskewTest, ATurningSensorsTagIsMeasuredAtItsPrintedSizeDeskewed) {
  for (const double distance : {5.0, 7.0, 10.0}) {
    const PoseErrors e = turning_sensor(distance, 0, 30.0, 4, 8);
    print("face-on", distance, 0, 30.0, e);
    EXPECT_GT(e.deskewed_clusters, 0);
    EXPECT_GT(e.marked, 0);
    EXPECT_EQ(e.mismarked, 0);
    ASSERT_GE(e.deskewed_mm.size(), 16u);
    ASSERT_GE(e.plain_mm.size(), 16u);
    EXPECT_LE(median(e.deskewed_mm), median(e.plain_mm) + 0.5);
    EXPECT_LE(median(e.deskewed_deg), median(e.plain_deg) + 0.05);
    if (distance <= 7.0) {  // at 10 m the black square's steps are noisier than the stretch
      EXPECT_GT(median(e.plain_size), 0.3);
      EXPECT_LT(median(e.deskewed_size), 0.5 * median(e.plain_size));
      // Without odometry, once the tracks know how the world moves through the sensor's frame.
      EXPECT_GT(e.model_clusters, 0);
      EXPECT_LT(median(e.model_size), 0.6 * median(e.plain_size));
    }
  }
}

// Turned 45 deg away, the stretch along the rings turns the tag's plane: at 90 deg/s (a robot
// spinning in place) the normal is off by twice as much as fired.
TEST(DeskewTest, ATagTurnedAwayKeepsItsOrientationDeskewed) {
  for (const double distance : {5.0, 7.0}) {
    const PoseErrors e = turning_sensor(distance, 45, 90.0, 4, 8);
    print("45 deg", distance, 45, 90.0, e);
    ASSERT_GE(e.deskewed_deg.size(), 16u);
    EXPECT_LT(median(e.deskewed_deg), 0.75 * median(e.plain_deg));
    EXPECT_LE(median(e.deskewed_mm), median(e.plain_mm) + 0.5);
  }
}

// The per-scan path: deskewing with the odometry allocates nothing once the buffers have grown.
TEST(DeskewTest, DetectingWithTheDeskewDoesNotAllocateInSteadyState) {
  sim::Scene scene = eval::accuracy_scene(velodyne::Model::kVLP16, 6.0, 0, 5);
  scene.sensor.angular_velocity = {0.0, 0.0, 30.0};
  const sim::Trajectory trajectory(scene.sensor);
  EgoMotion ego;
  const auto t0 = static_cast<int64_t>(scene.sensor.start_time_s * 1e9);
  for (int k = -5; k <= 60; ++k) {
    const sim::Pose p = trajectory.at(0.01 * k);
    ASSERT_EQ(ego.add_pose(t0 + k * 10'000'000, p.position, Eigen::Quaterniond(p.rotation)),
              EgoSample::kAccepted);
  }
  DetectorOptions options;
  options.deskew.enabled = true;
  Detector det(options);
  SensorMotion motion;
  motion.ego = &ego;
  ScanResult result;
  long allocations = -1;
  int deskewed = 0;
  const sim::Simulator simulator(scene);
  eval::SimScans scans(simulator);
  (void)scans.run(3, 11, [&](const Scan& scan, size_t index) {
    if (index != 2) return;
    det.detect(scan, result, motion);
    det.detect(scan, result, motion);
    const long before = testing::heap_allocations();
    det.detect(scan, result, motion);
    allocations = testing::heap_allocations() - before;
    deskewed = result.deskewed_ego;
  });
  EXPECT_GT(deskewed, 0);
  EXPECT_EQ(allocations, 0);
}

}  // namespace
}  // namespace lidartag::detector
