// Where the tests find the real bags (../shared/captures/bags), and copies of them made in a
// temporary folder for the damage tests (never committed).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

namespace lidartag::driver::bag::testing {

inline std::string bags_dir() {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/bags";
}
inline std::string bag(const std::string& name) {
  return bags_dir() + "/" + name;
}
inline std::string capture(const std::string& name) {
  return std::string(LIDARTAG_SHARED_DIR) + "/captures/" + name;
}

// Skips the test, saying why, when the real bags are not there.
#define LIDARTAG_REQUIRE_BAGS()                                                          \
  do {                                                                                   \
    if (!std::filesystem::is_directory(::lidartag::driver::bag::testing::bags_dir())) {  \
      GTEST_SKIP() << "no real bags in " << ::lidartag::driver::bag::testing::bags_dir() \
                   << " (../shared/captures/bags beside the project)";                   \
    }                                                                                    \
  } while (false)

inline std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void write_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// A fresh temporary folder, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("lidartag_bag_test_" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace lidartag::driver::bag::testing
