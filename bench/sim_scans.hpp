// Simulated rotations in memory, and detections scored against the simulator's truth: what
// bench_accuracy, bench_tracker, the detector's end-to-end tests and `lidartag plan` share. The
// simulator's packets go straight through the project's own Decoder and ScanBatcher (no pcap
// file), one rotation at a time: Velodyne's, or for an Ouster sensor Ouster's decoder, the
// frame-id batcher and destaggering.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <numbers>
#include <span>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/ouster/decoder.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/calibration.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/driver/velodyne/packet.hpp"
#include "lidartag/driver/velodyne/sensor_clock.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/sim/ouster_sim.hpp"
#include "lidartag/sim/sensor_sim.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::eval {

// Runs a simulator and hands every complete rotation to a callback while the simulation runs
// (memory stays at a few scans whatever the number of rotations).
class SimScans final {
 public:
  using OnScan = std::function<void(const Scan& scan, size_t index)>;

  explicit SimScans(const sim::Simulator& simulator) : sim_(simulator) {
    const auto& sensor = sim_.scene().sensor;
    if (!sensor.ouster) calibration_ = velodyne::Calibration::builtin(sensor.model);
  }

  // Simulates `rotations` rotations with noise seed `seed`; `on_scan` gets the k-th complete
  // rotation as index k (the truth's rotation k once run() returns it).
  sim::Truth run(int rotations, uint64_t seed, const OnScan& on_scan) {
    const auto& sensor = sim_.scene().sensor;
    if (sensor.ouster) return run_ouster(rotations, seed, on_scan);
    const auto& spec = velodyne::model_spec(sensor.model);
    velodyne::Decoder decoder(calibration_);
    velodyne::SensorClock clock;
    driver::BatcherOptions bo;
    bo.cut_azimuth_deg = sensor.cut_azimuth_deg;
    driver::ScanBatcher batcher = velodyne::make_batcher(spec, sensor.return_mode, bo);
    on_scan_ = &on_scan;
    index_ = 0;
    sim::Truth truth =
        sim_.run(rotations, seed, [&](std::span<const uint8_t> payload, int64_t t, uint16_t port) {
          if (port != velodyne::kDefaultDataPort) return;
          if (decoder.decode(payload, clock, t, packet_) == velodyne::DecodeStatus::kOk &&
              batcher.add(packet_, scans_[next_])) {
            deliver();
          }
        });
    while (batcher.flush(scans_[next_])) deliver();
    on_scan_ = nullptr;
    return truth;
  }

 private:
  // An Ouster sensor: its frames, destaggered (a column's cells point the same way).
  sim::Truth run_ouster(int rotations, uint64_t seed, const OnScan& on_scan) {
    namespace ouster = driver::ouster;
    const ouster::SensorInfo info = sim::ouster_sensor_info(sim_.scene().sensor);
    ouster::Decoder decoder(info);
    driver::ScanBatcher batcher(
        ouster::sensor_layout(info),
        static_cast<uint8_t>(ouster::kReturnModeBase + static_cast<uint8_t>(info.profile)),
        info.returns(), driver::BatcherOptions{});
    if (!ouster_packet_) ouster_packet_ = std::make_unique<ouster::PacketColumns>();
    on_scan_ = &on_scan;
    index_ = 0;
    sim::Truth truth =
        sim_.run(rotations, seed, [&](std::span<const uint8_t> payload, int64_t, uint16_t port) {
          if (port != ouster::kLidarPort) return;
          if (decoder.parse(payload, *ouster_packet_) == ouster::DecodeStatus::kOk &&
              batcher.add(*ouster_packet_, scans_[next_])) {
            deliver(&decoder);
          }
        });
    while (batcher.flush(scans_[next_])) deliver(&decoder);
    on_scan_ = nullptr;
    return truth;
  }

  // The rotation just finished goes to the callback; the other scan takes the next one.
  void deliver(const driver::ouster::Decoder* ouster = nullptr) {
    Scan& scan = scans_[next_];
    if (ouster != nullptr && scan.complete) (void)ouster->destagger(scan);
    next_ = 1 - next_;
    if (scan.complete && on_scan_ != nullptr) (*on_scan_)(scan, index_++);
  }

  const sim::Simulator& sim_;
  velodyne::Calibration calibration_;
  velodyne::DecodedPacket packet_;
  std::unique_ptr<driver::ouster::PacketColumns> ouster_packet_;
  std::array<Scan, 2> scans_;  // sized by the batcher on first use
  size_t next_ = 0;
  const OnScan* on_scan_ = nullptr;
  size_t index_ = 0;
};

