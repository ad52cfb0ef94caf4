// Squares of known size in the tag's plane: the generic fit, the outline of a few rings, the black
// square's outline from intensity steps and the in-plane placement on it.
#include "lidartag/detector/square_fit.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

namespace lidartag::detector {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Points on the boundary of `s`, `per_side` per side, with Gaussian noise.
std::vector<Eigen::Vector2d> on_square(const Square2& s, int per_side, double noise,
                                       uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise);
  const Eigen::Vector2d eu(std::cos(s.angle), std::sin(s.angle)), ev(-eu.y(), eu.x());
  std::vector<Eigen::Vector2d> out;
  for (int side = 0; side < 4; ++side)
    for (int k = 0; k < per_side; ++k) {
      const double a = s.half * (-0.8 + 1.6 * (k + 0.5) / per_side);
      const Eigen::Vector2d normal = side == 0 ? -eu : side == 1 ? eu : side == 2 ? -ev : ev;
      const Eigen::Vector2d along = side < 2 ? ev : eu;
      out.push_back(s.center + s.half * normal + a * along + n(rng) * normal);
    }
  return out;
}

// The ends of horizontal rings at heights `z` across a square (every ring that crosses it).
std::vector<Eigen::Vector2d> ring_ends(const Square2& s, const std::vector<double>& z) {
  std::vector<Eigen::Vector2d> out;
  const Eigen::Vector2d eu(std::cos(s.angle), std::sin(s.angle)), ev(-eu.y(), eu.x());
  for (double h : z) {
    // Inside the square along the horizontal line y = h: |u|, |v| <= half.
    double lo = -1e9, hi = 1e9;
    bool empty = false;
    for (const Eigen::Vector2d& axis : {eu, ev}) {
      // (x, h) - c projected on axis within [-half, half]: linear in x.
      const double k = axis.x(), b = (h - s.center.y()) * axis.y() - s.center.x() * axis.x();
      if (std::abs(k) < 1e-12) {
        empty = empty || std::abs(b) > s.half;
        continue;
      }
      double a0 = (-s.half - b) / k, a1 = (s.half - b) / k;
      if (a0 > a1) std::swap(a0, a1);
      lo = std::max(lo, a0);
      hi = std::min(hi, a1);
    }
    if (empty || lo >= hi) continue;
    out.emplace_back(lo, h);
    out.emplace_back(hi, h);
  }
  return out;
}

double angle_mod_90(double a) {
  const double q = std::numbers::pi / 2;
  return std::fmod(std::fmod(a, q) + q, q);
}

TEST(SquareFit, RecoversASquareFromPointsOnItsSides) {
  Square2 truth;
  truth.center = Eigen::Vector2d(0.3, -0.2);
  truth.angle = 20 * kDeg;
  truth.half = 0.6;
  const auto pts = on_square(truth, 6, 0.003, 1);
  Square2 start = truth;
  start.center += Eigen::Vector2d(0.03, -0.02);
  start.angle += 3 * kDeg;
  start.half = 0.58;
  SquareFitOptions opt;
  opt.fit_size = true;
  const SquareFit f = fit_square(pts, start, opt);
  ASSERT_TRUE(f.ok);
  EXPECT_LT((f.square.center - truth.center).norm(), 0.003);
  EXPECT_NEAR(f.square.angle, truth.angle, 0.3 * kDeg);
  EXPECT_NEAR(f.square.half, truth.half, 0.003);
  EXPECT_TRUE(f.along_u && f.along_v && f.size_fitted);
  for (int n : f.per_side) EXPECT_EQ(n, 6);
  EXPECT_LT(f.rms_m, 0.005);
  // Without fit_size the size stays where it started.
  opt.fit_size = false;
  EXPECT_NEAR(fit_square(pts, start, opt).square.half, 0.58, 1e-9);
}

TEST(SquareFit, HoldsADirectionWithoutPointsWhereItStarted) {
  Square2 truth;
  truth.half = 0.45;
  auto pts = on_square(truth, 5, 0.0, 2);
  pts.resize(10);  // the -u and +u sides only: a square mount's left and right
  Square2 start = truth;
  start.center = Eigen::Vector2d(0.02, 0.07);
  const SquareFit f = fit_square(pts, start, SquareFitOptions{});
  ASSERT_TRUE(f.ok);
  EXPECT_TRUE(f.along_u);
  EXPECT_FALSE(f.along_v);
  EXPECT_NEAR(f.square.center.x(), 0.0, 1e-6);
  EXPECT_NEAR(f.square.center.y(), 0.07, 1e-6);  // held
  // With the size free, two opposite sides fix it too; one side alone does not.
  SquareFitOptions sized;
  sized.fit_size = true;
  EXPECT_TRUE(fit_square(pts, start, sized).ok);
  pts.resize(5);
  EXPECT_FALSE(fit_square(pts, start, sized).ok);
}

