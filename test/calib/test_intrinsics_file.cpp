#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "lidartag/calib/intrinsics_file.hpp"

namespace lidartag::calib {
namespace {

// What ROS camera_calibration writes (ost.yaml).
const char* kRosPlumbBob = R"(image_width: 1280
image_height: 720
camera_name: front
camera_matrix:
  rows: 3
  cols: 3
  data: [900.5, 0, 639.25, 0, 901.5, 359.75, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.28, 0.09, 0.001, -0.0007, -0.012]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [900.5, 0, 639.25, 0, 0, 901.5, 359.75, 0, 0, 0, 1, 0]
)";

// What cv::FileStorage writes: the %YAML:1.0 line, !!opencv-matrix nodes, "0." numbers.
const char* kOpenCv = R"(%YAML:1.0
---
image_width: 1280
image_height: 720
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 9.0050000000000000e+02, 0., 6.3925000000000000e+02, 0.,
       9.0150000000000000e+02, 3.5975000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -2.8e-01, 9.0e-02, 1.0e-03, -7.0e-04, -1.2e-02 ]
)";

void expect_plumb_bob(const CameraModel& c) {
  EXPECT_EQ(c.width, 1280);
  EXPECT_EQ(c.height, 720);
  EXPECT_DOUBLE_EQ(c.fx, 900.5);
  EXPECT_DOUBLE_EQ(c.fy, 901.5);
  EXPECT_DOUBLE_EQ(c.cx, 639.25);
  EXPECT_DOUBLE_EQ(c.cy, 359.75);
  EXPECT_EQ(c.distortion, Distortion::kPlumbBob);
  EXPECT_DOUBLE_EQ(c.d[0], -0.28);
  EXPECT_DOUBLE_EQ(c.d[2], 0.001);
  EXPECT_DOUBLE_EQ(c.d[4], -0.012);
}

// The key an error names (or "" when it did not throw IntrinsicsFileError).
std::string error_key(const std::string& text) {
  try {
    parse_intrinsics(text, "test.yaml");
  } catch (const IntrinsicsFileError& e) {
    EXPECT_NE(std::string(e.what()).find("test.yaml"), std::string::npos) << e.what();
    return e.key();
  }
  return "(no error)";
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

TEST(IntrinsicsFile, ReadsRosCameraInfo) {
  expect_plumb_bob(parse_intrinsics(kRosPlumbBob));
}

TEST(IntrinsicsFile, ReadsOpenCvFileStorageWithItsDirectiveLine) {
  expect_plumb_bob(parse_intrinsics(kOpenCv));
  // The same with OpenCV's short keys K and D and 8 coefficients whose extra ones are zero.
  std::string short_keys = replace(kOpenCv, "camera_matrix:", "K:");
  short_keys = replace(short_keys, "distortion_coefficients:", "D:");
  short_keys = replace(short_keys, "cols: 5", "cols: 8");
  short_keys = replace(short_keys, "-1.2e-02 ]", "-1.2e-02, 0., 0., 0. ]");
  expect_plumb_bob(parse_intrinsics(short_keys));
}

TEST(IntrinsicsFile, ReadsEquidistantFromRosAndFromAnOpenCvFisheyeFlag) {
  std::string ros = replace(kRosPlumbBob, "plumb_bob", "equidistant");
  ros = replace(ros, "cols: 5\n  data: [-0.28, 0.09, 0.001, -0.0007, -0.012]",
                "cols: 4\n  data: [-0.013, 0.021, -0.011, 0.002]");
  const CameraModel a = parse_intrinsics(ros);
  EXPECT_EQ(a.distortion, Distortion::kEquidistant);
  EXPECT_DOUBLE_EQ(a.d[0], -0.013);
  EXPECT_DOUBLE_EQ(a.d[3], 0.002);

  std::string cv = replace(kOpenCv, "image_width", "fisheye: 1\nimage_width");
  cv = replace(cv, "cols: 5", "cols: 4");
  cv = replace(cv, "-7.0e-04, -1.2e-02 ]", "-7.0e-04 ]");
  const CameraModel b = parse_intrinsics(cv);
  EXPECT_EQ(b.distortion, Distortion::kEquidistant);
  EXPECT_DOUBLE_EQ(b.d[3], -7.0e-04);
  // A fisheye flag with 5 coefficients is refused, naming the coefficients' key.
  EXPECT_EQ(error_key(replace(kOpenCv, "image_width", "fisheye: 1\nimage_width")),
            "distortion_coefficients");
}

TEST(IntrinsicsFile, NoCoefficientsIsAPinhole) {
  std::string s = replace(kRosPlumbBob, "distortion_model: plumb_bob\n", "");
  s = replace(s, "data: [-0.28, 0.09, 0.001, -0.0007, -0.012]", "data: [0, 0, 0, 0, 0]");
  EXPECT_EQ(parse_intrinsics(s).distortion, Distortion::kNone);
}

TEST(IntrinsicsFile, RefusesRationalPolynomialClearly) {
  const std::string s = replace(kRosPlumbBob, "plumb_bob", "rational_polynomial");
  try {
    parse_intrinsics(s, "cam.yaml");
    FAIL() << "accepted rational_polynomial";
  } catch (const IntrinsicsFileError& e) {
    EXPECT_EQ(e.key(), "distortion_model");
    EXPECT_NE(std::string(e.what()).find("rational_polynomial"), std::string::npos) << e.what();
  }
  // OpenCV's 8 coefficients with k4 set: refused, naming the coefficients.
  std::string cv = replace(kOpenCv, "cols: 5", "cols: 8");
  cv = replace(cv, "-1.2e-02 ]", "-1.2e-02, 0.5, 0., 0. ]");
  EXPECT_EQ(error_key(cv), "distortion_coefficients");
}

TEST(IntrinsicsFile, BadFilesNameTheKey) {
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "image_width: 1280\n", "")), "image_width");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "image_height: 720", "image_height: wide")),
            "image_height");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "camera_matrix:", "camera_matrx:")), "camera_matrix");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "639.25, 0, 901.5", "639.25, 0")), "camera_matrix");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "359.75, 0, 0, 1]", "359.75, 0, 0, x]")),
            "camera_matrix.data[8]");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "distortion_model: plumb_bob", "distortion_model: x")),
            "distortion_model");
  EXPECT_EQ(error_key(replace(kRosPlumbBob, "cols: 5", "cols: 4")), "distortion_coefficients");
  EXPECT_EQ(error_key(replace(kOpenCv, "dt: d", "dt: u")), "camera_matrix.dt");
  EXPECT_EQ(error_key("[1, 2, 3]"), "");
  EXPECT_EQ(error_key("a: [1, 2"), "");
  EXPECT_EQ(error_key(""), "");
  // A matrix that CameraModel::check() refuses (principal point outside the image).
  const std::string outside = replace(kRosPlumbBob, "639.25, 0, 901.5", "1639.25, 0, 901.5");
  try {
    parse_intrinsics(outside, "x.yaml");
    FAIL();
  } catch (const IntrinsicsFileError& e) {
    EXPECT_NE(std::string(e.what()).find("principal point"), std::string::npos) << e.what();
  }
}

