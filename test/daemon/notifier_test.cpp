// sd_notify through a fake NOTIFY_SOCKET: what systemd would receive.
#include "lidartag/daemon/notifier.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

namespace lidartag::daemon {
namespace {

class FakeNotifySocket {
 public:
  FakeNotifySocket() {
    path_ = ::testing::TempDir() + "/notify." + std::to_string(getpid());
    unlink(path_.c_str());
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    path_.copy(addr.sun_path, sizeof(addr.sun_path) - 1);
    EXPECT_EQ(bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
    timeval tv{1, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  }
  ~FakeNotifySocket() {
    close(fd_);
    unlink(path_.c_str());
  }
  const std::string& path() const { return path_; }
  std::string receive() {
    char buf[4096];
    const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
    return n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string();
  }

 private:
  std::string path_;
  int fd_ = -1;
};

TEST(Notifier, SendsReadyStatusWatchdogStopping) {
  FakeNotifySocket sock;
  setenv("NOTIFY_SOCKET", sock.path().c_str(), 1);
  setenv("WATCHDOG_USEC", "400000", 1);
  unsetenv("WATCHDOG_PID");
  const Notifier n;
  ASSERT_TRUE(n.watchdog_timeout().has_value());
  EXPECT_EQ(n.watchdog_timeout()->count(), 400000);
  EXPECT_EQ(n.ping_interval()->count(), 200000);
  n.ready("running: 1 sensor");
  EXPECT_EQ(sock.receive(), "READY=1\nSTATUS=running: 1 sensor");
  n.status("two\nlines");
  EXPECT_EQ(sock.receive(), "STATUS=two lines");
  n.watchdog();
  EXPECT_EQ(sock.receive(), "WATCHDOG=1");
  n.stopping("bye");
  EXPECT_EQ(sock.receive(), "STOPPING=1\nSTATUS=bye");
  unsetenv("NOTIFY_SOCKET");
  unsetenv("WATCHDOG_USEC");
}

TEST(Notifier, NoWatchdogWithoutTheVariable) {
  unsetenv("WATCHDOG_USEC");
  unsetenv("NOTIFY_SOCKET");
  const Notifier n;
  EXPECT_FALSE(n.watchdog_timeout().has_value());
  n.ready("x");  // no socket: a no-op, must not fail
}

}  // namespace
}  // namespace lidartag::daemon
