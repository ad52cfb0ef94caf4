#include "lidartag/calib/extrinsic_solver.hpp"

// Eigen/Dense before the AutoDiff module (it uses what Dense declares).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <unsupported/Eigen/AutoDiff>

namespace lidartag::calib {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec8 = Eigen::Matrix<double, 8, 1>;
using Mat8 = Eigen::Matrix<double, 8, 8>;
using Mat86 = Eigen::Matrix<double, 8, 6>;

constexpr double kDeg = 180.0 / std::numbers::pi;

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity() + hat(w);
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

// The pixel of a camera-frame point and its derivative by the point; false outside the lens
// model's field of view.
bool project_jacobian(const CameraModel& cam, const Eigen::Vector3d& p, Eigen::Vector2d& uv,
                      Eigen::Matrix<double, 2, 3>& j) {
  if (!cam.project(p)) return false;
  using Ad = Eigen::AutoDiffScalar<Eigen::Vector3d>;
  Eigen::Matrix<Ad, 3, 1> pa;
  for (int i = 0; i < 3; ++i) pa(i) = Ad(p(i), 3, i);
  const Eigen::Matrix<Ad, 2, 1> u = project_point<Ad>(cam, pa);
  for (int r = 0; r < 2; ++r) {
    uv(r) = u(r).value();
    j.row(r) = u(r).derivatives().transpose();
  }
  return true;
}

struct Transform {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

// One pose's residual under a transform: raw (pixels), whitened, and the whitened Jacobian by
// (rotation vector on the camera side, translation).
struct PoseEval {
  bool ok = false;
  Vec8 raw = Vec8::Zero();
  Vec8 white = Vec8::Zero();
  Mat86 jac = Mat86::Zero();
  double chi2 = 0.0;
};

PoseEval evaluate(const CameraModel& cam, const TagPose& pose, const Transform& x) {
  PoseEval e;
  Eigen::Matrix<double, 8, 12> b = Eigen::Matrix<double, 8, 12>::Zero();
  Mat86 j;
  for (int k = 0; k < 4; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    const Eigen::Vector3d rx = x.r * pose.lidar.corners[ks];
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 3> jp;
    if (!project_jacobian(cam, rx + x.t, uv, jp)) return e;
    e.raw.segment<2>(2 * k) = uv - pose.pixels[ks];
    j.block<2, 3>(2 * k, 0) = -jp * hat(rx);
    j.block<2, 3>(2 * k, 3) = jp;
    b.block<2, 3>(2 * k, 3 * k) = jp * x.r;
  }
  Mat8 cov = b * pose.lidar.corner_cov * b.transpose();
  cov.diagonal().array() += pose.sigma_px * pose.sigma_px;
  const Eigen::LLT<Mat8> llt(cov);
  if (llt.info() != Eigen::Success) return e;
  e.white = llt.matrixL().solve(e.raw);
  e.jac = llt.matrixL().solve(j);
  e.chi2 = e.white.squaredNorm();
  e.ok = e.raw.allFinite() && std::isfinite(e.chi2);
  return e;
}

double huber_cost(double chi2, double c) {
  const double s = std::sqrt(chi2);
  return s <= c ? chi2 : 2 * c * s - c * c;
}

double huber_weight(double chi2, double c) {
  const double s = std::sqrt(chi2);
  return s <= c ? 1.0 : c / s;
}

struct Accum {
  bool ok = false;
  double cost = 0.0;
  Mat6 h = Mat6::Zero();
  Vec6 g = Vec6::Zero();
};

Accum accumulate(const CameraModel& cam, std::span<const TagPose> poses,
                 const std::vector<int>& active, const Transform& x, double huber) {
  Accum a;
  for (int i : active) {
    const PoseEval e = evaluate(cam, poses[static_cast<std::size_t>(i)], x);
    if (!e.ok) return a;
    const double w = huber_weight(e.chi2, huber);
    a.cost += huber_cost(e.chi2, huber);
    a.h += w * e.jac.transpose() * e.jac;
    a.g += w * e.jac.transpose() * e.white;
  }
  a.ok = true;
  return a;
}

Transform apply(const Transform& x, const Vec6& d) {
  Transform y;
  y.r = exp_so3(d.head<3>()) * x.r;
  y.t = x.t + d.tail<3>();
  return y;
}

// Levenberg-Marquardt from `x` over the active poses; returns the iterations taken.
int refine(const CameraModel& cam, std::span<const TagPose> poses, const std::vector<int>& active,
           const SolverOptions& opt, Transform& x) {
  double lambda = 1e-3;
  int it = 0;
  Accum cur = accumulate(cam, poses, active, x, opt.huber);
  if (!cur.ok) return 0;
  for (; it < opt.max_iterations; ++it) {
    bool accepted = false;
    Vec6 step = Vec6::Zero();
    while (lambda < 1e10) {
      Mat6 a = cur.h;
      a.diagonal() += lambda * cur.h.diagonal().cwiseMax(1e-9);
      step = -a.ldlt().solve(cur.g);
      const Transform cand = apply(x, step);
      const Accum next = accumulate(cam, poses, active, cand, opt.huber);
      if (next.ok && next.cost <= cur.cost) {
        x = cand;
        cur = next;
        lambda = std::max(lambda / 3, 1e-9);
        accepted = true;
        break;
      }
      lambda *= 4;
    }
    if (!accepted || (step.head<3>().norm() < 1e-10 && step.tail<3>().norm() < 1e-10)) break;
  }
  return it;
}

double rms(std::span<const double> v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / static_cast<double>(v.size()));
}

double lower_median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>((v.size() - 1) / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

std::string fmt(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

// First guess: each pose's square from its image, one Kabsch over all; poses whose LiDAR corners
// land far from their image square (a wrong ID, a moved tag) are dropped from it one at a time.
bool first_guess(const CameraModel& cam, std::span<const TagPose> poses,
                 const std::vector<int>& candidates, Transform& x) {
  std::vector<int> use;
  std::vector<std::array<Eigen::Vector3d, 4>> cam_corners(poses.size());
  for (int i : candidates) {
    const TagPose& p = poses[static_cast<std::size_t>(i)];
    const double h = (p.lidar.corners[2] - p.lidar.corners[0]).norm() / (2 * std::sqrt(2.0));
    if (planar_square_pose(cam, p.pixels, h, cam_corners[static_cast<std::size_t>(i)]))
      use.push_back(i);
  }
  while (!use.empty()) {
    std::vector<Eigen::Vector3d> from, to;
    for (int i : use)
      for (std::size_t k = 0; k < 4; ++k) {
        from.push_back(poses[static_cast<std::size_t>(i)].lidar.corners[k]);
        to.push_back(cam_corners[static_cast<std::size_t>(i)][k]);
      }
    Eigen::Isometry3d t;
    if (!rigid_align(from, to, t)) return false;
    x.r = t.linear();
    x.t = t.translation();
    if (use.size() <= 2) return true;
    // Each pose's misfit relative to its range (the planar pose's depth scatters with range).
    std::vector<double> misfit;
    for (int i : use) {
      double s = 0;
      for (std::size_t k = 0; k < 4; ++k)
        s += (t * poses[static_cast<std::size_t>(i)].lidar.corners[k] -
              cam_corners[static_cast<std::size_t>(i)][k])
                 .squaredNorm();
      misfit.push_back(std::sqrt(s / 4) / cam_corners[static_cast<std::size_t>(i)][0].norm());
    }
    const double med = median(misfit);
    const auto worst = std::max_element(misfit.begin(), misfit.end()) - misfit.begin();
    if (misfit[static_cast<std::size_t>(worst)] < std::max(0.02, 4 * med)) return true;
    use.erase(use.begin() + worst);
  }
  return false;
}

const char* const kDofNames[6] = {"rotation about camera x",    "rotation about camera y",
                                  "rotation about camera z",    "translation along camera x",
                                  "translation along camera y", "translation along camera z"};

std::string direction_name(const Vec6& v) {
  std::vector<std::pair<double, int>> parts;
  for (int i = 0; i < 6; ++i) parts.emplace_back(std::abs(v(i)), i);
  std::sort(parts.begin(), parts.end(), std::greater<>());
  std::string name = kDofNames[parts[0].second];
  // The second largest component when it matters (a rotation traded against a translation).
  if (parts[1].first >= 0.35) name += " coupled with " + std::string(kDofNames[parts[1].second]);
  return name;
}

// The pose to add next: what the used poses lack (distances, image regions, tilt), the most
// relevant to the weak direction first.
std::string suggest(const CameraModel& cam, std::span<const TagPose> poses,
                    const std::vector<int>& used, const Transform& x, const Vec6& weak) {
  double rmin = std::numeric_limits<double>::max(), rmax = 0, max_tilt = 0;
  int grid[3][3] = {};
  for (int i : used) {
    const TagPose& p = poses[static_cast<std::size_t>(i)];
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    Eigen::Vector2d u = Eigen::Vector2d::Zero();
    for (std::size_t k = 0; k < 4; ++k) {
      c += x.r * p.lidar.corners[k] + x.t;
      u += p.pixels[k];
    }
    c /= 4;
    u /= 4;
    rmin = std::min(rmin, c.norm());
    rmax = std::max(rmax, c.norm());
    const Eigen::Vector3d n = x.r * (p.lidar.orientation * Eigen::Vector3d::UnitX());
    max_tilt = std::max(max_tilt, std::acos(std::min(1.0, std::abs(n.dot(c.normalized())))));
    const int gx = std::clamp(static_cast<int>(3 * (u.x() + 0.5) / cam.width), 0, 2);
    const int gy = std::clamp(static_cast<int>(3 * (u.y() + 0.5) / cam.height), 0, 2);
    ++grid[gy][gx];
  }
  std::vector<std::string> hints;
  if (rmax < 1.5 * rmin) {
    // Nearer when the tags are far (a near tag is the stronger lever), else farther.
    const double at = rmin >= 3.0 ? std::max(1.5, rmin / 2) : 2 * rmax;
    hints.push_back("a tag at another distance (all are at " + fmt(rmin, 1) + "-" + fmt(rmax, 1) +
                    " m: add one at about " + fmt(at, 1) + " m)");
  }
  static const char* const kRow[3] = {"top", "middle", "bottom"};
  static const char* const kCol[3] = {"left", "centre", "right"};
  std::string empty;
  int empties = 0;
  for (int gy : {0, 2, 1})
    for (int gx : {0, 2, 1})
      if (grid[gy][gx] == 0 && !(gx == 1 && gy == 1)) {
        if (empties++ < 3)
          empty += (empty.empty() ? "" : ", ") + std::string(kRow[gy]) + "-" + kCol[gx];
      }
  if (empties >= 4)
    hints.push_back("a tag on another side of the image (none in the " + empty + " of it)");
  if (max_tilt * kDeg < 20)
    hints.push_back("a tilted tag (all face the camera within " + fmt(max_tilt * kDeg, 0) +
                    " degrees: turn one 30-45 degrees)");
  if (hints.empty()) hints.push_back("more poses spread over distance, image sides and tilt");
  // A weak direction with translation in it (depth, or rotation traded against a sideways
  // translation, which one range cannot tell apart) is cured by another distance; pure
  // rotations by other image sides.
  if (weak.tail<3>().norm() < 0.35 && hints.size() > 1 &&
      hints[0].rfind("a tag at another", 0) == 0)
    std::rotate(hints.begin(), hints.begin() + 1, hints.end());
  std::string s = "add " + hints[0];
  for (std::size_t i = 1; i < hints.size(); ++i) s += "; or " + hints[i];
  return s;
}

}  // namespace

bool planar_square_pose(const CameraModel& camera, const std::array<Eigen::Vector2d, 4>& pixels,
                        double half_side, std::array<Eigen::Vector3d, 4>& corners_camera) {
  // Object points in the tag plane (y right, z up), normalised image points (undistorted).
  Eigen::Matrix<double, 8, 9> a = Eigen::Matrix<double, 8, 9>::Zero();
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d o = tag_frame_corner(k, 1.0);  // (0, y, z), unit half side
    const Eigen::Vector3d ray = camera.unproject(pixels[static_cast<std::size_t>(k)]);
    if (!(ray.z() > 1e-6)) return false;
    const double u = ray.x() / ray.z(), v = ray.y() / ray.z();
    const double X = o.y(), Y = o.z();
    a.row(2 * k) << X, Y, 1, 0, 0, 0, -u * X, -u * Y, -u;
    a.row(2 * k + 1) << 0, 0, 0, X, Y, 1, -v * X, -v * Y, -v;
  }
  const Eigen::JacobiSVD<Eigen::Matrix<double, 8, 9>> svd(a, Eigen::ComputeFullV);
  const Eigen::Matrix<double, 9, 1> hv = svd.matrixV().col(8);
  Eigen::Matrix3d h;
  h << hv(0), hv(1), hv(2), hv(3), hv(4), hv(5), hv(6), hv(7), hv(8);
  // h ~ [r1 r2 t] (object units of one half side).
  double s = (h.col(0).norm() + h.col(1).norm()) / 2;
  if (!(s > 0)) return false;
  if (h(2, 2) < 0) s = -s;  // the tag's centre in front of the camera
  Eigen::Matrix3d r;
  r.col(0) = h.col(0) / s;
  r.col(1) = h.col(1) / s;
  r.col(2) = r.col(0).cross(r.col(1));
  const Eigen::JacobiSVD<Eigen::Matrix3d> rs(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  r = rs.matrixU() * rs.matrixV().transpose();
  if (r.determinant() < 0) return false;
  const Eigen::Vector3d t = h.col(2) / s * half_side;
  if (!(t.z() > 0)) return false;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d o = tag_frame_corner(k, half_side);
    corners_camera[static_cast<std::size_t>(k)] = r.col(0) * o.y() + r.col(1) * o.z() + t;
  }
  return true;
}

bool rigid_align(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                 Eigen::Isometry3d& out) {
  if (from.size() != to.size() || from.size() < 3) return false;
  Eigen::Vector3d mf = Eigen::Vector3d::Zero(), mt = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    mf += from[i];
    mt += to[i];
  }
  mf /= static_cast<double>(from.size());
  mt /= static_cast<double>(to.size());
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) c += (to[i] - mt) * (from[i] - mf).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(c, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(1) > 1e-9 * std::max(1.0, sv(0)))) return false;  // collinear
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  out = Eigen::Isometry3d::Identity();
  out.linear() = svd.matrixU() * d * svd.matrixV().transpose();
  out.translation() = mt - out.linear() * mf;
  return true;
}

