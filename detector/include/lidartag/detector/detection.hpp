// The last step (paper Sec. V remark and Sec. VI): the tag's pose from the fitted pull-back and
// the decoded quarter turns, and the detection that reports it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>

#include "lidartag/detector/pose_fit.hpp"
#include "lidartag/detector/result.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

// The fitted tag frame before decoding, sensor frame: H_L^T is the inverse of eq. (9)'s
// pull-back H_T^L, its centre moved by `shift` along `unseen_axis` (a unit axis in the sensor
// frame, or zero: see TagOutline::unseen_axis).
struct TagFrame {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d undecoded = Eigen::Matrix3d::Identity();  // tag frame -> sensor frame
};
TagFrame tag_frame(const RigidPose& pull_back, const Eigen::Vector3d& unseen_axis, double shift);

// Eq. (9) is blind to quarter turns about the normal (Sec. V remark); decoding fixes them: the
// marker image turned q times clockwise is what the points show, so the tag frame is the fitted
// one turned by -q quarter turns about its normal (x).
Eigen::Matrix3d decoded_rotation(const Eigen::Matrix3d& undecoded, int quarter_turns);

// A rotation as a unit quaternion with w >= 0.
Eigen::Quaterniond unit_quaternion(const Eigen::Matrix3d& r);

// When the beams crossed a cluster (Detection::time_first_s, ...): the firing times of its points
// in `scan` (seconds from the rotation's start), the earliest, the latest, and that of the point
// nearest `center`. Zeros for no points.
struct FiringTimes {
  double first_s = 0.0, center_s = 0.0, last_s = 0.0;
};
FiringTimes firing_times(std::span<const ClusterPoint> points, const Scan& scan,
                         const Eigen::Vector3d& center);

// The detection of a decoded cluster: pose, the black square's corners, ID, score and margin.
Detection assemble_detection(const TagFrame& frame, const DecodeResult& decoded, int family_index,
                             const tags::TagFamily& family, double t, int points, double fit_cost);

}  // namespace lidartag::detector
