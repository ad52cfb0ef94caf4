// Point clouds (as read from PCD files) into scans: organised grids exactly, unorganised clouds by
// azimuth, rings regressed without ring numbers, and the errors a user meets.
#include "lidartag/detector/cloud_scan.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

#include "lidartag/detector/detector.hpp"
#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A cloud's columns of numbers, as a PCD file holds them.
struct Columns {
  std::vector<double> x, y, z, intensity, ring, azimuth, time, return_type;
  size_t width = 0, height = 1;

  void add(double px, double py, double pz, double i, double r, double az, double t, double ret) {
    x.push_back(px);
    y.push_back(py);
    z.push_back(pz);
    intensity.push_back(i);
    ring.push_back(r);
    azimuth.push_back(az);
    time.push_back(t);
    return_type.push_back(ret);
  }
  CloudFields fields(bool with_ring = true, bool with_intensity = true) const {
    CloudFields f;
    f.x = x;
    f.y = y;
    f.z = z;
    if (with_intensity) f.intensity = intensity;
    if (with_ring) f.ring = ring;
    f.azimuth_deg = azimuth;
    f.time_s = time;
    f.return_type = return_type;
    f.width = width;
    f.height = height;
    return f;
  }
};

// A scene with a tag: its cells get firing azimuths and times as the decoder gives them.
Scan tag_scene() {
  static const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.id = 3;
  tag.center = Eigen::Vector3d(5.0, 1.0, 0.2);
  tag.rotation = test::facing_sensor(tag.center, 45.0);
  scene.tags.push_back(tag);
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  for (int ring = 0; ring < s.rings; ++ring)
    for (int col = 0; col < s.columns; ++col) {
      const size_t i = s.at(0, ring, col);
      s.azimuth_deg[i] = s.column_azimuth_deg[static_cast<size_t>(col)];
      s.time_s[i] = static_cast<float>(1e-4 * col + 1e-6 * ring);
    }
  return s;
}

// The organised layout `lidartag dump --organized` writes: rows = rings, NaN without a return.
Columns organised(const Scan& s) {
  Columns c;
  c.width = static_cast<size_t>(s.columns);
  c.height = static_cast<size_t>(s.rings * s.returns);
  for (int ret = 0; ret < s.returns; ++ret)
    for (int ring = 0; ring < s.rings; ++ring)
      for (int col = 0; col < s.columns; ++col) {
        const size_t i = s.at(ret, ring, col);
        const bool v = s.valid(i);
        c.add(v ? s.x[i] : kNaN, v ? s.y[i] : kNaN, v ? s.z[i] : kNaN, v ? s.intensity[i] : 0, ring,
              s.azimuth_deg[i], s.time_s[i], v ? static_cast<double>(s.return_type[i]) : 0);
      }
  return c;
}

// The valid cells alone (an unorganised dump).
Columns unorganised(const Scan& s) {
  Columns c;
  for (int ring = 0; ring < s.rings; ++ring)
    for (int col = 0; col < s.columns; ++col) {
      const size_t i = s.at(0, ring, col);
      if (s.valid(i))
        c.add(s.x[i], s.y[i], s.z[i], s.intensity[i], ring, s.azimuth_deg[i], s.time_s[i], 1);
    }
  c.width = c.x.size();
  return c;
}

std::vector<Detection> detect(const Scan& s) {
  Detector det(DetectorOptions{});
  ScanResult r;
  det.detect(s, r);
  return r.detections;
}

