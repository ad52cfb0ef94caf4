#include "lidartag/calib/camera_model.hpp"

#include <Eigen/Dense>
#include <numbers>

namespace lidartag::calib {
namespace {

bool finite(double v) {
  return std::isfinite(v);
}

// Derivative of the equidistant model's theta_d by theta: where it turns negative the lens model
// folds back, so angles past it are outside the field of view.
double equidistant_slope(const std::array<double, 5>& d, double theta) {
  const double t2 = theta * theta;
  return 1.0 + t2 * (3 * d[0] + t2 * (5 * d[1] + t2 * (7 * d[2] + t2 * 9 * d[3])));
}

// Plumb-bob: the radial factor's derivative by r^2 times r^2 keeps the mapping one-to-one while
// d(r_d)/d(r) > 0; beyond, distant points fold back onto the image (a known OpenCV trap).
bool plumb_bob_monotonic(const std::array<double, 5>& d, double r2) {
  const double k1 = d[0], k2 = d[1], k3 = d[4];
  return 1.0 + r2 * (3 * k1 + r2 * (5 * k2 + r2 * 7 * k3)) > 0;
}

}  // namespace

void CameraModel::check() const {
  auto fail = [](const std::string& what) { throw CameraModelError("camera model: " + what); };
  if (width <= 0 || height <= 0) fail("image size must be positive (width, height)");
  if (!(finite(fx) && finite(fy) && fx > 0 && fy > 0)) fail("focal lengths fx, fy must be > 0");
  if (!finite(skew)) fail("skew must be finite");
  if (!(finite(cx) && finite(cy)) || cx < -0.5 || cy < -0.5 || cx > width - 0.5 ||
      cy > height - 0.5)
    fail("principal point (cx, cy) must lie inside the image");
  for (double v : d)
    if (!finite(v)) fail("distortion coefficients must be finite");
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p) const {
  if (distortion == Distortion::kEquidistant) {
    const double theta = std::atan2(std::hypot(p.x(), p.y()), p.z());
    if (theta >= std::numbers::pi / 2 * 1.2 || equidistant_slope(d, theta) <= 0) return {};
  } else {
    if (p.z() <= 1e-9) return {};
    const double r2 = (p.x() * p.x() + p.y() * p.y()) / (p.z() * p.z());
    if (distortion == Distortion::kPlumbBob && !plumb_bob_monotonic(d, r2)) return {};
  }
  return project_point<double>(*this, p);
}

Eigen::Vector3d CameraModel::unproject(const Eigen::Vector2d& pixel) const {
  // Distorted normalised coordinates.
  const double yd = (pixel.y() - cy) / fy;
  const double xd = (pixel.x() - cx - skew * yd) / fx;
  if (distortion == Distortion::kEquidistant) {
    const double theta_d = std::hypot(xd, yd);
    if (theta_d < 1e-12) return {0, 0, 1};
    double theta = theta_d;  // Newton on theta (1 + k1 theta^2 + ...) = theta_d
    for (int i = 0; i < 20; ++i) {
      const double t2 = theta * theta;
      const double f = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])))) - theta_d;
      const double step = f / equidistant_slope(d, theta);
      theta -= step;
      if (std::abs(step) < 1e-14) break;
    }
    const double s = std::sin(theta) / theta_d;
    return Eigen::Vector3d(xd * s, yd * s, std::cos(theta)).normalized();
  }
  double x = xd, y = yd;
  if (distortion == Distortion::kPlumbBob) {
    // Gauss-Newton on the forward model from the distorted point: converges in a few steps
    // wherever the model is one-to-one.
    for (int i = 0; i < 30; ++i) {
      const Eigen::Vector3d p(x, y, 1.0);
      const Eigen::Vector2d f = project_point<double>(*this, p) - pixel;
      const double h = 1e-7;
      Eigen::Matrix2d J;
      J.col(0) = (project_point<double>(*this, Eigen::Vector3d(x + h, y, 1.0)) -
                  project_point<double>(*this, p)) /
                 h;
      J.col(1) = (project_point<double>(*this, Eigen::Vector3d(x, y + h, 1.0)) -
                  project_point<double>(*this, p)) /
                 h;
      const Eigen::Vector2d step = J.partialPivLu().solve(f);
      x -= step.x();
      y -= step.y();
      if (step.squaredNorm() < 1e-24) break;
    }
  }
  return Eigen::Vector3d(x, y, 1.0).normalized();
}

}  // namespace lidartag::calib
