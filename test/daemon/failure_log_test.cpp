// Publish failures: every one counted, logged at most once per interval with the count.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <sstream>
#include <thread>

#include "lidartag/daemon/rotation_publisher.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

// The default logger writes into `out` while it lives.
class CapturedLog {
 public:
  CapturedLog() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out_);
    sink->set_pattern("%v");
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("captured", sink));
  }
  ~CapturedLog() { spdlog::set_default_logger(previous_); }
  std::vector<std::string> lines() const {
    std::vector<std::string> v;
    std::istringstream in(out_.str());
    for (std::string l; std::getline(in, l);) v.push_back(l);
    return v;
  }

 private:
  std::ostringstream out_;
  std::shared_ptr<spdlog::logger> previous_;
};

TEST(FailureLog, CountsEveryFailureAndLogsAtMostOncePerInterval) {
  CapturedLog log;
  FailureLog failures("front", 300ms);
  for (int i = 0; i < 10; ++i) failures.failed("front_LIDARTAG_DETECTIONS");
  EXPECT_EQ(failures.count(), 10u);
  failures.report();  // too soon for another line
  ASSERT_EQ(log.lines().size(), 1u);
  EXPECT_EQ(log.lines()[0],
            "sensor front: 1 LCM message not published (last on front_LIDARTAG_DETECTIONS; 1 in "
            "all)");
  std::this_thread::sleep_for(350ms);
  failures.report();  // the burst that followed, once the interval is over
  ASSERT_EQ(log.lines().size(), 2u);
  EXPECT_EQ(log.lines()[1],
            "sensor front: 9 LCM messages not published since the last report (last on "
            "front_LIDARTAG_DETECTIONS; 10 in all)");
  failures.report();  // nothing new: no line
  EXPECT_EQ(log.lines().size(), 2u);
}

}  // namespace
}  // namespace lidartag::daemon
