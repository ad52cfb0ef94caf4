// The simulator's camera: the `camera:` section, images whose tags AprilTag finds where the truth
// says (corners projected with the camera model, lidartag's pixel convention), the truth file's
// camera round trip, determinism.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "lidartag/calib/image_tags.hpp"
#include "lidartag/sim/camera_sim.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim {
namespace {

// A 1.2 m tag36h11 at 4 m, turned 20 degrees, a VLP-32C and a 1280x720 plumb-bob camera 10 cm
// beside it, turned slightly.
constexpr const char* kScene = R"(
sensor: {model: vlp32c, height: 1.0, noise: none}
world: {ground_reflectivity: 15, room: {center: [2, 0], size: [14, 10], height: 3.2}}
camera:
  width: 1280
  height: 720
  fx: 900
  fy: 905
  cx: 641.3
  cy: 357.8
  distortion_model: plumb_bob
  distortion_coefficients: [-0.12, 0.06, 0.0008, -0.0005, 0.0]
  rotation_wxyz: [0.5, 0.49, -0.51, 0.5]
  translation_m: [0.1, -0.05, -0.08]
  noise_sigma: 2.0
  blur_sigma: 0.5
tags:
  - {family: tag36h11, id: 5, size: 1.2, center: [4.0, 0.3, 1.2], rotation: 20}
)";

struct Rendered {
  Truth truth;
  calib::GrayImage image;
};

Rendered render_scene(const std::string& yaml, uint64_t seed = 3) {
  Simulator sim(parse_scene(yaml));
  Rendered r;
  r.truth = sim.run(1, seed, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  r.image = sim.render_image(r.truth.rotations.at(0), seed);
  return r;
}

TEST(SimCamera, DetectedCornersMatchTheTruthsImageCorners) {
  const Rendered r = render_scene(kScene);
  ASSERT_EQ(r.image.width, 1280);
  ASSERT_EQ(r.image.height, 720);
  const TagTruth& tag = r.truth.rotations[0].tags.at(0);
  ASSERT_TRUE(tag.image_corners.has_value());
  calib::ImageTagDetector detector;
  // Edges fitted in the image (bent by the distortion) and on the pinhole plane (the lens known).
  for (bool with_lens : {false, true}) {
    const auto found =
        with_lens ? detector.detect(r.image, r.truth.camera->model) : detector.detect(r.image);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].id, 5);
    std::vector<double> errors;
    for (size_t k = 0; k < 4; ++k) {
      errors.push_back((found[0].corners[k] - (*tag.image_corners)[k]).norm());
      EXPECT_LT(errors.back(), with_lens ? 0.15 : 0.6) << "corner " << k;
    }
    std::sort(errors.begin(), errors.end());
    const double median = (errors[1] + errors[2]) / 2.0;
    EXPECT_LT(median, with_lens ? 0.1 : 0.3);
    std::printf(
        "1.2 m tag at 4 m, 1280x720 fx 900 plumb-bob, %s: corner errors %.3f %.3f %.3f %.3f px\n",
        with_lens ? "lens known" : "image only", errors[0], errors[1], errors[2], errors[3]);
  }
}

// A half-pixel mistake anywhere between the renderer, the truth and the detector would put every
// corner about 0.7 px off; the test above holds them to 0.3 px median. This one checks that the
// truth corners are the camera model's projection of the truth's 3D corners.
TEST(SimCamera, TruthImageCornersAreTheCameraModelsProjection) {
  Simulator sim(parse_scene(kScene));
  const Truth truth = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  ASSERT_TRUE(truth.camera.has_value());
  const TagTruth& tag = truth.rotations[0].tags[0];
  for (size_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d pc = truth.camera->rotation * tag.corners[k] + truth.camera->translation;
    const auto px = truth.camera->model.project(pc);
    ASSERT_TRUE(px.has_value());
    EXPECT_LT((*px - (*tag.image_corners)[k]).norm(), 1e-9);
    EXPECT_TRUE(truth.camera->model.in_image(*px));
  }
}

