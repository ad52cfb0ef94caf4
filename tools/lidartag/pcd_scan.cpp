#include "lidartag/pcd_scan.hpp"

#include <algorithm>

#include "lidartag/driver/cloud_fields.hpp"

namespace lidartag::clouds {

PcdScan describe_pcd(const velodyne::PcdCloud& pcd) {
  PcdScan out;
  out.fields = pcd.fields;
  out.file_points = pcd.size();
  out.width = pcd.width;
  out.height = pcd.height;
  out.width_from_points = pcd.width_from_points;
  out.format = pcd.format;
  out.rotation = pcd.rotation;
  return out;
}

PcdScan read_pcd_scan(const std::string& path, const std::optional<driver::ModelName>& model,
                      int rings, double resolution_deg, Scan& scan) {
  const velodyne::PcdCloud pcd = velodyne::read_pcd_points(path);
  driver::CloudColumns columns;  // another driver's field names read as a bag's clouds are
  velodyne::pcd_cloud_columns(pcd, columns);
  const detector::CloudFields fields =
      detector::cloud_fields_by_name(columns.names, columns.columns, columns.width, columns.height);
  const driver::RingSource ring_source = driver::ring_source(model, rings);
  const detector::CloudScanOptions options = detector::cloud_scan_options(
      fields, ring_source.elevations_deg, ring_source.rings, resolution_deg);
  PcdScan out = describe_pcd(pcd);
  if (const auto ring = std::find(columns.names.begin(), columns.names.end(), "ring");
      ring != columns.names.end())
    out.ring_field = columns.source[static_cast<size_t>(ring - columns.names.begin())];
  try {
    out.report = detector::cloud_to_scan(fields, options, scan);
  } catch (const detector::NoRingFieldError& e) {
    throw detector::NoRingFieldError(path + ": " + e.what());
  } catch (const detector::CloudError& e) {
    throw detector::CloudError(path + ": " + e.what());
  }
  velodyne::apply_pcd_rotation(pcd.rotation, scan);
  if (!pcd.rotation.model && model && model->velodyne)
    scan.model = static_cast<uint8_t>(*model->velodyne);
  return out;
}

}  // namespace lidartag::clouds
