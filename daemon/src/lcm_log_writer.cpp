#include "lidartag/daemon/lcm_log_writer.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>

#include "lidartag/daemon/lcm_url.hpp"

namespace lidartag::daemon {

namespace {

constexpr uint32_t kMagic = 0xEDA1DA01;
constexpr size_t kHeader = 4 + 8 + 8 + 4 + 4;

void put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (24 - 8 * i));
}
void put64(uint8_t* p, uint64_t v) {
  put32(p, static_cast<uint32_t>(v >> 32));
  put32(p + 4, static_cast<uint32_t>(v));
}

}  // namespace

LcmLogWriter::LcmLogWriter(const std::string& path, bool append) : path_(path) {
  // Always O_APPEND: after a torn event is cut off, the next one goes to the new end.
  // No link followed (as root, one would overwrite what it points to); non-blocking, so that a
  // FIFO without a reader fails here instead of blocking (a FIFO with one is refused below).
  const int flags =
      O_WRONLY | O_CREAT | O_CLOEXEC | O_APPEND | O_NOFOLLOW | O_NONBLOCK | (append ? 0 : O_TRUNC);
  fd_ = ::open(path.c_str(), flags, 0666);
  if (fd_ < 0) {
    const int error = errno;
    throw LcmError("cannot create the LCM log '" + path + "': " +
                   (error == ELOOP   ? "it is a symbolic link (not followed)"
                    : error == ENXIO ? "it is a FIFO that nobody reads"
                                     : std::strerror(error)));
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string why = S_ISDIR(st.st_mode) ? "a directory" : "not a regular file";
    ::close(fd_);
    throw LcmError("cannot write the LCM log '" + path + "': " + why);
  }
  end_ = static_cast<uint64_t>(st.st_size);
}

LcmLogWriter::~LcmLogWriter() {
  if (fd_ >= 0) ::close(fd_);
}

bool LcmLogWriter::write(const std::string& channel, const uint8_t* data, size_t size,
                         int64_t utime, std::string& error) noexcept {
  std::array<uint8_t, kHeader> header{};
  put32(header.data(), kMagic);
  put64(header.data() + 4, events_);
  put64(header.data() + 12, static_cast<uint64_t>(utime));
  put32(header.data() + 20, static_cast<uint32_t>(channel.size()));
  put32(header.data() + 24, static_cast<uint32_t>(size));
  std::array<iovec, 3> parts = {{{header.data(), header.size()},
                                 {const_cast<char*>(channel.data()), channel.size()},
                                 {const_cast<uint8_t*>(data), size}}};
  const size_t total = header.size() + channel.size() + size;
  size_t done = 0;
  size_t first = 0;  // the first part not yet written whole
  while (done < total) {
    const ssize_t n = ::writev(fd_, parts.data() + first, static_cast<int>(parts.size() - first));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = "cannot write the LCM log '" + path_ +
              "': " + (n < 0 ? std::strerror(errno) : "nothing written");
      // Cut the torn event off, so that the file holds whole events only.
      if (done > 0 && ::ftruncate(fd_, static_cast<off_t>(end_)) != 0) {
        error +=
            std::string(" (and the torn event could not be cut off: ") + std::strerror(errno) + ")";
      }
      return false;
    }
    done += static_cast<size_t>(n);
    // Skip what a short write completed.
    auto left = static_cast<size_t>(n);
    while (first < parts.size() && left >= parts[first].iov_len) {
      left -= parts[first].iov_len;
      ++first;
    }
    if (first < parts.size()) {
      parts[first].iov_base = static_cast<uint8_t*>(parts[first].iov_base) + left;
      parts[first].iov_len -= left;
    }
  }
  end_ += total;
  ++events_;
  return true;
}

}  // namespace lidartag::daemon
