// Detection assembly: the fitted frame, the decoded quarter turns, the black square's corners.
#include "lidartag/detector/detection.hpp"

#include <gtest/gtest.h>

#include <numbers>

namespace lidartag::detector {
namespace {

Eigen::Matrix3d some_rotation() {
  return (Eigen::AngleAxisd(2.9, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

TEST(Detection, TheFrameIsTheInverseOfThePullBackMovedByTheShift) {
  const Eigen::Matrix3d R = some_rotation();
  const Eigen::Vector3d c(7, -2, 0.4);
  RigidPose pull_back;
  pull_back.R = R.transpose();
  pull_back.p = -R.transpose() * c;
  const TagFrame f = tag_frame(pull_back, Eigen::Vector3d::Zero(), 0.3);
  EXPECT_LT((f.center - c).norm(), 1e-12);
  EXPECT_LT((f.undecoded - R).norm(), 1e-12);
  const Eigen::Vector3d axis = R.col(2);
  const TagFrame g = tag_frame(pull_back, axis, 0.3);
  EXPECT_LT((g.center - (c + 0.3 * axis)).norm(), 1e-12);
}

TEST(Detection, QuarterTurnsTurnAboutTheNormal) {
  const Eigen::Matrix3d R = some_rotation();
  for (int q = 0; q < 4; ++q) {
    const Eigen::Matrix3d d = decoded_rotation(R, q);
    EXPECT_LT((d.col(0) - R.col(0)).norm(), 1e-12) << q;  // the normal stays
    // The tag frame is the fitted one turned by -q quarter turns about its normal.
    const double a = -q * std::numbers::pi / 2;
    const Eigen::Vector3d y = std::cos(a) * R.col(1) + std::sin(a) * R.col(2);
    EXPECT_LT((d.col(1) - y).norm(), 1e-12) << q;
  }
  EXPECT_LT((decoded_rotation(R, 4) - R).norm(), 1e-12);
}

TEST(Detection, AssembledFromTheFrameAndTheDecodedCode) {
  const auto& fam = tags::builtin_family("tag16h5");
  const Eigen::Matrix3d R = some_rotation();
  TagFrame frame;
  frame.center = Eigen::Vector3d(5, 1, 0.2);
  frame.undecoded = R;
  DecodeResult r;
  r.code_index = 11;
  r.quarter_turns = 3;
  r.score = 0.97;
  r.margin_bits = 4.5;
  const Detection d = assemble_detection(frame, r, 2, fam, 1.2, 900, 3.5);
  EXPECT_EQ(d.family_index, 2);
  EXPECT_EQ(d.family, "tag16h5");
  EXPECT_EQ(d.id, 11);
  EXPECT_EQ(d.size_m, 1.2);
  EXPECT_EQ(d.points, 900);
  EXPECT_EQ(d.fit_cost, 3.5);
  EXPECT_EQ(d.score, 0.97);
  EXPECT_EQ(d.margin, 4.5);
  EXPECT_EQ(d.position, frame.center);
  EXPECT_GE(d.orientation.w(), 0.0);
  const Eigen::Matrix3d rs = decoded_rotation(R, 3);
  EXPECT_LT((d.orientation.toRotationMatrix() - rs).norm(), 1e-9);
  // The black square (6 of 8 cells) in the tag's plane: bottom-left, bottom-right, top-right,
  // top-left seen from the front.
  const double h = 0.75 * 0.6;
  const std::array<Eigen::Vector2d, 4> yz = {Eigen::Vector2d(-h, -h), Eigen::Vector2d(h, -h),
                                             Eigen::Vector2d(h, h), Eigen::Vector2d(-h, h)};
  for (size_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d local = rs.transpose() * (d.corners[k] - frame.center);
    EXPECT_NEAR(local.x(), 0.0, 1e-12);
    EXPECT_NEAR(local.y(), yz[k].x(), 1e-12);
    EXPECT_NEAR(local.z(), yz[k].y(), 1e-12);
  }
}

TEST(Detection, QuaternionsHaveANonNegativeScalarPart) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(3.0, Eigen::Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  const Eigen::Quaterniond q = unit_quaternion(r);
  EXPECT_GE(q.w(), 0.0);
  EXPECT_NEAR(q.norm(), 1.0, 1e-12);
  EXPECT_LT((q.toRotationMatrix() - r).norm(), 1e-12);
}

}  // namespace
}  // namespace lidartag::detector
