// sd_notify through a fake NOTIFY_SOCKET: what systemd would receive.
#include "lidartag/daemon/notifier.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include "fake_notify_socket.hpp"

namespace lidartag::daemon {
namespace {

// One socket path per test process.
struct FakeNotifySocket : lidartag::testing::FakeNotifySocket {
  FakeNotifySocket()
      : lidartag::testing::FakeNotifySocket(::testing::TempDir() + "/notify." +
                                            std::to_string(getpid())) {}
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
