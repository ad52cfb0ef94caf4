// The calibration end to end on the LiDAR side: a tag moved through 9 poses at 2-8 m in front of
// a simulated VLP-32C; each pose's 10 rotations through the decoder, batcher, detector and
// tracker; the confirmed track's window gives the LiDAR tag (lidar_tag_from_track). The image
// side is the simulator's true black-square corners projected through a known extrinsic and a
// 1280 x 720 plumb-bob camera with 0.3 px noise (the image tag detector is tested on its own).
// Checks the corner order and the tag frame through the real detector, and the targets
// for the VLP-32C row: rotation <= 0.1 deg, translation <= 5 mm, held-out <= 1 px.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <random>
#include <vector>

#include "../../bench/sim_scans.hpp"
#include "calib/calib_synthetic.hpp"
#include "lidartag/calib/extrinsic_solver.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tracker.hpp"

namespace lidartag::calib {
namespace {

struct Observed {
  bool found = false;
  LidarTag lidar;
  sim::TagTruth truth;
};

// One pose: `rotations` rotations of a static VLP-32C looking at a 1.2 m tag16h5 `id` at
// `centre` (world; the sensor at the origin, 1 m up), facing the sensor, diamond-mounted.
Observed observe(const std::array<double, 3>& centre, int id, int rotations, uint64_t seed) {
  sim::Scene scene;
  scene.sensor.model = velodyne::Model::kVLP32C;
  scene.sensor.noise = sim::noise_defaults(scene.sensor.model);
  sim::TagOptions t;
  t.family = "tag16h5";
  t.id = id;
  t.size = 1.2;
  t.center = centre;
  t.rotation_deg = 45.0;
  scene.tags.push_back(t);
  const sim::Simulator simulator(scene);
  eval::SimScans scans(simulator);
  detector::DetectorOptions options;
  detector::Detector det(options);
  detector::Tracker tracker({}, options);
  detector::ScanResult result;
  detector::TrackerResult tracked;
  const sim::Truth truth = scans.run(rotations, seed, [&](const Scan& scan, size_t) {
    det.detect(scan, result);
    tracker.update(result, scan.stamp_ns, tracked);
  });
  Observed o;
  o.truth = truth.rotations.back().tags.front();
  for (const detector::TrackedDetection& td : tracked.tags) {
    if (!td.track.confirmed || td.track.id != id || !eval::at_tag(td.detection, o.truth)) continue;
    o.lidar = lidar_tag_from_track(td.track, tags::builtin_family("tag16h5"), td.detection.size_m);
    o.found = true;
  }
  return o;
}

TEST(CalibrationEndToEnd, NinePosesOfASimulatedVlp32cTag) {
  // World positions (x ahead, y left, z up; the sensor 1 m up): 2.5-8 m over the image.
  const std::array<std::array<double, 3>, 9> centres = {{{2.5, 0.0, 1.0},
                                                         {3.5, 1.0, 1.3},
                                                         {3.5, -1.0, 0.8},
                                                         {4.5, 1.6, 0.6},
                                                         {5.0, -1.8, 1.8},
                                                         {6.0, 0.3, 1.8},
                                                         {6.5, -2.5, 0.5},
                                                         {7.5, 2.8, 1.6},
                                                         {8.0, -0.5, 1.0}}};
  const CameraModel cam = testing::test_camera();
  const Eigen::Isometry3d truth = testing::true_extrinsic();
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 0.3);
  std::vector<TagPose> poses;
  double worst_corner_mm = 0;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    const int id = static_cast<int>(i) + 3;
    const Observed o = observe(centres[i], id, 10, 40 + i);
    ASSERT_TRUE(o.found) << "pose " << i << ": no confirmed track";
    ImageTagCorners im;
    im.family = "tag16h5";
    im.id = id;
    im.sigma_px = 0.3;
    for (std::size_t k = 0; k < 4; ++k) {
      // AprilTag's p[] of the true corners: calibration corner k is p[apriltag_corner_of(k)].
      const auto px = cam.project(truth * o.truth.corners[k]);
      ASSERT_TRUE(px && cam.in_image(*px)) << "pose " << i << " corner " << k;
      im.apriltag_p[static_cast<std::size_t>(apriltag_corner_of(static_cast<int>(k)))] =
          *px + Eigen::Vector2d(g(rng), g(rng));
      worst_corner_mm =
          std::max(worst_corner_mm, (o.lidar.corners[k] - o.truth.corners[k]).norm() * 1e3);
    }
    const Pairing p =
        pair_tags(std::span(&o.lidar, 1), std::span(&im, 1), "pose " + std::to_string(i));
    ASSERT_EQ(p.poses.size(), 1u);
    poses.push_back(p.poses[0]);
  }
  const CalibrationResult r = solve_extrinsic(cam, poses);
  const double rot = testing::rotation_error_deg(r.camera_from_lidar, truth);
  const double trans = testing::translation_error_mm(r.camera_from_lidar, truth);
  std::printf(
      "VLP-32C, 9 poses: rotation error %.4f deg (1 sigma %.4f), translation error %.2f mm "
      "(1 sigma %.2f %.2f %.2f), rms %.3f px, held out median %.3f max %.3f px; LiDAR "
      "corners off truth by up to %.1f mm; %d poses used\n",
      rot, r.rotation_sigma_total_deg, trans, r.translation_sigma_mm.x(),
      r.translation_sigma_mm.y(), r.translation_sigma_mm.z(), r.rms_px, r.held_out_median_px,
      r.held_out_max_px, worst_corner_mm, r.used_poses);
  for (const std::string& w : r.warnings) std::printf("  warning: %s\n", w.c_str());
  EXPECT_EQ(r.used_poses, 9);
  EXPECT_LE(rot, 0.1);
  EXPECT_LE(trans, 5.0);
  EXPECT_LE(r.held_out_median_px, 1.0);
}

}  // namespace
}  // namespace lidartag::calib
