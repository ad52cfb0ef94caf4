#include "lidartag/sim/ouster_sim.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "lidartag/driver/ouster/encoder.hpp"
#include "lidartag/sim/beam_model.hpp"
#include "lidartag/sim/random.hpp"
#include "lidartag/sim/sensor_sim.hpp"
#include "lidartag/sim/simulator.hpp"
#include "truth_poses.hpp"

namespace lidartag::sim {
namespace {

namespace ouster = driver::ouster;
constexpr double kDeg = std::numbers::pi / 180.0;
// Signal photons of an echo: kSignalScale x apparent reflectivity / range^2 (metres), clamped to
// 16 bits: representative magnitudes (a white target at 5 m gives a few thousand), not a model
// of a sensor's gain.
constexpr double kSignalScale = 1000.0;
constexpr int kLeadPackets = 2;  // packets before the first and after the last frame

// One beam's fixed geometry in the lidar frame.
struct Beam {
  double altitude_rad;
  double azimuth_rad;  // theta_a of the formula: minus the metadata's clockwise offset
};

// What an Ouster sensor reports of a beam's echoes: the strongest (out[0]); in a dual profile
// also the second strongest (out[1]), when there is one (Ouster's dual returns: RANGE the
// strongest echo, RANGE2 the second strongest, 0 when there is none). Returns how many.
int ouster_returns(const BeamEchoes& echoes, bool dual, std::array<Echo, 2>& out) {
  if (echoes.count == 0) return 0;
  const auto count = static_cast<size_t>(echoes.count);
  size_t first = 0;
  for (size_t i = 1; i < count; ++i)
    if (echoes.echo[i].strength() > echoes.echo[first].strength()) first = i;
  out[0] = echoes.echo[first];
  if (!dual || count == 1) return 1;
  size_t second = first == 0 ? 1 : 0;
  for (size_t i = 0; i < count; ++i)
    if (i != first && echoes.echo[i].strength() > echoes.echo[second].strength()) second = i;
  out[1] = echoes.echo[second];
  return 2;
}

}  // namespace

ouster::SensorInfo ouster_sensor_info(const SensorOptions& sensor) {
  const OusterSensorOptions& o = *sensor.ouster;
  ouster::SensorInfo info = ouster::nominal_sensor_info(o.model, o.columns, o.rate_hz, o.profile);
  info.serial_number = kOusterSimSerial;
  info.init_id = kOusterSimInitId;
  return info;
}

Truth run_ouster(const Scene& scene, const World& world, const std::vector<TagTarget>& tags,
                 int rotations, uint64_t seed, const PacketCallback& emit, RunStats* stats) {
  const SensorOptions& so = scene.sensor;
  const OusterSensorOptions& o = *so.ouster;
  const ouster::ModelSpec& model = ouster::model_spec(o.model);
  const ouster::SensorInfo info = ouster_sensor_info(so);
  const ouster::PacketFormat format = ouster::PacketFormat::of(info);
  const bool dual = info.returns() == 2;
  const NoiseOptions& noise = so.noise;
  const Trajectory trajectory(so);

  const int w = info.columns_per_frame;
  const int per_packet = info.columns_per_packet;
  const double period_ns = 1e9 / (double(o.rate_hz) * w);
  const int64_t start_ns = std::llround(so.start_time_s * 1e9);
  const double min_range = noise.min_range_m > 0.0 ? noise.min_range_m : model.min_range_m;
  // Never beyond what the profile's range field carries.
  const ouster::FieldSpec& range_field = *ouster::find_field(*format.spec, ouster::Field::kRange);
  const double field_max_m = double(((1ull << range_field.bits) - 1) << range_field.upshift) * 1e-3;
  const double max_range =
      std::min(noise.max_range_m > 0.0 ? noise.max_range_m : model.max_range_m, field_max_m - 1.0);
  std::array<std::array<double, 2>, 9> footprint{};
  const int footprint_count = footprint_offsets(noise, footprint);

  const auto beams = static_cast<size_t>(info.pixels_per_column);
  std::vector<Beam> beam(beams);
  for (size_t b = 0; b < beams; ++b)
    beam[b] = {info.beam_altitude_deg[b] * kDeg, -info.beam_azimuth_deg[b] * kDeg};
  const double n_m = info.lidar_origin_to_beam_origin_mm * 1e-3;
  const auto& t = info.lidar_to_sensor_transform;
  Eigen::Matrix3d lidar_rot;
  lidar_rot << t[0], t[1], t[2], t[4], t[5], t[6], t[8], t[9], t[10];
  const Eigen::Vector3d lidar_pos(t[3] * 1e-3, t[7] * 1e-3, t[11] * 1e-3);

  Truth truth;
  truth.model = std::string(model.name);
  truth.return_mode = std::string(ouster::profile_name(o.profile));
  truth.rpm = 60.0 * o.rate_hz;
  truth.seed = seed;
  truth.rotations.resize(static_cast<size_t>(std::max(rotations, 0)));
  for (size_t i = 0; i < truth.rotations.size(); ++i) {
    RotationTruth& rt = truth.rotations[i];
    rt.index = static_cast<int>(i);
    rt.tags.resize(tags.size());
  }

  Rng rng(seed);
  std::vector<ouster::ColumnPixels> packet_columns(static_cast<size_t>(per_packet));
  std::vector<uint8_t> buffer(format.packet_bytes);
  std::array<SubReturn, 9> subs{};
  RunStats st;
  uint64_t packets = 0;
  // Global column k: frame k / w (frame 0 the lead-in's), measurement id k % w.
  const int64_t lead = int64_t(kLeadPackets) * per_packet;
  const int64_t first = int64_t(w) - lead;
  const int64_t end = int64_t(w) * (rotations + 1) + lead;
  for (int64_t k = first; k < end; ++k) {
    const int64_t frame = k / w;
    const auto m = static_cast<int>(k % w);
    const int64_t t_ns = start_ns + std::llround(double(k - first) * period_ns);
    const int rot = static_cast<int>(frame) - 1;
    RotationTruth* rt =
        rot >= 0 && rot < rotations ? &truth.rotations[static_cast<size_t>(rot)] : nullptr;
    if (rt != nullptr && m == 0) rt->stamp_ns = t_ns;

    ouster::ColumnPixels& col = packet_columns[static_cast<size_t>(k % per_packet)];
    col = ouster::ColumnPixels{};
    col.timestamp_ns = static_cast<uint64_t>(t_ns);
    col.measurement_id = static_cast<uint16_t>(m);
    const Pose pose = trajectory.at(double(t_ns - start_ns) * 1e-9);
    const Eigen::Matrix3d to_world = pose.rotation * lidar_rot;
    const Eigen::Vector3d lidar_origin = pose.rotation * lidar_pos + pose.position;
    // The encoder angle, counter-clockwise in the lidar frame.
    const double theta_e = 2.0 * std::numbers::pi * (1.0 - double(m) / double(w));
    const Eigen::Vector3d origin =
        to_world * Eigen::Vector3d(n_m * std::cos(theta_e), n_m * std::sin(theta_e), 0.0) +
        lidar_origin;
    for (size_t b = 0; b < beams; ++b) {
      for (size_t s = 0; s < static_cast<size_t>(footprint_count); ++s) {
        // Footprint offsets: small angles clockwise (horizontal) and up.
        const double az = theta_e + beam[b].azimuth_rad - footprint[s][0];
        const double alt = beam[b].altitude_rad + footprint[s][1];
        const Eigen::Vector3d dir =
            to_world * Eigen::Vector3d(std::cos(az) * std::cos(alt), std::sin(az) * std::cos(alt),
                                       std::sin(alt));
        const Hit h = world.cast({origin, dir}, max_range * 1.2);
        subs[s] = {h.hit(), h.t, h.reflectivity, h.tag};
      }
      const BeamEchoes echoes =
          form_echoes(std::span<const SubReturn>(subs.data(), static_cast<size_t>(footprint_count)),
                      noise, rng);
      std::array<Echo, 2> picked{};
      const int count = ouster_returns(echoes, dual, picked);
      for (size_t r = 0; r < static_cast<size_t>(count); ++r) {
        const Echo e = add_noise(picked[r], noise, rng);
        // Out of range: no return (and no second return without a first).
        if (e.range < min_range || e.range > max_range) break;
        // The formula's point is beam origin + (r - n) direction: r = n + the distance along the
        // ray.
        const auto range_mm =
            static_cast<uint32_t>(std::max(1L, std::lround((e.range + n_m) * 1e3)));
        const auto reflectivity =
            static_cast<uint8_t>(std::clamp(std::lround(e.reflectivity), 0L, 255L));
        // SIGNAL of the echo before the noise: the returns' order (the strongest first) holds.
        const Echo& x = picked[r];
        const auto signal = static_cast<uint16_t>(std::clamp(
            std::lround(kSignalScale * x.reflectivity / std::max(x.range * x.range, 0.01)), 0L,
            65535L));
        if (r == 0) {
          col.range_mm[b] = range_mm;
          col.reflectivity[b] = reflectivity;
          col.signal[b] = signal;
        } else {
          col.range2_mm[b] = range_mm;
          col.reflectivity2[b] = reflectivity;
          col.signal2[b] = signal;
        }
        ++st.points;
        // The truth counts the tag's returns of the first (strongest) echo.
        if (r == 0 && rt != nullptr && e.tag >= 0) ++rt->tags[static_cast<size_t>(e.tag)].returns;
      }
    }
    ++st.columns;
    if ((k + 1) % per_packet != 0) continue;
    ouster::PacketHeader header;
    header.packet_type = ouster::kLidarPacketType;
    header.frame_id =
        static_cast<uint32_t>(frame & (format.frame_id_bits == 32 ? 0xffffffff : 0xffff));
    header.init_id = info.init_id;
    header.serial_number = info.serial_number;
    if (!ouster::encode_lidar_packet(format, header, w, packet_columns, buffer)) continue;
    emit(buffer, t_ns + std::llround(period_ns), ouster::kLidarPort);
    ++packets;
  }
  fill_truth_poses(truth, trajectory, tags, start_ns);
  st.data_packets = packets;
  if (stats) *stats = st;
  return truth;
}

}  // namespace lidartag::sim