// A truth orientation (w, x, y, z) as a quaternion.
inline Eigen::Quaterniond truth_quaternion(const Eigen::Vector4d& wxyz) {
  return Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized();
}

// Geodesic distance between two rotations, eq. (23), degrees.
inline double rotation_error_deg(const Eigen::Quaterniond& estimate,
                                 const Eigen::Vector4d& truth_wxyz) {
  const double d = std::min(1.0, std::abs(estimate.normalized().dot(truth_quaternion(truth_wxyz))));
  return 2.0 * std::acos(d) * 180.0 / std::numbers::pi;
}

// Angle between the tags' normals (their x axes), degrees: the plane's error alone, whatever the
// quarter turns about the normal (a wrong code's may be any).
inline double normal_error_deg(const Eigen::Quaterniond& estimate,
                               const Eigen::Vector4d& truth_wxyz) {
  const double c = (estimate.normalized() * Eigen::Vector3d::UnitX())
                       .dot(truth_quaternion(truth_wxyz) * Eigen::Vector3d::UnitX());
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

// Where a truth tag (of the rotation `rotation`, given at its first firing) is in the sensor's
// frame `after_s` seconds later: a moving sensor moves it meanwhile (30 deg/s turns a tag at 7 m
// by 0.37 m in one rotation). Its centre; the orientation turns with it.
inline sim::TagTruth tag_at_time(const sim::SensorOptions& sensor,
                                 const sim::RotationTruth& rotation, const sim::TagTruth& tag,
                                 double after_s) {
  const Eigen::Quaterniond s = truth_quaternion(rotation.sensor_orientation);
  const sim::Trajectory trajectory(sensor);
  const double t_s =
      static_cast<double>(rotation.stamp_ns - static_cast<int64_t>(sensor.start_time_s * 1e9)) *
          1e-9 +
      after_s;
  const sim::Pose then = trajectory.at(t_s);
  const Eigen::Matrix3d to_sensor = then.rotation.transpose() * s.toRotationMatrix();
  const Eigen::Vector3d shift =
      then.rotation.transpose() * (rotation.sensor_position - then.position);
  sim::TagTruth out = tag;
  out.position = to_sensor * tag.position + shift;
  for (size_t k = 0; k < 4; ++k) out.corners[k] = to_sensor * tag.corners[k] + shift;
  const Eigen::Quaterniond o(to_sensor * truth_quaternion(tag.orientation).toRotationMatrix());
  out.orientation = {o.w(), o.x(), o.y(), o.z()};
  return out;
}

// One truth tag of one rotation against the detections of that rotation.
struct TagScore {
  bool detected = false;  // a detection of the right family and id at the tag
  bool wrong_id = false;  // a detection at the tag with another family or id
  double translation_m = 0.0;
  double rotation_deg = 0.0;
  double corner_m = 0.0;  // largest corner distance
};

// A detection belongs to a tag when its centre is within half the tag's size of the truth.
inline bool at_tag(const detector::Detection& d, const sim::TagTruth& tag) {
  return (d.position - tag.position).norm() < tag.size / 2;
}

inline TagScore score_tag(std::span<const detector::Detection> detections,
                          const sim::TagTruth& tag) {
  TagScore s;
  for (const auto& d : detections) {
    if (!at_tag(d, tag)) continue;
    if (d.family != tag.family || d.id != tag.id) {
      s.wrong_id = true;
      continue;
    }
    s.detected = true;
    s.translation_m = (d.position - tag.position).norm();
    s.rotation_deg = rotation_error_deg(d.orientation, tag.orientation);
    for (size_t k = 0; k < 4; ++k)
      s.corner_m = std::max(s.corner_m, (d.corners[k] - tag.corners[k]).norm());
  }
  return s;
}

// Detections that belong to no tag of the rotation.
inline int false_positives(std::span<const detector::Detection> detections,
                           const sim::RotationTruth& truth) {
  int n = 0;
  for (const auto& d : detections)
    n += std::none_of(truth.tags.begin(), truth.tags.end(),
                      [&](const sim::TagTruth& t) { return at_tag(d, t); })
             ? 1
             : 0;
  return n;
}

// Metres between the two beams whose elevations enclose the direction of a point `above` metres
// above the sensor's height at `distance` (2 degrees on a VLP-16, 0.33 near the horizon on a
// VLP-32C), measured at that distance.
// The same for any beam table (elevations in degrees, any order).
inline double beam_spacing_m(std::vector<double> el, double distance, double above) {
  std::sort(el.begin(), el.end());
  const double e = std::atan2(above, distance) * 180.0 / std::numbers::pi;
  auto hi = std::upper_bound(el.begin(), el.end(), e);
  if (hi == el.begin()) ++hi;
  if (hi == el.end()) --hi;
  const double deg = std::numbers::pi / 180.0;
  return distance * (std::tan(*hi * deg) - std::tan(*(hi - 1) * deg));
}

inline double beam_spacing_m(velodyne::Model model, double distance, double above) {
  return beam_spacing_m(velodyne::beam_elevations_deg(model), distance, above);
}

// bench_tracker's run `run` of a static cell at `distance` metres turned `angle_deg`: the tag's
// code (each of 30 once in 30 runs), the share of the beam spacing its centre is raised by
// (((11 run) mod 30 + 0.5) / 30 - 0.5: each of 30 offsets once in 30 runs, in another order than
// the codes) and the simulator's noise seed. One definition, so that a test replays a run.
inline int run_code(int run, double distance, int angle_deg) {
  return (7 * run + 3 * static_cast<int>(distance) + angle_deg) % 30;
}
inline double run_height_share(int run) {
  return ((11 * run) % 30 + 0.5) / 30.0 - 0.5;
}
inline uint64_t run_seed(int run, int angle_deg) {
  return static_cast<uint64_t>(5000 + 100 * run + angle_deg);
}

// The accuracy scene of the paper's Table I: a tag16h5 of `size` metres (1.2 by default) on an
// easel stand, centre `above` metres above the sensor's height (1 m), diamond mount, at `distance`
// metres straight ahead, turned `angle_deg` about the vertical.
inline sim::Scene accuracy_scene(velodyne::Model model, double distance, int angle_deg, int id,
                                 double size = 1.2, double above = 0.0) {
  sim::Scene s;
  s.sensor.model = model;
  s.sensor.rpm = 600;
  s.sensor.height = 1.0;
  s.sensor.noise = sim::noise_defaults(model);
  sim::TagOptions t;
  t.family = "tag16h5";
  t.id = id;
  t.size = size;
  t.center = {distance, 0.0, 1.0 + above};
  // The printed face looks at the sensor, turned about the vertical by angle_deg.
  const double a = angle_deg * std::numbers::pi / 180.0;
  t.normal = {-std::cos(a), std::sin(a), 0.0};
  t.rotation_deg = 45.0;
  t.stand.enabled = true;
  t.stand.width = 0.05;
  s.tags.push_back(t);
  return s;
}

// Tagless clutter from a moving sensor: trees, poles, people, cars, walls and blank boards of tag
// sizes (planar squares are what a tag detector must not mistake for tags).
inline sim::Scene clutter_scene(int k) {
  sim::Scene s;
  s.sensor.model = velodyne::Model::kVLP32C;
  s.sensor.noise = sim::noise_defaults(s.sensor.model);
  s.sensor.velocity = {0.5, 0.0, 0.0};
  s.sensor.angular_velocity = {0.0, 0.0, 5.0};
  const sim::ClutterKind kinds[] = {sim::ClutterKind::kOutdoor, sim::ClutterKind::kLab,
                                    sim::ClutterKind::kParking};
  s.world.clutter.enabled = true;
  s.world.clutter.kind = kinds[k % 3];
  s.world.clutter.seed = static_cast<uint64_t>(100 + k);
  s.world.clutter.count = 40;
  s.world.clutter.region = {-18.0, 18.0, -15.0, 15.0};
  s.world.clutter.clearance = 1.0;
  s.world.walls.push_back({{-20.0, 16.0}, {22.0, 16.0}, 4.0, 0.15, 45.0});
  s.world.walls.push_back({{22.0, -16.0}, {22.0, 16.0}, 4.0, 0.15, 35.0});
  const double sizes[] = {0.6, 0.8, 1.2};
  for (int b = 0; b < 6; ++b) {
    const double angle = (60.0 * b + 17.0 * k) * std::numbers::pi / 180.0;
    const double r = 4.0 + 2.5 * b;
    const double size = sizes[(b + k) % 3];
    sim::BoxOptions box;
    box.center = {r * std::cos(angle), r * std::sin(angle), 1.0};
    box.size = {0.02, size, size};
    box.yaw_deg = 30.0 * b + 11.0 * k;
    box.reflectivity = 20.0 + 12.0 * ((b + k) % 6);
    s.world.boxes.push_back(box);
  }
  return s;
}

}  // namespace lidartag::eval
