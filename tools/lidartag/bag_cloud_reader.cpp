#include "lidartag/bag_cloud_reader.hpp"

#include <string>

namespace lidartag::clouds {

namespace bag = driver::bag;

namespace {
// The topic asked for, or the one LiDAR topic, and whether it holds PointCloud2.
std::pair<std::string, bool> cloud_topic(const bag::MessageReader& reader, const std::string& topic,
                                         const std::string& path) {
  const std::string chosen = bag::choose_lidar_topic(reader.connections(), topic, path);
  for (const bag::Connection& c : reader.connections())
    if (c.topic == chosen)
      return {chosen, bag::message_kind(c.type) == bag::MessageKind::kPointCloud2};
  return {chosen, false};
}
}  // namespace

bool holds_point_clouds(const std::string& path, const std::string& topic) {
  if (bag::detect_bag_format(path) == bag::BagFormat::kNone) return false;
  return cloud_topic(*bag::open_bag(path), topic, path).second;
}

BagCloudReader::BagCloudReader(const std::string& path, BagCloudOptions options)
    : options_(std::move(options)) {
  bag::ReaderOptions reader_options;
  {
    const auto all = bag::open_bag(path);
    const auto [topic, clouds] = cloud_topic(*all, options_.topic, path);
    if (!clouds)
      throw bag::BagError(path + ": topic " + topic + " does not hold sensor_msgs/PointCloud2");
    options_.topic = topic;
  }
  reader_options.topics = {options_.topic};
  reader_options.start_s = options_.start_s;
  reader_options.duration_s = options_.duration_s;
  reader_ = bag::open_bag(path, reader_options);
}

BagCloudReader::Step BagCloudReader::next(Scan& scan) {
  if (!reader_->next(message_)) return Step::kEnd;
  problem_.clear();
  const bag::DecodeResult decoded = bag::decode_point_cloud(
      message_.data, reader_->connections()[message_.connection].encoding, cloud_);
  if (decoded != bag::DecodeResult::kOk) {
    problem_ = std::string(bag::decode_result_name(decoded));
    ++skipped_;
    return Step::kSkipped;
  }
  bag::cloud_columns(cloud_, columns_);
  const detector::CloudFields fields = detector::cloud_fields_by_name(
      columns_.names, columns_.columns, columns_.width, columns_.height);
  const detector::CloudScanOptions scan_options = detector::cloud_scan_options(
      fields, options_.elevations_deg, options_.rings, options_.resolution_deg);
  needs_rings_ = false;
  try {
    report_ = detector::cloud_to_scan(fields, scan_options, scan);
  } catch (const detector::CloudError& e) {
    needs_rings_ = dynamic_cast<const detector::NoRingFieldError*>(&e) != nullptr;
    problem_ = e.what();
    ++skipped_;
    return Step::kSkipped;
  }
  scan.stamp_ns = cloud_.stamp_ns != 0 ? cloud_.stamp_ns : message_.time_ns;
  scan.sequence = scans_++;
  scan.complete = true;
  return Step::kScan;
}

}  // namespace lidartag::clouds
