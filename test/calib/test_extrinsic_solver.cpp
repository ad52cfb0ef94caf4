#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "calib/calib_synthetic.hpp"
#include "lidartag/calib/extrinsic_solver.hpp"

namespace lidartag::calib {
namespace {

using testing::make_scene;
using testing::rotation_error_deg;
using testing::Scene;
using testing::SceneNoise;
using testing::test_camera;
using testing::translation_error_mm;
using testing::true_extrinsic;

TEST(ExtrinsicSolver, RigidAlignAndPlanarPoseAreExactOnExactData) {
  const Scene s = make_scene(3, 9, SceneNoise{0, 0, 0, 0});
  const Eigen::Isometry3d truth = true_extrinsic();
  std::vector<Eigen::Vector3d> from, to;
  for (std::size_t i = 0; i < s.poses.size(); ++i) {
    std::array<Eigen::Vector3d, 4> c;
    const double h =
        (s.poses[i].lidar.corners[2] - s.poses[i].lidar.corners[0]).norm() / (2 * std::sqrt(2.0));
    ASSERT_TRUE(planar_square_pose(test_camera(), s.poses[i].pixels, h, c));
    for (std::size_t k = 0; k < 4; ++k) {
      EXPECT_LT((c[k] - truth * s.poses[i].lidar.corners[k]).norm(), 1e-6) << i << " " << k;
      from.push_back(s.poses[i].lidar.corners[k]);
      to.push_back(truth * s.poses[i].lidar.corners[k]);
    }
  }
  Eigen::Isometry3d t;
  ASSERT_TRUE(rigid_align(from, to, t));
  EXPECT_LT(rotation_error_deg(t, truth), 1e-9);
  EXPECT_LT(translation_error_mm(t, truth), 1e-9);
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  EXPECT_FALSE(rigid_align(line, line, t));
}

TEST(ExtrinsicSolver, RecoversTheExtrinsicFromNinePoses) {
  const Scene s = make_scene(11);
  ASSERT_EQ(s.poses.size(), 9u);
  const CalibrationResult r = solve_extrinsic(test_camera(), s.poses);
  const double rot = rotation_error_deg(r.camera_from_lidar, true_extrinsic());
  const double trans = translation_error_mm(r.camera_from_lidar, true_extrinsic());
  std::printf(
      "rotation error %.4f deg (1 sigma %.4f), translation error %.2f mm (1 sigma %.2f "
      "%.2f %.2f), rms %.3f px, held out median %.3f max %.3f px\n",
      rot, r.rotation_sigma_total_deg, trans, r.translation_sigma_mm.x(),
      r.translation_sigma_mm.y(), r.translation_sigma_mm.z(), r.rms_px, r.held_out_median_px,
      r.held_out_max_px);
  EXPECT_LE(rot, 0.1);
  EXPECT_LE(trans, 5.0);
  EXPECT_EQ(r.used_poses, 9);
  EXPECT_LE(r.held_out_median_px, 1.0);
  EXPECT_GT(r.held_out_median_px, r.rms_px * 0.5);  // computed, not a copy of the fit's
  EXPECT_TRUE(r.weak.empty()) << r.weak[0].name;
  EXPECT_TRUE(r.warnings.empty()) << r.warnings[0];
  for (const PoseReport& p : r.poses) {
    EXPECT_TRUE(p.used);
    EXPECT_GT(p.range_m, 1.5);
    EXPECT_LT(p.rms_px, 3.0);
  }
}

// The true error lies within twice the reported 1 sigma in at least 90 % of 50 seeds.
TEST(ExtrinsicSolver, ReportedSigmaIsHonest) {
  SolverOptions opt;
  opt.held_out = false;
  int rot_in = 0, trans_in = 0, axes_in = 0, axes = 0;
  const int seeds = 50;
  double worst_rot = 0, worst_trans = 0;
  for (int seed = 0; seed < seeds; ++seed) {
    const Scene s = make_scene(1000 + static_cast<unsigned>(seed));
    const CalibrationResult r = solve_extrinsic(test_camera(), s.poses, opt);
    const Eigen::Isometry3d truth = true_extrinsic();
    const double rot = rotation_error_deg(r.camera_from_lidar, truth);
    const double trans = translation_error_mm(r.camera_from_lidar, truth);
    worst_rot = std::max(worst_rot, rot);
    worst_trans = std::max(worst_trans, trans);
    rot_in += rot <= 2 * r.rotation_sigma_total_deg;
    trans_in += trans <= 2 * r.translation_sigma_mm.norm();
    const Eigen::Vector3d dt = (r.camera_from_lidar.translation() - truth.translation()) * 1e3;
    const Eigen::AngleAxisd da(r.camera_from_lidar.linear() * truth.linear().transpose());
    const Eigen::Vector3d dr = da.axis() * da.angle() * 180 / std::numbers::pi;
    for (int i = 0; i < 3; ++i) {
      axes_in += std::abs(dt(i)) <= 2 * r.translation_sigma_mm(i);
      axes_in += std::abs(dr(i)) <= 2 * r.rotation_sigma_deg(i);
      axes += 2;
    }
  }
  std::printf(
      "within 2 sigma: rotation %d/%d, translation %d/%d, per axis %d/%d; worst errors "
      "%.4f deg %.2f mm\n",
      rot_in, seeds, trans_in, seeds, axes_in, axes, worst_rot, worst_trans);
  EXPECT_GE(rot_in, seeds * 9 / 10);
  EXPECT_GE(trans_in, seeds * 9 / 10);
  EXPECT_GE(axes_in, axes * 9 / 10);
  // Not honest by being huge: the sigmas stay below the targets' scale.
  EXPECT_LT(worst_rot, 0.1);
  EXPECT_LT(worst_trans, 5.0);
}

TEST(ExtrinsicSolver, DegenerateSetNamesTheWeakDegreeOfFreedom) {
  const Scene s = make_scene(5, 9, SceneNoise{}, /*one_spot=*/true);
  const CalibrationResult r = solve_extrinsic(test_camera(), s.poses);
  ASSERT_FALSE(r.weak.empty());
  std::printf("weak: %s, 1 sigma %.3f deg; suggestion: %s\n", r.weak[0].name.c_str(),
              r.weak[0].sigma_deg, r.suggestion.c_str());
  for (const WeakDirection& w : r.weak) std::printf("  %s %.3f\n", w.name.c_str(), w.sigma_deg);
  EXPECT_NE(r.weak[0].name.find("camera"), std::string::npos);
  // Rotation traded against sideways translation: one range cannot tell them apart, another can.
  EXPECT_NE(r.weak[0].name.find("translation"), std::string::npos);
  EXPECT_NE(r.weak[0].name.find("rotation"), std::string::npos);
  EXPECT_EQ(r.suggestion.rfind("add a tag at another distance", 0), 0u) << r.suggestion;
  EXPECT_NE(r.suggestion.find("side of the image"), std::string::npos);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("weakly constrained"), std::string::npos);
}

// Only the far tags (5-8 m, one side of the image): rotation and sideways translation trade
// against each other; a nearer tag is asked for.
TEST(ExtrinsicSolver, FarTagsOnlyAskForANearerOne) {
  const Scene s = make_scene(1);
  std::vector<TagPose> far;
  for (const TagPose& p : s.poses)
    if ((true_extrinsic() * p.lidar.position).norm() > 5.0) far.push_back(p);
  ASSERT_GE(far.size(), 3u);
  const CalibrationResult r = solve_extrinsic(test_camera(), far);
  ASSERT_FALSE(r.weak.empty());
  std::printf("far tags only: weak %s (%.3f deg); %s\n", r.weak[0].name.c_str(),
              r.weak[0].sigma_deg, r.suggestion.c_str());
  EXPECT_NE(r.weak[0].name.find("coupled with"), std::string::npos) << r.weak[0].name;
  EXPECT_EQ(r.suggestion.rfind("add a tag at another distance", 0), 0u) << r.suggestion;
  // A nearer one: half the nearest range.
  const std::size_t at = r.suggestion.find("add one at about ");
  ASSERT_NE(at, std::string::npos) << r.suggestion;
  double nearest = 1e9;
  for (const PoseReport& p : r.poses) nearest = std::min(nearest, p.range_m);
  EXPECT_NEAR(std::stod(r.suggestion.substr(at + 17)), nearest / 2, 0.06) << r.suggestion;
}

TEST(ExtrinsicSolver, WrongIdAndMovedTagAreRejectedAndTheRestUsed) {
  Scene s = make_scene(21);
  // Pose 2's image paired with the LiDAR's tag of pose 6 (a wrong ID); pose 5's tag moved 10 cm
  // between the image and the capture.
  s.poses[2].lidar = s.poses[6].lidar;
  for (Eigen::Vector3d& c : s.poses[5].lidar.corners) c += Eigen::Vector3d(0.0, 0.1, 0.0);
  const CalibrationResult r = solve_extrinsic(test_camera(), s.poses);
  EXPECT_FALSE(r.poses[2].used);
  EXPECT_FALSE(r.poses[5].used);
  EXPECT_NE(r.poses[2].reason.find("wrong ID"), std::string::npos) << r.poses[2].reason;
  std::printf("pose 2: %s\npose 5: %s\n", r.poses[2].reason.c_str(), r.poses[5].reason.c_str());
  EXPECT_EQ(r.used_poses, 7);
  EXPECT_LE(rotation_error_deg(r.camera_from_lidar, true_extrinsic()), 0.1);
  EXPECT_LE(translation_error_mm(r.camera_from_lidar, true_extrinsic()), 5.0);
  EXPECT_GT(r.poses[5].rms_px, 5.0);  // its error under the solution says why
}

// Corners half a pixel off the intrinsics' convention (a pixel's corner taken for its centre):
// a bias the held-out error hides, the true error and the reported sigma do not.
TEST(ExtrinsicSolver, HalfPixelShiftIsAMeasurableBias) {
  // Quiet corners on both sides, so that the bias (about 0.5 sqrt(2) / 900 rad = 0.045 degrees,
  // inside the 0.1 degree target) stands out of the noise.
  SceneNoise quiet;
  quiet.pixel_sigma = 0.1;
  quiet.position_sigma = 0.0003;
  quiet.angle_sigma_deg = 0.02;
  quiet.floor_m = 0.0002;
  const Scene s = make_scene(31, 9, quiet);
  Scene shifted = s;
  for (TagPose& p : shifted.poses)
    for (Eigen::Vector2d& u : p.pixels) u += Eigen::Vector2d(0.5, 0.5);
  const CalibrationResult a = solve_extrinsic(test_camera(), s.poses);
  const CalibrationResult b = solve_extrinsic(test_camera(), shifted.poses);
  const double rot_a = rotation_error_deg(a.camera_from_lidar, true_extrinsic());
  const double rot_b = rotation_error_deg(b.camera_from_lidar, true_extrinsic());
  std::printf(
      "rotation error %.4f deg (1 sigma %.4f) -> shifted %.4f deg (1 sigma %.4f); held "
      "out median %.3f -> %.3f px\n",
      rot_a, a.rotation_sigma_total_deg, rot_b, b.rotation_sigma_total_deg, a.held_out_median_px,
      b.held_out_median_px);
  EXPECT_LE(rot_a, 3 * a.rotation_sigma_total_deg);
  EXPECT_GT(rot_b, 4 * b.rotation_sigma_total_deg);  // caught: far outside its own sigma
  EXPECT_GT(rot_b, 0.03);
  // The shift alone moves the solution by about that angle.
  EXPECT_NEAR(rotation_error_deg(a.camera_from_lidar, b.camera_from_lidar),
              0.5 * std::sqrt(2.0) / 900 * 180 / std::numbers::pi, 0.015);
  EXPECT_LT(std::abs(b.held_out_median_px - a.held_out_median_px), 0.25);  // hidden there
}

TEST(ExtrinsicSolver, RecoversTheExtrinsicThroughAFisheyeLens) {
  CameraModel fisheye = test_camera();
  fisheye.fx = fisheye.fy = 420;
  fisheye.distortion = Distortion::kEquidistant;
  fisheye.d = {-0.013, 0.021, -0.011, 0.002, 0};
  const Scene s = make_scene(51, 9, SceneNoise{}, false, true_extrinsic(), fisheye);
  ASSERT_EQ(s.poses.size(), 9u);
  const CalibrationResult r = solve_extrinsic(fisheye, s.poses);
  EXPECT_EQ(r.used_poses, 9);
  EXPECT_LE(rotation_error_deg(r.camera_from_lidar, true_extrinsic()),
            std::max(0.1, 3 * r.rotation_sigma_total_deg));
  EXPECT_LE(translation_error_mm(r.camera_from_lidar, true_extrinsic()), 5.0);
}

TEST(ExtrinsicSolver, RefusesNoPosesAndWarnsForFew) {
  EXPECT_THROW(solve_extrinsic(test_camera(), std::span<const TagPose>{}), CalibrationError);
  const Scene s = make_scene(41, 2);
  const CalibrationResult r = solve_extrinsic(test_camera(), s.poses);
  EXPECT_EQ(r.used_poses, 2);
  bool warned = false;
  for (const std::string& w : r.warnings) warned |= w.find("only 2 pose") != std::string::npos;
  EXPECT_TRUE(warned);
  const CalibrationResult one = solve_extrinsic(test_camera(), std::span(s.poses).first(1));
  EXPECT_EQ(one.used_poses, 1);
  EXPECT_EQ(one.held_out_median_px, -1);
  Scene bad = s;
  for (TagPose& p : bad.poses) p.pixels[0].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(solve_extrinsic(test_camera(), bad.poses), CalibrationError);
  // One pose with a covariance that is no covariance: refused with the reason, the rest used.
  Scene mixed = make_scene(11);
  mixed.poses[4].lidar.corner_cov(0, 0) = -1.0;
  const CalibrationResult m = solve_extrinsic(test_camera(), mixed.poses);
  EXPECT_EQ(m.used_poses, 8);
  EXPECT_NE(m.poses[4].reason.find("positive semi-definite"), std::string::npos);
}

}  // namespace
}  // namespace lidartag::calib
