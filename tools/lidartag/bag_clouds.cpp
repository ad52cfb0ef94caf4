#include "lidartag/bag_clouds.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <optional>

#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::cli {

namespace bag = driver::bag;

bool is_point_cloud_bag(const CaptureArgs& args) {
  if (bag::detect_bag_format(args.capture) == bag::BagFormat::kNone) return false;
  const auto reader = bag::open_bag(args.capture);
  const std::string topic =
      bag::choose_lidar_topic(reader->connections(), args.topic, args.capture);
  for (const bag::Connection& c : reader->connections())
    if (c.topic == topic) return bag::message_kind(c.type) == bag::MessageKind::kPointCloud2;
  return false;
}

size_t for_each_bag_cloud(const CaptureArgs& args, int rings, double resolution_deg,
                          const std::function<void(const Scan&)>& each) {
  bag::ReaderOptions options;
  {
    const auto all = bag::open_bag(args.capture);
    options.topics = {bag::choose_lidar_topic(all->connections(), args.topic, args.capture)};
  }
  const auto reader = bag::open_bag(args.capture, options);
  const auto model = args.model.empty() ? std::nullopt : velodyne::model_from_name(args.model);
  bag::BagMessage m;
  bag::PointCloudView cloud;
  bag::CloudColumns columns;
  Scan scan;
  size_t n = 0, skipped = 0;
  while (reader->next(m)) {
    const std::string name =
        fmt::format("{}: cloud {} on {}", args.capture, n + skipped, options.topics.front());
    const bag::DecodeResult decoded =
        bag::decode_point_cloud(m.data, reader->connections()[m.connection].encoding, cloud);
    if (decoded != bag::DecodeResult::kOk) {
      spdlog::warn("{}: {}, skipped", name, bag::decode_result_name(decoded));
      ++skipped;
      continue;
    }
    bag::cloud_columns(cloud, columns);
    const detector::CloudFields fields = detector::cloud_fields_by_name(
        columns.names, columns.columns, columns.width, columns.height);
    const detector::CloudScanOptions scan_options = detector::cloud_scan_options(
        fields, velodyne::beam_elevations_deg(model), rings, resolution_deg);
    detector::CloudScanReport report;
    try {
      report = detector::cloud_to_scan(fields, scan_options, scan);
    } catch (const detector::CloudError& e) {
      const bool hint = fields.ring.empty() && !model && rings == 0;
      spdlog::warn("{}: {}{}, skipped", name, e.what(), hint ? " (--model or --rings N)" : "");
      ++skipped;
      continue;
    }
    if (report.merged > 0)
      spdlog::warn(
          "{}: {} of {} points fell into a cell of their ring a nearer point took "
          "(--resolution sets the column width)",
          name, report.merged, cloud.points());
    scan.stamp_ns = cloud.stamp_ns != 0 ? cloud.stamp_ns : m.time_ns;
    scan.sequence = n;
    scan.complete = true;
    each(scan);
    ++n;
  }
  if (!reader->error().empty()) spdlog::warn("{}: {}", args.capture, reader->error());
  if (skipped > 0) spdlog::warn("{}: {} clouds skipped", args.capture, skipped);
  return n;
}

}  // namespace lidartag::cli
