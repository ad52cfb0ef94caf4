#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <numbers>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/correspondence.hpp"
#include "lidartag/detector/detection.hpp"

namespace lidartag::calib {
namespace {

CameraModel camera() {
  CameraModel c;
  c.width = 1280;
  c.height = 720;
  c.fx = c.fy = 900;
  c.cx = 639.5;
  c.cy = 359.5;
  c.distortion = Distortion::kPlumbBob;
  c.d = {-0.1, 0.02, 0.0005, -0.0003, 0.0};
  return c;
}

// LiDAR (x forward, y left, z up) to the camera's optical frame (x right, y down, z forward),
// the camera 10 cm above the LiDAR.
Eigen::Isometry3d camera_from_lidar() {
  Eigen::Matrix3d r;
  r << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = r;
  t.translation() = r * Eigen::Vector3d(0, 0, -0.1);
  return t;
}

Eigen::Matrix3d about_x(double quarter_turns) {
  return Eigen::AngleAxisd(quarter_turns * std::numbers::pi / 2, Eigen::Vector3d::UnitX())
      .toRotationMatrix();
}

// A tag facing the LiDAR at `position`, upright: its frame (x normal towards the sensor, y right
// as seen from the front, z up) in the LiDAR frame.
Eigen::Matrix3d upright_facing_sensor() {
  Eigen::Matrix3d r;
  r.col(0) = -Eigen::Vector3d::UnitX();
  r.col(1) = -Eigen::Vector3d::UnitY();
  r.col(2) = Eigen::Vector3d::UnitZ();
  return r;
}

// What AprilTag 3 reports for a marker whose tag frame is `r` (LiDAR frame) at `position`:
// p[i] is the projection of tag coordinates (-1, 1), (1, 1), (1, -1), (-1, -1) (apriltag.c, x
// right and y DOWN the printed code, +-1 at the black square's corners), written independently
// of the library's corner mapping.
std::array<Eigen::Vector2d, 4> apriltag_p(const Eigen::Vector3d& position, const Eigen::Matrix3d& r,
                                          double h) {
  const double tc[4][2] = {{-1, 1}, {1, 1}, {1, -1}, {-1, -1}};
  std::array<Eigen::Vector2d, 4> p;
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d tag(0.0, tc[i][0] * h, -tc[i][1] * h);  // y right, z up
    p[i] = *camera().project(camera_from_lidar() * (position + r * tag));
  }
  return p;
}

double signed_area(const std::array<Eigen::Vector2d, 4>& p) {
  double a = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector2d& u = p[i];
    const Eigen::Vector2d& v = p[(i + 1) % 4];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return a / 2;
}

TEST(Correspondence, CornerOrderIsTheDetectorsBlackSquareCorners) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  detector::TagFrame frame;
  frame.center = Eigen::Vector3d(4, 1, 0.3);
  frame.undecoded = upright_facing_sensor();
  detector::DecodeResult decoded;
  decoded.code_index = 7;
  const detector::Detection det = detector::assemble_detection(frame, decoded, 0, fam, 1.0, 100, 0);
  const double h = black_half_side(fam, 1.0);
  EXPECT_NEAR(h, 0.4, 1e-12);  // tag36h11: 8 of 10 cells
  for (int k = 0; k < 4; ++k)
    EXPECT_LT((det.corners[static_cast<std::size_t>(k)] -
               (frame.center + frame.undecoded * tag_frame_corner(k, h)))
                  .norm(),
              1e-12);
  // Corner 0 is bottom-left seen from the front (the sensor): lowest z, and on the viewer's left
  // (+y in the LiDAR frame when looking along +x).
  EXPECT_LT(det.corners[0].z(), frame.center.z());
  EXPECT_GT(det.corners[0].y(), frame.center.y());
  EXPECT_EQ(apriltag_corner_of(0), 0);
}

