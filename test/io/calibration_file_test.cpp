#include "lidartag/driver/io/calibration_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

namespace lidartag::velodyne {
namespace {

class CalibrationFile : public ::testing::Test {
 protected:
  std::string write(const std::string& text) {
    path_ = (std::filesystem::temp_directory_path() /
             ("lidartag_calib_" + std::to_string(::getpid()) + ".yaml"))
                .string();
    std::ofstream(path_) << text;
    return path_;
  }
  void TearDown() override {
    if (!path_.empty()) std::filesystem::remove(path_);
  }
  // The error for `text` loaded as `model`; fails the test when none is thrown.
  CalibrationError error_for(const std::string& text, Model model = Model::kVLP16) {
    try {
      load_calibration_file(write(text), model);
    } catch (const CalibrationError& e) {
      return e;
    }
    ADD_FAILURE() << "expected CalibrationError";
    return CalibrationError("", "", "");
  }
  std::string path_;
};

// A ros-drivers style file of `c`, angles in radians, with `edit` applied to the laser lines.
std::string yaml_of(const Calibration& c, int skip_laser = -1, int duplicate_id = -1) {
  std::ostringstream out;
  out.precision(17);
  out << "lasers:\n";
  int n = 0;
  for (size_t i = 0; i < c.lasers.size(); ++i) {
    if (static_cast<int>(i) == skip_laser) continue;
    const LaserCorrection& l = c.lasers[i];
    const int id = static_cast<int>(i) == duplicate_id ? 0 : static_cast<int>(i);
    out << "- {dist_correction: " << l.distance_offset_m
        << ", dist_correction_x: 0.0, dist_correction_y: 0.0, focal_distance: 0.0, focal_slope: "
           "0.0, horiz_offset_correction: "
        << l.horizontal_offset_m << ", laser_id: " << id << ", max_intensity: 255, min_intensity: 0"
        << ", rot_correction: " << l.azimuth_offset_deg * std::numbers::pi / 180.0
        << ", two_pt_correction_available: false, vert_correction: "
        << l.elevation_deg * std::numbers::pi / 180.0
        << ", vert_offset_correction: " << l.vertical_offset_m << "}\n";
    ++n;
  }
  out << "num_lasers: " << n << "\ndistance_resolution: " << c.distance_unit_m << "\n";
  return out.str();
}

void expect_same(const Calibration& a, const Calibration& b) {
  EXPECT_EQ(a.model, b.model);
  EXPECT_DOUBLE_EQ(a.distance_unit_m, b.distance_unit_m);
  ASSERT_EQ(a.lasers.size(), b.lasers.size());
  for (size_t i = 0; i < a.lasers.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_NEAR(a.lasers[i].elevation_deg, b.lasers[i].elevation_deg, 1e-12);
    EXPECT_NEAR(a.lasers[i].azimuth_offset_deg, b.lasers[i].azimuth_offset_deg, 1e-12);
    EXPECT_NEAR(a.lasers[i].vertical_offset_m, b.lasers[i].vertical_offset_m, 1e-15);
    EXPECT_NEAR(a.lasers[i].horizontal_offset_m, b.lasers[i].horizontal_offset_m, 1e-15);
    EXPECT_NEAR(a.lasers[i].distance_offset_m, b.lasers[i].distance_offset_m, 1e-15);
  }
  EXPECT_EQ(a.ring_of_laser, b.ring_of_laser);
}

TEST_F(CalibrationFile, FullFilesOfTheBuiltinTablesLoadBackEqual) {
  for (Model model : all_models()) {
    SCOPED_TRACE(std::string(model_spec(model).name));
    const Calibration builtin = Calibration::builtin(model);
    expect_same(load_calibration_file(write(yaml_of(builtin)), model), builtin);
  }
}

TEST_F(CalibrationFile, ConvertsRadiansAndReadsOffsets) {
  Calibration c = Calibration::builtin(Model::kVLP16);
  c.lasers[3].horizontal_offset_m = 0.0123;
  c.lasers[3].distance_offset_m = -0.05;
  c.lasers[3].azimuth_offset_deg = 1.5;
  // Swap two elevations: rings must follow the file, not the built-in table.
  std::swap(c.lasers[0].elevation_deg, c.lasers[15].elevation_deg);
  const Calibration loaded = load_calibration_file(write(yaml_of(c)), Model::kVLP16);
  EXPECT_NEAR(loaded.lasers[3].azimuth_offset_deg, 1.5, 1e-12);
  EXPECT_NEAR(loaded.lasers[3].horizontal_offset_m, 0.0123, 1e-15);
  EXPECT_NEAR(loaded.lasers[3].distance_offset_m, -0.05, 1e-15);
  EXPECT_NEAR(loaded.lasers[0].elevation_deg, 15.0, 1e-12);
  EXPECT_EQ(loaded.ring_of_laser[0], 15);
  EXPECT_EQ(loaded.ring_of_laser[15], 0);
}

TEST_F(CalibrationFile, OptionalKeysDefaultToZeroAndOrderDoesNotMatter) {
  std::ostringstream out;
  out << "lasers:\n";
  for (int id = 15; id >= 0; --id) {  // listed in reverse
    out << "  - laser_id: " << id
        << "\n    rot_correction: 0\n    vert_correction: " << (id - 8) * 0.01 << "\n";
  }
  const Calibration c = load_calibration_file(write(out.str()), Model::kVLP16);
  ASSERT_EQ(c.lasers.size(), 16u);
  EXPECT_NEAR(c.lasers[15].elevation_deg, 7 * 0.01 * 180.0 / std::numbers::pi, 1e-12);
  EXPECT_EQ(c.lasers[15].vertical_offset_m, 0.0);
  EXPECT_EQ(c.ring_of_laser[0], 0);
  EXPECT_EQ(c.ring_of_laser[15], 15);
  EXPECT_DOUBLE_EQ(c.distance_unit_m, model_spec(Model::kVLP16).distance_unit_m);
}

TEST_F(CalibrationFile, MissingFile) {
  try {
    load_calibration_file("/nonexistent-lidartag/VLP16.yaml", Model::kVLP16);
    FAIL() << "expected CalibrationError";
  } catch (const CalibrationError& e) {
    EXPECT_EQ(e.path(), "/nonexistent-lidartag/VLP16.yaml");
    EXPECT_NE(std::string(e.what()).find("/nonexistent-lidartag/VLP16.yaml"), std::string::npos);
  }
}

TEST_F(CalibrationFile, BadYaml) {
  const auto e = error_for("lasers: [ {laser_id: 0, \n  - broken");
  EXPECT_NE(std::string(e.what()).find("YAML"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find(path_), std::string::npos) << e.what();
}

TEST_F(CalibrationFile, WrongLaserCountForTheModel) {
  const auto e = error_for(yaml_of(Calibration::builtin(Model::kVLP16)), Model::kVLP32C);
  EXPECT_EQ(e.key(), "lasers");
  EXPECT_NE(std::string(e.what()).find("16 lasers"), std::string::npos) << e.what();
}

TEST_F(CalibrationFile, NumLasersDisagreeingWithTheList) {
  std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  text.replace(text.find("num_lasers: 16"), 14, "num_lasers: 32");
  EXPECT_EQ(error_for(text).key(), "num_lasers");
}

TEST_F(CalibrationFile, DuplicateLaserId) {
  const auto e = error_for(yaml_of(Calibration::builtin(Model::kVLP16), -1, 5));
  EXPECT_EQ(e.key(), "lasers[5].laser_id");
  EXPECT_NE(std::string(e.what()).find("duplicate"), std::string::npos) << e.what();
}

TEST_F(CalibrationFile, MissingLaser) {
  // 15 entries: laser 7 is absent.
  const auto e = error_for(yaml_of(Calibration::builtin(Model::kVLP16), 7));
  EXPECT_EQ(e.key(), "lasers");
}

TEST_F(CalibrationFile, LaserIdOutOfRange) {
  std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  text.replace(text.find("laser_id: 15"), 12, "laser_id: 16");
  EXPECT_EQ(error_for(text).key(), "lasers[15].laser_id");
}

TEST_F(CalibrationFile, NonNumericValuesNameTheKey) {
  std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  const size_t at = text.find("vert_offset_correction", text.find("laser_id: 2,"));
  text.replace(text.find(':', at) + 2, 1, "abc");  // "0.0097..." -> "abc.0097..." is not a number
  const auto e = error_for(text);
  EXPECT_EQ(e.key(), "lasers[2].vert_offset_correction");
  EXPECT_NE(std::string(e.what()).find("not a number"), std::string::npos) << e.what();

  std::string id_text = yaml_of(Calibration::builtin(Model::kVLP16));
  id_text.replace(id_text.find("laser_id: 4"), 11, "laser_id: 4.5");
  EXPECT_EQ(error_for(id_text).key(), "lasers[4].laser_id");
}

TEST_F(CalibrationFile, MissingRequiredKeys) {
  EXPECT_EQ(error_for("num_lasers: 16\n").key(), "lasers");
  std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  const size_t at = text.find("rot_correction", text.find("laser_id: 9,"));
  text.replace(at, 3, "xxx");  // rot_correction -> xxx_correction
  EXPECT_EQ(error_for(text).key(), "lasers[9].rot_correction");
}

TEST_F(CalibrationFile, DegreesInsteadOfRadiansAreRejected) {
  std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  const size_t at = text.find("vert_correction", text.find("laser_id: 0,"));
  const size_t value = text.find(':', at) + 2;
  text.replace(value, text.find(',', value) - value, "-15.0");
  EXPECT_EQ(error_for(text).key(), "lasers[0].vert_correction");
}

}  // namespace
}  // namespace lidartag::velodyne
