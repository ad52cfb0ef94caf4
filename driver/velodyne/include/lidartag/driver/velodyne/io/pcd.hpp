// Point Cloud Data (PCD v0.7, PCL's format) files: a rotation written as a PCD, and a reader of
// any PCD (ascii, binary, binary_compressed; organised or not; fields by name).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/driver/cloud_fields.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::velodyne {

enum class PcdFormat : uint8_t {
  kAscii,             // DATA ascii: text, one point per line
  kBinary,            // DATA binary: packed little-endian points
  kBinaryCompressed,  // DATA binary_compressed: field by field, LZF-compressed (liblzf)
};
std::string_view pcd_format_name(PcdFormat format);  // "ascii", "binary", "binary_compressed"

struct PcdWriteOptions {
  PcdFormat format = PcdFormat::kBinary;
  // false (default): the cells with a return only, HEIGHT 1, ring by ring, return by return, in
  // column order. true: organised as PCL expects, WIDTH = the rotation's columns, HEIGHT = rings
  // x returns (row r: return r / rings, ring r % rings, ring 0 the lowest beam), every cell
  // written; a cell without a return has x y z NaN, intensity 0, return_type 0, and the azimuth
  // and time of its laser's firing.
  bool organized = false;
};

// Writes `scan` as a PCD file with the fields
//   x y z        float, metres, sensor frame (x forward, y left, z up)
//   intensity    float, calibrated reflectivity 0..255
//   ring         uint16, 0 = lowest beam
//   azimuth      float, degrees [0, 360)
//   time         float, seconds from the rotation start (its first firing): for deskewing
//   return_type  uint8, lidartag::ReturnType
// and the rotation in comment lines of the header (PCL skips them; VIEWPOINT stays the
// identity): "# stamp_ns N" (absolute time of the first firing, ns since the epoch; a point's
// time is stamp_ns + 1e9 time), "# sequence N", "# model NAME", "# return_mode NAME",
// "# complete 0|1", "# rpm X". Throws IoError when the file cannot be written. Returns the number
// of points with a return.
size_t write_pcd(const std::string& path, const Scan& scan, const PcdWriteOptions& options = {});

// The rotation a PCD's header comments describe (write_pcd's); absent keys stay empty.
struct PcdRotation {
  std::optional<int64_t> stamp_ns;
  std::optional<uint64_t> sequence;
  std::optional<Model> model;
  std::optional<uint8_t> return_mode;  // packet byte: 0x37 strongest, 0x38 last, 0x39 dual
  std::optional<bool> complete;
  std::optional<float> rpm;
};

// A PCD file's contents, each field as one column of numbers.
struct PcdCloud {
  std::vector<std::string> fields;           // fields read (COUNT 1), in file order
  std::vector<std::vector<double>> columns;  // columns[f][point]; NaN where the file says nan
  std::vector<char> types;                   // types[f]: the field's PCD TYPE, 'F', 'U' or 'I'
  std::vector<std::string> skipped_fields;   // COUNT > 1 fields and "_" padding: not read
  size_t width = 0, height = 0;              // organised when height > 1 (row-major)
  bool width_from_points = false;            // WIDTH 0 (HEIGHT 0 or 1) and POINTS N: read as N x 1
  PcdFormat format = PcdFormat::kBinary;
  PcdRotation rotation;

  size_t size() const { return width * height; }
  bool has(const std::string& name) const;
  // The column of field `name`; throws IoError if there is no such field.
  const std::vector<double>& field(const std::string& name) const;
};

// Reads DATA ascii, binary or binary_compressed, any field order; types F (4, 8), U and I (1, 2,
// 4, 8); COUNT > 1 fields and "_" padding are skipped (listed in skipped_fields). Header
// comments "# key value" of write_pcd's keys fill `rotation`. Throws IoError naming the file and
// the problem (bad header, short or corrupt data, an unsupported type, a bad rotation comment).
PcdCloud read_pcd(const std::string& path);

// read_pcd for a cloud of points (what `lidartag detect` and the Python module read): also an
// IoError naming the file when it has no x, y or z field.
PcdCloud read_pcd_points(const std::string& path);

// The cloud's columns as the detector reads them, its fields named by the vocabulary PointCloud2
// clouds share (driver/cloud_fields.hpp: another driver's `timestamp` or `t` becomes `time` in
// seconds, its `channel`, `laser_id` or `line` the `ring`). `out` is cleared first.
void pcd_cloud_columns(const PcdCloud& cloud, driver::CloudColumns& out);

// Sets the per-rotation fields of `scan` (stamp_ns, sequence, model, return_mode, complete, rpm)
// that `rotation` has; the others are left as they are.
void apply_pcd_rotation(const PcdRotation& rotation, Scan& scan);

}  // namespace lidartag::velodyne
