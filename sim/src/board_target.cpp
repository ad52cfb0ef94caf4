#include "lidartag/sim/board_target.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lidartag/sim/random.hpp"
#include "lidartag/sim/tag_target.hpp"

namespace lidartag::sim {
namespace {

// Raster of about 1 cm cells over the whole board, filled with the board's reflectivity.
PrintedPattern blank(const CalibrationBoardOptions& b, double cell) {
  PrintedPattern p;
  p.width = b.size[0];
  p.height = b.size[1];
  p.cols = std::max(1, static_cast<int>(std::lround(p.width / cell)));
  p.rows = std::max(1, static_cast<int>(std::lround(p.height / cell)));
  p.reflectivity.assign(static_cast<size_t>(p.cols) * static_cast<size_t>(p.rows), b.reflectivity);
  return p;
}

// The raster cells whose centres lie in [y0, y1] x [z0, z1] (board frame, metres) take `value`.
void fill(PrintedPattern& p, double y0, double y1, double z0, double z1, double value) {
  const double cw = p.width / p.cols, ch = p.height / p.rows;
  for (int r = 0; r < p.rows; ++r) {
    const double z = p.height / 2 - (r + 0.5) * ch;
    if (z < z0 || z > z1) continue;
    for (int c = 0; c < p.cols; ++c) {
      const double y = -p.width / 2 + (c + 0.5) * cw;
      if (y >= y0 && y <= y1)
        p.reflectivity[static_cast<size_t>(r) * static_cast<size_t>(p.cols) +
                       static_cast<size_t>(c)] = value;
    }
  }
}

PrintedPattern checkerboard(const CalibrationBoardOptions& b) {
  // One raster cell per square, the rest of the board (a margin) in the board's reflectivity:
  // the printed area is exactly the squares.
  PrintedPattern p;
  p.cols = b.inner_corners[0] + 1;
  p.rows = b.inner_corners[1] + 1;
  p.width = p.cols * b.square_m;
  p.height = p.rows * b.square_m;
  for (int r = 0; r < p.rows; ++r)
    for (int c = 0; c < p.cols; ++c)
      p.reflectivity.push_back((r + c) % 2 == 0 ? b.dark_reflectivity : b.reflectivity);
  return p;
}

PrintedPattern strips(const CalibrationBoardOptions& b) {
  PrintedPattern p = blank(b, 0.005);
  const double span = b.vertical_strips ? b.size[0] : b.size[1];
  const double w = b.strip_width_m / 2;
  for (int k = 0; k < b.strips; ++k) {
    const double centre = -span / 2 + (k + 0.5) * span / b.strips;
    if (b.vertical_strips)
      fill(p, centre - w, centre + w, -b.size[1], b.size[1], b.strip_reflectivity);
    else
      fill(p, -b.size[0], b.size[0], centre - w, centre + w, b.strip_reflectivity);
  }
  return p;
}

// A dark border, then lines of letters: each a 3 x 5 glyph of random dark pixels (at least one
// per column, as letters are), letter height 0.6 of the line pitch, width 0.6 of its height.
PrintedPattern sign(const CalibrationBoardOptions& b) {
  PrintedPattern p = blank(b, 0.005);
  const double hw = b.size[0] / 2, hh = b.size[1] / 2, e = b.border_m;
  fill(p, -hw, hw, hh - e, hh, b.dark_reflectivity);
  fill(p, -hw, hw, -hh, -hh + e, b.dark_reflectivity);
  fill(p, -hw, -hw + e, -hh, hh, b.dark_reflectivity);
  fill(p, hw - e, hw, -hh, hh, b.dark_reflectivity);
  if (b.text_lines <= 0) return p;
  Rng rng(b.text_seed);
  const double inner_h = b.size[1] - 2 * e - 2 * e, inner_w = b.size[0] - 4 * e;
  const double pitch = inner_h / b.text_lines;
  const double letter_h = 0.6 * pitch, letter_w = 0.6 * letter_h, gap = 0.3 * letter_h;
  const double px = letter_w / 3, pz = letter_h / 5;
  const int letters = std::max(1, static_cast<int>((inner_w + gap) / (letter_w + gap)));
  const double line_w = letters * letter_w + (letters - 1) * gap;
  for (int line = 0; line < b.text_lines; ++line) {
    const double top = hh - 2 * e - (pitch - letter_h) / 2 - line * pitch;
    for (int k = 0; k < letters; ++k) {
      if (rng.bernoulli(0.15)) continue;  // a space between words
      const double left = -line_w / 2 + k * (letter_w + gap);
      for (int gx = 0; gx < 3; ++gx) {
        const int forced = rng.uniform_int(0, 4);
        for (int gz = 0; gz < 5; ++gz) {
          if (gz != forced && !rng.bernoulli(0.5)) continue;
          fill(p, left + gx * px, left + (gx + 1) * px, top - (gz + 1) * pz, top - gz * pz,
               b.dark_reflectivity);
        }
      }
    }
  }
  return p;
}

}  // namespace

PrintedPattern board_pattern(const CalibrationBoardOptions& b) {
  switch (b.kind) {
    case BoardKind::kCheckerboard:
      return checkerboard(b);
    case BoardKind::kStrips:
      return strips(b);
    case BoardKind::kSign:
      return sign(b);
    case BoardKind::kHoles:
      break;
  }
  return blank(b, std::max(b.size[0], b.size[1]));  // plain: one cell
}

Eigen::Matrix3d board_rotation(const CalibrationBoardOptions& b,
                               const Eigen::Vector3d& sensor_position, const std::string& key) {
  const Eigen::Vector3d center(b.center[0], b.center[1], b.center[2]);
  Eigen::Vector3d n(b.normal[0], b.normal[1], b.normal[2]);
  if (n.norm() < 1e-9) {
    n = sensor_position - center;
    n.z() = 0.0;
    if (n.norm() < 1e-9)
      throw SceneError(key +
                       ".normal: the board is straight above or below the sensor; give a normal");
  }
  return tag_rotation(n, b.rotation_deg);
}

void add_board(World& world, const CalibrationBoardOptions& b, const Eigen::Matrix3d& rotation) {
  const Eigen::Vector3d center(b.center[0], b.center[1], b.center[2]);
  OrientedBox box;
  box.rotation = rotation;
  box.half = Eigen::Vector3d(b.thickness / 2.0, b.size[0] / 2.0, b.size[1] / 2.0);
  box.center = center - rotation.col(0) * (b.thickness / 2.0);
  box.reflectivity = b.reflectivity;
  for (const auto& h : b.holes) box.holes.push_back({h[0], h[1], h[2]});
  box.pattern = world.add_pattern(board_pattern(b));
  world.add_box(box);
  if (b.stand.enabled && center.z() > 0.0) {
    // A post from the ground up to the board's centre, just behind it.
    const Eigen::Vector3d behind =
        center - rotation.col(0) * (b.thickness + b.stand.width / 2.0 + 1e-3);
    const Eigen::Vector3d n = rotation.col(0);
    const double yaw = std::atan2(n.y(), n.x()) * 180.0 / std::numbers::pi;
    world.add_box(make_box(Eigen::Vector3d(behind.x(), behind.y(), center.z() / 2.0),
                           Eigen::Vector3d(b.stand.width, b.stand.width, center.z()), yaw,
                           b.stand.reflectivity));
  }
}

}  // namespace lidartag::sim
