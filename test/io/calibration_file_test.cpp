#include "lidartag/driver/io/calibration_file.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>

#include "lidartag/driver/decoder.hpp"

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

// The value of `key` of laser `id` replaced by `value`.
std::string with_value(std::string text, int id, const std::string& key, const std::string& value) {
  const size_t line = text.rfind('\n', text.find("laser_id: " + std::to_string(id) + ","));
  size_t at = text.find(key + ":", line);
  while (text[at - 1] != ' ' && text[at - 1] != '{') at = text.find(key + ":", at + 1);
  const size_t from = text.find(':', at) + 2;
  text.replace(from, text.find_first_of(",}", from) - from, value);
  return text;
}

TEST_F(CalibrationFile, ImplausibleCorrectionsAreRejectedNamingTheKey) {
  const std::string text = yaml_of(Calibration::builtin(Model::kVLP16));
  struct Case {
    const char* key;
    const char* value;
  };
  // Finite but absurd: each used to decode into NaN (inf - inf) or kilometre-away points.
  for (const Case& c : {Case{"rot_correction", "1e300"}, Case{"rot_correction", "-7.0"},
                        Case{"dist_correction", "1e39"}, Case{"dist_correction", "-120.5"},
                        Case{"vert_offset_correction", "1e30"},
                        Case{"horiz_offset_correction", "50"}, Case{"rot_correction", ".nan"},
                        Case{"dist_correction", ".inf"}, Case{"vert_correction", "-.inf"}}) {
    SCOPED_TRACE(std::string(c.key) + " = " + c.value);
    const auto e = error_for(with_value(text, 3, c.key, c.value));
    EXPECT_EQ(e.key(), std::string("lasers[3].") + c.key);
  }
  // The largest plausible values still load.
  std::string edge = with_value(text, 3, "rot_correction", "3.14");
  edge = with_value(edge, 3, "dist_correction", "9.5");
  edge = with_value(edge, 3, "horiz_offset_correction", "-9.5");
  EXPECT_NO_THROW(load_calibration_file(write(edge), Model::kVLP16));
}

// A VLP-16 strongest-return packet with every distance `raw` and azimuths from `az0`.
std::vector<uint8_t> vlp16_packet(uint16_t raw, uint16_t az0) {
  std::vector<uint8_t> p(kDataPacketSize, 0);
  for (size_t b = 0; b < 12; ++b) {
    uint8_t* blk = p.data() + b * kBlockSize;
    write_u16(blk, kBankFlags[0]);
    write_u16(blk + 2, static_cast<uint16_t>((az0 + 40 * b) % 36000));
    for (size_t ch = 0; ch < 32; ++ch) {
      write_u16(blk + 4 + 3 * ch, static_cast<uint16_t>(raw + 97 * ch));
      blk[4 + 3 * ch + 2] = 100;
    }
  }
  p[kReturnModeOffset] = 0x37;
  p[kProductIdOffset] = 0x22;
  return p;
}

TEST_F(CalibrationFile, RandomlyDamagedFilesLoadSaneOrFailWithCalibrationError) {
  const std::string good = yaml_of(Calibration::builtin(Model::kVLP16));
  std::mt19937 rng(21);
  int loaded = 0, refused = 0;
  for (int k = 0; k < 300; ++k) {
    std::string text = good;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits; ++e) {
      const size_t at = rng() % text.size();
      switch (rng() % 4) {
        case 0:
          text[at] = static_cast<char>('0' + rng() % 10);
          break;
        case 1:
          text[at] = "-.e:,{}[] \n9"[rng() % 12];
          break;
        case 2:  // a value replaced by a number of any magnitude
          if (const size_t colon = text.find(": ", at); colon != std::string::npos) {
            const size_t from = colon + 2, to = text.find_first_of(",}\n", from);
            text.replace(from, to == std::string::npos ? std::string::npos : to - from,
                         (rng() % 2 ? "-" : "") + std::to_string(rng() % 10) + "e" +
                             std::to_string(static_cast<int>(rng() % 80) - 20));
          }
          break;
        default:
          text.resize(at);
      }
    }
    Calibration c;
    try {
      c = load_calibration_file(write(text), Model::kVLP16);
    } catch (const CalibrationError& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find(path_), std::string::npos) << e.what();
      continue;
    }
    ++loaded;
    // Whatever loaded decodes into finite points, azimuths in [0, 360).
    Decoder d(c);
    SensorClock clock;
    DecodedPacket out;
    for (uint16_t raw : {uint16_t{1}, uint16_t{500}, uint16_t{40000}, uint16_t{65535}}) {
      ASSERT_EQ(d.decode(vlp16_packet(raw, static_cast<uint16_t>(rng() % 36000)), clock, 0, out),
                DecodeStatus::kOk);
      for (int col = 0; col < out.columns; ++col)
        for (int ring = 0; ring < out.rings; ++ring) {
          const auto i = static_cast<size_t>(out.at(0, col, ring));
          ASSERT_TRUE(std::isfinite(out.x[i]) && std::isfinite(out.y[i]) &&
                      std::isfinite(out.z[i]) && std::isfinite(out.range[i]))
              << "mutant " << k;
          ASSERT_TRUE(out.azimuth_deg[i] >= 0.0f && out.azimuth_deg[i] < 360.0f)
              << "mutant " << k << ": " << out.azimuth_deg[i];
        }
    }
  }
  EXPECT_GT(loaded, 10);
  EXPECT_GT(refused, 10);
}

}  // namespace
}  // namespace lidartag::velodyne