CalibrationResult solve_extrinsic(const CameraModel& camera, std::span<const TagPose> poses,
                                  const SolverOptions& opt) {
  if (poses.empty()) throw CalibrationError("calibration: no tag pose seen by both sensors");
  CalibrationResult res;
  res.poses.resize(poses.size());
  std::vector<int> active;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    res.poses[i].label = poses[i].label;
    const bool finite = std::all_of(poses[i].pixels.begin(), poses[i].pixels.end(),
                                    [](const Eigen::Vector2d& p) { return p.allFinite(); }) &&
                        poses[i].lidar.corner_cov.allFinite() && poses[i].sigma_px > 0;
    const bool psd = finite && Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>>(
                                   poses[i].lidar.corner_cov, Eigen::EigenvaluesOnly)
                                       .eigenvalues()(0) >= -1e-12;
    if (!finite || !psd) {
      res.poses[i].used = false;
      res.poses[i].reason = !finite ? "not finite: corners, covariance or pixel sigma"
                                    : "the LiDAR corners' covariance is not positive semi-definite";
    } else {
      active.push_back(static_cast<int>(i));
    }
  }
  Transform x;
  if (active.empty() || !first_guess(camera, poses, active, x))
    throw CalibrationError("calibration: no first guess (no tag's image corners give a pose)");

  // A pose whose corners leave the camera's field of view under the first guess cannot be
  // evaluated.
  for (auto it = active.begin(); it != active.end();) {
    if (!evaluate(camera, poses[static_cast<std::size_t>(*it)], x).ok) {
      res.poses[static_cast<std::size_t>(*it)].used = false;
      res.poses[static_cast<std::size_t>(*it)].reason =
          "its LiDAR corners project outside the camera's view under the first guess";
      it = active.erase(it);
    } else {
      ++it;
    }
  }
  if (active.empty()) throw CalibrationError("calibration: no usable pose");

  // Solve, reject the worst outlier pose, again.
  for (;;) {
    res.iterations += refine(camera, poses, active, opt, x);
    std::vector<double> chi2;
    for (int i : active)
      chi2.push_back(evaluate(camera, poses[static_cast<std::size_t>(i)], x).chi2);
    const double med = lower_median(chi2);
    const auto worst = std::max_element(chi2.begin(), chi2.end()) - chi2.begin();
    const double w = chi2[static_cast<std::size_t>(worst)];
    if (active.size() < 2 || w <= opt.reject_chi2 || w <= opt.reject_ratio * med) break;
    PoseReport& pr = res.poses[static_cast<std::size_t>(active[static_cast<std::size_t>(worst)])];
    pr.used = false;
    const PoseEval e = evaluate(
        camera, poses[static_cast<std::size_t>(active[static_cast<std::size_t>(worst)])], x);
    pr.reason = "outlier: reprojection RMS " +
                fmt(rms(std::span(e.raw.data(), 8)) * std::sqrt(2.0), 1) + " px, chi-square " +
                fmt(w, 0) + " over 8 (median pose " + fmt(med, 1) +
                "): a wrong ID, a tag that moved between image and capture, or a bad detection";
    active.erase(active.begin() + worst);
  }

  // The solution's errors, every pose (rejected ones too).
  res.camera_from_lidar = Eigen::Isometry3d::Identity();
  res.camera_from_lidar.linear() = x.r;
  res.camera_from_lidar.translation() = x.t;
  std::vector<double> all_px;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const PoseEval e = evaluate(camera, poses[i], x);
    PoseReport& pr = res.poses[i];
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : poses[i].lidar.corners) c += x.r * p + x.t;
    pr.range_m = c.norm() / 4;
    if (!e.ok) continue;
    for (int k = 0; k < 4; ++k)
      pr.corner_px[static_cast<std::size_t>(k)] = e.raw.segment<2>(2 * k).norm();
    pr.rms_px = rms(pr.corner_px);
    pr.chi2 = e.chi2;
    if (pr.used) {
      all_px.insert(all_px.end(), pr.corner_px.begin(), pr.corner_px.end());
      res.chi2 += e.chi2;
    }
  }
  res.used_poses = static_cast<int>(active.size());
  res.rms_px = rms(all_px);
  res.dof = 8 * res.used_poses - 6;

  // Covariance: the inverse of the information (Huber weights included).
  const Accum a = accumulate(camera, poses, active, x, opt.huber);
  res.covariance_scale = res.dof > 0 ? std::max(1.0, res.chi2 / res.dof) : 1.0;
  const Eigen::SelfAdjointEigenSolver<Mat6> raw_eig(a.h);
  if (raw_eig.eigenvalues()(0) > 0) {
    res.covariance = a.h.inverse() * res.covariance_scale;
  } else {
    res.covariance.setConstant(std::numeric_limits<double>::infinity());
  }
  for (int i = 0; i < 3; ++i) {
    res.rotation_sigma_deg(i) = std::sqrt(res.covariance(i, i)) * kDeg;
    res.translation_sigma_mm(i) = std::sqrt(res.covariance(3 + i, 3 + i)) * 1e3;
  }
  res.rotation_sigma_total_deg = std::sqrt(res.covariance.topLeftCorner<3, 3>().trace()) * kDeg;

  // Held out: each used pose predicted by the others.
  if (opt.held_out && active.size() >= 2) {
    std::vector<double> held;
    for (std::size_t j = 0; j < active.size(); ++j) {
      std::vector<int> others = active;
      others.erase(others.begin() + static_cast<std::ptrdiff_t>(j));
      Transform y = x;
      refine(camera, poses, others, opt, y);
      const PoseEval e = evaluate(camera, poses[static_cast<std::size_t>(active[j])], y);
      if (!e.ok) continue;
      std::array<double, 4> px;
      for (int k = 0; k < 4; ++k) px[static_cast<std::size_t>(k)] = e.raw.segment<2>(2 * k).norm();
      res.poses[static_cast<std::size_t>(active[j])].held_out_px = rms(px);
      held.push_back(rms(px));
    }
    if (!held.empty()) {
      res.held_out_median_px = median(held);
      res.held_out_max_px = *std::max_element(held.begin(), held.end());
    }
  }

  // Degeneracy: the information in (rad, translation / median range) units.
  std::vector<double> ranges;
  for (int i : active) ranges.push_back(res.poses[static_cast<std::size_t>(i)].range_m);
  res.median_range_m = median(ranges);
  Vec6 scale;
  scale << 1, 1, 1, res.median_range_m, res.median_range_m, res.median_range_m;
  const Mat6 hn = scale.asDiagonal() * a.h * scale.asDiagonal() / res.covariance_scale;
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(hn);
  res.information_eigenvalues = eig.eigenvalues();
  const double lmax = std::max(eig.eigenvalues()(5), 1e-300);
  for (int i = 0; i < 6; ++i) {
    const double l = eig.eigenvalues()(i);
    const double sigma_deg = l > 0 ? kDeg / std::sqrt(l) : std::numeric_limits<double>::infinity();
    if (sigma_deg > opt.weak_sigma_deg || l < opt.weak_ratio * lmax) {
      WeakDirection w;
      w.direction = eig.eigenvectors().col(i);
      w.name = direction_name(w.direction);
      w.sigma_deg = sigma_deg;
      res.weak.push_back(w);
    }
  }
  if (!res.weak.empty()) {
    res.suggestion = suggest(camera, poses, active, x, res.weak[0].direction);
    res.warnings.push_back("weakly constrained: " + res.weak[0].name + " (1 sigma " +
                           fmt(res.weak[0].sigma_deg, 3) + " deg equivalent at " +
                           fmt(res.median_range_m, 1) + " m); " + res.suggestion);
  }
  if (res.used_poses <= 2)
    res.warnings.push_back("only " + std::to_string(res.used_poses) +
                           " pose(s) used: 9 or more spread over distance and the image are "
                           "advised");
  const int rejected = static_cast<int>(poses.size()) - res.used_poses;
  if (rejected > 0)
    res.warnings.push_back(std::to_string(rejected) + " pose(s) rejected (see poses)");
  if (res.dof > 0 && res.chi2 / res.dof > 3)
    res.warnings.push_back("residuals " + fmt(std::sqrt(res.chi2 / res.dof), 1) +
                           " times larger than the corners' noise model: uncertainties scaled up");
  return res;
}

}  // namespace lidartag::calib
