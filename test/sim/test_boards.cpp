// Boards that are not tags: the scene keys and their errors, the printed faces, holes that let
// beams through, the diamond rotation.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "lidartag/sim/board_target.hpp"
#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim {
namespace {

Ray ray(Eigen::Vector3d o, Eigen::Vector3d d) {
  return {o, d.normalized()};
}

std::string error_of(const std::string& yaml) {
  try {
    parse_scene(yaml, "test.yaml");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(Boards, SceneKeysMapOntoTheOptions) {
  const Scene s = parse_scene(R"(
boards:
  - {kind: checkerboard, center: [3, 0, 1], rotation: diamond, inner_corners: [9, 6],
     square_m: 0.08, size: [0.9, 0.7], thickness: 0.02, reflectivity: 70, dark_reflectivity: 5,
     stand: {width: 0.04, reflectivity: 20}}
  - {kind: holes, center: [4, 1, 1], size: [1.2, 0.8], holes: [[-0.3, 0.15, 0.12], [0.3, 0, 0.1]]}
  - {kind: strips, center: [5, 0, 1], strips: 2, strip_width_m: 0.1, vertical_strips: true,
     strip_reflectivity: 240, normal: [-1, 0, 0], rotation: 30}
  - {kind: sign, center: [6, 0, 2], border_m: 0.02, text_lines: 3, text_seed: 9}
)");
  ASSERT_EQ(s.boards.size(), 4u);
  const auto& c = s.boards[0];
  EXPECT_EQ(c.kind, BoardKind::kCheckerboard);
  EXPECT_EQ(c.rotation_deg, 45.0);
  EXPECT_EQ(c.inner_corners[0], 9);
  EXPECT_EQ(c.inner_corners[1], 6);
  EXPECT_EQ(c.square_m, 0.08);
  EXPECT_EQ(c.size[1], 0.7);
  EXPECT_EQ(c.thickness, 0.02);
  EXPECT_EQ(c.dark_reflectivity, 5.0);
  EXPECT_TRUE(c.stand.enabled);
  EXPECT_EQ(c.stand.width, 0.04);
  EXPECT_EQ(s.boards[1].kind, BoardKind::kHoles);
  ASSERT_EQ(s.boards[1].holes.size(), 2u);
  EXPECT_EQ(s.boards[1].holes[0][2], 0.12);
  EXPECT_EQ(s.boards[2].kind, BoardKind::kStrips);
  EXPECT_TRUE(s.boards[2].vertical_strips);
  EXPECT_EQ(s.boards[2].strip_reflectivity, 240.0);
  EXPECT_EQ(s.boards[2].rotation_deg, 30.0);
  EXPECT_EQ(s.boards[2].normal[0], -1.0);
  EXPECT_EQ(s.boards[3].kind, BoardKind::kSign);
  EXPECT_EQ(s.boards[3].text_lines, 3);
  EXPECT_EQ(s.boards[3].text_seed, 9u);
  // Documented defaults: a 7 x 5 checkerboard of 95 mm squares on a 0.85 x 0.61 m board.
  const Scene d = parse_scene("boards: [{center: [3, 0, 1]}]");
  EXPECT_EQ(d.boards[0].kind, BoardKind::kCheckerboard);
  EXPECT_EQ(d.boards[0].inner_corners[0], 7);
  EXPECT_EQ(d.boards[0].inner_corners[1], 5);
  EXPECT_EQ(d.boards[0].square_m, 0.095);
  EXPECT_EQ(d.boards[0].size[0], 0.85);
  EXPECT_EQ(d.boards[0].size[1], 0.61);
}

TEST(Boards, BadBoardsNameTheKey) {
  EXPECT_NE(error_of("boards: [{kind: target, center: [1, 0, 1]}]")
                .find("boards[0].kind: unknown board kind 'target'"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{kind: sign}]").find("boards[0]: needs 'center'"),
            std::string::npos);
  EXPECT_NE(
      error_of("boards: [{center: [1, 0, 1], colour: red}]").find("boards[0].colour: unknown key"),
      std::string::npos);
  EXPECT_NE(error_of("boards: [{kind: holes, center: [1, 0, 1]}]")
                .find("boards[0]: kind 'holes' needs 'holes'"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{kind: holes, center: [1, 0, 1], holes: [[0.5, 0, 0.1]]}]")
                .find("boards[0].holes[0]: a hole must"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{center: [1, 0, 1], square_m: 0.2}]")
                .find("boards[0].square_m: the squares do not fit"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{center: [1, 0, 1], inner_corners: [7.5, 5]}]")
                .find("boards[0].inner_corners: expected two whole numbers"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{kind: strips, center: [1, 0, 1], strips: 20, strip_width_m: 0.1}]")
                .find("boards[0].strips: the strips do not fit"),
            std::string::npos);
  EXPECT_NE(error_of("boards: [{kind: sign, center: [1, 0, 1], border_m: 0.4}]")
                .find("boards[0].border_m: the border leaves no face"),
            std::string::npos);
  EXPECT_NE(error_of("boards: {center: [1, 0, 1]}").find("boards: expected a list"),
            std::string::npos);
}

TEST(Boards, CheckerboardFaceAlternatesFromADarkTopLeftSquare) {
  CalibrationBoardOptions b;  // 7 x 5 inner corners: 8 x 6 squares of 95 mm
  b.reflectivity = 75.0;
  b.dark_reflectivity = 6.0;
  const PrintedPattern p = board_pattern(b);
  EXPECT_EQ(p.tag, -1);
  EXPECT_EQ(p.cols, 8);
  EXPECT_EQ(p.rows, 6);
  EXPECT_NEAR(p.width, 0.76, 1e-12);
  EXPECT_NEAR(p.height, 0.57, 1e-12);
  double r = 0;
  // Top-left square (y left, z up), its right neighbour, the one below it.
  ASSERT_TRUE(p.reflectivity_at(-0.38 + 0.04, 0.285 - 0.04, r));
  EXPECT_EQ(r, 6.0);
  ASSERT_TRUE(p.reflectivity_at(-0.38 + 0.095 + 0.04, 0.285 - 0.04, r));
  EXPECT_EQ(r, 75.0);
  ASSERT_TRUE(p.reflectivity_at(-0.38 + 0.04, 0.285 - 0.095 - 0.04, r));
  EXPECT_EQ(r, 75.0);
  // The margin around the squares is not printed: the board's own reflectivity.
  EXPECT_FALSE(p.reflectivity_at(0.40, 0.0, r));
}

TEST(Boards, StripsAndSignFacesHaveTheirReflectivities) {
  CalibrationBoardOptions s;
  s.kind = BoardKind::kStrips;
  s.size = {0.6, 0.6};
  s.strips = 3;
  s.strip_width_m = 0.05;
  s.reflectivity = 50.0;
  const PrintedPattern strips = board_pattern(s);
  double r = 0;
  // Strip centres at z = -0.2, 0, 0.2; between them the board.
  ASSERT_TRUE(strips.reflectivity_at(0.1, 0.2, r));
  EXPECT_EQ(r, 220.0);
  ASSERT_TRUE(strips.reflectivity_at(-0.2, 0.0, r));
  EXPECT_EQ(r, 220.0);
  ASSERT_TRUE(strips.reflectivity_at(0.0, 0.1, r));
  EXPECT_EQ(r, 50.0);

  CalibrationBoardOptions g;
  g.kind = BoardKind::kSign;
  g.size = {0.6, 0.6};
  g.border_m = 0.04;
  const PrintedPattern sign = board_pattern(g);
  ASSERT_TRUE(sign.reflectivity_at(-0.28, 0.0, r));  // the border
  EXPECT_EQ(r, g.dark_reflectivity);
  ASSERT_TRUE(sign.reflectivity_at(0.0, 0.25, r));  // between the border and the text
  EXPECT_EQ(r, g.reflectivity);
  // Letters: some of the face inside the border is dark, most of it is not.
  int dark = 0, light = 0;
  for (double y = -0.2; y <= 0.2; y += 0.01)
    for (double z = -0.2; z <= 0.2; z += 0.01) {
      ASSERT_TRUE(sign.reflectivity_at(y, z, r));
      (r == g.dark_reflectivity ? dark : light) += 1;
    }
  EXPECT_GT(dark, 100);
  EXPECT_GT(light, dark);
}

TEST(Boards, RaysPassThroughHolesAndHitTheBoardElsewhere) {
  CalibrationBoardOptions b;
  b.kind = BoardKind::kHoles;
  b.center = {4.0, 0.0, 1.0};
  b.size = {1.2, 0.8};
  b.reflectivity = 60.0;
  b.holes = {{-0.3, 0.15, 0.12}};
  World w;
  w.add_box(make_box({8, 0, 1}, {0.2, 6, 4}, 0.0, 30.0));  // a wall behind
  add_board(w, b, board_rotation(b, Eigen::Vector3d(0, 0, 1), "boards[0]"));
  // Facing the sensor at the origin: the board's y (to the right seen from the front) is the
  // sensor's -y (its y points left), so the hole at board y = -0.3 is at world y = +0.3.
  const Hit through = w.cast(ray({0, 0, 1}, {4, 0.3, 0.15}), 100.0);
  ASSERT_TRUE(through.hit());
  EXPECT_EQ(through.reflectivity, 30.0);  // the wall
  const Hit board = w.cast(ray({0, 0, 1}, {4, -0.3, 0.15}), 100.0);
  ASSERT_TRUE(board.hit());
  EXPECT_EQ(board.reflectivity, 60.0);
  EXPECT_NEAR(board.t, std::sqrt(16 + 0.09 + 0.0225), 1e-9);
  EXPECT_EQ(board.tag, -1);
}

TEST(Boards, DiamondRotationTurnsTheFace) {
  CalibrationBoardOptions b;  // 0.85 x 0.61 m
  b.center = {5.0, 0.0, 1.0};
  World square, diamond;
  add_board(square, b, board_rotation(b, Eigen::Vector3d(0, 0, 1), "boards[0]"));
  b.rotation_deg = 45.0;
  add_board(diamond, b, board_rotation(b, Eigen::Vector3d(0, 0, 1), "boards[0]"));
  // Square, the board spans |z| <= 0.305 above its centre; turned 45 degrees, its top edge
  // crosses the vertical through the centre at (0.425 + 0.305) / sqrt(2) - 0.085 = 0.431 m.
  auto up = [](double z) { return ray({0, 0, 1}, {5, 0, z}); };
  EXPECT_TRUE(square.cast(up(0.30), 100.0).hit());
  EXPECT_FALSE(square.cast(up(0.32), 100.0).hit());
  EXPECT_TRUE(diamond.cast(up(0.42), 100.0).hit());
  EXPECT_FALSE(diamond.cast(up(0.44), 100.0).hit());
}

}  // namespace
}  // namespace lidartag::sim