TEST(SquareFit, OutlineOfFourRingsAcrossADiamond) {
  // A VLP-16 at 10 m: beams 2 degrees apart, four rings across a 1.3 m board mounted as a diamond.
  Square2 truth;
  truth.center = Eigen::Vector2d(0.04, 0.01);
  truth.angle = 45 * kDeg;
  truth.half = 0.65;
  std::vector<double> z;
  for (int k = -3; k <= 3; k += 2) z.push_back(10.0 * std::tan(k * kDeg));
  const auto edge = ring_ends(truth, z);
  ASSERT_EQ(edge.size(), 8u);
  SquareFitOptions opt;
  opt.fit_size = true;
  opt.gate_m = 0.06;
  opt.huber_m = 0.012;
  SquareFit f;
  ASSERT_TRUE(fit_square_outline(edge, 0.4, 0.8, opt, f));
  EXPECT_LT((f.square.center - truth.center).norm(), 0.005);
  EXPECT_NEAR(angle_mod_90(f.square.angle), 45 * kDeg, 0.5 * kDeg);
  EXPECT_NEAR(f.square.half, truth.half, 0.005);
  for (int n : f.per_side) EXPECT_EQ(n, 2);
  // The same rings across a square mount (sides along the axes) only meet its left and right:
  // its width gives the size, its height is left to decoding.
  truth.angle = 0.0;
  const auto square_edge = ring_ends(truth, z);
  ASSERT_TRUE(fit_square_outline(square_edge, 0.4, 0.8, opt, f));
  EXPECT_NEAR(f.square.half, truth.half, 0.005);
  EXPECT_NEAR(std::cos(4 * f.square.angle), 1.0, 1e-3);  // sides along the axes
  EXPECT_NE(f.along_u, f.along_v);
}

TEST(SquareFit, OutlineOfDenseLowerAndSparseUpperRings) {
  // A 0.6 m tag (0.7 m board) at 4 m, centre 0.3 m above a VLP-32C: many rings across its lower
  // half, three across its upper half.
  Square2 truth;
  truth.center = Eigen::Vector2d(0.0, 0.3);
  truth.angle = 45 * kDeg;
  truth.half = 0.35;
  std::vector<double> z;
  for (double e : {-1.333, -1.0, -0.667, -0.333, 0.0, 0.333, 0.667, 1.0, 1.333, 1.667, 2.333, 3.333,
                   4.667, 7.0})
    z.push_back(4.0 * std::tan(e * kDeg));
  const auto edge = ring_ends(truth, z);
  SquareFitOptions opt;
  opt.fit_size = true;
  opt.gate_m = 0.035;
  opt.huber_m = 0.007;
  SquareFit f;
  ASSERT_TRUE(fit_square_outline(edge, 0.2, 0.45, opt, f));
  EXPECT_LT((f.square.center - truth.center).norm(), 0.003);
  EXPECT_NEAR(angle_mod_90(f.square.angle), 45 * kDeg, 0.3 * kDeg);
  EXPECT_NEAR(f.square.half, truth.half, 0.003);
}

// A marker (tag16h5, t = 1.2, on a 1.3 m board) crossed by horizontal rings, points every `step`
// (2 cm) symmetric about the centre, in its own frame (x normal), intensities white 200, black 20,
// bare board 150.
std::vector<ClusterPoint> scanned_marker(const Eigen::Matrix3d& r_in_plane, double step = 0.02) {
  const auto& fam = tags::builtin_family("tag16h5");
  const auto img = fam.render(fam.codes[3]);
  std::vector<ClusterPoint> out;
  int ring = 0;
  for (double z = -0.62; z <= 0.62; z += 0.07, ++ring)
    for (double y = -0.65 + step / 2; y <= 0.65; y += step) {  // symmetric, none on a border
      // The board's frame is the tag's turned in its plane.
      const Eigen::Vector3d q = r_in_plane.transpose() * Eigen::Vector3d(0, y, z);
      ClusterPoint p;
      p.x = 0.0f;
      p.y = static_cast<float>(y);
      p.z = static_cast<float>(z);
      p.ring = ring;
      if (std::abs(q.y()) > 0.6 || std::abs(q.z()) > 0.6) {
        if (std::abs(q.y()) > 0.65 || std::abs(q.z()) > 0.65) continue;
        p.intensity = 150.0f;
      } else {
        const int c = std::clamp(static_cast<int>((q.y() + 0.6) / 0.15), 0, 7);
        const int row = std::clamp(static_cast<int>((0.6 - q.z()) / 0.15), 0, 7);
        p.intensity = img[static_cast<size_t>(row * 8 + c)] ? 200.0f : 20.0f;
      }
      out.push_back(p);
    }
  return out;
}