TEST(CloudScan, OrganisedCloudKeepsEveryCellColumnAndTime) {
  const Scan s = tag_scene();
  const Columns c = organised(s);
  Scan out;
  const CloudScanReport report = cloud_to_scan(c.fields(), {}, out);
  EXPECT_TRUE(report.grid);
  EXPECT_FALSE(report.regressed);
  EXPECT_EQ(report.points, s.point_count());
  ASSERT_EQ(out.rings, s.rings);
  ASSERT_EQ(out.columns, s.columns);
  ASSERT_EQ(out.returns, 1);
  for (int ring = 0; ring < s.rings; ++ring)
    for (int col = 0; col < s.columns; ++col) {
      const size_t i = s.at(0, ring, col), j = out.at(0, ring, col);
      ASSERT_EQ(s.valid(i), out.valid(j)) << ring << " " << col;
      EXPECT_EQ(out.time_s[j], s.time_s[i]);
      EXPECT_EQ(out.azimuth_deg[j], s.azimuth_deg[i]);
      if (!s.valid(i)) continue;
      EXPECT_EQ(out.x[j], s.x[i]);
      EXPECT_EQ(out.z[j], s.z[i]);
      EXPECT_EQ(out.intensity[j], s.intensity[i]);
      EXPECT_NEAR(out.range[j], s.range[i], 1e-5);
    }
  for (int col = 0; col < s.columns; ++col) {
    EXPECT_EQ(out.column_azimuth_deg[static_cast<size_t>(col)],
              s.column_azimuth_deg[static_cast<size_t>(col)]);
    // Row 0 (ring 0) gives the column's time.
    EXPECT_EQ(out.column_time_s[static_cast<size_t>(col)], s.time_s[s.at(0, 0, col)]);
  }
  // The detector finds what it finds in the original.
  const auto a = detect(s), b = detect(out);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].id, 3);
  EXPECT_LT((a[0].position - b[0].position).norm(), 1e-6);
}

TEST(CloudScan, OrganisedDualCloudFillsBothReturns) {
  Scan s;
  s.reserve(2, 2, 3);
  s.columns = 3;
  for (int ret = 0; ret < 2; ++ret)
    for (int col = 0; col < 3; ++col) {
      const size_t i = s.at(ret, 1, col);
      s.x[i] = 2.0f + static_cast<float>(ret);
      s.y[i] = -0.01f * static_cast<float>(col);
      s.range[i] = s.x[i];
      s.intensity[i] = static_cast<uint8_t>(10 + ret);
      s.return_type[i] = ret == 0 ? ReturnType::kLast : ReturnType::kSecond;
    }
  Scan out;
  const auto report = cloud_to_scan(organised(s).fields(), {}, out);
  EXPECT_TRUE(report.grid);
  ASSERT_EQ(out.returns, 2);
  EXPECT_EQ(report.points, 6u);
  EXPECT_EQ(out.x[out.at(1, 1, 2)], 3.0f);
  EXPECT_EQ(out.return_type[out.at(1, 1, 2)], ReturnType::kSecond);
  EXPECT_EQ(out.return_type[out.at(0, 1, 0)], ReturnType::kLast);
  EXPECT_FALSE(out.valid(out.at(0, 0, 0)));
}

TEST(CloudScan, UnorganisedCloudWithRingsIsBinnedByAzimuthAndKeepsTime) {
  const Scan s = tag_scene();
  const Columns c = unorganised(s);
  Scan out;
  CloudScanOptions o;
  o.resolution_deg = 360.0 / s.columns;
  const auto report = cloud_to_scan(c.fields(), o, out);
  EXPECT_FALSE(report.grid);
  EXPECT_FALSE(report.regressed);
  EXPECT_EQ(report.points, s.point_count());
  EXPECT_EQ(out.rings, s.rings);
  size_t timed = 0;
  for (size_t j = 0; j < out.range.size(); ++j) timed += out.valid(j) && out.time_s[j] > 0.0f;
  EXPECT_GT(timed, report.points * 9 / 10);
  const auto b = detect(out);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].id, 3);
}

TEST(CloudScan, PointsThatShareACellAreCountedNotDroppedSilently) {
  // Issue 36: a dump read back binned 390 of 57,000 points into cells a nearer point took, with
  // no message. Three points of ring 0 at one azimuth (the nearest kept) and one elsewhere.
  Columns c;
  c.add(5.0, 0.0, 0.0, 10, 0, 0, 0, 0);
  c.add(6.0, 0.0, 0.0, 10, 0, 0, 0, 0);
  c.add(7.0, 0.001, 0.0, 10, 0, 0, 0, 0);
  c.add(0.0, -5.0, 0.0, 10, 0, 90, 0, 0);
  c.width = 4;
  Scan out;
  CloudScanOptions o;
  o.resolution_deg = 0.2;
  o.rings = 1;
  const auto report = cloud_to_scan(c.fields(), o, out);
  EXPECT_EQ(report.points, 2u);
  EXPECT_EQ(report.merged, 2u);
  EXPECT_EQ(report.points + report.merged, 4u);  // every point accounted for
  // Without rings, regressed: the same accounting.
  const auto regressed = cloud_to_scan(c.fields(false), o, out);
  EXPECT_TRUE(regressed.regressed);
  EXPECT_EQ(regressed.points + regressed.merged, 4u);
}