// The same physical marker turned by q quarter turns in its plane, decoded by the detector from
// any undecoded frame (its quarter turns q'), pairs the same physical corners as AprilTag's p[].
TEST(Correspondence, TurnedTagPairsTheSamePhysicalCorners) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  const Eigen::Vector3d pos(5.0, 0.8, 0.4);
  const double size = 1.0;
  const double h = black_half_side(fam, size);
  const CameraModel cam = camera();
  for (int q = 0; q < 4; ++q) {
    // The marker's upright frame after turning it q quarter turns about its normal.
    const Eigen::Matrix3d r = upright_facing_sensor() * about_x(q);
    const std::array<Eigen::Vector2d, 4> p = apriltag_p(pos, r, h);
    // AprilTag documents that p[] wraps counter-clockwise as seen in the image (y down): a
    // negative signed area in image coordinates.
    EXPECT_LT(signed_area(p), 0) << "q " << q;
    for (int qd = 0; qd < 4; ++qd) {
      detector::TagFrame frame;
      frame.center = pos;
      frame.undecoded = r * about_x(qd);  // what the fit found, blind to quarter turns
      detector::DecodeResult decoded;
      decoded.code_index = 3;
      decoded.quarter_turns = qd;
      const detector::Detection det =
          detector::assemble_detection(frame, decoded, 0, fam, size, 100, 0);
      const LidarTag lt = lidar_tag_from_detection(det, fam);
      ImageTagCorners im;
      im.family = "tag36h11";
      im.id = 3;
      im.apriltag_p = p;
      const Pairing pairing = pair_tags(std::span(&lt, 1), std::span(&im, 1), "scene");
      ASSERT_EQ(pairing.poses.size(), 1u);
      const TagPose& tp = pairing.poses[0];
      for (std::size_t k = 0; k < 4; ++k) {
        const Eigen::Vector2d proj = *cam.project(camera_from_lidar() * tp.lidar.corners[k]);
        EXPECT_LT((proj - tp.pixels[k]).norm(), 1e-6) << "q " << q << " qd " << qd << " k " << k;
      }
      // A wrong mapping (one corner along) would be off by the tag's side in the image.
      const Eigen::Vector2d wrong = *cam.project(camera_from_lidar() * tp.lidar.corners[1]);
      EXPECT_GT((wrong - tp.pixels[0]).norm(), 100.0);
    }
  }
}

TEST(Correspondence, TrackCovarianceShrinksWithRotationsAndKeepsTheFloor) {
  const tags::TagFamily& fam = tags::builtin_family("tag16h5");
  detector::TrackInfo track;
  track.id = 2;
  track.position = Eigen::Vector3d(6, 0, 0);
  track.orientation = Eigen::Quaterniond(upright_facing_sensor());
  track.position_std_m = Eigen::Vector3d(0.004, 0.002, 0.002);
  track.angle_std_deg = 0.3;
  track.window_rotations = 1;
  LidarCornerNoise noise;
  noise.floor_m = 0.001;
  const LidarTag one = lidar_tag_from_track(track, fam, 0.8, noise);
  track.window_rotations = 16;
  const LidarTag many = lidar_tag_from_track(track, fam, 0.8, noise);
  EXPECT_EQ(many.id, 2);
  EXPECT_EQ(many.family, "tag16h5");
  // Corner 0's x variance: position 0.004^2 plus the turn's lever arm, over N, plus the floor.
  const double var1 = one.corner_cov(0, 0) - 1e-6;
  const double var16 = many.corner_cov(0, 0) - 1e-6;
  EXPECT_NEAR(var16, var1 / 16, 1e-12);
  EXPECT_GT(var1, 0.004 * 0.004);
  // The corners of one pose are correlated (they move together).
  EXPECT_GT(one.corner_cov(0, 3), 0.0);
  EXPECT_EQ(one.corner_cov.llt().info(), Eigen::Success);
}

