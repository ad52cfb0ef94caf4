// Typed setup errors of the I/O layer: thrown while opening files, sockets and interfaces, caught
// once in main. Per-packet paths never throw; they count (SourceStats) instead.
#pragma once

#include <stdexcept>
#include <string>

namespace lidartag::driver {

// A file, socket or interface cannot be opened, created or written.
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace lidartag::driver