TEST(SimCamera, TruthFileCameraRoundTrips) {
  Simulator sim(parse_scene(kScene));
  const Truth truth = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  const nlohmann::json j = nlohmann::json::parse(truth_to_json(truth).dump(2));
  const CameraTruth back = camera_truth_from_json(j.at("camera"));
  const calib::CameraModel& a = truth.camera->model;
  const calib::CameraModel& b = back.model;
  EXPECT_EQ(b.width, 1280);
  EXPECT_EQ(b.height, 720);
  EXPECT_DOUBLE_EQ(b.fx, 900);
  EXPECT_DOUBLE_EQ(b.fy, 905);
  EXPECT_DOUBLE_EQ(b.cx, 641.3);
  EXPECT_DOUBLE_EQ(b.cy, 357.8);
  EXPECT_EQ(b.distortion, calib::Distortion::kPlumbBob);
  for (size_t i = 0; i < 5; ++i) EXPECT_DOUBLE_EQ(b.d[i], a.d[i]);
  EXPECT_LT((back.rotation - truth.camera->rotation).norm(), 1e-12);
  EXPECT_LT((back.translation - Eigen::Vector3d(0.1, -0.05, -0.08)).norm(), 1e-15);
  // The 4x4 matrix agrees with the quaternion and translation.
  const auto& m = j["camera"]["lidar_to_camera"]["matrix"];
  for (size_t r = 0; r < 3; ++r) {
    const auto ri = static_cast<Eigen::Index>(r);
    for (size_t c = 0; c < 3; ++c)
      EXPECT_NEAR(m[r][c].get<double>(), truth.camera->rotation(ri, static_cast<Eigen::Index>(c)),
                  1e-12);
    EXPECT_DOUBLE_EQ(m[r][3].get<double>(), truth.camera->translation[ri]);
  }
  // Image corners in the file, per tag.
  const auto& corners = j["rotations"][0]["tags"][0]["image_corners"];
  ASSERT_EQ(corners.size(), 4u);
  EXPECT_DOUBLE_EQ(corners[2][0].get<double>(), (*truth.rotations[0].tags[0].image_corners)[2].x());
  // A damaged camera section is refused naming the problem.
  nlohmann::json bad = j.at("camera");
  bad.erase("fx");
  EXPECT_THROW(camera_truth_from_json(bad), TruthError);
  bad = j.at("camera");
  bad["distortion_model"] = "kannala";
  EXPECT_THROW(camera_truth_from_json(bad), TruthError);
}

// A small camera (320x180) for the cheaper tests.
Scene small_scene() {
  Scene scene = parse_scene(kScene);
  calib::CameraModel& m = scene.camera->model;
  m.width = 320;
  m.height = 180;
  m.fx = m.fy = 225;
  m.cx = 159.5;
  m.cy = 89.5;
  return scene;
}

TEST(SimCamera, SameSeedSameImageOtherSeedOtherNoise) {
  Simulator sim(small_scene());
  const Truth truth = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  const calib::GrayImage a = sim.render_image(truth.rotations[0], 7);
  const calib::GrayImage b = sim.render_image(truth.rotations[0], 7);
  const calib::GrayImage c = sim.render_image(truth.rotations[0], 8);
  EXPECT_EQ(a.pixels, b.pixels);
  EXPECT_NE(a.pixels, c.pixels);
  {
    // Rows are rendered in parallel: one thread gives the same image.
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_EQ(sim.render_image(truth.rotations[0], 7).pixels, a.pixels);
  }
  // Noise sigma 2: the two images differ by about 2 * sqrt(2) grey levels RMS.
  double sq = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(c.pixels[i]);
    sq += d * d;
  }
  const double rms = std::sqrt(sq / double(a.pixels.size()));
  EXPECT_GT(rms, 2.0);
  EXPECT_LT(rms, 3.6);
}

