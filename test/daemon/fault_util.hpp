// Shared by the fault tests (fault_test.cpp, fault_pending_test.cpp): scratch paths, a re-run of
// one test inside new mount and network namespaces (where it may mount small or read-only tmpfs
// file systems of its own), waiting for a process's output, the final status of an LCM log, a
// short cut of a capture.
#pragma once

#include <gtest/gtest.h>
#include <sys/mount.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "daemon/demo_daemon.hpp"  // kDaemon, kDemoConfig, kDemo
#include "daemon/process.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/status_t.hpp"
#include "temp_dir.hpp"

namespace lidartag::test::faults {

using namespace std::chrono_literals;

inline std::string temp(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartagd_faults");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

inline constexpr const char* kInNamespaces = "LIDARTAG_FAULTS_IN_NAMESPACES";

// Runs the current test again inside new mount and network namespaces (lo up). False when
// unshare is not permitted (the caller skips).
inline bool rerun_in_namespaces() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test = std::string(info->test_suite_name()) + "." + info->name();
  Process probe({"/usr/bin/unshare", "-m", "-n", "true"}, {}, temp("probe"));
  if (probe.wait(10s) != 0) return false;
  Process inner({"/usr/bin/unshare", "-m", "--propagation", "private", "-n", "sh", "-c",
                 "ip link set lo up && exec \"$0\" --gtest_filter=\"$1\"",
                 std::filesystem::read_symlink("/proc/self/exe").string(), test},
                {std::string(kInNamespaces) + "=1"}, temp("inner"));
  const int status = inner.wait(300s);
  EXPECT_EQ(status, 0) << inner.out() << inner.err();
  EXPECT_NE(inner.out().find("[  PASSED  ] 1 test"), std::string::npos) << inner.out();
  return true;
}

#define IN_NAMESPACES()                                                                     \
  if (std::getenv(::lidartag::test::faults::kInNamespaces) == nullptr) {                    \
    if (!::lidartag::test::faults::rerun_in_namespaces())                                   \
      GTEST_SKIP() << "unshare -m -n is not permitted here: this test mounts file systems"; \
    return;                                                                                 \
  }

// A tmpfs of `kib` KiB at a new directory (inside the test's own mount namespace).
inline std::string mount_tmpfs(const std::string& name, int kib, bool read_only) {
  const std::string dir = temp(name);
  std::filesystem::create_directories(dir);
  const std::string options = "size=" + std::to_string(kib) + "k";
  EXPECT_EQ(mount("tmpfs", dir.c_str(), "tmpfs", read_only ? MS_RDONLY : 0, options.c_str()), 0)
      << "mount " << dir << ": " << std::strerror(errno);
  return dir;
}

// Fills the file system of `dir` (a filler file) until nothing more fits.
inline void fill(const std::string& dir) {
  std::FILE* f = std::fopen((dir + "/filler").c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::vector<char> block(4096, 'x');
  while (std::fwrite(block.data(), 1, block.size(), f) == block.size()) {
  }
  std::fclose(f);
}

inline bool wait_until(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return condition();
}

inline size_t lines_in(const std::string& text) {
  return static_cast<size_t>(std::count(text.begin(), text.end(), '\n'));
}

// The last status_t of an LCM log (the final one when the daemon ended normally).
inline std::optional<lidartag::status_t> last_status(const std::string& log) {
  lcm::LogFile in(log, "r");
  if (!in.good()) return std::nullopt;
  std::optional<lidartag::status_t> last;
  while (const lcm::LogEvent* e = in.readNextEvent()) {
    if (e->channel != "LIDARTAG_STATUS") continue;
    lidartag::status_t s;
    try {
      if (s.decode(e->data, 0, e->datalen) == e->datalen) last = s;
    } catch (const std::exception&) {
    }
  }
  return last;
}

// The first `seconds` of the demo as a capture of its own.
inline void cut_demo(const std::string& path, double seconds) {
  driver::PcapSource source(kDemo);
  driver::PcapWriter writer(path);
  driver::RawPacket p;
  int64_t first = -1;
  while (source.next(p, 0ms) == driver::ReadStatus::kPacket) {
    if (first < 0) first = p.receive_time_ns;
    if (static_cast<double>(p.receive_time_ns - first) * 1e-9 > seconds) break;
    writer.write_udp(p.payload, p.receive_time_ns, p.destination_port);
  }
  writer.close();
}

}  // namespace lidartag::test::faults
