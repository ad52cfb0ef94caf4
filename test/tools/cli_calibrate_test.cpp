// `lidartag calibrate` end to end on the simulator's calibration series: a VLP-32C and a 640 x 360
// plumb-bob camera with a hidden extrinsic, one tag36h11 in six poses; the command finds the
// extrinsic from the images and captures alone. Then bad input: the rest is still used.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "run_tool.hpp"

namespace lidartag::testing {
namespace {

namespace fs = std::filesystem;

// The hidden extrinsic: the camera looking along the LiDAR's +x, turned by about 2.6 degrees,
// 0.1 m aside.
const Eigen::Quaterniond kTruthRotation(0.481240400, 0.500957013, -0.511747708, 0.505533414);
const Eigen::Vector3d kTruthTranslation(0.1, -0.05, -0.08);

class CliCalibrate : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("lidartag_calibrate_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream scene(dir_ / "calib.yaml");
    scene << "sensor: {model: vlp32c, height: 1.0}\n"
             "world: {room: {center: [4, 0], size: [16, 10], height: 3.2}}\n"
             "camera: {width: 640, height: 360, fx: 450, distortion_model: plumb_bob,\n"
             "  distortion_coefficients: [-0.12, 0.06, 0.0008, -0.0005, 0.0],\n"
             "  rotation_wxyz: [0.481240400, 0.500957013, -0.511747708, 0.505533414],\n"
             "  translation_m: [0.1, -0.05, -0.08]}\n"
             "rotations: 5\n"
             "tags:\n  - {family: tag36h11, id: 5, size: 1.0, center: [4.0, 0.3, 1.2]}\n"
             "series:\n"
             "  - {center: [3.0, 0.9, 1.3], normal: [-1, 0.2, 0], rotation: square}\n"
             "  - {center: [3.5, -1.0, 0.9], normal: [-1, -0.3, 0.1], rotation: 30}\n"
             "  - {center: [5.0, 0.0, 1.6], normal: [-1, 0, -0.2], rotation: diamond}\n"
             "  - {center: [6.0, -1.8, 1.4], normal: [-1, -0.2, 0.2], rotation: 20}\n"
             "  - {center: [4.2, 0.3, 0.7], normal: [-1, 0.1, 0.3], rotation: diamond}\n"
             "  - {center: [4.8, 1.3, 1.5], normal: [-1, 0.3, -0.3], rotation: 40}\n";
    scene.close();
    // The intrinsics as ROS writes them (camera_info YAML).
    std::ofstream camera(dir_ / "camera.yaml");
    camera << "image_width: 640\nimage_height: 360\ncamera_name: sim\n"
              "camera_matrix: {rows: 3, cols: 3, data: [450, 0, 319.5, 0, 450, 179.5, 0, 0, 1]}\n"
              "distortion_model: plumb_bob\n"
              "distortion_coefficients: {rows: 1, cols: 5, data: [-0.12, 0.06, 0.0008, -0.0005, "
              "0.0]}\n";
    camera.close();
    sim_ = run_tool("sim " + path("calib.yaml") + " --out " + path("cal.pcap"));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string path(const std::string& name) { return (dir_ / name).string(); }
  static std::string pair(int i) {
    const std::string n = "cal_0" + std::to_string(i);
    return " --pair " + path(n + ".png") + " " + path(n + ".pcap");
  }
  static std::string all_pairs() {
    std::string s;
    for (int i = 0; i < 6; ++i) s += pair(i);
    return s;
  }
  static std::string command(const std::string& pairs) {
    return "calibrate --camera " + path("camera.yaml") + pairs +
           " --family tag36h11 --tag-size 1.0";
  }

  static fs::path dir_;
  static ToolResult sim_;
};
fs::path CliCalibrate::dir_;
ToolResult CliCalibrate::sim_;

// Rotation and translation errors of a result's lidar_to_camera against the hidden truth.
std::pair<double, double> errors(const nlohmann::json& j) {
  const auto& q = j["lidar_to_camera"]["rotation_wxyz"];
  const Eigen::Quaterniond r(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
                             q[3].get<double>());
  const auto& t = j["lidar_to_camera"]["translation_m"];
  const Eigen::Vector3d tr(t[0].get<double>(), t[1].get<double>(), t[2].get<double>());
  return {r.angularDistance(kTruthRotation) * 180.0 / std::numbers::pi,
          (tr - kTruthTranslation).norm()};
}

TEST_F(CliCalibrate, FindsTheHiddenExtrinsicFromImagesAndCaptures) {
  ASSERT_EQ(sim_.exit_code, 0) << sim_.out;
  const ToolResult r = run_tool(
      command(all_pairs()) + " -o " + path("result.json") + " --pictures " + path("view"), false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // A picture per pair, the image's width, taller by the caption.
  for (int i = 0; i < 6; ++i) {
    const std::string png =
        run_command("od -An -tx1 -j16 -N8 " + path("view-pair") + std::to_string(i) + ".png").out;
    EXPECT_NE(png.find("00 00 02 80 00 00 01"), std::string::npos) << i << ": " << png;
  }
  const nlohmann::json j = nlohmann::json::parse(run_command("cat " + path("result.json")).out);
  const auto [rot_deg, trans_m] = errors(j);
  std::printf(
      "calibrate, 6 poses: rotation error %.3f deg (1-sigma %.3f), translation error %.1f mm, "
      "held-out median %.2f px\n",
      rot_deg, j["lidar_to_camera"]["sigma"]["rotation_total_deg"].get<double>(), 1000 * trans_m,
      j["errors"]["held_out_median_px"].get<double>());
  EXPECT_LT(rot_deg, 0.1);
  EXPECT_LT(trans_m, 0.005);
  // The 1-sigma it reports covers the true error within 3 sigma, and is not absurdly loose.
  const double sigma_deg = j["lidar_to_camera"]["sigma"]["rotation_total_deg"].get<double>();
  EXPECT_LT(rot_deg, 3 * sigma_deg);
  EXPECT_LT(sigma_deg, 0.2);
  EXPECT_GE(j["poses_used"].get<int>(), 5);
  EXPECT_LT(j["errors"]["held_out_median_px"].get<double>(), 1.0);
  EXPECT_EQ(j["pairs"].size(), 6u);
  // The text names the transform and the ready-to-paste forms.
  EXPECT_NE(r.out.find("lidar_to_camera"), std::string::npos);
  EXPECT_NE(r.out.find("<origin xyz="), std::string::npos);
  EXPECT_NE(r.out.find("static_transform_publisher"), std::string::npos);
  // --json prints the same result.
  const ToolResult js = run_tool(command(all_pairs()) + " --json", false);
  ASSERT_EQ(js.exit_code, 0);
  EXPECT_EQ(nlohmann::json::parse(js.out)["lidar_to_camera"]["translation_m"],
            j["lidar_to_camera"]["translation_m"]);
}

TEST_F(CliCalibrate, BadPairsAreReportedAndTheRestIsStillUsed) {
  ASSERT_EQ(sim_.exit_code, 0) << sim_.out;
  // A corrupt PNG, an image of another size, a capture without the tag (an image paired with the
  // wrong capture still has the tag: it is the pose that moved, which the solver rejects).
  {
    std::ofstream bad(dir_ / "corrupt.png", std::ios::binary);
    bad << "\x89PNG\r\n\x1a\n garbage";
  }
  {
    std::ofstream empty(dir_ / "empty.yaml");
    empty << "sensor: {model: vlp32c}\nrotations: 3\n";
  }
  ASSERT_EQ(run_tool("sim " + path("empty.yaml") + " --out " + path("empty.pcap")).exit_code, 0);
  const std::string bad_pairs = " --pair " + path("corrupt.png") + " " + path("cal_00.pcap") +
                                " --pair " + path("cal_01.png") + " " + path("empty.pcap") +
                                " --pair " + path("cal_02.png") + " " + path("cal_04.pcap");
  const ToolResult r =
      run_split(std::string(LIDARTAG_CLI) + " " + command(all_pairs() + bad_pairs) + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const auto [rot_deg, trans_m] = errors(j);
  EXPECT_LT(rot_deg, 0.1);
  EXPECT_LT(trans_m, 0.005);
  const auto& pairs = j["pairs"];
  ASSERT_EQ(pairs.size(), 9u);
  EXPECT_NE(pairs[6]["error"].get<std::string>().find("corrupt.png"), std::string::npos);
  EXPECT_EQ(pairs[7]["paired"], 0);  // the capture has no tag
  // The image of pose 2 with the capture of pose 4: paired by ID, rejected as an outlier.
  bool rejected = false;
  for (const auto& p : j["poses_rejected"])
    rejected |= p["label"].get<std::string>().rfind("pair 8", 0) == 0;
  EXPECT_TRUE(rejected) << j["poses_rejected"].dump();
  EXPECT_NE(r.err.find("no tag in " + path("empty.pcap")), std::string::npos) << r.err;
}

TEST_F(CliCalibrate, AnImageOfAnotherSizeAndMissingInputsAreClearErrors) {
  ASSERT_EQ(sim_.exit_code, 0) << sim_.out;
  {
    std::ofstream camera(dir_ / "camera_hd.yaml");
    camera << "image_width: 1280\nimage_height: 720\n"
              "camera_matrix: {rows: 3, cols: 3, data: [900, 0, 639.5, 0, 900, 359.5, 0, 0, 1]}\n"
              "distortion_model: plumb_bob\n"
              "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n";
  }
  // Every pair of another size: nothing to solve, exit 1 with the reason.
  const ToolResult r = run_tool("calibrate --camera " + path("camera_hd.yaml") + pair(0) +
                                " --family tag36h11 --tag-size 1.0");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("the image is 640 x 360 px but the camera's intrinsics"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("no tag was seen by both"), std::string::npos) << r.out;
  // An intrinsics file that is not one: a usage error naming the key.
  {
    std::ofstream camera(dir_ / "camera_bad.yaml");
    camera << "image_width: 640\n";
  }
  const ToolResult bad = run_tool("calibrate --camera " + path("camera_bad.yaml") + pair(0));
  EXPECT_EQ(bad.exit_code, 2) << bad.out;
  EXPECT_NE(bad.out.find("camera_bad.yaml"), std::string::npos) << bad.out;
}

// --pairs-dir: a folder of images and captures paired by base name gives the same answer as the
// same pairs given one by one; files without a partner, or a base name with two captures, are
// reported as pairs that cannot be used, and other files are left alone.
TEST_F(CliCalibrate, PairsDirPairsImagesAndCapturesByBaseName) {
  ASSERT_EQ(sim_.exit_code, 0) << sim_.out;
  const fs::path folder = dir_ / "folder";
  fs::create_directories(folder / "sub");
  for (int i = 0; i < 6; ++i) {
    const std::string n = "cal_0" + std::to_string(i);
    fs::copy_file(dir_ / (n + ".pcap"), folder / (n + ".pcap"));
    fs::copy_file(dir_ / (n + ".png"), folder / (i == 3 ? n + ".PNG" : n + ".png"));
    std::ofstream(folder / (n + ".json")) << "{}\n";  // a truth file beside it: not an input
  }
  fs::copy_file(dir_ / "cal_00.png", folder / "lonely.png");    // no capture
  fs::copy_file(dir_ / "cal_01.pcap", folder / "orphan.pcap");  // no image
  fs::copy_file(dir_ / "cal_02.png", folder / "twice.jpg");     // two captures, one name
  fs::copy_file(dir_ / "cal_02.pcap", folder / "twice.pcap");
  fs::copy_file(dir_ / "cal_02.pcap", folder / "twice.pcd");
  fs::copy_file(dir_ / "cal_04.png", folder / "sub" / "cal_09.png");  // not searched
  fs::copy_file(dir_ / "cal_04.pcap", folder / "sub" / "cal_09.pcap");

  const ToolResult r =
      run_split(std::string(LIDARTAG_CLI) + " calibrate --camera " + path("camera.yaml") +
                " --pairs-dir " + folder.string() + " --family tag36h11 --tag-size 1.0 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const auto& pairs = j["pairs"];
  ASSERT_EQ(pairs.size(), 11u) << pairs.dump();  // 6 pairs, then 5 files without a partner
  for (size_t i = 0; i < 6; ++i) {
    const std::string n = "cal_0" + std::to_string(i);
    EXPECT_EQ(pairs[i]["capture"], (folder / (n + ".pcap")).string());
    EXPECT_EQ(pairs[i]["image"], (folder / (i == 3 ? n + ".PNG" : n + ".png")).string());
    EXPECT_FALSE(pairs[i].contains("error")) << pairs[i].dump();
  }
  std::map<std::string, std::string> errors_of;
  for (size_t i = 6; i < pairs.size(); ++i) {
    const std::string file =
        pairs[i]["image"].get<std::string>() + pairs[i]["capture"].get<std::string>();
    errors_of[fs::path(file).filename().string()] = pairs[i]["error"].get<std::string>();
  }
  EXPECT_NE(errors_of["lonely.png"].find("no capture lonely.pcap"), std::string::npos);
  EXPECT_NE(errors_of["orphan.pcap"].find("no image orphan.png"), std::string::npos);
  for (const char* f : {"twice.jpg", "twice.pcap", "twice.pcd"})
    EXPECT_NE(errors_of[f].find("the base name 'twice' has 1 image and 2 captures"),
              std::string::npos)
        << f << ": " << errors_of[f];
  EXPECT_NE(r.err.find("lonely.png: not used"), std::string::npos) << r.err;
  // The same six pairs in the same order: the same answer as --pair.
  const ToolResult one_by_one = run_tool(command(all_pairs()) + " --json", false);
  ASSERT_EQ(one_by_one.exit_code, 0);
  EXPECT_EQ(nlohmann::json::parse(one_by_one.out)["lidar_to_camera"], j["lidar_to_camera"]);

  // A folder with nothing to pair and no --pair: a usage error that says what to give.
  fs::create_directories(dir_ / "nothing");
  const ToolResult none =
      run_tool("calibrate --camera " + path("camera.yaml") + " --pairs-dir " + path("nothing"));
  EXPECT_EQ(none.exit_code, 2) << none.out;
  EXPECT_NE(none.out.find("give --pair IMAGE CAPTURE or --pairs-dir DIR"), std::string::npos)
      << none.out;
  const ToolResult missing = run_tool("calibrate --camera " + path("camera.yaml") +
                                      " --pairs-dir " + path("no_such_folder"));
  // A folder that does not exist is an input that cannot be read (exit 1, as a missing file).
  EXPECT_EQ(missing.exit_code, 1) << missing.out;
  EXPECT_NE(missing.out.find("--pairs-dir: Directory does not exist"), std::string::npos)
      << missing.out;
}

}  // namespace
}  // namespace lidartag::testing
