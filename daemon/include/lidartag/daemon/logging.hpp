// spdlog set up for a service: on standard error with syslog priority prefixes ("<6>...") and no
// timestamps when journald reads it ($JOURNAL_STREAM), timestamped otherwise, or into a file that
// SIGHUP reopens (for logrotate).
#pragma once

#include <memory>
#include <string>

#include "lidartag/daemon/config.hpp"

namespace lidartag::daemon {

class LogOutput;

// Installs the default logger for `options`; throws ConfigError (key logging.file) when the file
// cannot be opened. Keep the returned object alive while logging.
class Logging {
 public:
  explicit Logging(const LoggingOptions& options);
  ~Logging();
  // Reopens the log file (after logrotate moved it); a no-op on standard error.
  void reopen();
  void flush();

 private:
  std::shared_ptr<LogOutput> sink_;
};

// Whether standard error is connected to the journal ($JOURNAL_STREAM names its device:inode).
bool stderr_is_journal();

}  // namespace lidartag::daemon
