#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <sstream>

#include "calib/calib_synthetic.hpp"
#include "lidartag/calib/calibration_report.hpp"

namespace lidartag::calib {
namespace {

using testing::make_scene;
using testing::test_camera;
using testing::true_extrinsic;

Eigen::Matrix3d from_rpy(const Eigen::Vector3d& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

std::vector<std::string> words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> w;
  for (std::string x; in >> x;) w.push_back(x);
  return w;
}

TEST(CalibrationReport, RollPitchYawIsFixedAxisAndRoundTrips) {
  for (const Eigen::Vector3d& rpy :
       {Eigen::Vector3d(0.3, -0.2, 2.5), Eigen::Vector3d(-3.0, 1.2, -0.4),
        Eigen::Vector3d(0.1, std::numbers::pi / 2, 0.7)}) {
    const Eigen::Matrix3d r = from_rpy(rpy);
    EXPECT_LT((from_rpy(roll_pitch_yaw(r)) - r).norm(), 1e-9) << rpy.transpose();
  }
  // The camera optical frame of a camera looking along the LiDAR's x: rpy (-90, 0, -90) degrees,
  // the value every ROS user knows.
  Eigen::Matrix3d axes;
  axes << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // camera_from_lidar
  const Eigen::Vector3d rpy = roll_pitch_yaw(axes.transpose());
  EXPECT_NEAR(rpy.x(), -std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(rpy.y(), 0.0, 1e-12);
  EXPECT_NEAR(rpy.z(), -std::numbers::pi / 2, 1e-12);
}

TEST(CalibrationReport, UrdfAndRosFormsGiveTheOpticalFramesPoseInTheLidarFrame) {
  const Eigen::Isometry3d c_from_l = true_extrinsic();
  const Eigen::Isometry3d l_from_c = c_from_l.inverse();
  const FrameNames frames{"velodyne", "cam0_optical"};

  const std::string urdf = urdf_joint(l_from_c, frames);
  EXPECT_NE(urdf.find("<parent link=\"velodyne\"/>"), std::string::npos) << urdf;
  EXPECT_NE(urdf.find("<child link=\"cam0_optical\"/>"), std::string::npos);
  double x, y, z, rr, pp, yy;
  const std::size_t at = urdf.find("<origin");
  ASSERT_EQ(std::sscanf(urdf.c_str() + at, "<origin xyz=\"%lf %lf %lf\" rpy=\"%lf %lf %lf\"", &x,
                        &y, &z, &rr, &pp, &yy),
            6)
      << urdf;
  EXPECT_LT((Eigen::Vector3d(x, y, z) - l_from_c.translation()).norm(), 1e-12);
  EXPECT_LT((from_rpy({rr, pp, yy}) - l_from_c.linear()).norm(), 1e-12);

  // ROS 1: x y z qx qy qz qw frame_id child_frame_id; the transform is the child's pose in the
  // parent.
  const std::vector<std::string> w = words(ros1_static_transform(l_from_c, frames));
  ASSERT_EQ(w.size(), 12u);
  EXPECT_EQ(w[2], "static_transform_publisher");
  EXPECT_EQ(w[10], "velodyne");
  EXPECT_EQ(w[11], "cam0_optical");
  const Eigen::Quaterniond q(std::stod(w[9]), std::stod(w[6]), std::stod(w[7]), std::stod(w[8]));
  EXPECT_LT((q.toRotationMatrix() - l_from_c.linear()).norm(), 1e-12);
  EXPECT_NEAR(std::stod(w[3]), l_from_c.translation().x(), 1e-15);
  // A point of the camera frame mapped into the LiDAR frame by what the line says.
  const Eigen::Vector3d pc(0.3, -0.2, 4.0);
  const Eigen::Vector3d pl =
      q * pc + Eigen::Vector3d(std::stod(w[3]), std::stod(w[4]), std::stod(w[5]));
  EXPECT_LT((c_from_l * pl - pc).norm(), 1e-12);

  const std::string ros2 = ros2_static_transform(l_from_c, frames);
  EXPECT_NE(ros2.find("--frame-id velodyne --child-frame-id cam0_optical"), std::string::npos);
  EXPECT_NE(ros2.find("--qw " + w[9]), std::string::npos) << ros2;
}

TEST(CalibrationReport, OpenCvYamlReadsBack) {
  const Eigen::Isometry3d c_from_l = true_extrinsic();
  std::string text = opencv_yaml(c_from_l);
  ASSERT_EQ(text.rfind("%YAML:1.0\n", 0), 0u);
  text = text.substr(text.find('\n') + 1);  // yaml-cpp refuses OpenCV's directive line
  const YAML::Node root = YAML::Load(text);
  const YAML::Node m = root["camera_from_lidar"];
  EXPECT_EQ(m.Tag(), "tag:yaml.org,2002:opencv-matrix");
  ASSERT_EQ(m["data"].size(), 16u);
  for (int i = 0; i < 16; ++i)
    EXPECT_EQ(m["data"][static_cast<std::size_t>(i)].as<double>(), c_from_l.matrix()(i / 4, i % 4));
  Eigen::Vector3d rvec;
  for (int i = 0; i < 3; ++i)
    rvec(i) = root["rvec"]["data"][static_cast<std::size_t>(i)].as<double>();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(rvec.norm(), rvec.normalized()).toRotationMatrix();
  EXPECT_LT((r - c_from_l.linear()).norm(), 1e-12);
  EXPECT_EQ(root["tvec"]["rows"].as<int>(), 3);
  EXPECT_EQ(root["lidar_from_camera"]["data"][3].as<double>(),
            c_from_l.inverse().translation().x());
}

TEST(CalibrationReport, ResultJsonHoldsTransformSigmaErrorsAndPoses) {
  testing::Scene s = make_scene(21);
  s.poses[2].lidar = s.poses[6].lidar;  // a wrong ID
  const CalibrationResult r = solve_extrinsic(test_camera(), s.poses);
  const nlohmann::json j = nlohmann::json::parse(calibration_json(r).dump());
  const nlohmann::json& l2c = j.at("lidar_to_camera");
  const Eigen::Quaterniond q(
      l2c["rotation_wxyz"][0].get<double>(), l2c["rotation_wxyz"][1].get<double>(),
      l2c["rotation_wxyz"][2].get<double>(), l2c["rotation_wxyz"][3].get<double>());
  EXPECT_LT((q.toRotationMatrix() - r.camera_from_lidar.linear()).norm(), 1e-12);
  EXPECT_GE(q.w(), 0.0);
  Eigen::Matrix4d m, inv;
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 4; ++k) {
      m(i, k) =
          l2c["matrix"][static_cast<std::size_t>(i)][static_cast<std::size_t>(k)].get<double>();
      inv(i, k) =
          l2c["inverse"][static_cast<std::size_t>(i)][static_cast<std::size_t>(k)].get<double>();
    }
  EXPECT_LT((m * inv - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  EXPECT_EQ(l2c["translation_m"][2].get<double>(), r.camera_from_lidar.translation().z());
  EXPECT_EQ(l2c["sigma"]["translation_mm"].size(), 3u);
  EXPECT_GT(l2c["sigma"]["rotation_total_deg"].get<double>(), 0.0);
  EXPECT_GT(j["errors"]["held_out_median_px"].get<double>(), 0.0);
  EXPECT_EQ(j["poses"].size(), 9u);
  EXPECT_EQ(j["poses_used"].get<int>(), 8);
  ASSERT_EQ(j["poses_rejected"].size(), 1u);
  EXPECT_EQ(j["poses_rejected"][0]["label"], "pose 2");
  EXPECT_NE(j["poses_rejected"][0]["reason"].get<std::string>().find("wrong ID"),
            std::string::npos);
  EXPECT_EQ(j["poses"][0]["corner_px"].size(), 4u);
  EXPECT_NE(j["forms"]["urdf"].get<std::string>().find("<origin xyz="), std::string::npos);
  EXPECT_EQ(j["forms"]["opencv_yaml"].get<std::string>().rfind("%YAML:1.0", 0), 0u);
  EXPECT_EQ(j["frames"]["parent"], "lidar");
}

}  // namespace
}  // namespace lidartag::calib
