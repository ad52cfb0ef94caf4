#include "lidartag/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace lidartag::cli {

Progress::Progress(uint64_t total) : total_(total), on_(total > 0 && ::isatty(STDERR_FILENO)) {}

void Progress::update(uint64_t done, const std::string& note) {
  if (!on_) return;
  const int pct = static_cast<int>(std::min<uint64_t>(100, done * 100 / total_));
  if (pct == last_) return;
  last_ = pct;
  constexpr int kWidth = 30;
  const int filled = pct * kWidth / 100;
  std::fprintf(stderr, "\r[%s%s] %3d%%  %s\x1b[K", std::string(size_t(filled), '#').c_str(),
               std::string(size_t(kWidth - filled), '.').c_str(), pct, note.c_str());
  std::fflush(stderr);
}

void Progress::done() {
  if (on_ && last_ >= 0) {
    std::fputs("\r\x1b[K", stderr);
    std::fflush(stderr);
  }
  last_ = -1;
}

}  // namespace lidartag::cli
