// The PointCloud2 topic of a ROS bag or MCAP file as scans, for `lidartag detect`: each cloud's
// fields by name (driver/bag/messages.hpp's cloud_columns) into a scan as a PCD file's are
// (detector/cloud_scan.hpp): a ring field when the cloud has one, else rings regressed from the
// elevations (--model's beam table or --rings beams).
#pragma once

#include <cstddef>
#include <functional>
#include <string>

#include "lidartag/common.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::cli {

// Whether `args.capture` is a bag (by content) whose LiDAR topic (--topic, or the one LiDAR
// topic) holds sensor_msgs/PointCloud2; false for anything else (the capture reader then takes
// it, and says what is wrong with it). Throws driver::IoError when the bag's topic choice fails.
bool is_point_cloud_bag(const CaptureArgs& args);

// Calls `each` with every cloud of the topic as a scan (its stamp the cloud's header stamp, its
// sequence the cloud's number from 0); returns the clouds read. Clouds that do not decode, or
// cannot become a scan, are skipped with a warning naming them. Throws driver::IoError when the
// bag cannot be opened.
size_t for_each_bag_cloud(const CaptureArgs& args, int rings, double resolution_deg,
                          const std::function<void(const Scan&)>& each);

}  // namespace lidartag::cli
