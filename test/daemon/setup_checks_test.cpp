// Setup checks: each resource the daemon will open, refused before it starts with one line that
// names the setting and the problem.
#include "lidartag/daemon/setup_checks.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

std::string temp_path(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartag_setup");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

// A ros-drivers calibration of `lasers` lasers, elevations spread over +-15 degrees.
std::string calibration_file(const std::string& name, int lasers, double first_elevation_rad = 0) {
  std::ostringstream out;
  out << "num_lasers: " << lasers << "\nlasers:\n";
  for (int i = 0; i < lasers; ++i) {
    const double elevation =
        i == 0 && first_elevation_rad != 0
            ? first_elevation_rad
            : (-15.0 + 30.0 * i / std::max(1, lasers - 1)) * std::numbers::pi / 180.0;
    out << "  - {laser_id: " << i << ", rot_correction: 0.0, vert_correction: " << elevation
        << "}\n";
  }
  const std::string path = temp_path(name);
  std::ofstream(path) << out.str();
  return path;
}

// Options that need nothing from the machine: in-process LCM, a replay of an existing file.
DaemonOptions replay_options() {
  DaemonOptions o;
  o.lcm.url = "memq://";
  o.sensors[0].source.kind = SourceKind::kPcap;
  o.sensors[0].source.file = calibration_file("any.file", 1);  // read, not parsed, here
  return o;
}

std::string error_of(const DaemonOptions& o) {
  try {
    check_setup(o);
  } catch (const SetupError& e) {
    return e.what();
  }
  return "";
}

TEST(SetupChecks, CalibrationFilesAreReadAtStartupWhateverTheModel) {
  DaemonOptions o = replay_options();
  EXPECT_EQ(error_of(o), "");
  auto& sensor = o.sensors[0];

  sensor.calibration = calibration_file("vlp32.yaml", 32);
  sensor.model.reset();  // auto: a 32-laser file fits the VLP-32C and the HDL-32E
  EXPECT_EQ(error_of(o), "");
  sensor.model = velodyne::Model::kVLP32C;
  EXPECT_EQ(error_of(o), "");
  sensor.model = velodyne::Model::kVLP16;  // configured: checked against the model
  // (Entries beyond a model's lasers are accepted only all zero: 64-entry files of 32-laser
  // sensors.)
  EXPECT_EQ(error_of(o), "sensors[0].calibration: calibration file '" + sensor.calibration +
                             "', key 'lasers[16].vert_correction': 32 lasers listed, but a "
                             "VLP-16 has 16: laser 16 is beyond the 16 lasers, and such an entry "
                             "must be all zero, found 0.00844514");

  sensor.model.reset();
  sensor.calibration = calibration_file("twenty.yaml", 20);
  EXPECT_EQ(error_of(o), "sensors[0].calibration: calibration file '" + sensor.calibration +
                             "': 20 lasers, but no model has that many (vlp16 16, puck-hires 16, "
                             "vlp32c 32, hdl32e 32, vls128 128)");
  // A fault of the file itself is found with model auto too.
  sensor.calibration = calibration_file("degrees.yaml", 16, 45.0);  // degrees where radians belong
  EXPECT_NE(error_of(o).find("key 'lasers[0].vert_correction': elevation beyond +-90 degrees"),
            std::string::npos)
      << error_of(o);

  const std::string dir = temp_path("a_dir");
  std::filesystem::create_directories(dir);
  const std::string garbage = temp_path("garbage.yaml");
  std::ofstream(garbage) << "lasers: [ {laser_id: 0,\n  - broken";
  const std::string huge = temp_path("huge.yaml");
  std::ofstream(huge) << std::string(kMaxCalibrationBytes + 1, '#');
  const std::pair<std::string, std::string> bad[] = {
      {"/nonexistent/calibration.yaml",
       "calibration file '/nonexistent/calibration.yaml': No such file or directory"},
      {dir, "calibration file '" + dir + "' is not a regular file"},
      {"/dev/zero", "calibration file '/dev/zero' is not a regular file"},
      {garbage, "calibration file '" + garbage + "': not valid YAML"},
      {huge, "calibration file '" + huge + "': 1048577 bytes, more than the limit of 1048576"},
  };
  for (const auto& [path, message] : bad) {
    SCOPED_TRACE(path);
    sensor.calibration = path;
    const std::string e = error_of(o);
    EXPECT_EQ(e.rfind("sensors[0].calibration: " + message, 0), 0u) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos);
  }
}

