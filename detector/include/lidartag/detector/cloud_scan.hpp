// A point cloud read from a file (a PCD written by `lidartag dump`, or by another tool) as the
// ring-major Scan the detector takes. Used by `lidartag detect` and the Python module alike.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

// The cloud cannot become a scan (no intensity, no way to tell the rings, sizes that disagree).
class CloudError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The cloud has no ring field and the options give no way to regress one (neither beam
// elevations nor a ring count): callers that can supply either (a --model, --rings) say so.
class NoRingFieldError : public CloudError {
 public:
  using CloudError::CloudError;
};

// The cloud's fields, one value per point (e.g. a PCD file's columns); an empty span: the cloud
// has no such field.
struct CloudFields {
  std::span<const double> x, y, z;      // metres, sensor frame; required. NaN: no return
  std::span<const double> intensity;    // 0..255 reflectivity; required (tags are read from it)
  std::span<const double> ring;         // optional: 0 = the lowest beam
  std::span<const double> azimuth_deg;  // optional: clockwise from +x, as the sensor's
  std::span<const double> time_s;       // optional: seconds from the rotation start
  std::span<const double> return_type;  // optional: lidartag::ReturnType values
  size_t width = 0, height = 1;         // height > 1: organised, row-major, width columns
};

struct CloudScanOptions {
  // With ring numbers: the scan's rings (0: the largest ring in the cloud + 1). Without: the
  // number of beams to estimate from the cloud when no elevations are given.
  int rings = 0;
  // Beam elevations, degrees, for a cloud without ring numbers (a model's table). Empty: estimated.
  std::vector<double> elevations_deg;
  // Column width, degrees of azimuth, when columns are made by binning azimuths (every cloud
  // that is not organised with ring numbers). Default 0: the cloud's own, kColumnStepShare of the
  // median azimuth step between neighbouring points of a ring; kDefaultColumnWidthDeg for a cloud
  // without level ring numbers. Negative or NaN: CloudError.
  double resolution_deg = 0.0;
  // A ring field whose rings are not level (kMaxRingSpreadDeg: Livox's line numbers, each line of
  // its non-repetitive pattern sweeping every elevation; Luminar's two lasers): set aside and the
  // rings regressed instead, from `elevations_deg` or else this many beams estimated from the
  // cloud. 0 (default) with no elevations: such a field is kept as the rings (reported).
  int unlevel_ring_beams = 0;
};

// Mean distance, degrees, of a ring's points from their ring's mean elevation above which a ring
// field's rings are not level (a spinning sensor's ring holds one elevation to a few hundredths of
// a degree, and its beams are at least 0.1 degrees apart).
inline constexpr double kMaxRingSpreadDeg = 1.0;
// The column width of a cloud without level ring numbers (a Velodyne at 10 Hz), degrees.
inline constexpr double kDefaultColumnWidthDeg = 0.2;
// The column width read from a cloud: this share of its azimuth step (a firing that comes 5 %
// early or late still gets a column of its own; one in 20 columns is left empty), within
// [kMinColumnWidthDeg, kMaxColumnWidthDeg]; read from at least kMinColumnSteps steps.
inline constexpr double kColumnStepShare = 0.95;
inline constexpr double kMinColumnWidthDeg = 0.01;
inline constexpr double kMaxColumnWidthDeg = 2.0;
inline constexpr size_t kMinColumnSteps = 100;
// The level check reads the points this far or farther, metres, when there are this many of them
// (nearer, a beam origin's offset from the axis widens a ring's elevations; see cloud_scan.cpp).
inline constexpr double kLevelMinRangeM = 3.0;
inline constexpr size_t kLevelMinPoints = 1000;

struct CloudScanReport {
  size_t points = 0;               // points with a return placed in the scan
  size_t skipped_coordinates = 0;  // x, y or z infinite or beyond a float (NaN is "no return")
  size_t skipped_rings = 0;        // ring not a whole number in 0..255 (or >= options.rings)
  // Binned by azimuth (not a grid): points that fell into a cell of their ring a nearer point
  // took (the column width is too coarse for them), dropped.
  size_t merged = 0;
  // Of `merged`: points that met a point of their ring in the same direction, the other echo of
  // one firing (a dual-return cloud); the nearer echo is kept.
  size_t echoes = 0;
  double resolution_deg = 0.0;  // the column width the points were binned with (not a grid)
  // That width was read from the cloud's own step (neither given nor the default).
  bool column_from_cloud = false;
  // Organised with ring numbers: each point kept its column and return (rows: the rings of return
  // 0, then of return 1, as `lidartag dump --organized` writes).
  bool grid = false;
  bool regressed = false;  // no ring numbers: rings from elevations (ring_regression.hpp)
  // The ring field's rings are not level (CloudScanOptions::unlevel_ring_beams): regressed when
  // the options allow, else kept as they are.
  bool rings_not_level = false;
  bool intensity_scaled = false;  // every intensity within [0, 1]: read as 0..1, scaled by 255
};

// The names of a cloud's fields, as `lidartag dump` writes them and Rotation.points has them: x,
// y, z, intensity, ring, azimuth, time, return_type (CloudFields: x ... return_type).
inline constexpr std::array<std::string_view, 8> kCloudFieldNames = {
    "x", "y", "z", "intensity", "ring", "azimuth", "time", "return_type"};

// The fields of a cloud whose columns are named as in kCloudFieldNames (other names are ignored),
// e.g. a PCD file's (velodyne::PcdCloud's fields and columns): each views its column, empty where
// the cloud has no column of that name.
CloudFields cloud_fields_by_name(const std::vector<std::string>& names,
                                 const std::vector<std::span<const double>>& columns, size_t width,
                                 size_t height);
CloudFields cloud_fields_by_name(const std::vector<std::string>& names,
                                 const std::vector<std::vector<double>>& columns, size_t width,
                                 size_t height);

// The options for `cloud` from a sensor model's beam elevations (`model_elevations_deg`, one per
// ring: the scan has that many rings) or, without a model (empty), `rings` beams to estimate when
// the cloud has no ring numbers (with ring numbers, the rings they give; `rings` beams are
// estimated when they are not level).
CloudScanOptions cloud_scan_options(const CloudFields& cloud,
                                    std::vector<double> model_elevations_deg, int rings,
                                    double resolution_deg);

// Fills `out` (resized as needed) with the cloud; its per-rotation fields (stamp, sequence, ...)
// are left cleared for the caller. Throws CloudError: points without intensity (the detector
// decodes tags from intensity; an xyz-only cloud would silently give no tags), fields of different
// sizes, width x height not the size, no ring numbers with neither elevations nor a ring count,
// rings that cannot be regressed, no usable point with a ring number.
CloudScanReport cloud_to_scan(const CloudFields& cloud, const CloudScanOptions& options, Scan& out);

}  // namespace lidartag::detector
