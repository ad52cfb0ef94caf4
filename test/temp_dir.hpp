#pragma once
// A scratch folder for one test program: created on first use under gtest's TempDir, removed with
// everything in it when the program ends normally, so repeated test runs leave nothing behind.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace lidartag::test {

class ProcessTempDir {
 public:
  // TempDir()/PREFIX.PID: one per process, so tests run in parallel do not share it.
  explicit ProcessTempDir(const std::string& prefix)
      : owner_(::getpid()),
        path_(::testing::TempDir() + "/" + prefix + "." + std::to_string(owner_)) {
    std::filesystem::create_directories(path_);
  }
  // Only the process that made it removes it: a forked child that exits leaves it to its parent.
  ~ProcessTempDir() {
    if (::getpid() != owner_) return;
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  ProcessTempDir(const ProcessTempDir&) = delete;
  ProcessTempDir& operator=(const ProcessTempDir&) = delete;

  const std::string& path() const { return path_; }

 private:
  pid_t owner_;
  std::string path_;
};

}  // namespace lidartag::test
