// Boards that are not tags (calibration checkerboards, boards with holes, retro-reflective strips,
// signs): their printed face as a raster, and their placement in the world. They exist to find
// false positives: a detector must never report a tag on them.
#pragma once

#include <Eigen/Core>
#include <string>

#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

// The printed face of a board (not a tag: PrintedPattern::tag = -1), width x height of the board,
// row 0 at the top, as seen from the front before the board's rotation.
PrintedPattern board_pattern(const CalibrationBoardOptions& board);

// World <- board frame: x the normal out of the front face, z up the board before the rotation
// (tag_rotation's convention); an unset normal faces `sensor_position` horizontally. Throws
// SceneError naming `key` when the board is straight above or below the sensor.
Eigen::Matrix3d board_rotation(const CalibrationBoardOptions& board,
                               const Eigen::Vector3d& sensor_position, const std::string& key);

// Adds the board (front face through `center`, its holes, its printed face) and its stand.
void add_board(World& world, const CalibrationBoardOptions& board, const Eigen::Matrix3d& rotation);

}  // namespace lidartag::sim
