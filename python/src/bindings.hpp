// The Python module `lidartag` (package python/lidartag, extension lidartag._lidartag): one
// binding file per part, each with its bind_* function called from module.cpp.
#pragma once

#include <pybind11/pybind11.h>

#include <cstdint>
#include <optional>
#include <string>

#include "lidartag/driver/scan.hpp"

namespace lidartag::python {

namespace py = pybind11;

// One rotation, owned by Python: a copy of the reader's scan holding its filled columns only.
struct Rotation {
  Scan scan;
  // The sensor's model name when the scan's model byte does not say it (an Ouster frame: "os1-128",
  // from its metadata); empty otherwise.
  std::string sensor_model;

  // Copies the filled columns of `source` (the reader's scan is reused for the next rotation).
  static Rotation copy_of(const Scan& source);
  // A rotation made of any point cloud (Rotation.from_points): `points` a numpy structured array
  // or a dict of equally long arrays, with fields x, y, z, intensity and optionally ring,
  // azimuth, time, return_type (the names Rotation.points uses). Throws CloudError.
  static Rotation from_points(const py::object& points, int rings,
                              const std::optional<std::string>& model, double resolution_deg,
                              int64_t stamp_ns, uint64_t sequence);
};

// Model and return-mode names of a scan ("vlp32c", "dual"; an Ouster frame's return mode is its
// packet profile, "RNG19_RFL8_SIG16_NIR16"); empty when unknown.
std::string model_name(const Scan& scan);
std::string model_name(const Rotation& rotation);  // sensor_model, else model_name(scan)
std::string return_mode_name(const Scan& scan);

void bind_errors(py::module_& m);
void bind_rotation(py::module_& m);  // Rotation, Reader (pcap/pcapng/PCD), PCD files
void bind_detector(py::module_& m);  // Detector, Detection, DetectionResult
void bind_sim(py::module_& m);       // simulate
void bind_lcm_log(py::module_& m);   // LcmLog, LogEvent (lidartag.lcmtypes: lcm_types.hpp)
// CameraModel, load_intrinsics, calibrate, detect_image_tags (their wrappers: __init__.py)
void bind_calib(py::module_& m);

}  // namespace lidartag::python