// A square-mounted tag's edges run along the rings: its position across them is known to the
// gap over sqrt(12), whatever the spread over rotations says, and the four corners move together.
// A tag turned 45 degrees (a diamond) crosses rings with every edge and gets nothing added; finer
// rings give less.
TEST(Correspondence, RingSpacingUncertaintyAcrossTheRingsOfASquareTag) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  detector::TrackInfo track;
  track.id = 5;
  track.position = Eigen::Vector3d(5, 0, 0);
  track.orientation = Eigen::Quaterniond(upright_facing_sensor());
  track.position_std_m = Eigen::Vector3d(0.001, 0.001, 0.001);
  track.angle_std_deg = 0.1;
  track.window_rotations = 10;
  const LidarTag before = lidar_tag_from_track(track, fam, 1.0);
  std::vector<double> vlp16;  // 16 rings 2 degrees apart, -15..15
  for (int i = 0; i < 16; ++i) vlp16.push_back((-15.0 + 2.0 * i) * std::numbers::pi / 180);
  LidarTag square = before;
  add_ring_spacing_uncertainty(square, fam, vlp16);
  const double gap = 5 * 2.0 * std::numbers::pi / 180;  // 0.175 m at 5 m
  const double var = gap * gap / 12;                    // (50 mm)^2
  for (int k = 0; k < 4; ++k) {
    const int z = 3 * k + 2;
    EXPECT_NEAR(square.corner_cov(z, z) - before.corner_cov(z, z), var, 1e-9) << k;
    // Across the rings only: x (range) and y (along the rings) are unchanged.
    EXPECT_NEAR(square.corner_cov(3 * k, 3 * k), before.corner_cov(3 * k, 3 * k), 1e-12);
    EXPECT_NEAR(square.corner_cov(3 * k + 1, 3 * k + 1), before.corner_cov(3 * k + 1, 3 * k + 1),
                1e-12);
    // Every corner's z moves with corner 0's.
    EXPECT_NEAR(square.corner_cov(2, z) - before.corner_cov(2, z), var, 1e-9) << k;
  }
  EXPECT_EQ(square.corner_cov.llt().info(), Eigen::Success);

  // Turned 45 degrees in its plane: every edge crosses rings; nothing added.
  track.orientation = Eigen::Quaterniond(
      upright_facing_sensor() * Eigen::AngleAxisd(std::numbers::pi / 4, Eigen::Vector3d::UnitX()));
  const LidarTag diamond_before = lidar_tag_from_track(track, fam, 1.0);
  LidarTag diamond = diamond_before;
  add_ring_spacing_uncertainty(diamond, fam, vlp16);
  EXPECT_NEAR((diamond.corner_cov - diamond_before.corner_cov).norm(), 0.0, 1e-15);

  // Turned 3 degrees: a little resolved (the 0.8 m black square spans 42 mm of the 175 mm gap).
  track.orientation =
      Eigen::Quaterniond(upright_facing_sensor() *
                         Eigen::AngleAxisd(3 * std::numbers::pi / 180, Eigen::Vector3d::UnitX()));
  LidarTag slight = lidar_tag_from_track(track, fam, 1.0);
  const double slight_before = slight.corner_cov(2, 2);
  add_ring_spacing_uncertainty(slight, fam, vlp16);
  const double left = 1 - 0.8 * std::sin(3 * std::numbers::pi / 180) / gap;
  EXPECT_NEAR(slight.corner_cov(2, 2) - slight_before, var * left * left, 1e-6 * var);

  // Rings a third of a degree apart about the tag (a VLP-32C's middle) leave a sixth as much.
  std::vector<double> fine;
  for (int i = -30; i <= 30; ++i) fine.push_back(i / 3.0 * std::numbers::pi / 180);
  LidarTag fine_tag = before;
  add_ring_spacing_uncertainty(fine_tag, fam, fine);
  EXPECT_NEAR(fine_tag.corner_cov(2, 2) - before.corner_cov(2, 2), var / 36, 1e-9);
  // No rings known: nothing added.
  LidarTag none = before;
  add_ring_spacing_uncertainty(none, fam, {});
  EXPECT_EQ(none.corner_cov, before.corner_cov);
}

TEST(Correspondence, PairsByFamilyIdAndSizeAndSaysWhyNot) {
  const tags::TagFamily& fam = tags::builtin_family("tag36h11");
  std::vector<LidarTag> lidar;
  for (int id : {1, 2, 3, 5, 5}) {
    detector::TrackInfo t;
    t.id = id;
    t.window_rotations = 10;
    lidar.push_back(lidar_tag_from_track(t, fam, 1.0));
  }
  std::vector<ImageTagCorners> image;
  for (int id : {1, 2, 4, 5}) {
    ImageTagCorners c;
    c.family = "tag36h11";
    c.id = id;
    image.push_back(c);
  }
  image[1].size_m = 0.8;  // tag 2 given as 0.8 m: the LiDAR's is 1.0 m
  ImageTagCorners other = image[0];
  other.family = "tag25h9";
  image.push_back(other);
  const Pairing p = pair_tags(lidar, image, "pair 1");
  ASSERT_EQ(p.poses.size(), 1u);
  EXPECT_EQ(p.poses[0].lidar.id, 1);
  EXPECT_EQ(p.poses[0].label, "pair 1 tag36h11:1");
  auto reason = [&](const std::string& label) {
    for (const Unpaired& u : p.unpaired)
      if (u.label == label) return u.reason;
    return std::string("(paired)");
  };
  EXPECT_NE(reason("pair 1 tag36h11:2").find("size"), std::string::npos);
  EXPECT_NE(reason("pair 1 tag36h11:4").find("image only"), std::string::npos);
  EXPECT_NE(reason("pair 1 tag36h11:5").find("ambiguous"), std::string::npos);
  EXPECT_NE(reason("pair 1 tag36h11:3").find("LiDAR capture only"), std::string::npos);
  EXPECT_NE(reason("pair 1 tag25h9:1").find("image only"), std::string::npos);
}

}  // namespace
}  // namespace lidartag::calib
