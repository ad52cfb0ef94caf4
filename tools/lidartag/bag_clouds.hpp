// The PointCloud2 topic of a ROS bag or MCAP file as scans, for `lidartag detect`, `dump` and
// `render` (bag_cloud_reader.hpp with the command line's options and warnings): each cloud as a
// scan as a PCD file's is (detector/cloud_scan.hpp): a ring field when the cloud has one, else
// rings regressed from the elevations (--model's beam table or --rings beams).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include "lidartag/common.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::cli {

// Whether `args.capture` is a bag (by content) whose LiDAR topic (--topic, or the one LiDAR
// topic) holds sensor_msgs/PointCloud2; false for anything else (the capture reader then takes
// it, and says what is wrong with it). Throws driver::IoError when the bag's topic choice fails.
bool is_point_cloud_bag(const CaptureArgs& args);

// Calls `each` with every cloud of the topic in the time window (--start, --duration) as a scan
// (its stamp the cloud's header stamp, its sequence the cloud's number from 0) until `each`
// returns false; returns the clouds handed to `each`. Clouds that do not decode, or cannot become
// a scan, are skipped with a warning naming them. Throws driver::IoError when the bag cannot be
// opened.
size_t for_each_bag_cloud(const CaptureArgs& args, int rings, double resolution_deg,
                          const std::function<bool(const Scan&)>& each);

// `lidartag dump` of a PointCloud2 topic: each cloud as rotation_NNNNNN.pcd in `out` (already
// prepared), written as a rotation is; returns the files written. Throws UsageError when no cloud
// became a scan.
size_t dump_bag_clouds(const CaptureArgs& args, int rings, double resolution_deg,
                       const std::string& out, bool organized);

// `lidartag render` of a PointCloud2 topic: the cloud numbered `number` (-1: the first) into
// `scan`. Throws UsageError when the topic has no such cloud.
void bag_cloud_scan(const CaptureArgs& args, int rings, double resolution_deg, int64_t number,
                    Scan& scan);

// `lidartag info` of a PointCloud2 topic: clouds, points, stamps, the fields of the first cloud and
// what could not be read (text, or one JSON object with `json`). Returns the exit code.
int info_bag_clouds(const CaptureArgs& args, bool json);

}  // namespace lidartag::cli
