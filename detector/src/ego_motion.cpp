// The sensor's poses in the odometry frame: a ring of stamped samples, twists integrated at their
// stamps, and interpolation between the two samples around a time.
#include "lidartag/detector/ego_motion.hpp"

#include <algorithm>
#include <cmath>

#include "geometry.hpp"

namespace lidartag::detector {

namespace {

void fail(const std::string& key, const std::string& value, const std::string& reason) {
  throw OptionsError(key, value, reason);
}

// A quaternion that is a rotation up to rounding (norm within 1 %), normalised; false otherwise.
bool unit(const Eigen::Quaterniond& q, Eigen::Quaterniond& out) {
  const double n = q.norm();
  if (!q.coeffs().allFinite() || std::abs(n - 1.0) > 0.01) return false;
  out = Eigen::Quaterniond(q.coeffs() / n);
  return true;
}

}  // namespace

void validate_ego_motion_options(const EgoMotionOptions& options) {
  EgoMotionOptions copy = options;
  rules::RuleChecker checker("ego_motion.", fail);
  visit_ego_motion_options(checker, copy);
}

const char* to_string(EgoSample s) {
  switch (s) {
    case EgoSample::kAccepted:
      return "accepted";
    case EgoSample::kOutOfOrder:
      return "out_of_order";
    case EgoSample::kInvalid:
      return "invalid";
  }
  return "unknown";
}

const char* to_string(EgoLookup l) {
  switch (l) {
    case EgoLookup::kOk:
      return "ok";
    case EgoLookup::kEmpty:
      return "empty";
    case EgoLookup::kBefore:
      return "before";
    case EgoLookup::kGap:
      return "gap";
    case EgoLookup::kStale:
      return "stale";
  }
  return "unknown";
}

EgoMotion::EgoMotion(EgoMotionOptions options) : opt_(options) {
  validate_ego_motion_options(opt_);
  ring_.resize(static_cast<size_t>(opt_.capacity));
}

const EgoMotion::Sample& EgoMotion::sample(size_t i) const {
  const size_t n = ring_.size();
  return ring_[(head_ + n - count_ + i) % n];
}

void EgoMotion::push(const Sample& s) {
  ring_[head_] = s;
  head_ = (head_ + 1) % ring_.size();
  count_ = std::min(count_ + 1, ring_.size());
  ++counters_.accepted;
}

int64_t EgoMotion::newest_ns() const noexcept {
  return count_ == 0 ? 0 : sample(count_ - 1).t_ns;
}

void EgoMotion::clear() noexcept {
  count_ = 0;
  head_ = 0;
}

EgoSample EgoMotion::add_pose(int64_t stamp_ns, const Eigen::Vector3d& position,
                              const Eigen::Quaterniond& orientation) noexcept {
  Sample s;
  if (!position.allFinite() || !unit(orientation, s.pose.orientation)) {
    ++counters_.invalid;
    return EgoSample::kInvalid;
  }
  if (count_ > 0 && stamp_ns <= newest_ns()) {
    ++counters_.out_of_order;
    return EgoSample::kOutOfOrder;
  }
  s.t_ns = stamp_ns;
  s.pose.position = position;
  s.pose.segment = 0;  // poses share the odometry's frame whatever the gaps
  push(s);
  return EgoSample::kAccepted;
}

EgoSample EgoMotion::add_twist(int64_t stamp_ns, const Eigen::Vector3d& linear_mps,
                               const Eigen::Vector3d& angular_rad_s) noexcept {
  if (!linear_mps.allFinite() || !angular_rad_s.allFinite()) {
    ++counters_.invalid;
    return EgoSample::kInvalid;
  }
  if (count_ > 0 && stamp_ns <= newest_ns()) {
    ++counters_.out_of_order;
    return EgoSample::kOutOfOrder;
  }
  Sample s;
  s.t_ns = stamp_ns;
  s.linear = linear_mps;
  s.angular = angular_rad_s;
  const double gap = count_ == 0 ? 0.0 : static_cast<double>(stamp_ns - newest_ns()) * 1e-9;
  if (count_ == 0 || gap > opt_.max_gap_s) {
    // A new odometry frame: the sensor's pose now is its origin.
    ++segment_;
    ++counters_.segments;
    s.pose.segment = segment_;
  } else {
    // The previous twist held over the interval, in the sensor's frame: a constant body twist
    // moves the pose by exp of (v, w) dt; its translation by the left Jacobian of SO(3).
    const Sample& prev = sample(count_ - 1);
    const Eigen::Vector3d phi = prev.angular * gap;
    const double th = phi.norm();
    const Eigen::Matrix3d k = geometry::hat(phi);
    Eigen::Matrix3d jl = Eigen::Matrix3d::Identity();
    if (th < 1e-6)
      jl += 0.5 * k;
    else
      jl += (1 - std::cos(th)) / (th * th) * k + (th - std::sin(th)) / (th * th * th) * k * k;
    const Eigen::Matrix3d r = prev.pose.orientation.toRotationMatrix();
    s.pose.position = prev.pose.position + r * (jl * (prev.linear * gap));
    s.pose.orientation = Eigen::Quaterniond(r * geometry::exp_so3(phi)).normalized();
    s.pose.segment = prev.pose.segment;
  }
  push(s);
  return EgoSample::kAccepted;
}

EgoLookup EgoMotion::at(int64_t t_ns, EgoPose& out) const noexcept {
  if (count_ == 0) return EgoLookup::kEmpty;
  const Sample& oldest = sample(0);
  const Sample& newest = sample(count_ - 1);
  if (t_ns < oldest.t_ns) return EgoLookup::kBefore;
  const Sample* a = nullptr;
  const Sample* b = nullptr;
  if (t_ns >= newest.t_ns) {
    const double past = static_cast<double>(t_ns - newest.t_ns) * 1e-9;
    if (past > opt_.max_extrapolation_s) return EgoLookup::kStale;
    if (past == 0.0 || count_ == 1) {
      out = newest.pose;
      return past == 0.0 ? EgoLookup::kOk : EgoLookup::kStale;
    }
    a = &sample(count_ - 2);
    b = &newest;
  } else {
    // The first sample after t_ns: binary search over the ring's order.
    size_t lo = 0, hi = count_ - 1;  // sample(lo) <= t < sample(hi)
    while (hi - lo > 1) {
      const size_t mid = (lo + hi) / 2;
      (sample(mid).t_ns <= t_ns ? lo : hi) = mid;
    }
    a = &sample(lo);
    b = &sample(hi);
  }
  const double span = static_cast<double>(b->t_ns - a->t_ns) * 1e-9;
  if (span > opt_.max_gap_s || a->pose.segment != b->pose.segment) return EgoLookup::kGap;
  // Linear in time (past b: extrapolated along the same line).
  const double u = static_cast<double>(t_ns - a->t_ns) * 1e-9 / span;
  out.segment = a->pose.segment;
  out.position = a->pose.position + u * (b->pose.position - a->pose.position);
  if (u <= 1.0) {
    out.orientation = a->pose.orientation.slerp(u, b->pose.orientation).normalized();
  } else {
    const Eigen::AngleAxisd step(a->pose.orientation.conjugate() * b->pose.orientation);
    out.orientation =
        (a->pose.orientation * Eigen::AngleAxisd(step.angle() * u, step.axis())).normalized();
  }
  return EgoLookup::kOk;
}

}  // namespace lidartag::detector
