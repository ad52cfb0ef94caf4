#include "lidartag/daemon/logging.hpp"

#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>

namespace lidartag::daemon {

bool stderr_is_journal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  if (stream == nullptr) return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  unsigned long long dev = 0, ino = 0;
  if (std::sscanf(stream, "%llu:%llu", &dev, &ino) != 2) return false;
  return dev == st.st_dev && ino == st.st_ino;
}

// One sink for every destination: a FILE* (standard error or the log file), optionally with
// syslog priority prefixes for journald.
class LogOutput final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  LogOutput(std::string path, bool journal) : path_(std::move(path)), journal_(journal) { open(); }
  ~LogOutput() override { close(); }

  void reopen() {
    std::lock_guard lock(mutex_);
    close();
    failing_ = false;
    open();
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    spdlog::memory_buf_t formatted;
    formatter_->format(msg, formatted);
    if (journal_) std::fprintf(file_, "<%d>", priority(msg.level));
    std::fwrite(formatted.data(), 1, formatted.size(), file_);
    if (msg.level >= spdlog::level::warn) std::fflush(file_);
    check_written(true);
  }
  void flush_() override {
    std::fflush(file_);
    check_written(false);
  }

 private:
  // A log file that cannot be written (full disk, I/O error) is said once on standard error with
  // the reason, not per lost line; again once a line is written (the file is line-buffered, so
  // a line written without an error reached the file; a flush of nothing proves nothing).
  void check_written(bool line) {
    if (file_ == stderr) return;
    if (std::ferror(file_) != 0) {
      const int error = errno;
      std::clearerr(file_);
      if (!failing_) {
        std::fprintf(stderr, "lidartagd: log file '%s': cannot write: %s; log lines are lost\n",
                     path_.c_str(), std::strerror(error));
        failing_ = true;
      }
    } else if (failing_ && line) {
      std::fprintf(stderr, "lidartagd: log file '%s': writing again\n", path_.c_str());
      failing_ = false;
    }
  }
  static int priority(spdlog::level::level_enum level) {
    switch (level) {
      case spdlog::level::trace:
      case spdlog::level::debug:
        return 7;
      case spdlog::level::info:
        return 6;
      case spdlog::level::warn:
        return 4;
      case spdlog::level::err:
        return 3;
      case spdlog::level::critical:
        return 2;
      default:
        return 6;
    }
  }
  void open() {
    if (path_.empty()) {
      file_ = stderr;
      return;
    }
    file_ = std::fopen(path_.c_str(), "a");
    if (file_ == nullptr) {
      const std::string reason = std::strerror(errno);
      file_ = stderr;
      throw ConfigError("logging.file", path_, "cannot open: " + reason);
    }
    setvbuf(file_, nullptr, _IOLBF, 0);
  }
  void close() {
    if (file_ != nullptr && file_ != stderr) std::fclose(file_);
    file_ = nullptr;
  }

  std::string path_;
  bool journal_;
  std::FILE* file_ = nullptr;
  bool failing_ = false;  // the last write to the file failed (and was reported)
};

Logging::Logging(const LoggingOptions& options) {
  const bool journal =
      options.file.empty() && (options.journald == JournalMode::kAlways ||
                               (options.journald == JournalMode::kAuto && stderr_is_journal()));
  sink_ = std::make_shared<LogOutput>(options.file, journal);
  auto logger = std::make_shared<spdlog::logger>("lidartagd", sink_);
  // journald stamps each line itself.
  logger->set_pattern(journal ? "%v" : "%Y-%m-%d %H:%M:%S.%e lidartagd %l: %v");
  logger->set_level(spdlog::level::from_str(options.level));
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
}

Logging::~Logging() {
  spdlog::default_logger()->flush();
}

void Logging::reopen() {
  sink_->reopen();
}

void Logging::flush() {
  spdlog::default_logger()->flush();
}

}  // namespace lidartag::daemon
