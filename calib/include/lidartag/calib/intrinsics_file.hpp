// A camera's intrinsics from the files users already have: ROS camera_info YAML (what
// camera_calibration writes: image_width, image_height, camera_matrix {rows, cols, data},
// distortion_model, distortion_coefficients) and OpenCV FileStorage YAML ("%YAML:1.0",
// !!opencv-matrix nodes with rows, cols, dt, data; keys camera_matrix or K,
// distortion_coefficients or D, image_width / image_height, distortion_model or a fisheye flag).
// Both are read into a CameraModel, which must then pass CameraModel::check(). Pixel convention:
// both formats put (0, 0) at the centre of the top-left pixel, as CameraModel does, so the
// numbers are taken as they are.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

#include "lidartag/calib/camera_model.hpp"

namespace lidartag::calib {

// An intrinsics file that cannot be read or does not describe a camera: the message names the
// file and the key ("camera.yaml: camera_matrix: expected 9 values, got 6").
class IntrinsicsFileError : public std::runtime_error {
 public:
  IntrinsicsFileError(const std::string& origin, const std::string& key, const std::string& what)
      : std::runtime_error(origin + ": " + (key.empty() ? "" : key + ": ") + what), key_(key) {}
  // The offending key ("" for the file as a whole: unreadable, not YAML, not a map).
  const std::string& key() const { return key_; }

 private:
  std::string key_;
};

// Parses the text of a ROS camera_info or OpenCV FileStorage YAML file (the form is recognised by
// its keys; OpenCV's "%YAML:1.0" first line, which YAML parsers refuse, is accepted). `origin`
// names the file in messages. Distortion models: plumb_bob (ROS; OpenCV's 4, 5, 8, 12 or 14
// coefficients when those past the fifth are zero), equidistant / fisheye (4 coefficients) and
// none (no or empty coefficients). rational_polynomial and OpenCV's extra coefficients that are
// not zero are refused: the camera model has no such lens. Throws IntrinsicsFileError naming the
// key, also for a model that fails CameraModel::check().
CameraModel parse_intrinsics(std::string_view text, const std::string& origin = "intrinsics");

// Reads and parses a file (parse_intrinsics). Throws IntrinsicsFileError when it cannot be read.
CameraModel load_intrinsics(const std::string& path);

}  // namespace lidartag::calib
