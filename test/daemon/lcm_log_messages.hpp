// The daemon's messages as an LCM log holds them, decoded with the generated types: what the
// end-to-end tests read back after a replay into file://LOG?mode=w.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <exception>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

#include "lidartag/point_cloud_t.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "lidartag/status_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "lidartag/tag_points_t.hpp"

namespace lidartag::daemon::lcm_test {

// Decodes one message; false when its bytes are not exactly one T.
template <class T>
bool decode(const void* data, size_t size, T& out) {
  try {
    return out.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
  } catch (const std::exception&) {
    return false;
  }
}

struct LoggedMessages {
  std::vector<lidartag::tag_detections_t> detections;
  std::vector<lidartag::status_t> status;
  std::vector<lidartag::raw_packet_t> raw;
  std::vector<lidartag::tag_points_t> tag_points;
  std::vector<lidartag::point_cloud_t> clouds;
};

// Every message of the daemon's channels (named PREFIX + LIDARTAG_...) in the log at `path`; a log
// that cannot be opened or a message that does not decode fails the test.
inline LoggedMessages read_log(const std::string& path, const std::string& prefix = "") {
  LoggedMessages d;
  lcm::LogFile log(path, "r");
  EXPECT_TRUE(log.good()) << path;
  if (!log.good()) return d;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    const auto size = static_cast<size_t>(e->datalen);
    if (e->channel == prefix + "LIDARTAG_DETECTIONS") {
      EXPECT_TRUE(decode(e->data, size, d.detections.emplace_back()));
    } else if (e->channel == prefix + "LIDARTAG_STATUS") {
      EXPECT_TRUE(decode(e->data, size, d.status.emplace_back()));
    } else if (e->channel == prefix + "LIDARTAG_RAW") {
      EXPECT_TRUE(decode(e->data, size, d.raw.emplace_back()));
    } else if (e->channel == prefix + "LIDARTAG_TAG_POINTS") {
      EXPECT_TRUE(decode(e->data, size, d.tag_points.emplace_back()));
    } else if (e->channel == prefix + "LIDARTAG_CLOUD") {
      EXPECT_TRUE(decode(e->data, size, d.clouds.emplace_back()));
    }
  }
  return d;
}

}  // namespace lidartag::daemon::lcm_test
