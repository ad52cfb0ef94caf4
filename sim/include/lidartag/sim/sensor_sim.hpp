// The sensor: its trajectory and the firing of one column (one firing sequence of every laser),
// ray cast with the model's exact laser times, elevations, azimuth offsets and vertical offsets,
// so the decoder places each return where the surface is.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "lidartag/driver/velodyne/encoder.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/sim/beam_model.hpp"
#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/random.hpp"
#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

// Sensor pose: world <- sensor.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

// Constant linear velocity (world frame) and angular velocity (sensor frame) from the start pose.
class Trajectory {
 public:
  explicit Trajectory(const SensorOptions& options);
  // Pose `t_s` seconds after the first firing.
  Pose at(double t_s) const;

 private:
  Pose start_;
  Eigen::Vector3d velocity_;
  Eigen::Vector3d omega_rad_;  // rad/s, sensor frame
};

// Direction of a laser in the sensor frame (the decoder's convention): x = cos e cos a,
// y = -cos e sin a, z = sin e; azimuth in degrees clockwise from +x seen from above.
Eigen::Vector3d beam_direction(double elevation_deg, double azimuth_deg);
// Where the laser's range is measured from (the calibration's vertical offset v):
// point = origin + d * direction with origin = v * (-sin e cos a, sin e sin a, cos e).
Eigen::Vector3d beam_origin(double elevation_deg, double azimuth_deg, double vertical_offset_m);

// Which tag's printed marker each reported point came from: [echo slot][laser], -1 for none or
// for the repeated copy of a single echo in dual mode (so each distinct point counts once).
struct ColumnLabels {
  std::array<std::array<int8_t, 128>, 2> tag{};
};

class SensorModel {
 public:
  SensorModel(const SensorOptions& options, const World& world);

  const velodyne::ModelSpec& spec() const { return spec_; }
  // Rotation rate, degrees of azimuth per microsecond.
  double rate_deg_per_us() const { return rate_deg_per_us_; }
  const Trajectory& trajectory() const { return trajectory_; }
  const NoiseOptions& noise() const { return noise_; }

  // Fires the column whose first laser fires `t_us` after the first firing of the capture at
  // firing azimuth `azimuth_centideg` (the value the packet carries). Fills distances in the
  // model's units and reflectivities.
  void fire(double t_us, uint16_t azimuth_centideg, Rng& rng, velodyne::FiringColumn& column,
            ColumnLabels& labels) const;

 private:
  const SensorOptions& options_;
  const World& world_;
  const velodyne::ModelSpec& spec_;
  Trajectory trajectory_;
  NoiseOptions noise_;
  double rate_deg_per_us_;
  double min_range_m_, max_range_m_;
  std::array<std::array<double, 2>, 9> footprint_{};
  int footprint_count_ = 1;
};

}  // namespace lidartag::sim