TEST(SetupChecks, RecordAndLogFilesMustBeCreatable) {
  DaemonOptions o = replay_options();
  const std::string dir = temp_path("out");
  std::filesystem::create_directories(dir);
  o.record_pcap = dir + "/x.pcap";
  EXPECT_EQ(error_of(o), "");
  o.record_pcap = "/nonexistent-lidartag/x.pcap";
  EXPECT_EQ(error_of(o),
            "record_pcap: the --record file '/nonexistent-lidartag/x.pcap': its directory "
            "'/nonexistent-lidartag' does not exist");
  o.record_pcap = dir;
  EXPECT_EQ(error_of(o), "record_pcap: the --record file '" + dir + "' is a directory");
  o.record_pcap = "";
  o.lcm.url = "file:///nonexistent-lidartag/x.lcmlog?mode=w";
  EXPECT_EQ(error_of(o),
            "lcm.url: the LCM log '/nonexistent-lidartag/x.lcmlog': its directory "
            "'/nonexistent-lidartag' does not exist");
  o.lcm.url = "file://" + dir + "/x.lcmlog?mode=w";
  EXPECT_EQ(error_of(o), "");
  o.lcm.url = "bogus://";
  EXPECT_EQ(error_of(o).rfind("lcm.url: LCM URL 'bogus://': unknown provider 'bogus'", 0), 0u);
  o.lcm.url = "memq://";
  o.sensors[0].source.file = "/nonexistent/replay.pcap";
  EXPECT_EQ(error_of(o),
            "sensors[0].source.file: replay file '/nonexistent/replay.pcap': No such file or "
            "directory");
}

TEST(SetupChecks, OutputsAreNeitherLinksNorFifosNorAnInput) {
  // Attack round 2: as root --record followed a link and overwrote its target; a FIFO blocked
  // the daemon in open() before READY=1 past SIGTERM; --replay X --record X truncated X.
  DaemonOptions o = replay_options();
  const std::string dir = temp_path("outputs");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string target = dir + "/precious", link = dir + "/link.pcap";
  std::ofstream(target) << "keep me";
  std::filesystem::create_symlink(target, link);
  o.record_pcap = link;
  EXPECT_EQ(error_of(o), "record_pcap: the --record file '" + link +
                             "' is a symbolic link: refused (it would overwrite whatever it "
                             "points to); give the real path");
  o.record_pcap = "";
  o.lcm.url = "file://" + link + "?mode=w";
  EXPECT_NE(error_of(o).find("lcm.url: the LCM log '" + link + "' is a symbolic link"),
            std::string::npos)
      << error_of(o);
  const std::string fifo = dir + "/fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  o.lcm.url = "file://" + fifo + "?mode=w";
  EXPECT_EQ(error_of(o), "lcm.url: the LCM log '" + fifo + "' is a FIFO, not a regular file");
  o.lcm.url = "memq://";
  o.record_pcap = fifo;
  EXPECT_EQ(error_of(o),
            "record_pcap: the --record file '" + fifo + "' is a FIFO, not a regular file");
  o.record_pcap = "";
  o.logging.file = fifo;
  EXPECT_THROW(
      {
        try {
          check_setup(o);
        } catch (const ConfigError& e) {
          EXPECT_EQ(e.key(), "logging.file");
          EXPECT_EQ(e.reason(), "a FIFO that nobody reads (opening it would block)");
          throw;
        }
      },
      ConfigError);
  o.logging.file = "";
  // The replay itself as an output (also through a link that names it).
  const std::string replay = o.sensors[0].source.file;
  o.record_pcap = replay;
  EXPECT_NE(error_of(o).find("is the file sensors[0] replays"), std::string::npos) << error_of(o);
  o.record_pcap = "";
  o.lcm.url = "file://" + replay + "?mode=a";
  EXPECT_NE(error_of(o).find("lcm.url: the LCM log"), std::string::npos) << error_of(o);
  o.lcm.url = "memq://";
  o.logging.file = replay;
  EXPECT_THROW(check_setup(o), ConfigError);  // the log file's problems are configuration errors
  o.logging.file = "";
  // A replay from a FIFO nobody writes: refused after a bounded wait, not a hang.
  o.sensors[0].source.file = fifo;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(error_of(o), "sensors[0].source.file: replay file '" + fifo +
                             "' is a FIFO without a writer (waited 5 s)");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
  std::ifstream kept(target);
  std::string text;
  std::getline(kept, text);
  EXPECT_EQ(text, "keep me");
}

