#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/AutoDiff>

#include "lidartag/calib/camera_model.hpp"

namespace lidartag::calib {
namespace {

CameraModel pinhole() {
  CameraModel c;
  c.width = 1280;
  c.height = 720;
  c.fx = 900;
  c.fy = 905;
  c.cx = 639.5;
  c.cy = 359.5;
  return c;
}

CameraModel plumb_bob() {
  CameraModel c = pinhole();
  c.distortion = Distortion::kPlumbBob;
  c.d = {-0.28, 0.09, 0.001, -0.0007, -0.012};
  return c;
}

CameraModel fisheye() {
  CameraModel c = pinhole();
  c.fx = c.fy = 400;
  c.distortion = Distortion::kEquidistant;
  c.d = {-0.013, 0.021, -0.011, 0.002, 0};
  return c;
}

TEST(CameraModel, PinholeProjectsByTheMatrixWithPixelCentresAtIntegers) {
  const CameraModel c = pinhole();
  // On the optical axis: the principal point, i.e. between the two middle pixels of an even
  // width (639.5 in the convention where pixel 0's centre is 0).
  EXPECT_NEAR(c.project({0, 0, 5})->x(), 639.5, 1e-12);
  const Eigen::Vector2d p = *c.project({1.0, -0.5, 4.0});
  EXPECT_NEAR(p.x(), 639.5 + 900 * 0.25, 1e-9);
  EXPECT_NEAR(p.y(), 359.5 - 905 * 0.125, 1e-9);
  EXPECT_FALSE(c.project({0, 0, -1}).has_value());
}

TEST(CameraModel, PlumbBobMatchesTheFormulaWrittenOut) {
  const CameraModel c = plumb_bob();
  const double x = 0.3, y = -0.2;
  const double r2 = x * x + y * y;
  const double k1 = -0.28, k2 = 0.09, p1 = 0.001, p2 = -0.0007, k3 = -0.012;
  const double radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  const Eigen::Vector2d p = *c.project({x * 3, y * 3, 3});
  EXPECT_NEAR(p.x(), 900 * xd + 639.5, 1e-9);
  EXPECT_NEAR(p.y(), 905 * yd + 359.5, 1e-9);
}

TEST(CameraModel, EquidistantMatchesTheFormulaWrittenOut) {
  const CameraModel c = fisheye();
  const Eigen::Vector3d p(1.0, 0.5, 0.8);
  const double r = std::hypot(p.x(), p.y());
  const double t = std::atan2(r, p.z());
  const double td = t * (1 - 0.013 * t * t + 0.021 * std::pow(t, 4) - 0.011 * std::pow(t, 6) +
                         0.002 * std::pow(t, 8));
  const Eigen::Vector2d q = *c.project(p);
  EXPECT_NEAR(q.x(), 400 * td * p.x() / r + 639.5, 1e-9);
  EXPECT_NEAR(q.y(), 400 * td * p.y() / r + 359.5, 1e-9);
}

TEST(CameraModel, UnprojectInvertsProjectOverTheImage) {
  for (const CameraModel& c : {pinhole(), plumb_bob(), fisheye()}) {
    for (double u = 0; u < c.width; u += 91.7) {
      for (double v = 0; v < c.height; v += 63.1) {
        const Eigen::Vector2d px(u, v);
        const Eigen::Vector3d ray = c.unproject(px);
        EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
        const auto back = c.project(ray * 7.0);
        ASSERT_TRUE(back.has_value()) << u << " " << v;
        EXPECT_NEAR((*back - px).norm(), 0.0, 1e-6) << u << " " << v;
      }
    }
  }
}

TEST(CameraModel, RefusesPointsWhereTheLensModelFoldsBack) {
  // Strong barrel distortion: r_d(r) peaks near r = 1.2 and folds back beyond; a point there
  // would land inside the image at a wrong place.
  CameraModel c = pinhole();
  c.distortion = Distortion::kPlumbBob;
  c.d = {-0.35, 0, 0, 0, 0};
  EXPECT_TRUE(c.project({0.5, 0, 1}).has_value());
  EXPECT_FALSE(c.project({3.0, 0, 1}).has_value());
  // Behind a fisheye's hemisphere-and-a-bit.
  EXPECT_FALSE(fisheye().project({0, 0.1, -1}).has_value());
  EXPECT_TRUE(fisheye().project({1, 0, 0.05}).has_value());
}

TEST(CameraModel, ProjectionDifferentiatesWithAutoDiff) {
  using Scalar = Eigen::AutoDiffScalar<Eigen::Vector3d>;
  const CameraModel c = plumb_bob();
  const Eigen::Vector3d p0(0.4, -0.3, 2.5);
  Eigen::Matrix<Scalar, 3, 1> p;
  for (int i = 0; i < 3; ++i) p[i] = Scalar(p0[i], 3, i);
  const Eigen::Matrix<Scalar, 2, 1> q = project_point<Scalar>(c, p);
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d h = Eigen::Vector3d::Zero();
    h[i] = 1e-6;
    const Eigen::Vector2d numeric = (*c.project(p0 + h) - *c.project(p0 - h)) / 2e-6;
    EXPECT_NEAR(q.x().derivatives()[i], numeric.x(), 1e-4);
    EXPECT_NEAR(q.y().derivatives()[i], numeric.y(), 1e-4);
  }
}

TEST(CameraModel, CheckNamesTheBrokenRule) {
  auto message = [](CameraModel c) {
    try {
      c.check();
    } catch (const CameraModelError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(message(plumb_bob()), "");
  CameraModel c = pinhole();
  c.width = 0;
  EXPECT_NE(message(c).find("image size"), std::string::npos);
  c = pinhole();
  c.fy = -1;
  EXPECT_NE(message(c).find("focal"), std::string::npos);
  c = pinhole();
  c.cx = 2000;
  EXPECT_NE(message(c).find("principal point"), std::string::npos);
  c = plumb_bob();
  c.d[2] = std::nan("");
  EXPECT_NE(message(c).find("distortion"), std::string::npos);
}

}  // namespace
}  // namespace lidartag::calib