TEST(CloudScan, WithoutAColumnWidthTheCloudsOwnStepIsUsed) {
  // A VLP-32C rotation (0.2 degree steps) unorganised: columns of 0.95 x 0.2 degrees, so that no
  // firing shares a column (at 0.2, firings whose azimuths straddle a column's edge did), and the
  // tag is found.
  const Scan s = tag_scene();
  const Columns c = unorganised(s);
  Scan out;
  CloudScanReport r = cloud_to_scan(c.fields(), CloudScanOptions{}, out);
  EXPECT_NEAR(r.resolution_deg, kColumnStepShare * 360.0 / s.columns, 1e-3);
  EXPECT_EQ(r.merged, 0u);
  EXPECT_EQ(r.points, s.point_count());
  EXPECT_EQ(detect(out).size(), 1u);
  // Every third point of each ring kept: a sensor of 0.6 degree steps.
  Columns sparse;
  for (size_t k = 0; k < c.x.size(); ++k)
    if (std::lround(c.azimuth[k] / (360.0 / s.columns)) % 3 == 0)
      sparse.add(c.x[k], c.y[k], c.z[k], c.intensity[k], c.ring[k], c.azimuth[k], c.time[k], 1);
  sparse.width = sparse.x.size();
  r = cloud_to_scan(sparse.fields(), CloudScanOptions{}, out);
  EXPECT_NEAR(r.resolution_deg, kColumnStepShare * 3 * 360.0 / s.columns, 1e-3);
  EXPECT_EQ(r.merged, 0u);
  // A width given is used; without ring numbers (regressed), the default.
  CloudScanOptions given;
  given.resolution_deg = 0.4;
  EXPECT_EQ(cloud_to_scan(c.fields(), given, out).resolution_deg, 0.4);
  CloudScanOptions beams;
  beams.rings = 32;
  EXPECT_EQ(cloud_to_scan(c.fields(false), beams, out).resolution_deg, kDefaultColumnWidthDeg);
  // A negative or NaN width is refused, not taken for "the cloud's own".
  given.resolution_deg = -0.2;
  EXPECT_THROW(cloud_to_scan(c.fields(), given, out), CloudError);
  given.resolution_deg = kNaN;
  EXPECT_THROW(cloud_to_scan(c.fields(), given, out), CloudError);
}

TEST(CloudScan, TheFartherEchoOfADualReturnFiringIsToldFromAColumnTooCoarse) {
  // Ring 0: two echoes of one firing (the same direction, 5 and 6 m), a firing 0.05 degrees on
  // (the same 0.2 degree column) and a point 0.5 degrees above the first (the same ring here, not
  // the same direction); a point elsewhere.
  Columns c;
  c.add(5.0, 0.0, 0.0, 10, 0, 0, 0, 0);
  c.add(6.0, 0.0, 0.0, 10, 0, 0, 0, 0);
  c.add(7.0, -7.0 * std::tan(0.05 * std::numbers::pi / 180.0), 0.0, 10, 0, 0, 0, 0);
  c.add(6.0, 0.0, 6.0 * std::tan(0.5 * std::numbers::pi / 180.0), 10, 0, 0, 0, 0);
  c.add(0.0, -5.0, 0.0, 10, 0, 90, 0, 0);
  c.width = c.x.size();
  Scan out;
  CloudScanOptions o;
  o.resolution_deg = 0.2;
  o.rings = 1;
  const auto report = cloud_to_scan(c.fields(), o, out);
  EXPECT_EQ(report.points, 2u);
  EXPECT_EQ(report.merged, 3u);
  EXPECT_EQ(report.echoes, 1u);
  EXPECT_FLOAT_EQ(out.range[out.at(0, 0, 0)], 5.0f);  // the nearer echo kept
  // The nearer echo after the farther: still one echo, the nearer kept.
  Columns swapped = c;
  std::swap(swapped.x[0], swapped.x[1]);
  EXPECT_EQ(cloud_to_scan(swapped.fields(), o, out).echoes, 1u);
  EXPECT_FLOAT_EQ(out.range[out.at(0, 0, 0)], 5.0f);
  // Rings regressed (one beam): the same accounting.
  const auto regressed = cloud_to_scan(c.fields(false), o, out);
  EXPECT_TRUE(regressed.regressed);
  EXPECT_EQ(regressed.merged, 3u);
  EXPECT_EQ(regressed.echoes, 1u);
}