// Without noise and blur, the tag's centre pixel area shows the printed cells' reflectivities
// times the gain, and rays into nothing the background.
TEST(SimCamera, GreyLevelsAreReflectivityTimesGain) {
  Scene scene = small_scene();
  scene.camera->noise_sigma = 0;
  scene.camera->blur_sigma = 0;
  scene.world.room.enabled = false;
  scene.world.ground = false;
  Simulator sim(scene);
  const Truth truth = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  const calib::GrayImage img = sim.render_image(truth.rotations[0], 1);
  int black = 0, white = 0, sky = 0;
  for (uint8_t p : img.pixels) {
    black += p == 20;   // 8 * 2.55 = 20.4
    white += p == 204;  // 80 * 2.55
    sky += p == 200;    // background
  }
  EXPECT_GT(black, 200);
  EXPECT_GT(white, 200);
  EXPECT_GT(sky, 320 * 180 / 2);
  EXPECT_EQ(img.at(0, 0), 200);
}

TEST(SimCamera, CameraSectionErrorsNameTheKey) {
  auto error = [](const std::string& camera) {
    try {
      (void)parse_scene("camera: " + camera + "\n");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("{fx: -3}").find("camera.fx"), std::string::npos);
  EXPECT_NE(error("{focal: 3}").find("camera.focal: unknown key"), std::string::npos);
  EXPECT_NE(error("{distortion_model: kb4}").find("camera.distortion_model"), std::string::npos);
  EXPECT_NE(error("{rotation_wxyz: [0, 0, 0, 0]}").find("camera.rotation_wxyz"), std::string::npos);
  EXPECT_NE(error("{cx: 5000}").find("camera"), std::string::npos);
  EXPECT_NE(error("{distortion_coefficients: [1, 2, 3, 4, 5, 6]}").find("at most 5"),
            std::string::npos);
  // Defaults: 1280x720, fx = fy = 900, centred, looking along the LiDAR's +x.
  const Scene s = parse_scene("camera: {}\n");
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->model.width, 1280);
  EXPECT_DOUBLE_EQ(s.camera->model.cx, 639.5);
  const Eigen::Matrix3d r = camera_rotation(*s.camera);
  EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_LT((r * Eigen::Vector3d::UnitY() + Eigen::Vector3d::UnitX()).norm(), 1e-12);
  EXPECT_LT((r * Eigen::Vector3d::UnitZ() + Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_FALSE(parse_scene("seed: 1\n").camera.has_value());
}

TEST(SimCamera, SeriesMovesTheFirstTag) {
  const Scene scene = parse_scene(std::string(kScene) + R"(
series:
  - {center: [3, 0.5, 1.1]}
  - {center: [6, -1, 1.3], normal: [-1, 0.2, 0], rotation: square}
)");
  ASSERT_EQ(scene.series.size(), 2u);
  const Scene a = series_scene(scene, 0);
  EXPECT_EQ(a.tags[0].center, (std::array<double, 3>{3, 0.5, 1.1}));
  EXPECT_DOUBLE_EQ(a.tags[0].rotation_deg, 20.0);  // the tag's own, kept
  EXPECT_DOUBLE_EQ(a.tags[0].size, 1.2);
  EXPECT_TRUE(a.series.empty());
  const Scene b = series_scene(scene, 1);
  EXPECT_EQ(b.tags[0].normal, (std::array<double, 3>{-1, 0.2, 0}));
  EXPECT_DOUBLE_EQ(b.tags[0].rotation_deg, 0.0);
  EXPECT_THROW((void)series_scene(scene, 2), std::out_of_range);
  // The truth of a series pose has the tag where the pose put it.
  Simulator sim(b);
  const Truth t = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  EXPECT_NEAR(t.rotations[0].tags[0].position.x(), 6.0, 1e-9);
  EXPECT_THROW((void)parse_scene("series: [{center: [1, 2, 3]}]\n"), SceneError);
  EXPECT_THROW((void)parse_scene(std::string(kScene) + "series: [{normal: [1, 0, 0]}]\n"),
               SceneError);
  EXPECT_THROW((void)parse_scene(std::string(kScene) + "series: [{center: [1, 2, 3], id: 3}]\n"),
               SceneError);
}

// A series at 3, 5 and 7 m (square, turned 30 degrees and obliquely, diamond) with a stand and
// a room: each pose's image gives the tag at its truth corners, the lens known, to a tenth of a
// pixel.
TEST(SimCamera, SeriesPosesDetectAtTheirTruthCorners) {
  const Scene scene = parse_scene(std::string(kScene) + R"(
series:
  - {center: [3.0, 0.5, 1.1], rotation: square}
  - {center: [5.0, -0.8, 1.3], normal: [-1, 0.3, 0.1], rotation: 30}
  - {center: [7.0, 1.0, 1.0], rotation: diamond}
)");
  calib::ImageTagDetector detector;
  for (size_t i = 0; i < scene.series.size(); ++i) {
    Simulator sim(series_scene(scene, i));
    const Truth truth = sim.run(1, i, [](std::span<const uint8_t>, int64_t, uint16_t) {});
    const calib::GrayImage image = sim.render_image(truth.rotations[0], i);
    const auto found = detector.detect(image, truth.camera->model);
    ASSERT_EQ(found.size(), 1u) << "pose " << i;
    const auto& expected = *truth.rotations[0].tags[0].image_corners;
    std::vector<double> errors;
    for (size_t k = 0; k < 4; ++k) errors.push_back((found[0].corners[k] - expected[k]).norm());
    std::printf("pose %zu (%.0f m): corner errors %.3f %.3f %.3f %.3f px\n", i,
                scene.series[i].center[0], errors[0], errors[1], errors[2], errors[3]);
    std::sort(errors.begin(), errors.end());
    EXPECT_LT((errors[1] + errors[2]) / 2.0, 0.1) << "pose " << i;
    EXPECT_LT(errors[3], 0.2) << "pose " << i;
  }
}

// An equidistant fisheye (640x480, fx 320, about 110 degrees across): the rays bent by the lens
// model's inverse, the tag found at its truth corners once the lens is known.
TEST(SimCamera, FisheyeImagesDetectAtTheirTruthCorners) {
  Scene scene = parse_scene(kScene);
  calib::CameraModel& m = scene.camera->model;
  m.width = 640;
  m.height = 480;
  m.fx = m.fy = 320;
  m.cx = 321.2;
  m.cy = 238.9;
  m.distortion = calib::Distortion::kEquidistant;
  m.d = {0.04, -0.01, 0.002, 0.0, 0.0};
  scene.tags[0].center = {2.5, 0.9, 1.3};  // toward the edge of the view, where the lens bends most
  Simulator sim(scene);
  const Truth truth = sim.run(1, 1, [](std::span<const uint8_t>, int64_t, uint16_t) {});
  const calib::GrayImage image = sim.render_image(truth.rotations[0], 1);
  calib::ImageTagDetector detector;
  const auto found = detector.detect(image, truth.camera->model);
  ASSERT_EQ(found.size(), 1u);
  const auto& expected = *truth.rotations[0].tags[0].image_corners;
  std::vector<double> errors;
  for (size_t k = 0; k < 4; ++k) errors.push_back((found[0].corners[k] - expected[k]).norm());
  std::printf("fisheye, tag at 2.7 m off-axis: corner errors %.3f %.3f %.3f %.3f px\n", errors[0],
              errors[1], errors[2], errors[3]);
  std::sort(errors.begin(), errors.end());
  EXPECT_LT((errors[1] + errors[2]) / 2.0, 0.1);
  EXPECT_LT(errors[3], 0.2);
}

}  // namespace
}  // namespace lidartag::sim
