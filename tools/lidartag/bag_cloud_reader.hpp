// A bag's sensor_msgs/PointCloud2 topic as scans, for the lidartag tool (detect, dump, render)
// and Python's lidartag.read(): each cloud's fields by name (driver/bag/messages.hpp's
// cloud_columns) into a scan as a PCD file's are (detector/cloud_scan.hpp): its ring field when it
// has one, else rings regressed from the elevations (a model's beam table, or `rings` estimated).
// Glue between the bag reader (bytes) and the detector's cloud conversion (scans); it knows no
// command line.
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <string>

#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::clouds {

struct BagCloudOptions {
  std::string topic;  // the PointCloud2 topic; empty: the bag's one LiDAR topic
  // Time window, seconds from the bag's first message (driver::bag::ReaderOptions). Defaults: all.
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();
  // A cloud without a ring field: these beam elevations (a model's table), degrees, else `rings`
  // beams estimated from the cloud (detector::CloudScanOptions).
  std::vector<double> elevations_deg;
  int rings = 0;
  double resolution_deg = 0.0;  // column width, degrees of azimuth (0: the cloud's own)
};

// Whether `path` is a bag (by content) whose topic (`topic`, or the one LiDAR topic) holds
// sensor_msgs/PointCloud2; false for anything that is not a bag. Throws driver::bag::BagError when
// the bag's topic choice fails (listing the topics).
bool holds_point_clouds(const std::string& path, const std::string& topic);

class BagCloudReader {
 public:
  // Opens `path`; throws driver::bag::BagError: not a bag, no such topic, no LiDAR topic or
  // several, or a topic that does not hold PointCloud2.
  BagCloudReader(const std::string& path, BagCloudOptions options);

  enum class Step : uint8_t {
    kScan,     // `scan` holds the next cloud (report() says how it was placed)
    kSkipped,  // a cloud that did not decode or could not become a scan: problem() says why
    kEnd,      // the topic is read (or damage ended the reading: reader().error())
  };
  // The next cloud: stamped with its header stamp (the message's receive time when that is 0),
  // numbered from 0 among the clouds that became scans, complete.
  Step next(Scan& scan);

  const std::string& topic() const { return options_.topic; }
  const std::string& problem() const { return problem_; }
  // The last skipped cloud had no ring field and the options give neither elevations nor rings.
  bool needs_rings() const { return needs_rings_; }
  const detector::CloudScanReport& report() const { return report_; }
  size_t cloud_points() const { return cloud_.points(); }  // of the last cloud read
  size_t scans() const { return scans_; }
  size_t skipped() const { return skipped_; }
  const driver::bag::MessageReader& reader() const { return *reader_; }
  // The topic's messages undecoded (for a summary that converts none; do not mix with next()).
  driver::bag::MessageReader& messages() { return *reader_; }

 private:
  BagCloudOptions options_;
  std::unique_ptr<driver::bag::MessageReader> reader_;
  driver::bag::BagMessage message_;
  driver::bag::PointCloudView cloud_;
  driver::bag::CloudColumns columns_;
  detector::CloudScanReport report_;
  std::string problem_;
  bool needs_rings_ = false;
  size_t scans_ = 0, skipped_ = 0;
};

}  // namespace lidartag::clouds
