// A camera's intrinsics: the pinhole matrix and its lens distortion (plumb-bob, the five
// coefficients of ROS camera_info and OpenCV, or equidistant fisheye), with projection and its
// inverse. Pixel convention (ROS camera_info, OpenCV): (0, 0) is the CENTRE of the top-left pixel;
// a pixel spans [u - 0.5, u + 0.5). Every producer of pixel coordinates in lidartag (the image
// tag detector, the simulator's renderer) converts to this convention, so intrinsics and corners
// agree to the sub-pixel.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace lidartag::calib {

enum class Distortion {
  kNone,         // pinhole without distortion
  kPlumbBob,     // radial k1 k2 k3, tangential p1 p2 (ROS "plumb_bob", OpenCV's 5 coefficients)
  kEquidistant,  // fisheye: theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
};

// A camera model that breaks CameraModel::check()'s rules (named in the message).
class CameraModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CameraModel {
  int width = 0, height = 0;              // image size, pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels; (cx, cy) in the convention above
  double skew = 0;                        // K[0][1], pixels (0 for almost every camera)
  Distortion distortion = Distortion::kNone;
  // kPlumbBob: k1 k2 p1 p2 k3 (that order, as ROS and OpenCV store them); kEquidistant: k1 k2 k3
  // k4 (the fifth unused); kNone: unused.
  std::array<double, 5> d{};

  // Throws CameraModelError naming the first broken rule: a positive size, positive finite focal
  // lengths, a principal point inside the image, finite coefficients.
  void check() const;

  // Pixel of a point in the camera's optical frame (x right, y down, z forward); nullopt behind
  // the camera or where the lens model stops being one-to-one (outside its field of view).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p) const;
  // Unit ray (camera frame) through a pixel: the inverse of project() within its field of view.
  Eigen::Vector3d unproject(const Eigen::Vector2d& pixel) const;
  // Whether a pixel lies on the image: [-0.5, width - 0.5) x [-0.5, height - 0.5).
  bool in_image(const Eigen::Vector2d& pixel) const {
    return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() < width - 0.5 &&
           pixel.y() < height - 0.5;
  }
};

// The distortion and the pinhole matrix applied to a point of the camera frame, templated on the
// scalar so that the calibration's refinement can differentiate it (Eigen's AutoDiffScalar). The
// caller has checked that the point is in front of the lens (project() does); returns the pixel.
template <typename T>
Eigen::Matrix<T, 2, 1> project_point(const CameraModel& c, const Eigen::Matrix<T, 3, 1>& p) {
  using std::atan2;
  using std::sqrt;
  T xd, yd;
  if (c.distortion == Distortion::kEquidistant) {
    const T r = sqrt(p.x() * p.x() + p.y() * p.y());
    const T theta = atan2(r, p.z());
    const T t2 = theta * theta;
    const T theta_d = theta * (1.0 + t2 * (c.d[0] + t2 * (c.d[1] + t2 * (c.d[2] + t2 * c.d[3]))));
    // On the axis theta_d / r tends to 1 / z.
    const T s = r > T(1e-12) ? T(theta_d / r) : T(1.0 / p.z());
    xd = p.x() * s;
    yd = p.y() * s;
  } else {
    const T x = p.x() / p.z(), y = p.y() / p.z();
    xd = x;
    yd = y;
    if (c.distortion == Distortion::kPlumbBob) {
      const double k1 = c.d[0], k2 = c.d[1], p1 = c.d[2], p2 = c.d[3], k3 = c.d[4];
      const T r2 = x * x + y * y;
      const T radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    }
  }
  return {c.fx * xd + c.skew * yd + c.cx, c.fy * yd + c.cy};
}

}  // namespace lidartag::calib
