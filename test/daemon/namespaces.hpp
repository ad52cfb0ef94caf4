// Runs one test of the current test binary again inside new Linux namespaces: a network namespace
// (lo up, optionally a multicast route), so that network tests never touch the machine's
// interfaces, or a mount namespace, so that a test can mount a small tmpfs of its own. Skips the
// test with a message where unshare is not permitted.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "daemon/process.hpp"

namespace lidartag::test {

// Set in the re-run test's environment.
inline constexpr const char* kInNamespace = "LIDARTAG_IN_NAMESPACE";

inline bool in_namespace() {
  return std::getenv(kInNamespace) != nullptr;
}

// `flags`: unshare's, e.g. {"-n"} or {"-m"}; `setup`: shell commands run first inside (e.g. "ip
// link set lo up"). `scratch` names the files for the runs' output. Returns false (the test then
// skipped) when unshare is not permitted.
inline bool rerun_in_namespace(const std::vector<std::string>& flags, const std::string& setup,
                               const std::string& scratch) {
  const std::string test =
      std::string(::testing::UnitTest::GetInstance()->current_test_suite()->name()) + "." +
      ::testing::UnitTest::GetInstance()->current_test_info()->name();
  std::vector<std::string> probe_args = {"/usr/bin/unshare"};
  probe_args.insert(probe_args.end(), flags.begin(), flags.end());
  probe_args.push_back("true");
  Process probe(probe_args, {}, scratch + ".probe");
  if (probe.wait(std::chrono::seconds(10)) != 0) return false;
  std::vector<std::string> args = {"/usr/bin/unshare"};
  args.insert(args.end(), flags.begin(), flags.end());
  args.insert(args.end(), {"sh", "-c", setup + " && exec \"$0\" --gtest_filter=\"$1\"",
                           std::filesystem::read_symlink("/proc/self/exe").string(), test});
  Process inner(args, {std::string(kInNamespace) + "=1"}, scratch + ".inner");
  const int status = inner.wait(std::chrono::seconds(300));
  EXPECT_EQ(status, 0) << inner.out() << inner.err();
  EXPECT_NE(inner.out().find("[  PASSED  ] 1 test"), std::string::npos) << inner.out();
  return true;
}

}  // namespace lidartag::test

// Re-runs the current test inside the namespaces and returns, or skips it; inside, goes on.
#define LIDARTAG_RUN_IN_NAMESPACE(flags, setup, scratch)                               \
  if (!::lidartag::test::in_namespace()) {                                             \
    if (!::lidartag::test::rerun_in_namespace(flags, setup, scratch)) {                \
      GTEST_SKIP() << "unshare " << ::testing::PrintToString(flags)                    \
                   << " is not permitted here: this test needs namespaces of its own"; \
    }                                                                                  \
    return;                                                                            \
  }
