// LCM messages as the tests see them on the bus: raw bytes, decoded with the generated types.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace lidartag::daemon::lcm_test {

// Decodes one message; a length that does not match the type fails the test.
template <class T>
T decode(const std::vector<uint8_t>& bytes) {
  T msg;
  EXPECT_EQ(msg.decode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return msg;
}

}  // namespace lidartag::daemon::lcm_test
