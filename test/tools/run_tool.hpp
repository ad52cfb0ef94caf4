// Runs the built `lidartag` tool as a user would and captures what it prints.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace lidartag::testing {

struct ToolResult {
  int exit_code = -1;
  std::string out;  // stdout, and stderr when merged
};

// `args` follow the tool's path (LIDARTAG_CLI); stderr is merged into `out` or discarded.
inline ToolResult run_tool(const std::string& args, bool merge_stderr = true) {
  const std::string command =
      std::string(LIDARTAG_CLI) + " " + args + (merge_stderr ? " 2>&1" : " 2>/dev/null");
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

}  // namespace lidartag::testing
