// One exit status convention for every program of the project (lidartag, lidartagd):
//   0  success;
//   1  runtime failure: an input cannot be opened or read, an output cannot be written;
//   2  usage or configuration: a bad option or value, a configuration, scene, family or
//      calibration file that is wrong, an Ouster metadata file that is malformed or not the
//      capture's sensor's (the user has to change the command or a file).
#pragma once

#include <exception>
#include <stdexcept>

namespace lidartag::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitRuntime = 1;
inline constexpr int kExitUsage = 2;

// A usage error found after parsing (options that contradict each other, a value out of range
// that only the command can judge). Exits 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The exit status for an exception thrown by a command (2 for the configuration and usage error
// types of every library, 1 for everything else).
int exit_code_of(const std::exception& e);

}  // namespace lidartag::cli
