// Refused configurations as data: each case's YAML must be refused by one ConfigError that names
// its key and value, with a one-line message whose reason contains reason_part.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "lidartag/daemon/config.hpp"

namespace lidartag::daemon::test {

struct BadCase {
  std::string yaml;
  std::string key, value, reason_part;
};

inline void expect_refused(const std::vector<BadCase>& cases) {
  for (const auto& c : cases) {
    SCOPED_TRACE(c.yaml);
    try {
      (void)parse_config(c.yaml);
      ADD_FAILURE() << "accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.key(), c.key);
      EXPECT_EQ(e.value(), c.value);
      EXPECT_NE(e.reason().find(c.reason_part), std::string::npos) << e.reason();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
}

}  // namespace lidartag::daemon::test
