#include "lidartag/driver/velodyne/io/calibration_file.hpp"

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

#include "io/veloview_xml.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"

namespace lidartag::velodyne {
namespace {

class CalibrationFile : public ::testing::Test {
 protected:
  std::string write(const std::string& text, const std::string& extension = ".yaml") {
    if (!path_.empty()) std::filesystem::remove(path_);
    path_ = (std::filesystem::temp_directory_path() /
             ("lidartag_calib_" + std::to_string(::getpid()) + extension))
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
      load_calibration_file(write(text, text.starts_with("<") ? ".xml" : ".yaml"), model);
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

// `c` with zero-filled lasers appended up to `total` entries (the 64-entry files of 32-laser
// sensors).
Calibration padded(Calibration c, int total) {
  c.lasers.resize(static_cast<size_t>(total), LaserCorrection{});
  return c;
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

TEST_F(CalibrationFile, VeloViewXmlFilesOfTheBuiltinTablesLoadBackEqual) {
  for (Model model : all_models()) {
    SCOPED_TRACE(std::string(model_spec(model).name));
    Calibration builtin = Calibration::builtin(model);
    // Offsets of every kind, so that the centimetre conversion is exercised.
    builtin.lasers[1].horizontal_offset_m = 0.0259;
    builtin.lasers[2].distance_offset_m = 1.3670362;
    const std::string text = test::veloview_xml(builtin);
    EXPECT_EQ(calibration_format(write(text, ".xml")), CalibrationFormat::kVeloViewXml);
    expect_same(load_calibration_file(path_, model), builtin);
    // The format comes from the contents, not the name.
    expect_same(load_calibration_file(write(text, ".yaml"), model), builtin);
    EXPECT_EQ(calibration_format(write(yaml_of(builtin), ".xml")), CalibrationFormat::kRosYaml);
    expect_same(load_calibration_file(path_, model), builtin);
  }
}

TEST_F(CalibrationFile, SixtyFourEntryFilesOfThirtyTwoLaserSensorsLoad) {
  for (Model model : {Model::kVLP32C, Model::kHDL32E}) {
    SCOPED_TRACE(std::string(model_spec(model).name));
    const Calibration builtin = Calibration::builtin(model);
    const Calibration file = padded(builtin, 64);
    // ros-drivers/Autoware: num_lasers 32 with 64 entries; the Apollo variant says 64.
    std::string text = yaml_of(file);
    ASSERT_NE(text.find("num_lasers: 64"), std::string::npos);
    expect_same(load_calibration_file(write(text), model), builtin);
    text.replace(text.find("num_lasers: 64"), 14, "num_lasers: 32");
    expect_same(load_calibration_file(write(text), model), builtin);
    text.replace(text.find("num_lasers: 32"), 14, "");
    expect_same(load_calibration_file(write(text), model), builtin);
    // VeloView: 64 points, 32 zero-filled, count 64 (or 32).
    expect_same(load_calibration_file(write(test::veloview_xml(file), ".xml"), model), builtin);
    expect_same(load_calibration_file(write(test::veloview_xml(file, 32), ".xml"), model), builtin);
  }
  // The same for a 16-laser file padded to 32 entries.
  const Calibration vlp16 = Calibration::builtin(Model::kVLP16);
  expect_same(load_calibration_file(write(yaml_of(padded(vlp16, 32))), Model::kVLP16), vlp16);
}

TEST_F(CalibrationFile, ANonZeroEntryBeyondTheModelsLasersIsNamed) {
  const Calibration file = padded(Calibration::builtin(Model::kVLP32C), 64);
  for (const bool xml : {false, true}) {
    SCOPED_TRACE(xml ? "xml" : "yaml");
    // Lasers 45 and 40 non-zero (40 listed first): the error names laser 40's first value.
    Calibration bad = file;
    bad.lasers[45].azimuth_offset_deg = 2.0;
    bad.lasers[40].vertical_offset_m = 0.25;
    bad.lasers[40].elevation_deg = 3.0;
    const auto e = error_for(xml ? test::veloview_xml(bad) : yaml_of(bad), Model::kVLP32C);
    // In file order: the YAML writer lists vert_offset_correction last, the XML writer lists
    // vertCorrection_ before vertOffsetCorrection_.
    EXPECT_EQ(e.key(), xml ? "points_[40].vertCorrection_" : "lasers[40].vert_correction");
    EXPECT_NE(std::string(e.what()).find("beyond the 32 lasers"), std::string::npos) << e.what();
    // The value as written: degrees in XML, radians in YAML.
    EXPECT_NE(std::string(e.what()).find(xml ? "must be all zero, found 3"
                                             : "must be all zero, found 0.05235"),
              std::string::npos)
        << e.what();
  }
  // A true 64-laser file (HDL-64E style, every entry calibrated) is refused for a 32-laser model.
  Calibration hdl64 = padded(Calibration::builtin(Model::kVLP32C), 64);
  for (size_t i = 32; i < 64; ++i)
    hdl64.lasers[i].elevation_deg = -24.0 + 0.5 * (static_cast<double>(i) - 32.0);
  EXPECT_EQ(error_for(yaml_of(hdl64), Model::kVLP32C).key(), "lasers[32].vert_correction");
  // A declared count that is neither the model's nor the number listed.
  std::string text = yaml_of(file);
  text.replace(text.find("num_lasers: 64"), 14, "num_lasers: 48");
  EXPECT_EQ(error_for(text, Model::kVLP32C).key(), "num_lasers");
  EXPECT_EQ(error_for(test::veloview_xml(file, 40), Model::kVLP32C).key(), "points_.count");
}

// The text of `xml` with the first `from` after `after` replaced by `to`.
std::string edited(std::string xml, const std::string& after, const std::string& from,
                   const std::string& to) {
  const size_t at = xml.find(from, xml.find(after));
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? xml : xml.replace(at, from.size(), to);
}

// `xml` with the first element `from` after `after` renamed `to` (both of its tags).
std::string renamed(const std::string& xml, const std::string& after, const std::string& from,
                    const std::string& to) {
  return edited(edited(xml, after, "<" + from, "<" + to), "<" + to, "</" + from + ">",
                "</" + to + ">");
}

TEST_F(CalibrationFile, BadVeloViewFilesNameTheKey) {
  const std::string good = test::veloview_xml(Calibration::builtin(Model::kVLP16));
  ASSERT_NO_THROW(load_calibration_file(write(good, ".xml"), Model::kVLP16));
  struct Case {
    std::string text, key, words;
  };
  const std::string laser3 = "<id_>3</id_>";
  const std::vector<Case> cases = {
      {good.substr(0, good.size() / 2), "", "not valid XML"},
      {"<?xml version=\"1.0\"?><boost_serialization><nothing/></boost_serialization>", "DB",
       "not a VeloView calibration"},
      {renamed(good, "<DB", "points_", "pointz_"), "points_", "missing"},
      {renamed(good, laser3, "vertCorrection_", "vertCorrectio_"), "points_[3].vertCorrection_",
       "missing"},
      {edited(good, laser3, "<rotCorrection_>0", "<rotCorrection_>abc"),
       "points_[3].rotCorrection_", "not a number"},
      {edited(good, laser3, "</distCorrection_>", "x</distCorrection_>"),
       "points_[3].distCorrection_", "not a number"},
      {edited(good, laser3, "<focalSlope_>0", "<focalSlope_>nan"), "points_[3].focalSlope_",
       "not a number"},
      {edited(good, laser3, "<vertCorrection_>", "<vertCorrection_>10"),
       "points_[3].vertCorrection_", "degrees expected"},  // 3 degrees -> 103
      {edited(good, laser3, "<horizOffsetCorrection_>0", "<horizOffsetCorrection_>2500"),
       "points_[3].horizOffsetCorrection_", "centimetres expected"},
      {edited(good, laser3, "<id_>3</id_>", "<id_>2</id_>"), "points_[3].id_", "duplicate"},
      {edited(good, laser3, "<id_>3</id_>", "<id_>16</id_>"), "points_[3].id_", "outside 0..15"},
      {edited(good, laser3, "<id_>3</id_>", "<id_>3.5</id_>"), "points_[3].id_", "integer"},
      {edited(good, "<points_", "<count>16</count>", "<count>15</count>"), "points_.count",
       "15 declared but 16"},
      {edited(good, "<DB", "<distLSB_>", "<distLSB_>two"), "distLSB_", "not a number"},
      {renamed(good, "<id_>2</id_>", "px", "qx"), "points_[3].px", "missing"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.key + ": " + c.words);
    const auto e = error_for(c.text);
    EXPECT_EQ(e.key(), c.key);
    EXPECT_NE(std::string(e.what()).find(c.words), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path_), std::string::npos) << e.what();
  }
  // Too few points for the model.
  EXPECT_EQ(error_for(good, Model::kVLP32C).key(), "points_");
}

TEST_F(CalibrationFile, WhiteSpaceAroundXmlNumbersIsAccepted) {
  // VeloView's own files hold values such as "<vertCorrection_>0.000 </vertCorrection_>".
  Calibration c = Calibration::builtin(Model::kVLP16);
  std::string text = test::veloview_xml(c);
  text = edited(text, "<id_>5</id_>", "</vertCorrection_>", " \n\t</vertCorrection_>");
  text = edited(text, "<id_>6</id_>", "<rotCorrection_>", "<rotCorrection_> +");
  expect_same(load_calibration_file(write(text, ".xml"), Model::kVLP16), c);
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
  for (const bool xml : {false, true}) {
    SCOPED_TRACE(xml ? "xml" : "yaml");
    const Calibration builtin = Calibration::builtin(Model::kVLP16);
    const std::string good = xml ? test::veloview_xml(builtin) : yaml_of(builtin);
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
            text[at] = (xml ? "-.e<>/_ \n9x0" : "-.e:,{}[] \n9")[rng() % 12];
            break;
          case 2:  // a value replaced by a number of any magnitude
            if (const size_t colon = text.find(xml ? ">" : ": ", at); colon != std::string::npos) {
              const size_t from = colon + (xml ? 1 : 2),
                           to = text.find_first_of(xml ? "<" : ",}\n", from);
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
        c = load_calibration_file(write(text, xml ? ".xml" : ".yaml"), Model::kVLP16);
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
}

}  // namespace
}  // namespace lidartag::velodyne
