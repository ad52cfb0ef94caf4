// Point Cloud Data (PCD v0.7) files: one rotation written as binary PCD, and a small reader
// (ascii and binary, fields by name) for tests and for PCD input to the detector tools.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::velodyne {

// Writes the valid cells of `scan` (every return) as binary PCD, unorganised (HEIGHT 1, WIDTH =
// point count), fields:
//   x y z        float, metres, sensor frame
//   intensity    float, calibrated reflectivity 0..255
//   ring         uint16, 0 = lowest beam
//   azimuth      float, degrees [0, 360)
//   time         float, seconds from the rotation start
//   return_type  uint8, lidartag::ReturnType
// Points go ring by ring, return by return, in column order. Throws IoError when the file cannot
// be written. Returns the number of points written.
size_t write_pcd(const std::string& path, const Scan& scan);

// A PCD file's contents, each field as one column of numbers (COUNT 1 fields only).
struct PcdCloud {
  std::vector<std::string> fields;
  std::vector<std::vector<double>> columns;  // columns[f][point]
  size_t width = 0, height = 0;

  size_t size() const { return width * height; }
  bool has(const std::string& name) const;
  // The column of field `name`; throws IoError if there is no such field.
  const std::vector<double>& field(const std::string& name) const;
};

// Reads DATA ascii or binary (not binary_compressed). Types F (4, 8), U and I (1, 2, 4, 8).
// Throws IoError naming the file and the problem (bad header, short data, unsupported layout).
PcdCloud read_pcd(const std::string& path);

}  // namespace lidartag::velodyne
