// The camera-from-LiDAR extrinsic from tag poses seen by both sensors (issue 30 item 3).
//
// 1. A first guess: each pose's tag in the camera frame from its image corners (the homography
//    of the square's plane to the undistorted image, decomposed: Zhang's planar pose), then one
//    rigid alignment (Kabsch) of every pose's LiDAR corners to those camera-frame corners, poses
//    far off the rest dropped from it.
// 2. Levenberg-Marquardt over the 6 degrees of freedom (a rotation vector applied on the camera
//    side, and the translation) minimising each pose's reprojection residual (8 pixels) whitened
//    by its covariance: the LiDAR corners' joint covariance pushed through the projection's
//    Jacobian plus the pixel noise. Huber loss per pose on the whitened norm.
// 3. Whole poses whose residual is an outlier (chi-square over 8 degrees of freedom beyond
//    reject_chi2 and beyond reject_ratio times the median pose's) are rejected with the reason,
//    worst first, one at a time, re-solving after each.
// 4. The covariance is the inverse of the whitened information matrix (scaled up by the reduced
//    chi-square when the residuals are larger than their model says, never down); held-out
//    error by leaving each pose out; degeneracy from the eigen-decomposition of the information
//    matrix with translation in units of the tags' median range.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/correspondence.hpp"

namespace lidartag::calib {

// Not enough usable poses to solve (none paired, or all rejected).
class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct SolverOptions {
  // Huber threshold on a pose's whitened residual norm (sqrt of its chi-square over 8 degrees of
  // freedom). Default 4.5 (the 99 % point of chi-square with 8 dof is 20.1 = 4.48^2).
  double huber = 4.5;
  // A pose is rejected when its chi-square exceeds reject_chi2 AND reject_ratio times the median
  // pose's (the second guards against a noise model that is too optimistic for every pose).
  // Defaults 40 (chi-square 8 dof: p = 2e-6) and 10.
  double reject_chi2 = 40.0;
  double reject_ratio = 10.0;
  // Levenberg-Marquardt: at most this many iterations; stops when a step moves less than
  // 1e-10 rad / 1e-10 m.
  int max_iterations = 100;
  // Leave-one-pose-out held-out errors (one solve per pose). Default true.
  bool held_out = true;
  // Degeneracy: a direction of the normalised information matrix (rotation in rad, translation
  // in units of the tags' median range) is weak when its 1-sigma exceeds weak_sigma_deg
  // (degrees, or the translation that moves a tag at that range as much) or its eigenvalue is
  // below weak_ratio times the largest. Defaults 0.05 degrees (half the rotation target; 4 mm at
  // 5 m) and 1e-4.
  double weak_sigma_deg = 0.05;
  double weak_ratio = 1e-4;
};

// A pose's errors under the solution.
struct PoseReport {
  std::string label;
  bool used = true;
  std::string reason;                 // why it was rejected (empty when used)
  std::array<double, 4> corner_px{};  // reprojection error per corner (calibration order), px
  double rms_px = 0.0;
  double chi2 = 0.0;          // whitened, 8 degrees of freedom
  double held_out_px = -1.0;  // RMS over its corners when solved without it; -1 not computed
  double range_m = 0.0;       // tag centre's distance from the camera
};

// A weak direction of the information matrix.
struct WeakDirection {
  std::string name;        // "translation along camera z", "rotation about camera y + ..."
  double sigma_deg = 0.0;  // its 1-sigma, degrees (translation: the angle at the median range)
  Eigen::Matrix<double, 6, 1> direction = Eigen::Matrix<double, 6, 1>::Zero();  // rot, trans
};

struct CalibrationResult {
  // Maps a point of the LiDAR frame into the camera's optical frame (x right, y down, z forward).
  Eigen::Isometry3d camera_from_lidar = Eigen::Isometry3d::Identity();
  // Covariance of (rotation vector perturbation on the camera side, rad; translation, m),
  // camera frame: T = exp(d) T_hat.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Vector3d rotation_sigma_deg = Eigen::Vector3d::Zero();    // about camera x, y, z
  double rotation_sigma_total_deg = 0.0;                           // sqrt of the block's trace
  Eigen::Vector3d translation_sigma_mm = Eigen::Vector3d::Zero();  // along camera x, y, z
  double chi2 = 0.0;
  int dof = 0;                     // 8 x poses - 6
  double covariance_scale = 1.0;   // max(1, chi2 / dof): applied to `covariance`
  double rms_px = 0.0;             // over every corner of the used poses
  double held_out_median_px = -1;  // over the used poses' held_out_px (-1: fewer than 2 poses)
  double held_out_max_px = -1;
  std::vector<PoseReport> poses;  // one per input pose, in input order
  int used_poses = 0;
  int iterations = 0;
  // Degeneracy.
  Eigen::Matrix<double, 6, 1> information_eigenvalues = Eigen::Matrix<double, 6, 1>::Zero();
  double median_range_m = 0.0;
  std::vector<WeakDirection> weak;
  std::string suggestion;             // the pose to add next, when something is weak
  std::vector<std::string> warnings;  // few poses, weak directions, rejections
};

// Solves the extrinsic. Throws CalibrationError when no pose is usable (none given, or every
// pose rejected, or no first guess); warns (CalibrationResult::warnings) for 1-2 poses.
CalibrationResult solve_extrinsic(const CameraModel& camera, std::span<const TagPose> poses,
                                  const SolverOptions& options = {});

// The tag's pose in the camera frame from its image corners alone (the first guess of step 1):
// its 4 corners, camera frame, calibration order; `half_side` the black square's half side, m.
// False when the corners do not give one (degenerate, behind the camera).
bool planar_square_pose(const CameraModel& camera, const std::array<Eigen::Vector2d, 4>& pixels,
                        double half_side, std::array<Eigen::Vector3d, 4>& corners_camera);

// The rigid transform that best maps `from` onto `to` (least squares, Kabsch); false when the
// points do not fix it (fewer than 3 or collinear).
bool rigid_align(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to,
                 Eigen::Isometry3d& out);

}  // namespace lidartag::calib
