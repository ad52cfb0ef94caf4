#include "lidartag/bag_clouds.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <utility>

#include "lidartag/bag_cloud_reader.hpp"
#include "lidartag/driver/sources/model_name.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/exit_codes.hpp"

namespace lidartag::cli {

bool is_point_cloud_bag(const CaptureArgs& args) {
  return clouds::holds_point_clouds(args.capture, args.topic);
}

size_t for_each_bag_cloud(const CaptureArgs& args, int rings, double resolution_deg,
                          const std::function<bool(const Scan&)>& each) {
  clouds::BagCloudOptions options;
  options.topic = args.topic;
  options.start_s = args.start_s;
  options.duration_s = args.duration_s;
  const auto model = args.model.empty() ? std::nullopt : driver::model_from_name(args.model);
  driver::RingSource ring_source = driver::ring_source(model, rings);
  options.elevations_deg = std::move(ring_source.elevations_deg);
  options.rings = ring_source.rings;
  options.resolution_deg = resolution_deg;
  clouds::BagCloudReader reader(args.capture, options);
  Scan scan;
  size_t n = 0, unlevel = 0;
  for (;;) {
    const auto step = reader.next(scan);
    if (step == clouds::BagCloudReader::Step::kEnd) break;
    const std::string name = fmt::format("{}: cloud {} on {}", args.capture,
                                         reader.scans() + reader.skipped() - 1, reader.topic());
    if (step == clouds::BagCloudReader::Step::kSkipped) {
      spdlog::warn("{}: {}{}, skipped", name, reader.problem(),
                   reader.needs_rings() ? " (--model or --rings N)" : "");
      continue;
    }
    if (reader.report().merged > 0)
      spdlog::warn("{}: {}", name, merged_points_note(reader.report(), reader.cloud_points()));
    if (reader.report().rings_not_level && !reader.report().regressed) ++unlevel;
    ++n;
    if (!each(scan)) break;
  }
  const auto& r = reader.reader();
  if (!r.error().empty()) spdlog::warn("{}: {}", args.capture, r.error());
  if (reader.skipped() > 0) spdlog::warn("{}: {} clouds skipped", args.capture, reader.skipped());
  // Once, not per cloud: the ring field of every cloud of a sensor is alike.
  if (unlevel > 0)
    spdlog::warn(
        "{}: the ring field of {} cloud{} is not level (points of one ring at many elevations, as "
        "Livox's line numbers): --model or --rings N regresses rings from elevations instead",
        args.capture, unlevel, unlevel == 1 ? "" : "s");
  if (args.windowed())
    spdlog::info("{}: {} messages of {} outside --start/--duration", args.capture,
                 r.stats().outside_window, reader.topic());
  return n;
}

size_t dump_bag_clouds(const CaptureArgs& args, int rings, double resolution_deg,
                       const std::string& out, bool organized) {
  size_t written = 0, points = 0;
  for_each_bag_cloud(args, rings, resolution_deg, [&](const Scan& scan) {
    const std::string path =
        (std::filesystem::path(out) / fmt::format("rotation_{:06d}.pcd", scan.sequence)).string();
    points += velodyne::write_pcd(path, scan, {velodyne::PcdFormat::kBinary, organized});
    ++written;
    return true;
  });
  if (written == 0)
    throw UsageError(fmt::format("{}: no point cloud could be read{}", args.capture,
                                 args.windowed() ? " in --start/--duration" : ""));
  fmt::print("wrote {} PCD files ({} points) to {}\n", written, points, out);
  return written;
}

void bag_cloud_scan(const CaptureArgs& args, int rings, double resolution_deg, int64_t number,
                    Scan& scan) {
  bool found = false;
  size_t n = for_each_bag_cloud(args, rings, resolution_deg, [&](const Scan& s) {
    if (number >= 0 && s.sequence != static_cast<uint64_t>(number)) return true;
    scan = s;
    found = true;
    return false;
  });
  if (!found)
    throw UsageError(
        n == 0 ? fmt::format("{}: no point cloud could be read", args.capture)
               : fmt::format("--rotation {}: {} has clouds 0-{}", number, args.capture, n - 1));
}

int info_bag_clouds(const CaptureArgs& args, bool json) {
  clouds::BagCloudOptions options;
  options.topic = args.topic;
  options.start_s = args.start_s;
  options.duration_s = args.duration_s;
  options.rings = 1;  // info converts no cloud: only their shape and stamps are read
  clouds::BagCloudReader reader(args.capture, options);
  driver::bag::MessageReader& messages = reader.messages();
  driver::bag::BagMessage m;
  driver::bag::PointCloudView cloud;
  uint64_t clouds = 0, bad = 0, points = 0, min_points = 0, max_points = 0;
  int64_t first = 0, last = 0;
  std::string fields;
  while (messages.next(m)) {
    if (driver::bag::decode_point_cloud(m.data, messages.connections()[m.connection].encoding,
                                        cloud) != driver::bag::DecodeResult::kOk) {
      ++bad;
      continue;
    }
    const int64_t stamp = cloud.stamp_ns != 0 ? cloud.stamp_ns : m.time_ns;
    const uint64_t n = cloud.points();
    if (clouds == 0) {
      first = stamp;
      min_points = n;
      for (const auto& f : cloud.fields) {
        if (!fields.empty()) fields += ' ';
        fields += f.name;
      }
    }
    last = stamp;
    min_points = std::min(min_points, n);
    max_points = std::max(max_points, n);
    points += n;
    ++clouds;
  }
  const auto& s = messages.stats();
  const double duration = static_cast<double>(last - first) * 1e-9;
  if (json) {
    nlohmann::json j = {{"capture", args.capture},
                        {"container", driver::bag::format_name(messages.format())},
                        {"topic", reader.topic()},
                        {"type", "sensor_msgs/PointCloud2"},
                        {"clouds", clouds},
                        {"bad_clouds", bad},
                        {"points", points},
                        {"points_min", min_points},
                        {"points_max", max_points},
                        {"fields", fields},
                        {"first_stamp_ns", first},
                        {"duration_s", duration},
                        {"outside_window", s.outside_window},
                        {"skipped_chunks", s.skipped_chunks},
                        {"skipped_records", s.skipped_records},
                        {"truncated", s.truncated},
                        {"error", messages.error()}};
    fmt::print("{}\n", j.dump(2));
  } else {
    fmt::print("capture:        {}\n", args.capture);
    fmt::print("container:      {}, topic {} (sensor_msgs/PointCloud2)\n",
               driver::bag::format_name(messages.format()), reader.topic());
    fmt::print("clouds:         {} ({} did not decode), {:.3f} s\n", clouds, bad, duration);
    fmt::print("points:         {} ({} to {} a cloud)\n", points, min_points, max_points);
    fmt::print("fields:         {}\n", fields);
    if (args.windowed())
      fmt::print("window:         {} messages outside --start/--duration\n", s.outside_window);
    if (!messages.error().empty()) fmt::print("problems:       {}\n", messages.error());
  }
  if (clouds == 0)
    throw UsageError(fmt::format("{}: no point cloud could be read{}", args.capture,
                                 args.windowed() ? " in --start/--duration" : ""));
  return 0;
}

}  // namespace lidartag::cli
