// Writes an LCM log file (the format of lcm-logger and lcm::LogFile) for `file://...?mode=w|a`
// URLs, in place of LCM 1.3.1's file provider, which ignores every write error: its publish()
// returns 0 whatever lcm_eventlog_write_event() says, and the log's stdio buffer hides a full disk
// until a later flush that nobody checks. Here each event goes to the file in one writev(2), so a
// failed or short write is known at once and belongs to that event alone; a torn event is cut off
// again (ftruncate), so the file always holds whole events and exactly those reported written.
//
// Event format (all integers big-endian): magic 0xEDA1DA01 (u32), event number (i64, from 0),
// timestamp (i64, µs since the epoch), channel length (i32), data length (i32), the channel
// (no terminating zero), the data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace lidartag::daemon {

class LcmLogWriter {
 public:
  // Creates `path` (truncating it) or, with `append`, appends to it. Throws LcmError naming the
  // path when it cannot be opened.
  LcmLogWriter(const std::string& path, bool append);
  ~LcmLogWriter();
  LcmLogWriter(const LcmLogWriter&) = delete;
  LcmLogWriter& operator=(const LcmLogWriter&) = delete;

  // Appends one event stamped `utime` (µs since the epoch). False when it did not reach the file
  // whole (full disk, file size limit, I/O error): the file is cut back to the events before it
  // and `error` says why. Later calls try again (space may come back). Never throws.
  [[nodiscard]] bool write(const std::string& channel, const uint8_t* data, size_t size,
                           int64_t utime, std::string& error) noexcept;

  uint64_t events() const { return events_; }  // events in the file (written by this writer)
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t end_ = 0;     // file size after the last whole event
  uint64_t events_ = 0;  // also the next event number
};

}  // namespace lidartag::daemon
