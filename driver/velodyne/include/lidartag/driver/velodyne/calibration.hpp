// Per-laser corrections the decoder applies, built in for every model or read from a
// ros-drivers/velodyne YAML or VeloView XML calibration file (see calibration_file.hpp).
#pragma once

#include <vector>

#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::velodyne {

struct LaserCorrection {
  double elevation_deg = 0;        // vertical angle
  double azimuth_offset_deg = 0;   // subtracted from the firing azimuth
  double vertical_offset_m = 0;    // along the laser's vertical axis
  double horizontal_offset_m = 0;  // perpendicular to the beam in the horizontal plane
  double distance_offset_m = 0;    // added to every measured distance
};

struct Calibration {
  Model model = Model::kVLP16;
  double distance_unit_m = 0.002;       // metres per distance count
  std::vector<LaserCorrection> lasers;  // in laser (channel) order
  std::vector<int> ring_of_laser;       // rank of elevation, 0 = lowest

  // The factory table of `model` (sensor_model.cpp): what the decoder uses without a file.
  static Calibration builtin(Model model);
  // Recomputes ring_of_laser from the elevations (after editing `lasers`).
  void update_rings();
};

}  // namespace lidartag::velodyne