TEST(CloudScan, WithoutRingNumbersRingsAreRegressed) {
  const Scan s = tag_scene();
  const Columns c = unorganised(s);
  Scan out;
  CloudScanOptions o;
  o.elevations_deg = test::vlp32c().elevations_deg;
  const auto report = cloud_to_scan(c.fields(false), o, out);
  EXPECT_TRUE(report.regressed);
  EXPECT_EQ(out.rings, 32);
  EXPECT_EQ(detect(out).size(), 1u);
  // A ring count instead of the elevations.
  CloudScanOptions by_count;
  by_count.rings = 32;
  EXPECT_TRUE(cloud_to_scan(c.fields(false), by_count, out).regressed);
  // Neither: one clear error saying what to give, of its own type (the tools add their options).
  try {
    cloud_to_scan(c.fields(false), {}, out);
    FAIL() << "expected NoRingFieldError";
  } catch (const NoRingFieldError& e) {
    EXPECT_NE(std::string(e.what()).find("no ring field"), std::string::npos) << e.what();
  }
}

TEST(CloudScan, AMissingIntensityIsAClearErrorNotZeroTags) {
  const Columns c = unorganised(tag_scene());
  Scan out;
  try {
    cloud_to_scan(c.fields(true, false), {}, out);
    FAIL() << "expected CloudError";
  } catch (const CloudError& e) {
    EXPECT_NE(std::string(e.what()).find("no intensity field"), std::string::npos) << e.what();
    // Not the error a ring count or a model would mend.
    EXPECT_EQ(dynamic_cast<const NoRingFieldError*>(&e), nullptr);
  }
}

TEST(CloudScan, IntensitiesOfZeroToOneAreScaled) {
  const Scan s = tag_scene();
  Columns c = unorganised(s);
  for (double& i : c.intensity) i /= 255.0;
  Scan out;
  const auto report = cloud_to_scan(c.fields(), {}, out);
  EXPECT_TRUE(report.intensity_scaled);
  ASSERT_EQ(detect(out).size(), 1u);
  // 0..255 clouds are left as they are.
  EXPECT_FALSE(cloud_to_scan(unorganised(s).fields(), {}, out).intensity_scaled);
}

TEST(CloudScan, BadPointsAreCountedAndNaNIsNoReturn) {
  Columns c;
  const double inf = std::numeric_limits<double>::infinity();
  c.add(1, 0, 0, 50, 0, 0, 0, 1);
  c.add(kNaN, kNaN, kNaN, 0, 0, 0, 0, 0);  // no return: not counted
  c.add(inf, 0, 0, 50, 0, 0, 0, 1);        // skipped coordinate
  c.add(1e300, 0, 0, 50, 0, 0, 0, 1);      // beyond a float
  c.add(0, 1, 0, 50, 1.5, 0, 0, 1);        // ring not whole
  c.add(0, 1, 0, 50, 300, 0, 0, 1);        // ring out of range
  c.add(0, -1, 0, kNaN, 1, 270, 0, 1);     // NaN intensity reads 0
  c.width = c.x.size();
  Scan out;
  const auto report = cloud_to_scan(c.fields(), {}, out);
  EXPECT_EQ(report.skipped_coordinates, 2u);
  EXPECT_EQ(report.skipped_rings, 2u);
  EXPECT_EQ(report.points, 2u);
  EXPECT_EQ(out.rings, 2);
  // Sizes that disagree.
  c.height = 2;
  EXPECT_THROW(cloud_to_scan(c.fields(), {}, out), CloudError);
  c.height = 1;
  Columns short_y = c;
  short_y.y.pop_back();
  EXPECT_THROW(cloud_to_scan(short_y.fields(), {}, out), CloudError);
  // No point with a usable ring.
  Columns no_ring;
  no_ring.add(1, 0, 0, 5, -1, 0, 0, 1);
  no_ring.width = 1;
  EXPECT_THROW(cloud_to_scan(no_ring.fields(), {}, out), CloudError);
}

