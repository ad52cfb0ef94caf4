#include "lidartag/sim/simulator.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "lidartag/sim/board_target.hpp"
#include "lidartag/sim/camera_sim.hpp"
#include "lidartag/sim/clutter.hpp"
#include "lidartag/sim/random.hpp"
#include "lidartag/sim/sensor_sim.hpp"

namespace lidartag::sim {
namespace {

constexpr double kWallThickness = 0.2;  // room walls and ceiling, outside the inner size

void add_room(World& world, const RoomOptions& r) {
  const double yaw = r.yaw_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d c(r.center[0], r.center[1]);
  const Eigen::Vector2d ax(std::cos(yaw), std::sin(yaw)), ay(-std::sin(yaw), std::cos(yaw));
  const double hx = r.size[0] / 2.0, hy = r.size[1] / 2.0, t = kWallThickness;
  const double zc = r.height / 2.0;
  // Two walls across the room's x axis, two along it; each reaches past the corners.
  for (double s : {-1.0, 1.0}) {
    const Eigen::Vector2d px = c + ax * s * (hx + t / 2.0);
    world.add_box(make_box({px.x(), px.y(), zc}, {t, r.size[1] + 2 * t, r.height}, r.yaw_deg,
                           r.reflectivity));
    const Eigen::Vector2d py = c + ay * s * (hy + t / 2.0);
    world.add_box(make_box({py.x(), py.y(), zc}, {r.size[0] + 2 * t, t, r.height}, r.yaw_deg,
                           r.reflectivity));
  }
  if (r.ceiling)
    world.add_box(make_box({c.x(), c.y(), r.height + t / 2.0},
                           {r.size[0] + 2 * t, r.size[1] + 2 * t, t}, r.yaw_deg, r.reflectivity));
}

void add_wall(World& world, const WallOptions& w) {
  const Eigen::Vector2d a(w.from[0], w.from[1]), b(w.to[0], w.to[1]);
  const Eigen::Vector2d mid = (a + b) / 2.0, d = b - a;
  const double yaw = std::atan2(d.y(), d.x()) * 180.0 / std::numbers::pi;
  world.add_box(make_box({mid.x(), mid.y(), w.height / 2.0}, {d.norm(), w.thickness, w.height}, yaw,
                         w.reflectivity));
}

}  // namespace

Simulator::Simulator(Scene scene) : scene_(std::move(scene)) {
  const SensorOptions& s = scene_.sensor;
  const Eigen::Vector3d sensor_position(s.position[0], s.position[1], s.height);
  for (size_t i = 0; i < scene_.tags.size(); ++i)
    tags_.push_back(make_tag(scene_.tags[i], sensor_position, "tags[" + std::to_string(i) + "]"));
  std::vector<Eigen::Matrix3d> board_rotations;
  for (size_t i = 0; i < scene_.boards.size(); ++i)
    board_rotations.push_back(
        board_rotation(scene_.boards[i], sensor_position, "boards[" + std::to_string(i) + "]"));

  const WorldOptions& w = scene_.world;
  world_.set_ground(w.ground, w.ground_reflectivity);
  if (w.room.enabled) add_room(world_, w.room);
  for (const WallOptions& wall : w.walls) add_wall(world_, wall);
  std::vector<BoxOptions> boxes = w.boxes;
  std::vector<CylinderOptions> cylinders = w.cylinders;
  if (w.clutter.enabled) {
    // Keep clutter off the sensor's path (10 s of its motion) and off every tag, its
    // t*sqrt(2)/4 clearance and the line of sight to it.
    std::vector<KeepOut> keep_out;
    const Eigen::Vector2d p0(s.position[0], s.position[1]);
    const Eigen::Vector2d v(s.velocity[0], s.velocity[1]);
    keep_out.push_back({p0, p0 + 10.0 * v, 0.5});
    for (const TagTarget& t : tags_) {
      const double half = t.options.size / 2.0 + t.options.board.margin;
      const double r = half * std::sqrt(2.0) + t.options.size * std::sqrt(2.0) / 4.0;
      keep_out.push_back({p0, t.center.head<2>(), r});
    }
    for (const CalibrationBoardOptions& b : scene_.boards)
      keep_out.push_back(
          {p0, Eigen::Vector2d(b.center[0], b.center[1]), std::hypot(b.size[0], b.size[1]) / 2.0});
    const Clutter c = generate_clutter(w.clutter, keep_out);
    boxes.insert(boxes.end(), c.boxes.begin(), c.boxes.end());
    cylinders.insert(cylinders.end(), c.cylinders.begin(), c.cylinders.end());
  }
  for (const BoxOptions& b : boxes)
    world_.add_box(make_box({b.center[0], b.center[1], b.center[2]},
                            {b.size[0], b.size[1], b.size[2]}, b.yaw_deg, b.reflectivity));
  for (const CylinderOptions& c : cylinders)
    world_.add_cylinder({{c.base[0], c.base[1], c.base[2]}, c.radius, c.height, c.reflectivity});
  for (size_t i = 0; i < tags_.size(); ++i) add_tag(world_, tags_[i], static_cast<int>(i));
  for (size_t i = 0; i < scene_.boards.size(); ++i)
    add_board(world_, scene_.boards[i], board_rotations[i]);
}

Truth Simulator::run(int rotations, uint64_t seed, const PacketCallback& emit,
                     RunStats* stats) const {
  const SensorOptions& so = scene_.sensor;
  const SensorModel sensor(so, world_);
  const velodyne::ModelSpec& spec = sensor.spec();
  const int per_packet = spec.columns_per_packet(so.return_mode);
  const int64_t period_ns = std::llround(spec.firing_period_us * 1000.0);
  const int64_t start_ns = std::llround(so.start_time_s * 1e9);
  const double step_deg = sensor.rate_deg_per_us() * spec.firing_period_us;

  // Column k fires at k * period; its azimuth, unwrapped in hundredths of a degree, is what the
  // packet carries (mod 36000). Rotation i starts at the first column at or past the i-th cut.
  const auto cut = std::llround(so.cut_azimuth_deg * 100.0);
  const double start_deg = so.cut_azimuth_deg - 2.0 * per_packet * step_deg;
  auto azimuth_of = [&](int64_t k) {
    return std::llround(
        (start_deg + sensor.rate_deg_per_us() * spec.firing_period_us * static_cast<double>(k)) *
        100.0);
  };
  auto rotation_of = [&](int64_t k) {
    const long long d = azimuth_of(k) - cut;
    return static_cast<int>(d >= 0 ? d / 36000 : -((-d + 35999) / 36000));
  };

  Truth truth;
  truth.model = std::string(spec.name);
  truth.return_mode = std::string(velodyne::return_mode_name(so.return_mode));
  truth.rpm = so.rpm;
  truth.seed = seed;
  truth.rotations.resize(static_cast<size_t>(std::max(rotations, 0)));

  Packetizer packetizer(spec, so.return_mode, start_ns,
                        so.position_packets ? so.position_rate_hz : 0.0, emit);
  Rng rng(seed);
  velodyne::FiringColumn column;
  ColumnLabels labels;
  RunStats st;
  std::vector<bool> started(truth.rotations.size(), false);
  int64_t end_column = -1;
  for (int64_t k = 0;; ++k) {
    const int rot = rotation_of(k);
    if (rot >= rotations && end_column < 0) {
      // Two more packets after the last cut, ending on a packet boundary.
      end_column = ((k + per_packet - 1) / per_packet + 2) * per_packet;
    }
    if (end_column >= 0 && k >= end_column) break;
    const double t_us = spec.firing_period_us * static_cast<double>(k);
    const long long az = azimuth_of(k);
    const auto az_field = static_cast<uint16_t>(((az % 36000) + 36000) % 36000);
    sensor.fire(t_us, az_field, rng, column, labels);
    const int64_t t_ns = start_ns + k * period_ns;
    if (rot >= 0 && rot < rotations) {
      RotationTruth& rt = truth.rotations[static_cast<size_t>(rot)];
      if (!started[static_cast<size_t>(rot)]) {
        started[static_cast<size_t>(rot)] = true;
        rt.index = rot;
        rt.stamp_ns = t_ns;
        rt.tags.resize(tags_.size());
      }
      for (size_t slot = 0; slot < 2; ++slot)
        for (int l = 0; l < spec.lasers; ++l) {
          const int tag = labels.tag[slot][static_cast<size_t>(l)];
          if (tag >= 0) ++rt.tags[static_cast<size_t>(tag)].returns;
        }
    }
    // Reported points; in dual mode the second block repeats a single echo: count it once.
    for (size_t l = 0; l < static_cast<size_t>(spec.lasers); ++l) {
      const auto& e0 = column.echo[0];
      const auto& e1 = column.echo[1];
      st.points += e0.distance[l] != 0 ? 1u : 0u;
      if (so.return_mode == velodyne::ReturnMode::kDual && e1.distance[l] != 0 &&
          (e1.distance[l] != e0.distance[l] || e1.intensity[l] != e0.intensity[l]))
        ++st.points;
    }
    packetizer.add(column, t_ns);
    ++st.columns;
  }

  // Poses at each rotation's first firing; tags in that sensor frame.
  for (RotationTruth& rt : truth.rotations) {
    const Pose pose = sensor.trajectory().at(static_cast<double>(rt.stamp_ns - start_ns) * 1e-9);
    rt.sensor_position = pose.position;
    rt.sensor_orientation = quaternion_wxyz(pose.rotation);
    const Eigen::Matrix3d rt_inv = pose.rotation.transpose();
    for (size_t i = 0; i < tags_.size(); ++i) {
      const TagTarget& tag = tags_[i];
      TagTruth& tt = rt.tags[i];
      tt.family = tag.family_name;
      tt.id = tag.options.id;
      tt.size = tag.options.size;
      tt.position = rt_inv * (tag.center - pose.position);
      tt.orientation = quaternion_wxyz(rt_inv * tag.rotation);
      const auto corners = tag.corners_tag();
      for (size_t c = 0; c < 4; ++c)
        tt.corners[c] = rt_inv * (tag.center + tag.rotation * corners[c] - pose.position);
      if (scene_.camera) tt.image_corners = project_corners(*scene_.camera, tt.corners);
    }
  }
  if (scene_.camera)
    truth.camera = CameraTruth{scene_.camera->model, camera_rotation(*scene_.camera),
                               camera_translation(*scene_.camera)};
  st.data_packets = packetizer.data_packets();
  st.position_packets = packetizer.position_packets();
  if (stats) *stats = st;
  return truth;
}

calib::GrayImage Simulator::render_image(const RotationTruth& rotation, uint64_t seed) const {
  if (!scene_.camera) throw SceneError("the scene has no camera section");
  const Eigen::Vector4d& q = rotation.sensor_orientation;
  const Eigen::Matrix3d r = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).toRotationMatrix();
  return render_camera(world_, *scene_.camera, rotation.sensor_position, r, seed);
}

}  // namespace lidartag::sim
