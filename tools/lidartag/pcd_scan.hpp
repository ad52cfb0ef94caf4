// A PCD file as one scan, for the lidartag tool (detect, render, calibrate, info, dump) and
// Python's lidartag.read(): the file's fields by name (driver/cloud_fields.hpp's vocabulary, as a
// bag's clouds are) into a scan (detector/cloud_scan.hpp): organised dumps keep their cells, other
// clouds are binned by azimuth; rings from the ring field, or regressed from the elevations (a
// model's beam table, or `rings` beams estimated from the cloud). Glue between the PCD reader
// (bytes) and the detector's cloud conversion (scans); it knows no command line.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/sources/model_name.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"

namespace lidartag::clouds {

struct PcdScan {
  detector::CloudScanReport report;
  std::vector<std::string> fields;  // the file's fields, in file order (COUNT 1 ones)
  std::string ring_field;           // the file's field read as the ring; empty: none
  size_t file_points = 0;           // width x height of the file
  size_t width = 0, height = 0;     // organised when height > 1
  bool width_from_points = false;   // the file said WIDTH 0 and POINTS N: read as N x 1
  velodyne::PcdFormat format = velodyne::PcdFormat::kBinary;
  velodyne::PcdRotation rotation;  // what the header comments said (lidartag dump writes them)
};

// The file's side of a PcdScan (fields, size, format, header comments); no report, no ring field.
PcdScan describe_pcd(const velodyne::PcdCloud& pcd);

// Reads `path` into `scan`: the header comments' rotation fields (stamp, sequence, model, ...)
// are set where present; `model` (either vendor's) places a cloud without a ring field (its beam
// table, driver::ring_source), and a Velodyne model names the scan's model when the file does not.
// Throws driver::IoError (unreadable, corrupt, no x, y or z field) or detector::CloudError prefixed
// with the path (a cloud that cannot become a scan: no intensity, rings that cannot be regressed),
// detector::NoRingFieldError when it has no ring field and neither `model` nor `rings` is given.
PcdScan read_pcd_scan(const std::string& path, const std::optional<driver::ModelName>& model,
                      int rings, double resolution_deg, Scan& scan);

}  // namespace lidartag::clouds
