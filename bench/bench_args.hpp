// The command lines of the benchmarks that write a report (bench_accuracy, bench_tracker): option
// values, counts echoed into the report's "run with" line, and main's error handling.
#pragma once

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace lidartag::bench_args {

// The value after option `name` (argv[i + 1]; `i` moves onto it), or exit status 2 with a message
// when there is none.
inline std::string value(const char* program, int argc, char** argv, int& i, const char* name) {
  if (i + 1 >= argc) {
    std::fprintf(stderr, "%s: %s needs a value\n", program, name);
    std::exit(2);
  }
  return argv[++i];
}

// A whole-number option, raised to `min`, and appended to `command` as given to the run.
inline int count(const char* program, int argc, char** argv, int& i, const char* name, int min,
                 std::string& command) {
  const int n = std::max(min, std::atoi(value(program, argc, argv, i, name).c_str()));
  command += std::string(" ") + name + " " + std::to_string(n);
  return n;
}

// `run()`'s exit status, or 1 with the error's message.
template <class Run>
int run_reporting_errors(const char* program, Run&& run) {
  try {
    return run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", program, e.what());
    return 1;
  }
}

}  // namespace lidartag::bench_args