TEST(BorderCrossings, TheBlackSquareAlongEachRing) {
  const auto pts = scanned_marker(Eigen::Matrix3d::Identity());
  IntensityLevels lv;
  lv.black = 20.0f;
  lv.white = 200.0f;
  lv.valid = true;
  std::vector<BorderPoint> border;
  border_crossings(pts, RigidPose{}, lv, false, 0.3, border);
  ASSERT_FALSE(border.empty());
  int rings_through_black = 0;
  for (double z = -0.62; z <= 0.62; z += 0.07) rings_through_black += std::abs(z) < 0.45 ? 1 : 0;
  EXPECT_EQ(border.size(), static_cast<size_t>(2 * rings_through_black));
  for (const auto& b : border) {
    EXPECT_NEAR(std::abs(b.yz.x()), 0.45, 0.011) << b.yz.transpose();  // within half a step
    EXPECT_LT(std::abs(b.yz.y()), 0.45);
  }
  // Read as a reversed border (black outer ring, white border), the rings through the payload
  // find their steps inside the black border, never on its outline.
  border_crossings(pts, RigidPose{}, lv, true, 0.3, border);
  for (const auto& b : border)
    if (std::abs(b.yz.y()) < 0.3) {
      EXPECT_LT(std::abs(b.yz.x()), 0.44) << b.yz.transpose();
    }
}

TEST(BorderFit, PlacesTheTagOnTheBlackSquare) {
  // The marker turned 45 degrees in its plane (a diamond) and scanned by horizontal rings; the
  // pull-back starts 2 cm and 1.5 cm off in the plane and turned by 1.5 degrees.
  const Eigen::Matrix3d diamond =
      Eigen::AngleAxisd(45 * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const auto pts = scanned_marker(diamond, 0.01);
  RigidPose truth;  // pulls the points back into the diamond's own frame
  truth.R = diamond.transpose();
  RigidPose start = truth;
  start.R = Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix() * truth.R;
  start.p = Eigen::Vector3d(0.0, 0.02, -0.015);
  const std::vector<RkhsDictionary> fams = {RkhsDictionary(tags::builtin_family("tag16h5"))};
  IntensityLevels lv;
  lv.black = 20.0f;
  lv.white = 200.0f;
  lv.valid = true;
  BorderWorkspace ws;
  const BorderFit f = place_on_border(pts, start, 1.2, fams, lv, BorderFitOptions{}, ws);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.sides, 4);
  EXPECT_TRUE(f.along_y && f.along_z);
  // The tag's centre and turn about its normal as the truth, the normal untouched.
  const Eigen::Vector3d centre = -f.pose.R.transpose() * f.pose.p;
  EXPECT_LT(centre.norm(), 0.002) << centre.transpose();
  const double angle = Eigen::AngleAxisd(f.pose.R * truth.R.transpose()).angle();
  EXPECT_LT(angle, 0.2 * kDeg);
  EXPECT_LT((f.pose.R.row(0) - start.R.row(0)).norm(), 1e-12);
}

TEST(BorderFit, ASquareMountKeepsItsHeightForDecoding) {
  const auto pts = scanned_marker(Eigen::Matrix3d::Identity(), 0.01);
  RigidPose start;
  start.p = Eigen::Vector3d(0.0, 0.02, 0.05);
  const std::vector<RkhsDictionary> fams = {RkhsDictionary(tags::builtin_family("tag16h5"))};
  IntensityLevels lv;
  lv.black = 20.0f;
  lv.white = 200.0f;
  lv.valid = true;
  BorderWorkspace ws;
  const BorderFit f = place_on_border(pts, start, 1.2, fams, lv, BorderFitOptions{}, ws);
  ASSERT_TRUE(f.ok);
  EXPECT_TRUE(f.along_y);
  EXPECT_FALSE(f.along_z);  // horizontal rings meet only the left and right of the black square
  const Eigen::Vector3d centre = -f.pose.R.transpose() * f.pose.p;
  EXPECT_NEAR(centre.y(), 0.0, 0.002);
  EXPECT_NEAR(centre.z(), -0.05, 1e-6);  // where it started
}

}  // namespace
}  // namespace lidartag::detector
