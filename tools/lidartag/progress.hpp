// A progress bar on standard error, redrawn in place, only when standard error is a terminal
// (never in a pipe, a log or a test): "[#########.....................]  31%  12 rotations".
#pragma once

#include <cstdint>
#include <string>

namespace lidartag::cli {

class Progress {
 public:
  // `total`: the amount that is 100 % (bytes, nanoseconds, ...); 0 shows nothing.
  explicit Progress(uint64_t total);
  // Whether a bar is drawn at all (standard error is a terminal); false also forces it off.
  bool on() const { return on_; }
  void force_off() { on_ = false; }
  // Redraws when the whole percentage changed; `note` follows the percentage.
  void update(uint64_t done, const std::string& note = {});
  // Clears the bar so that what follows starts on a clean line.
  void done();
  ~Progress() { done(); }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

 private:
  uint64_t total_;
  bool on_;
  int last_ = -1;
};

}  // namespace lidartag::cli
