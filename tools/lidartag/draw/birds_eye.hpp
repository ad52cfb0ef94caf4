// The bird's-eye picture of one rotation: every point seen from above coloured by intensity, the
// detections (outline, family and id, axes) and the clusters the pipeline rejected, coloured by
// the stage that dropped them, with a legend, range rings and a scale bar.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::draw {

struct ViewCluster {
  int index = 0;  // in ScanResult::diagnostics: what `detect --clusters` prints
  const detector::ClusterDiagnostic* diagnostic = nullptr;
  std::span<const detector::ClusterPoint> points;  // empty when the detector did not keep them
};

struct BirdsEyeOptions {
  int size_px = 1000;  // the map is square; a strip below it holds the title and the legend
  // Half the side of the area shown, metres around the sensor; 0: the detections and the clusters
  // that reached the plane fit, with room around them (at least 5 m).
  double range_m = 0.0;
  int highlight = -1;  // a cluster index drawn thicker and labelled
  std::vector<std::string> title;
};

// Where a sensor-frame point lands: pixel x = centre_x - y * px_per_m, pixel y = centre_y -
// x * px_per_m (x forward is up, y left is left).
struct BirdsEyeMapping {
  double px_per_m = 0, centre_x = 0, centre_y = 0, range_m = 0;
};

// The range to show by default (see BirdsEyeOptions::range_m).
double auto_range_m(const Scan& scan, const detector::ScanResult& result,
                    const std::vector<ViewCluster>& clusters);

// Draws and writes the PNG; throws std::runtime_error when it cannot be written.
BirdsEyeMapping write_birds_eye(const Scan& scan, const detector::ScanResult& result,
                                const std::vector<ViewCluster>& clusters,
                                const BirdsEyeOptions& options, const std::string& path);

}  // namespace lidartag::draw