// A UDP socket bound to 127.0.0.1 on a free port, as another program would hold it.
class PortHolder {
 public:
  explicit PortHolder(bool share) : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    const int on = 1;
    if (share) ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &on, sizeof(on));
    sockaddr_in at{};
    at.sin_family = AF_INET;
    at.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&at), sizeof(at)), 0);
    socklen_t length = sizeof(at);
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&at), &length);
    port_ = ntohs(at.sin_port);
  }
  ~PortHolder() { ::close(fd_); }
  uint16_t port() const { return port_; }

 private:
  int fd_;
  uint16_t port_ = 0;
};

DaemonOptions udp_options(uint16_t data_port, uint16_t position_port) {
  DaemonOptions o;
  o.lcm.url = "memq://";
  auto& src = o.sensors[0].source;
  src.kind = SourceKind::kUdp;
  src.bind_address = "127.0.0.1";
  src.data_port = data_port;
  src.position_port = position_port;
  return o;
}

// A port nobody holds (bound and released at once).
uint16_t free_port() {
  return PortHolder(false).port();
}

TEST(SetupChecks, APortInUseIsRefusedUnlessEveryUserSharesIt) {
  PortHolder exclusive(false), shared(true);
  DaemonOptions o = udp_options(exclusive.port(), free_port());
  const std::string where = "UDP 127.0.0.1:" + std::to_string(exclusive.port());
  EXPECT_EQ(error_of(o), "sensors[0].source.data_port: " + where +
                             " is in use by another program (a second lidartagd, or a sensor "
                             "driver): stop it, give this sensor another port, or set share_port: "
                             "true here and share it there too (broadcast/multicast traffic only)");
  o.sensors[0].source.share_port = true;  // the holder does not share: still refused
  EXPECT_EQ(error_of(o), "sensors[0].source.data_port: " + where +
                             " is in use by another program that does not share it");
  o.sensors[0].source.data_port = shared.port();  // both share: accepted
  EXPECT_EQ(error_of(o), "");
  o.sensors[0].source.share_port = false;
  EXPECT_NE(error_of(o).find("is in use by another program (a second lidartagd"),
            std::string::npos);
  o.sensors[0].source.bind_address = "10.255.255.254";  // not this host's
  EXPECT_NE(error_of(o).find(": 10.255.255.254 is not an address of this host"), std::string::npos)
      << error_of(o);
}

TEST(SetupChecks, TwoSensorsOnOnePortOnlyWhenBothShare) {
  const uint16_t data = free_port(), position = free_port();
  DaemonOptions o = udp_options(data, position);
  o.sensors.push_back(o.sensors[0]);
  o.sensors[1].name = "second";
  o.sensors[1].channel_prefix = "SECOND_";
  o.sensors[1].source.bind_address = "0.0.0.0";  // overlaps 127.0.0.1
  o.sensors[1].source.position_port = static_cast<uint16_t>(position + 1);
  EXPECT_EQ(error_of(o), "sensors[1].source.data_port: UDP port " + std::to_string(data) +
                             " is also sensor 'lidar''s (sensors[0]): give each sensor its own "
                             "port, or set share_port: true on both and sensor_address on each "
                             "to tell them apart");
  o.sensors[0].source.share_port = true;
  EXPECT_NE(error_of(o), "");
  o.sensors[1].source.share_port = true;
  EXPECT_EQ(error_of(o), "");
}

}  // namespace
}  // namespace lidartag::daemon
