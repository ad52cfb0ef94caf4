// Runs the built `lidartag` tool (or any command) as a user would and captures what it prints.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace lidartag::testing {

struct ToolResult {
  int exit_code = -1;
  std::string out;  // stdout, and stderr when merged
  std::string err;  // stderr, when captured apart (run_split)
};

// Runs a shell command line; its stdout is returned (append " 2>&1" to merge stderr).
inline ToolResult run_command(const std::string& command) {
  ToolResult r;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    r.out.append(buffer.data(), n);
  const int status = ::pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// `args` follow the tool's path (LIDARTAG_CLI); stderr is merged into `out` or discarded.
inline ToolResult run_tool(const std::string& args, bool merge_stderr = true) {
  return run_command(std::string(LIDARTAG_CLI) + " " + args +
                     (merge_stderr ? " 2>&1" : " 2>/dev/null"));
}

// Runs a command line with stdout in `out` and stderr in `err`, apart.
inline ToolResult run_split(const std::string& command) {
  static std::atomic<int> counter{0};
  const auto err_file =
      std::filesystem::temp_directory_path() /
      ("lidartag_stderr_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  ToolResult r = run_command(command + " 2>" + err_file.string());
  std::ifstream in(err_file);
  std::stringstream text;
  text << in.rdbuf();
  r.err = text.str();
  std::filesystem::remove(err_file);
  return r;
}

}  // namespace lidartag::testing