// Truncated and corrupted files: a parse or an IntrinsicsFileError, never another exception.
TEST(IntrinsicsFile, TruncatedOrCorruptFilesGiveItsErrorOnly) {
  int parsed = 0, refused = 0;
  for (const std::string& full : {std::string(kRosPlumbBob), std::string(kOpenCv)}) {
    for (std::size_t n = 0; n <= full.size(); ++n) {
      for (int corrupt = 0; corrupt < 2; ++corrupt) {
        std::string text = full.substr(0, n);
        if (corrupt && n > 0) text[n / 2] = static_cast<char>(text[n / 2] ^ 0x5a);
        try {
          parse_intrinsics(text, "cut.yaml");
          ++parsed;
        } catch (const IntrinsicsFileError&) {
          ++refused;
        }
      }
    }
  }
  // Every byte of the whole files flipped in turn, three ways.
  for (const std::string& full : {std::string(kRosPlumbBob), std::string(kOpenCv)})
    for (std::size_t i = 0; i < full.size(); ++i)
      for (const char mask : {'\x01', '\x20', '\x5a'}) {
        std::string text = full;
        text[i] = static_cast<char>(text[i] ^ mask);
        try {
          parse_intrinsics(text, "flip.yaml");
          ++parsed;
        } catch (const IntrinsicsFileError&) {
          ++refused;
        }
      }
  EXPECT_GT(parsed, 0);
  EXPECT_GT(refused, 0);
}

TEST(IntrinsicsFile, LoadsAFileAndNamesItWhenMissing) {
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("lidartag_intrinsics_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "camera.yaml").string();
  { std::ofstream(path) << kOpenCv; }
  expect_plumb_bob(load_intrinsics(path));
  try {
    load_intrinsics((dir / "missing.yaml").string());
    FAIL();
  } catch (const IntrinsicsFileError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml"), std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace lidartag::calib
