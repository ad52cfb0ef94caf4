// Captures decoded with the project's own Decoder and ScanBatcher: points land where the surfaces
// are, tags give the expected returns, the truth's conventions match the rendered points, every
// model and return mode works, motion distorts, and the output is deterministic.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>

#include "lidartag/detector/tag_family.hpp"
#include "sim_test_util.hpp"

namespace lidartag::sim {
namespace {

using testing::Capture;
using testing::decode;
using testing::simulate;
using velodyne::Model;
using velodyne::ReturnMode;

constexpr double kDeg = std::numbers::pi / 180.0;

// Signed azimuth in (-180, 180].
double signed_az(double az) {
  return az > 180.0 ? az - 360.0 : az;
}

Scene wall_scene(Model model, double yaw_deg) {
  Scene s;
  s.sensor.model = model;
  s.sensor.noise = NoiseOptions::ideal();
  s.world.ground = false;
  // A 40 m x 60 m wall whose front face passes through (8, 0), turned by yaw about z.
  const double y = yaw_deg * kDeg;
  s.world.boxes.push_back(
      {{8.0 + 0.1 * std::cos(y), 0.1 * std::sin(y), 0.0}, {0.2, 40.0, 60.0}, yaw_deg, 50.0});
  return s;
}

class WallPerModel : public ::testing::TestWithParam<Model> {};

TEST_P(WallPerModel, IdealRangesPerLaserMatchTheWall) {
  for (double yaw : {0.0, 30.0}) {
    const Scene s = wall_scene(GetParam(), yaw);
    const Capture c = simulate(s, 1, 1);
    const auto d = decode(c, s);
    ASSERT_EQ(d.bad_packets, 0u);
    ASSERT_EQ(d.complete.size(), 1u);
    const Scan& scan = *d.complete[0];
    const Eigen::Vector3d n(std::cos(yaw * kDeg), std::sin(yaw * kDeg), 0.0);
    const double plane = n.x() * 8.0;  // the face passes through (8, 0, 0)
    const auto& spec = velodyne::model_spec(GetParam());
    const double tol = spec.distance_unit_m / 2.0 + 0.003;
    for (int ring = 0; ring < scan.rings; ++ring) {
      const auto& laser = spec.laser_table[static_cast<size_t>(spec.laser_of_ring(ring))];
      const double e = laser.elevation_deg * kDeg;
      int checked = 0;
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(0, ring, col);
        const double a = signed_az(scan.azimuth_deg[i]);
        if (std::abs(a) > 40.0) continue;
        ASSERT_TRUE(scan.valid(i)) << "ring " << ring << " azimuth " << a;
        // Range along the beam from its origin (vertical offset) to the plane n.p = 8.
        const Eigen::Vector3d dir(std::cos(e) * std::cos(a * kDeg),
                                  -std::cos(e) * std::sin(a * kDeg), std::sin(e));
        const Eigen::Vector3d origin =
            laser.vertical_offset_m * Eigen::Vector3d(-std::sin(e) * std::cos(a * kDeg),
                                                      std::sin(e) * std::sin(a * kDeg),
                                                      std::cos(e));
        const double expected = (plane - n.dot(origin)) / n.dot(dir);
        // The packet carries azimuths in 0.01 degree steps: on an oblique wall that quantum moves
        // the hit along the wall by range * tan(incidence) * 0.01 degree.
        const double cos_inc = std::abs(n.dot(dir));
        const double slack = expected * std::sqrt(1.0 - cos_inc * cos_inc) / cos_inc * 0.01 * kDeg;
        EXPECT_NEAR(scan.range[i], expected, tol + slack) << "ring " << ring << " azimuth " << a;
        const Eigen::Vector3d p(scan.x[i], scan.y[i], scan.z[i]);
        EXPECT_NEAR(n.dot(p), plane, tol);
        ++checked;
      }
      EXPECT_GT(checked, 300) << "ring " << ring;
    }
  }
}

TEST_P(WallPerModel, NoisyRangesScatterWithTheDocumentedSigma) {
  Scene s = wall_scene(GetParam(), 0.0);
  s.sensor.noise = noise_defaults(GetParam());
  const Capture c = simulate(s, 1, 7);
  const auto d = decode(c, s);
  ASSERT_EQ(d.complete.size(), 1u);
  const Scan& scan = *d.complete[0];
  double sum = 0, sum2 = 0;
  size_t n = 0, cells = 0;
  for (int ring = 0; ring < scan.rings; ++ring)
    for (int col = 0; col < scan.columns; ++col) {
      const size_t i = scan.at(0, ring, col);
      if (std::abs(signed_az(scan.azimuth_deg[i])) > 40.0) continue;
      ++cells;
      if (!scan.valid(i)) continue;
      const double err = scan.x[i] - 8.0;  // the wall is x = 8 (no vertical offset along x... )
      sum += err;
      sum2 += err * err;
      ++n;
    }
  const double sigma = s.sensor.noise.range_sigma_m;
  ASSERT_GT(n, 1000u);
  EXPECT_NEAR(sum / static_cast<double>(n), 0.0, 0.002);
  // Ranges scatter with sigma along beams that are within 40 degrees of the normal: the x
  // scatter lies between sigma cos(40 deg) and sigma (plus the distance quantum).
  const double rms = std::sqrt(sum2 / static_cast<double>(n));
  EXPECT_GT(rms, 0.7 * sigma);
  EXPECT_LT(rms, 1.05 * sigma + 0.002);
  // Dropout (0.2 %) removes a few points, nothing else on a plain wall.
  EXPECT_GT(static_cast<double>(n), 0.99 * static_cast<double>(cells));
  EXPECT_LT(n, cells);
}

INSTANTIATE_TEST_SUITE_P(AllModels, WallPerModel,
                         ::testing::Values(Model::kVLP16, Model::kPuckHiRes, Model::kVLP32C,
                                           Model::kHDL32E, Model::kVLS128),
                         [](const ::testing::TestParamInfo<Model>& p) {
                           std::string n(velodyne::model_spec(p.param).name);
                           for (char& ch : n)
                             if (ch == '-') ch = '_';
                           return n;
                         });

TEST(TagCapture, FaceOnTagGivesTheExpectedReturnsPerRing) {
  Scene s;
  s.sensor.model = Model::kVLP32C;
  s.sensor.noise = NoiseOptions::ideal();
  s.world.ground = false;
  TagOptions t;
  t.size = 0.8;
  t.center = {6.0, 0.0, 1.0};
  t.rotation_deg = 0.0;
  s.tags.push_back(t);
  const Capture c = simulate(s, 1, 1);
  const auto d = decode(c, s);
  ASSERT_EQ(d.complete.size(), 1u);
  const Scan& scan = *d.complete[0];
  const auto& spec = velodyne::model_spec(Model::kVLP32C);
  const double step = 600.0 * 360.0 / 60.0 * 1e-6 * spec.firing_period_us;  // degrees/column
  const double window = 2.0 * std::atan(0.4 / 6.0) / kDeg;
  int total = 0, rings_hit = 0;
  for (int ring = 0; ring < scan.rings; ++ring) {
    const double e = spec.laser_table[static_cast<size_t>(spec.laser_of_ring(ring))].elevation_deg;
    int count = 0;
    for (int col = 0; col < scan.columns; ++col) {
      const size_t i = scan.at(0, ring, col);
      if (!scan.valid(i)) continue;
      EXPECT_NEAR(scan.x[i], 6.0, 0.003);  // nothing else in the scene
      if (std::abs(scan.y[i]) <= 0.4 && std::abs(scan.z[i]) <= 0.4) ++count;
    }
    total += count;
    const double z_at_tag = 6.0 * std::tan(e * kDeg);
    if (std::abs(z_at_tag) < 0.39) {
      ++rings_hit;
      EXPECT_NEAR(count, window / step, 1.5) << "ring " << ring << " elevation " << e;
    } else if (std::abs(z_at_tag) > 0.41 / std::cos(window / 2 * kDeg)) {
      EXPECT_EQ(count, 0) << "ring " << ring << " elevation " << e;
    }
  }
  EXPECT_EQ(rings_hit, 19);  // VLP-32C elevations within +-3.81 degrees
  ASSERT_EQ(c.truth.rotations.size(), 1u);
  ASSERT_EQ(c.truth.rotations[0].tags.size(), 1u);
  EXPECT_EQ(c.truth.rotations[0].tags[0].returns, total);
}

// The tag's pose and corners in the truth file, applied to the decoded points, reproduce the
// printed pattern of the code the truth names.
TEST(TagCapture, TruthPoseCornersAndPatternMatchTheRenderedPoints) {
  Scene s;
  s.sensor.model = Model::kVLP32C;
  s.sensor.height = 1.2;
  s.sensor.yaw_deg = 20.0;
  s.sensor.noise = noise_defaults(Model::kVLP32C);
  s.world.room.enabled = true;
  s.world.room.size = {14.0, 12.0};
  TagOptions t;
  t.family = "tag16h5";
  t.id = 0;
  t.size = 0.8;
  t.center = {3.2, 1.6, 1.1};
  t.normal = {-1.0, -0.3, 0.1};
  t.rotation_deg = 45.0;
  t.stand.enabled = true;
  s.tags.push_back(t);
  const Capture c = simulate(s, 3, 5);
  const auto d = decode(c, s);
  ASSERT_EQ(d.complete.size(), 3u);
  const auto& family = tags::builtin_family("tag16h5");
  const double half = 0.4, cell = 0.1, black_half = 0.3;
  for (size_t r = 0; r < 3; ++r) {
    const RotationTruth& rt = c.truth.rotations[r];
    const TagTruth& tt = rt.tags[0];
    ASSERT_EQ(tt.family, "tag16h5");
    const std::vector<uint8_t> image = family.render(family.codes[static_cast<size_t>(tt.id)]);
    const Eigen::Quaterniond q(tt.orientation[0], tt.orientation[1], tt.orientation[2],
                               tt.orientation[3]);
    const Eigen::Matrix3d R = q.toRotationMatrix();
    // Corners: the black square, bottom-left, bottom-right, top-right, top-left.
    const double sg[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (size_t k = 0; k < 4; ++k) {
      const Eigen::Vector3d expect =
          tt.position + R * Eigen::Vector3d(0, sg[k][0] * black_half, sg[k][1] * black_half);
      EXPECT_LT((tt.corners[k] - expect).norm(), 1e-9);
    }
    // The tag faces the sensor: its +x points back toward the origin of the sensor frame.
    EXPECT_LT(R.col(0).dot(tt.position), 0.0);

    const Scan& scan = *d.complete[r];
    auto white_at = [&](double y, double z, bool mirrored) {
      if (mirrored) y = -y;
      const int col = static_cast<int>(std::floor((y + half) / cell));
      const int row = static_cast<int>(std::floor((half - z) / cell));
      return image[static_cast<size_t>(row * 8 + col)] != 0;
    };
    int on_marker = 0, judged = 0, agree = 0, agree_mirrored = 0, black_outside = 0;
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(0, ring, col);
        if (!scan.valid(i)) continue;
        const Eigen::Vector3d p =
            R.transpose() * (Eigen::Vector3d(scan.x[i], scan.y[i], scan.z[i]) - tt.position);
        if (std::abs(p.x()) > 0.06 || std::abs(p.y()) > half || std::abs(p.z()) > half) continue;
        ++on_marker;
        const bool dark = scan.intensity[i] < 30;
        if (dark && (std::abs(p.y()) > black_half + 0.02 || std::abs(p.z()) > black_half + 0.02))
          ++black_outside;
        // Away from cell boundaries (range noise moves points along oblique beams).
        const double fy = std::fmod(p.y() + half, cell), fz = std::fmod(half - p.z(), cell);
        if (std::min(fy, cell - fy) < 0.02 || std::min(fz, cell - fz) < 0.02) continue;
        ++judged;
        const bool bright = scan.intensity[i] > 50;
        agree += bright == white_at(p.y(), p.z(), false) ? 1 : 0;
        agree_mirrored += bright == white_at(p.y(), p.z(), true) ? 1 : 0;
      }
    ASSERT_GT(judged, 200);
    EXPECT_GT(agree, 0.97 * judged);
    EXPECT_LT(agree_mirrored, 0.85 * judged);  // a mirrored convention would be caught
    EXPECT_LT(black_outside, 3);
    EXPECT_NEAR(tt.returns, on_marker, 0.06 * on_marker);
  }
}

TEST(Capture, SameSceneAndSeedGiveIdenticalOutput) {
  Scene s;
  s.sensor.model = Model::kVLP16;
  s.world.clutter.enabled = true;
  s.world.clutter.count = 15;
  TagOptions t;
  t.center = {4.0, -1.0, 1.0};
  s.tags.push_back(t);
  const Capture a = simulate(s, 2, 3), b = simulate(s, 2, 3), other = simulate(s, 2, 4);
  ASSERT_EQ(a.packets.size(), b.packets.size());
  for (size_t i = 0; i < a.packets.size(); ++i) {
    ASSERT_EQ(a.packets[i].payload, b.packets[i].payload) << i;
    ASSERT_EQ(a.packets[i].time_ns, b.packets[i].time_ns);
  }
  EXPECT_EQ(truth_to_json(a.truth).dump(), truth_to_json(b.truth).dump());
  size_t differ = 0;
  for (size_t i = 0; i < a.packets.size(); ++i)
    differ += a.packets[i].payload != other.packets[i].payload ? 1u : 0u;
  EXPECT_GT(differ, a.packets.size() / 2);  // the noise seed changes the points...
  EXPECT_EQ(a.truth.rotations[1].tags[0].position, other.truth.rotations[1].tags[0].position);
}

struct ModeCase {
  Model model;
  ReturnMode mode;
};

class ModelsAndModes : public ::testing::TestWithParam<ModeCase> {};

TEST_P(ModelsAndModes, DecodesIntoWholeRotationsMatchingTheTruth) {
  const auto [model, mode] = GetParam();
  Scene s;
  s.sensor.model = model;
  s.sensor.return_mode = mode;
  s.world.room.enabled = true;
  s.world.room.size = {16.0, 12.0};
  s.world.cylinders.push_back({{3.0, -1.5, 0.0}, 0.1, 2.0, 60.0});  // a pole before the wall
  TagOptions t;
  t.center = {4.0, 1.0, 1.0};
  s.tags.push_back(t);
  const int rotations = model == Model::kVLS128 ? 1 : 2;
  const Capture c = simulate(s, rotations, 1);
  const auto d = decode(c, s);
  const auto& spec = velodyne::model_spec(model);
  EXPECT_EQ(d.bad_packets, 0u);
  ASSERT_EQ(d.complete.size(), static_cast<size_t>(rotations));
  ASSERT_EQ(c.truth.rotations.size(), static_cast<size_t>(rotations));
  EXPECT_EQ(c.truth.model, spec.name);
  const double period_ns = spec.firing_period_us * 1e3;
  for (int r = 0; r < rotations; ++r) {
    const Scan& scan = *d.complete[static_cast<size_t>(r)];
    EXPECT_NEAR(
        static_cast<double>(scan.stamp_ns - c.truth.rotations[static_cast<size_t>(r)].stamp_ns),
        0.0, 1.01 * period_ns);
    EXPECT_NEAR(scan.rpm, 600.0, 6.0);
    EXPECT_GT(c.truth.rotations[static_cast<size_t>(r)].tags[0].returns, 20);
    std::map<ReturnType, int> types;
    for (int ret = 0; ret < scan.returns; ++ret)
      for (int ring = 0; ring < scan.rings; ++ring)
        for (int col = 0; col < scan.columns; ++col)
          ++types[scan.return_type[scan.at(ret, ring, col)]];
    const int points = scan.returns * scan.rings * scan.columns - types[ReturnType::kNone];
    EXPECT_GT(points, scan.rings * scan.columns / 2);  // a closed room: most beams return
    if (mode == ReturnMode::kDual) {
      EXPECT_GT(types[ReturnType::kBoth], 0);
      // Footprints straddling the pole, the tag board and the room's edges give two echoes.
      EXPECT_GT(types[ReturnType::kLast] + types[ReturnType::kSecond], 10);
    } else {
      EXPECT_EQ(types[ReturnType::kBoth], 0);
      EXPECT_GT(types[mode == ReturnMode::kLast ? ReturnType::kLast : ReturnType::kStrongest], 0);
    }
  }
  // Packet spacing is the model's packet period, whatever the rpm.
  for (size_t i = 1; i < c.packets.size(); ++i)
    EXPECT_NEAR(static_cast<double>(c.packets[i].time_ns - c.packets[i - 1].time_ns),
                spec.packet_period_us(mode) * 1e3, 1.0);
}

std::vector<ModeCase> all_cases() {
  std::vector<ModeCase> v;
  for (Model m : velodyne::all_models())
    for (ReturnMode r : {ReturnMode::kStrongest, ReturnMode::kLast, ReturnMode::kDual})
      v.push_back({m, r});
  return v;
}

INSTANTIATE_TEST_SUITE_P(All, ModelsAndModes, ::testing::ValuesIn(all_cases()),
                         [](const ::testing::TestParamInfo<ModeCase>& p) {
                           std::string n(velodyne::model_spec(p.param.model).name);
                           for (char& ch : n)
                             if (ch == '-') ch = '_';
                           return n + "_" + std::string(velodyne::return_mode_name(p.param.mode));
                         });

// A moving, turning sensor: every point, put back in the world with the pose at its own firing
// time, lies on the wall; the same points read in the sensor frame are spread by the motion.
TEST(Capture, MotionDistortsARotationAsTheSensorMoves) {
  Scene s = wall_scene(Model::kVLP32C, 0.0);
  s.sensor.velocity = {4.0, 0.0, 0.0};
  s.sensor.angular_velocity = {0.0, 0.0, 30.0};  // deg/s about the sensor's z
  const Capture c = simulate(s, 1, 1);
  const auto d = decode(c, s);
  ASSERT_EQ(d.complete.size(), 1u);
  const Scan& scan = *d.complete[0];
  const int64_t start_ns = std::llround(s.sensor.start_time_s * 1e9);
  double xmin = 1e9, xmax = -1e9;
  int n = 0;
  for (int ring = 0; ring < scan.rings; ++ring)
    for (int col = 0; col < scan.columns; ++col) {
      const size_t i = scan.at(0, ring, col);
      if (!scan.valid(i) || std::abs(signed_az(scan.azimuth_deg[i])) > 30.0) continue;
      const double t = static_cast<double>(scan.stamp_ns - start_ns) * 1e-9 + scan.time_s[i];
      const Eigen::Vector3d world = Eigen::AngleAxisd(30.0 * kDeg * t, Eigen::Vector3d::UnitZ()) *
                                        Eigen::Vector3d(scan.x[i], scan.y[i], scan.z[i]) +
                                    Eigen::Vector3d(4.0 * t, 0.0, s.sensor.height);
      EXPECT_NEAR(world.x(), 8.0, 0.006);
      xmin = std::min(xmin, static_cast<double>(scan.x[i]));
      xmax = std::max(xmax, static_cast<double>(scan.x[i]));
      ++n;
    }
  ASSERT_GT(n, 1000);
  // Straight ahead, 60 degrees of sweep take 1/60 s: the sensor moves 6.7 cm meanwhile; the
  // turning adds its own skew. A static sensor would see the wall's points at x = 8 exactly.
  EXPECT_GT(8.0 - xmin, 0.2);  // 0.15 s after the start the wall is 0.6 m closer
  const auto static_capture = simulate(wall_scene(Model::kVLP32C, 0.0), 1, 1);
  const auto sd = decode(static_capture, wall_scene(Model::kVLP32C, 0.0));
  ASSERT_EQ(sd.complete.size(), 1u);
  for (int ring = 0; ring < sd.complete[0]->rings; ++ring)
    for (int col = 0; col < sd.complete[0]->columns; ++col) {
      const size_t i = sd.complete[0]->at(0, ring, col);
      if (sd.complete[0]->valid(i) && std::abs(signed_az(sd.complete[0]->azimuth_deg[i])) <= 30.0) {
        ASSERT_NEAR(sd.complete[0]->x[i], 8.0, 0.003);
      }
    }
  // Truth: the sensor pose of the rotation is the pose at its first firing.
  const RotationTruth& rt = c.truth.rotations[0];
  const double t0 = static_cast<double>(rt.stamp_ns - start_ns) * 1e-9;
  EXPECT_NEAR(rt.sensor_position.x(), 4.0 * t0, 1e-9);
  EXPECT_NEAR(2.0 * std::acos(rt.sensor_orientation[0]), 30.0 * kDeg * t0, 1e-9);
  EXPECT_GT(xmax - xmin, 0.0);
}

TEST(Capture, PositionPacketsCarryGprmcAndLockedPps) {
  Scene s;
  s.sensor.model = Model::kVLP16;
  s.sensor.position_packets = true;
  s.sensor.position_rate_hz = 100.0;
  s.sensor.noise = NoiseOptions::ideal();
  const Capture c = simulate(s, 1, 1);
  int positions = 0;
  int64_t last = 0;
  const int64_t start_ns = std::llround(s.sensor.start_time_s * 1e9);
  for (const auto& p : c.packets) {
    EXPECT_GE(p.time_ns, last);  // capture order
    last = p.time_ns;
    if (p.port != velodyne::kDefaultPositionPort) continue;
    ++positions;
    velodyne::PositionPacket pos;
    ASSERT_EQ(velodyne::parse_position_packet(p.payload, pos), velodyne::PositionStatus::kOk);
    EXPECT_EQ(pos.pps, velodyne::PpsStatus::kLocked);
    EXPECT_TRUE(pos.has_gprmc) << pos.sentence();
    EXPECT_EQ(pos.gps_fix_ns, p.time_ns - p.time_ns % 1'000'000'000LL);  // whole second
    EXPECT_EQ(pos.usec_since_hour, usec_since_hour(p.time_ns));
  }
  EXPECT_EQ(positions, 1 + static_cast<int>((last - start_ns) / 10'000'000));
  EXPECT_EQ(c.stats.position_packets, static_cast<uint64_t>(positions));
}

TEST(Capture, GprmcSentenceHasTimeDateAndChecksum) {
  // 2023-11-14 22:13:20 UTC.
  const std::string s = gprmc_sentence(1700000000LL * 1'000'000'000LL + 999'000'000LL);
  EXPECT_EQ(s.rfind("$GPRMC,221320,A,", 0), 0u) << s;
  EXPECT_NE(s.find(",141123,"), std::string::npos) << s;
  uint8_t x = 0;
  const size_t star = s.find('*');
  for (size_t i = 1; i < star; ++i) x = static_cast<uint8_t>(x ^ static_cast<uint8_t>(s[i]));
  char hex[3];
  std::snprintf(hex, sizeof(hex), "%02X", x);
  EXPECT_EQ(s.substr(star + 1), hex);
}

TEST(Capture, TruthJsonHasTheDocumentedShape) {
  Scene s;
  s.sensor.noise = NoiseOptions::ideal();
  TagOptions t;
  t.center = {5.0, 0.0, 1.0};
  s.tags.push_back(t);
  const Capture c = simulate(s, 2, 1);
  const nlohmann::json j = truth_to_json(c.truth);
  EXPECT_EQ(j["model"], "vlp32c");
  ASSERT_EQ(j["rotations"].size(), 2u);
  const auto& r = j["rotations"][1];
  EXPECT_EQ(r["index"], 1);
  EXPECT_NEAR(r["stamp"].get<double>() - j["rotations"][0]["stamp"].get<double>(), 0.1, 1e-4);
  EXPECT_EQ(r["sensor"]["position"].size(), 3u);
  EXPECT_EQ(r["sensor"]["orientation"].size(), 4u);
  const auto& tag = r["tags"][0];
  for (const char* key : {"family", "id", "size", "position", "orientation", "corners", "returns"})
    EXPECT_TRUE(tag.contains(key)) << key;
  EXPECT_EQ(tag["corners"].size(), 4u);
  EXPECT_NEAR(tag["position"][0].get<double>(), 5.0, 1e-9);
  EXPECT_GT(tag["returns"].get<int>(), 50);
}

}  // namespace
}  // namespace lidartag::sim