// A PCD file's columns by name (the first of a repeated name; unknown names ignored), and the
// options: a model's elevations give the rings, else `rings` counts only without ring numbers.
TEST(CloudScan, FieldsByNameAndOptionsForAModelOrNot) {
  const std::vector<std::string> names = {"x", "y", "z", "intensity", "curvature", "x"};
  const std::vector<std::vector<double>> columns = {{1}, {2}, {3}, {4}, {5}, {6}};
  const CloudFields f = cloud_fields_by_name(names, columns, 1, 1);
  EXPECT_EQ(f.x.data(), columns[0].data());
  EXPECT_EQ(f.intensity.data(), columns[3].data());
  EXPECT_TRUE(f.ring.empty() && f.azimuth_deg.empty() && f.time_s.empty());
  EXPECT_TRUE(f.return_type.empty());
  EXPECT_EQ(f.width, 1u);
  EXPECT_EQ(f.height, 1u);

  const CloudScanOptions model = cloud_scan_options(f, {-15, 15}, 7, 0.4);
  EXPECT_EQ(model.rings, 2);
  EXPECT_EQ(model.elevations_deg, (std::vector<double>{-15, 15}));
  EXPECT_EQ(model.resolution_deg, 0.4);
  EXPECT_EQ(cloud_scan_options(f, {}, 7, 0.2).rings, 7);
  CloudFields with_rings = f;
  with_rings.ring = f.x;
  EXPECT_EQ(cloud_scan_options(with_rings, {}, 7, 0.2).rings, 0);
  EXPECT_TRUE(cloud_scan_options(with_rings, {}, 7, 0.2).elevations_deg.empty());
}

TEST(CloudScan, ARingFieldWhoseRingsAreNotLevelIsSetAsideWhenBeamsAreGiven) {
  const Scan s = tag_scene();
  Columns level = unorganised(s);
  // Livox's line numbers: four lines, each through every eighth beam (every elevation).
  Columns lines = level;
  for (double& r : lines.ring) r = std::fmod(r, 4.0);
  Scan out;
  CloudScanReport r =
      cloud_to_scan(level.fields(), cloud_scan_options(level.fields(), {}, 32, 0.2), out);
  EXPECT_FALSE(r.rings_not_level);
  EXPECT_FALSE(r.regressed);
  // Kept as they are without beams to regress (reported), regressed with them.
  r = cloud_to_scan(lines.fields(), cloud_scan_options(lines.fields(), {}, 0, 0.2), out);
  EXPECT_TRUE(r.rings_not_level);
  EXPECT_FALSE(r.regressed);
  EXPECT_EQ(out.rings, 4);
  r = cloud_to_scan(lines.fields(), cloud_scan_options(lines.fields(), {}, 32, 0.2), out);
  EXPECT_TRUE(r.rings_not_level);
  EXPECT_TRUE(r.regressed);
  EXPECT_EQ(out.rings, 32);
  EXPECT_EQ(detect(out).size(), 1u);
}

TEST(CloudScan, RingsOfBeamsThatStartOffTheAxisAreLevel) {
  // A spinning sensor whose beams leave 4 cm off its axis and 5 cm above its origin (as RoboSense's
  // do): seen from the cloud's origin, a ring's points 0.3 to 1.2 m away sit up to 10 degrees off
  // its elevation, those at 10 m a few tenths. Its ring field is a sensor's rings, not Livox's
  // lines: kept, not regressed, whatever the beams given.
  auto cloud = [](bool far) {
    Columns c;
    for (int ring = 0; ring < 16; ++ring)
      for (int col = 0; col < 900; ++col) {
        const double e = (-15.0 + 2.0 * ring) * std::numbers::pi / 180.0;
        const double a = col * 0.4 * std::numbers::pi / 180.0;
        const double r = far && col % 2 == 0 ? 10.0 : 0.3 + 0.9 * (col % 7) / 6.0;
        c.add(0.04 * std::cos(a) + r * std::cos(e) * std::cos(a),
              0.04 * std::sin(a) + r * std::cos(e) * std::sin(a), 0.05 + r * std::sin(e), 100, ring,
              kNaN, 0, 1);
      }
    c.width = c.x.size();
    return c;
  };
  const Columns sensor = cloud(true);
  Scan out;
  CloudScanReport r =
      cloud_to_scan(sensor.fields(), cloud_scan_options(sensor.fields(), {}, 16, 0.4), out);
  EXPECT_FALSE(r.rings_not_level);
  EXPECT_FALSE(r.regressed);
  // With no point 3 m away or farther, every point is read, and these rings are too wide.
  const Columns near = cloud(false);
  r = cloud_to_scan(near.fields(), cloud_scan_options(near.fields(), {}, 0, 0.4), out);
  EXPECT_TRUE(r.rings_not_level);
}

}  // namespace
}  // namespace lidartag::detector
