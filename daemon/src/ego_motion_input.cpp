#include "lidartag/daemon/ego_motion_input.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <numbers>

#include "lidartag/daemon/lcm_url.hpp"

namespace lidartag::daemon {

namespace {

constexpr double kLogPeriodS = 5.0;

int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

SensorMount sensor_mount(const BodyMount& c) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  SensorMount m;
  m.rotation = (Eigen::AngleAxisd(c.yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(c.pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(c.roll_deg * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  m.position = Eigen::Vector3d(c.x, c.y, c.z);
  return m;
}

std::vector<SensorMount> sensor_mounts(const DaemonOptions& options) {
  std::vector<SensorMount> out;
  for (const SensorOptions& s : options.sensors) out.push_back(sensor_mount(mount_of(options, s)));
  return out;
}

EgoMessage apply_ego_message(const lidartag::ego_motion_t& msg, const SensorMount& mount,
                             detector::EgoMotion& ego) noexcept {
  // Microseconds to nanoseconds, refusing what would overflow.
  constexpr int64_t kMaxUtime = INT64_MAX / 1000;
  if (msg.utime > kMaxUtime || msg.utime < -kMaxUtime) return EgoMessage::kInvalid;
  const int64_t t_ns = msg.utime * 1000;
  detector::EgoSample result = detector::EgoSample::kInvalid;
  if (msg.kind == lidartag::ego_motion_t::POSE) {
    const Eigen::Vector3d p(msg.position[0], msg.position[1], msg.position[2]);
    const Eigen::Quaterniond q(msg.orientation[0], msg.orientation[1], msg.orientation[2],
                               msg.orientation[3]);
    if (!p.allFinite() || !q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 0.01)
      return EgoMessage::kInvalid;
    // The sensor's pose: body pose * mount.
    const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
    result = ego.add_pose(t_ns, p + r * mount.position,
                          Eigen::Quaterniond(r * mount.rotation).normalized());
  } else if (msg.kind == lidartag::ego_motion_t::TWIST) {
    const Eigen::Vector3d v(msg.linear[0], msg.linear[1], msg.linear[2]);
    const Eigen::Vector3d w(msg.angular[0], msg.angular[1], msg.angular[2]);
    // A point of the rigid body at p moves at v + w x p; both into the sensor's frame.
    const Eigen::Matrix3d back = mount.rotation.transpose();
    result = ego.add_twist(t_ns, back * (v + w.cross(mount.position)), back * w);
  } else {
    return EgoMessage::kUnknownKind;
  }
  switch (result) {
    case detector::EgoSample::kAccepted:
      return EgoMessage::kAccepted;
    case detector::EgoSample::kOutOfOrder:
      return EgoMessage::kOutOfOrder;
    case detector::EgoSample::kInvalid:
      return EgoMessage::kInvalid;
  }
  return EgoMessage::kInvalid;
}

EgoMotionInput::EgoMotionInput(const EgoMotionConfig& config, const std::string& default_url,
                               std::vector<SensorMount> mounts)
    : config_(config), mounts_(std::move(mounts)) {
  if (mounts_.empty()) mounts_.push_back(sensor_mount(config.sensor_in_body));
  ego_.reserve(mounts_.size());
  for (size_t i = 0; i < mounts_.size(); ++i) ego_.emplace_back(config.buffer);
  const LcmUrl parsed = parse_lcm_url(config.url.empty() ? default_url : config.url);
  const std::string& url = parsed.text;
  // A file:// URL is the daemon's output log (lcm.url), not where a robot's odometry arrives.
  if (parsed.provider == "file")
    throw LcmError("ego_motion: cannot receive '" + config.channel + "' from '" + url +
                   "' (a log file): set ego_motion.url to the LCM URL the robot publishes on");
  check_multicast_route(parsed);
  lcm_ = std::make_unique<lcm::LCM>(url);
  if (!lcm_->good())
    throw LcmError("ego_motion: cannot open LCM with URL '" + url + "' to receive '" +
                   config.channel + "' (see LCM's message above)");
  if (lcm_subscribe(lcm_->getUnderlyingLCM(), config_.channel.c_str(), &EgoMotionInput::on_raw,
                    this) == nullptr)
    throw LcmError("ego_motion: cannot subscribe to '" + config_.channel + "' on '" + url + "'");
}

EgoMotionInput::~EgoMotionInput() {
  stop();
}

void EgoMotionInput::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] {
    while (running_.load(std::memory_order_relaxed)) poll(100);
  });
}

void EgoMotionInput::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

void EgoMotionInput::poll(int timeout_ms) {
  lcm_->handleTimeout(timeout_ms);
  log_problems();
}

void EgoMotionInput::on_raw(const lcm_recv_buf_t* buffer, const char*, void* self) {
  static_cast<EgoMotionInput*>(self)->on_message(buffer->data, buffer->data_size);
}

void EgoMotionInput::on_message(const void* data, uint32_t size) {
  lidartag::ego_motion_t msg;
  std::lock_guard lock(mutex_);
  ++counts_.received;
  if (size > static_cast<uint32_t>(INT32_MAX) || msg.decode(data, 0, static_cast<int>(size)) < 0) {
    ++counts_.undecodable;
    return;
  }
  // Every sensor's poses take the message through its own mount; the outcome depends on the
  // message only (its stamp, its values), so the first sensor's is the message's.
  EgoMessage result = EgoMessage::kInvalid;
  for (size_t i = 0; i < ego_.size(); ++i) {
    const EgoMessage r = apply_ego_message(msg, mounts_[i], ego_[i]);
    if (i == 0) result = r;
  }
  switch (result) {
    case EgoMessage::kAccepted: {
      ++counts_.accepted;
      const int64_t stamp_ns = msg.utime * 1000;
      if (last_stamp_ns_ != 0 &&
          static_cast<double>(stamp_ns - last_stamp_ns_) * 1e-9 > config_.buffer.max_gap_s)
        ++counts_.gaps;
      last_stamp_ns_ = stamp_ns;
      last_host_ns_ = steady_now_ns();
      (void)stale_at(last_host_ns_);  // no longer stale
      break;
    }
    case EgoMessage::kOutOfOrder:
      ++counts_.out_of_order;
      break;
    case EgoMessage::kInvalid:
      ++counts_.invalid;
      break;
    case EgoMessage::kUnknownKind:
      ++counts_.unknown_kind;
      break;
  }
}

EgoMotionCounts EgoMotionInput::counts() const {
  std::lock_guard lock(mutex_);
  (void)stale_at(steady_now_ns());
  return counts_;
}

bool EgoMotionInput::stale_at(int64_t now_ns) const {
  const bool stale =
      last_host_ns_ != 0 && static_cast<double>(now_ns - last_host_ns_) * 1e-9 > config_.stale_s;
  if (stale && !stale_now_) ++counts_.stale_episodes;
  stale_now_ = stale;
  return stale;
}

EgoMotionState EgoMotionInput::state() const {
  std::lock_guard lock(mutex_);
  const int64_t now = steady_now_ns();
  EgoMotionState s;
  s.stale = stale_at(now);
  s.counts = counts_;
  s.age_s = last_host_ns_ == 0 ? -1.0 : static_cast<double>(now - last_host_ns_) * 1e-9;
  return s;
}

std::string EgoMotionInput::health_note() const {
  std::lock_guard lock(mutex_);
  const EgoMotionCounts& c = counts_;
  const uint64_t bad = c.dropped();
  std::string note;
  if (last_host_ns_ == 0) {
    note = fmt::format("ego motion: nothing received on {} yet", config_.channel);
  } else {
    const int64_t now = steady_now_ns();
    const double quiet = static_cast<double>(now - last_host_ns_) * 1e-9;
    if (stale_at(now))
      note = fmt::format("ego motion: stale, nothing on {} for {:.1f} s", config_.channel, quiet);
  }
  if (bad > 0) {
    note += fmt::format(
        "{}ego motion: {} of {} messages dropped ({} out of order, {} invalid, {} "
        "of unknown kind, {} undecodable)",
        note.empty() ? "" : "; ", bad, c.received, c.out_of_order, c.invalid, c.unknown_kind,
        c.undecodable);
  }
  return note;
}

void EgoMotionInput::log_problems() {
  const int64_t now = steady_now_ns();
  EgoMotionCounts c;
  bool stale = false;
  {
    // Every poll: a stale episode is counted however short (the log lines are rate-limited).
    std::lock_guard lock(mutex_);
    stale = stale_at(now);
    c = counts_;
  }
  if (now < next_log_ns_) return;
  const uint64_t bad = c.dropped();
  bool logged = false;
  if (bad > logged_problems_) {
    spdlog::warn(
        "ego motion on {}: {} message{} dropped ({} in all: {} out of order, {} invalid, "
        "{} of unknown kind, {} undecodable)",
        config_.channel, bad - logged_problems_, bad - logged_problems_ == 1 ? "" : "s", bad,
        c.out_of_order, c.invalid, c.unknown_kind, c.undecodable);
    logged_problems_ = bad;
    logged = true;
  }
  if (stale != stale_logged_) {
    if (stale)
      spdlog::warn("ego motion on {}: stale (nothing for {} s): tracking without it",
                   config_.channel, config_.stale_s);
    else
      spdlog::info("ego motion on {}: receiving again", config_.channel);
    stale_logged_ = stale;
    logged = true;
  }
  if (logged) next_log_ns_ = now + static_cast<int64_t>(kLogPeriodS * 1e9);
}

}  // namespace lidartag::daemon
