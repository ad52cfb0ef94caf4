#include "lidartag/sim/sensor_sim.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace lidartag::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Matrix3d rpy(double roll_deg, double pitch_deg, double yaw_deg) {
  return (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
      .matrix();
}

}  // namespace

Trajectory::Trajectory(const SensorOptions& o) {
  start_.rotation = rpy(o.roll_deg, o.pitch_deg, o.yaw_deg);
  start_.position = Eigen::Vector3d(o.position[0], o.position[1], o.height);
  velocity_ = Eigen::Vector3d(o.velocity[0], o.velocity[1], o.velocity[2]);
  omega_rad_ =
      Eigen::Vector3d(o.angular_velocity[0], o.angular_velocity[1], o.angular_velocity[2]) * kDeg;
}

Pose Trajectory::at(double t_s) const {
  Pose p;
  p.position = start_.position + velocity_ * t_s;
  const double angle = omega_rad_.norm() * t_s;
  p.rotation = angle > 0.0
                   ? Eigen::Matrix3d(start_.rotation *
                                     Eigen::AngleAxisd(angle, omega_rad_.normalized()).matrix())
                   : start_.rotation;
  return p;
}

Eigen::Vector3d beam_direction(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * kDeg, a = azimuth_deg * kDeg;
  return {std::cos(e) * std::cos(a), -std::cos(e) * std::sin(a), std::sin(e)};
}

Eigen::Vector3d beam_origin(double elevation_deg, double azimuth_deg, double vertical_offset_m) {
  const double e = elevation_deg * kDeg, a = azimuth_deg * kDeg;
  return vertical_offset_m *
         Eigen::Vector3d(-std::sin(e) * std::cos(a), std::sin(e) * std::sin(a), std::cos(e));
}

SensorModel::SensorModel(const SensorOptions& options, const World& world)
    : options_(options),
      world_(world),
      spec_(velodyne::model_spec(options.model)),
      trajectory_(options),
      noise_(options.noise),
      rate_deg_per_us_(options.rpm * 360.0 / 60.0 / 1e6) {
  min_range_m_ = noise_.min_range_m > 0.0 ? noise_.min_range_m : spec_.min_range_m;
  max_range_m_ = noise_.max_range_m > 0.0 ? noise_.max_range_m : spec_.max_range_m;
  // Never beyond what the packet's 16-bit distance can carry.
  max_range_m_ = std::min(max_range_m_, 65535.0 * spec_.distance_unit_m);
  footprint_count_ = footprint_offsets(noise_, footprint_);
}

void SensorModel::fire(double t_us, uint16_t azimuth_centideg, Rng& rng,
                       velodyne::FiringColumn& column, ColumnLabels& labels) const {
  column.azimuth_centideg = azimuth_centideg;
  const double firing_azimuth = azimuth_centideg / 100.0;
  const bool dual = options_.return_mode == velodyne::ReturnMode::kDual;
  std::array<SubReturn, 9> subs{};
  for (int laser = 0; laser < spec_.lasers; ++laser) {
    const auto l = static_cast<size_t>(laser);
    const velodyne::LaserSpec& ls = spec_.laser_table[l];
    const double laser_time = spec_.laser_time_us(laser);
    // The decoder's azimuth: firing azimuth advanced to this laser's time, minus its offset.
    const double azimuth = firing_azimuth + rate_deg_per_us_ * laser_time - ls.azimuth_offset_deg;
    const Pose pose = trajectory_.at((t_us + laser_time) * 1e-6);
    const Eigen::Vector3d origin =
        pose.rotation * beam_origin(ls.elevation_deg, azimuth, ls.vertical_offset_m) +
        pose.position;
    for (size_t s = 0; s < static_cast<size_t>(footprint_count_); ++s) {
      // Footprint offsets are small angles added to azimuth (clockwise) and elevation.
      const Eigen::Vector3d dir =
          pose.rotation * beam_direction(ls.elevation_deg + footprint_[s][1] / kDeg,
                                         azimuth + footprint_[s][0] / kDeg);
      const Hit h = world_.cast({origin, dir}, max_range_m_ * 1.2);
      subs[s] = {h.hit(), h.t, h.reflectivity, h.tag};
    }
    const BeamEchoes echoes =
        form_echoes(std::span<const SubReturn>(subs.data(), static_cast<size_t>(footprint_count_)),
                    noise_, rng);
    std::array<Echo, 2> picked{};
    const int distinct = select_returns(echoes, options_.return_mode, picked);
    for (size_t slot = 0; slot < 2; ++slot) {
      column.echo[slot].distance[l] = 0;
      column.echo[slot].intensity[l] = 0;
      labels.tag[slot][l] = -1;
    }
    const int slots = dual ? 2 : 1;
    for (int k = 0; k < std::min(distinct, slots); ++k) {
      const auto slot = static_cast<size_t>(k);
      const Echo e = add_noise(picked[slot], noise_, rng);
      if (e.range < min_range_m_ || e.range > max_range_m_) continue;
      const long counts = std::lround(e.range / spec_.distance_unit_m);
      column.echo[slot].distance[l] = static_cast<uint16_t>(std::clamp(counts, 1L, 65535L));
      column.echo[slot].intensity[l] = static_cast<uint8_t>(std::lround(e.reflectivity));
      labels.tag[slot][l] = static_cast<int8_t>(e.tag);
    }
    // A single echo in dual mode is sent twice (both blocks identical), as the sensor does.
    if (dual && distinct == 1) {
      column.echo[1].distance[l] = column.echo[0].distance[l];
      column.echo[1].intensity[l] = column.echo[0].intensity[l];
    }
  }
}

}  // namespace lidartag::sim
