#include "lidartag/daemon/setup_checks.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "lidartag/daemon/lcm_url.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/ouster/models.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

namespace lidartag::daemon {

namespace {

std::string errno_text(int error) {
  return std::strerror(error);
}

// `path` can be created or written: not a directory; when it exists, writable; otherwise its
// directory exists and new files can be made there.
void check_writable(const std::string& key, const std::string& path, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) {
      throw SetupError(key, fmt::format("{} '{}' is a directory", what, path));
    }
    if (::access(path.c_str(), W_OK) != 0) {
      throw SetupError(key,
                       fmt::format("{} '{}' cannot be written: {}", what, path, errno_text(errno)));
    }
    return;
  }
  if (errno != ENOENT) {
    throw SetupError(key, fmt::format("{} '{}': {}", what, path, errno_text(errno)));
  }
  // (Built in one go: assigning "." afterwards trips GCC 12's -Wrestrict false positive at -O3.)
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const std::string dir = parent.empty() ? std::string(".") : parent.string();
  if (::stat(dir.c_str(), &st) != 0) {
    throw SetupError(key,
                     fmt::format("{} '{}': its directory '{}' does not exist", what, path, dir));
  }
  if (!S_ISDIR(st.st_mode)) {
    throw SetupError(key, fmt::format("{} '{}': '{}' is not a directory", what, path, dir));
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw SetupError(key, fmt::format("{} '{}' cannot be created in '{}': {}", what, path, dir,
                                      errno_text(errno)));
  }
}

// How long a replay waits at setup for a FIFO's writer (opening one without a writer blocks).
constexpr int kFifoWaitMs = 5000;

// An output file of the daemon that it truncates and cuts back (the --record pcap, the LCM log):
// not a symbolic link (as root, following one overwrites whatever it points to), not a FIFO,
// socket or block device (opening a FIFO blocks until a reader comes, before READY=1). A
// character device (/dev/null) is the writer's to judge.
void check_plain_output(const std::string& key, const std::string& path, const std::string& what) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (S_ISLNK(st.st_mode)) {
      throw SetupError(key, fmt::format("{} '{}' is a symbolic link: refused (it would overwrite "
                                        "whatever it points to); give the real path",
                                        what, path));
    }
    if (!S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode) && !S_ISCHR(st.st_mode)) {
      throw SetupError(key, fmt::format("{} '{}' is {}, not a regular file", what, path,
                                        S_ISFIFO(st.st_mode)   ? "a FIFO"
                                        : S_ISSOCK(st.st_mode) ? "a socket"
                                                               : "a block device"));
    }
  }
  check_writable(key, path, what);
}

// The log file may be a device (/dev/null) or a FIFO that something reads; a FIFO nobody reads
// would block the daemon in open() before READY=1. (Whether it can be created is the logger's
// own check: a configuration error naming logging.file.)
void check_log_output(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISFIFO(st.st_mode)) return;
  const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    throw ConfigError(
        "logging.file", path,
        errno == ENXIO ? "a FIFO that nobody reads (opening it would block)" : errno_text(errno));
  }
  ::close(fd);
}

// A replay from a FIFO: its writer must be there within kFifoWaitMs (else opening it would block
// for good, before READY=1 and deaf to SIGTERM).
void check_fifo_writer(const std::string& key, const std::string& path, const std::string& what) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw SetupError(key, fmt::format("{} '{}': {}", what, path, errno_text(errno)));
  // Linux reports no event on a FIFO that never had a writer: POLLIN once one writes, POLLHUP
  // once one came and went.
  pollfd p{fd, POLLIN, 0};
  const int rc = ::poll(&p, 1, kFifoWaitMs);
  ::close(fd);
  if (rc <= 0) {
    throw SetupError(key, fmt::format("{} '{}' is a FIFO without a writer (waited {} s)", what,
                                      path, kFifoWaitMs / 1000));
  }
}

// An output must not be one of the inputs: `--replay X --record X` once truncated the capture
// being replayed, an LCM log written where it was read fed the daemon its own output.
void check_not_an_input(const DaemonOptions& options, const std::string& key,
                        const std::string& path, const std::string& what) {
  struct stat out {};
  if (path.empty() || ::stat(path.c_str(), &out) != 0) return;  // not there yet: no input
  for (size_t i = 0; i < options.sensors.size(); ++i) {
    const SourceOptions& src = options.sensors[i].source;
    if (src.kind != SourceKind::kPcap && src.kind != SourceKind::kLcm) continue;
    struct stat in {};
    if (::stat(src.file.c_str(), &in) != 0) continue;
    if (in.st_dev == out.st_dev && in.st_ino == out.st_ino) {
      throw SetupError(key, fmt::format("{} '{}' is the file sensors[{}] replays ('{}'): it would "
                                        "be overwritten while it is read",
                                        what, path, i, src.file));
    }
  }
  const std::string& log = options.logging.file;
  struct stat log_st {};
  if (!log.empty() && key != "logging.file" && ::stat(log.c_str(), &log_st) == 0 &&
      log_st.st_dev == out.st_dev && log_st.st_ino == out.st_ino) {
    throw SetupError(key, fmt::format("{} '{}' is also the log file", what, path));
  }
}

void check_lcm(const std::string& url_text) {
  LcmUrl url;
  try {
    url = parse_lcm_url(url_text);
    check_multicast_route(url);
  } catch (const LcmError& e) {
    throw SetupError("lcm.url", e.what());
  }
  if (url.provider == "file") check_plain_output("lcm.url", url.target, "the LCM log");
}

// A readable regular file of at most `limit` bytes.
void check_small_regular_file(const std::string& key, const std::string& path,
                              const std::string& what, size_t limit) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    throw SetupError(key, fmt::format("{} '{}': {}", what, path, errno_text(errno)));
  }
  if (!S_ISREG(st.st_mode)) {
    throw SetupError(key, fmt::format("{} '{}' is not a regular file", what, path));
  }
  if (::access(path.c_str(), R_OK) != 0) {
    throw SetupError(key, fmt::format("{} '{}' cannot be read: {}", what, path, errno_text(errno)));
  }
  if (static_cast<uint64_t>(st.st_size) > limit) {
    throw SetupError(key, fmt::format("{} '{}': {} bytes, more than the limit of {}", what, path,
                                      st.st_size, limit));
  }
}

// `path` can be read and is not a directory (a FIFO is fine for a replay), unless `bag_folder`
// and it is a ROS 2 bag's folder.
void check_readable(const std::string& key, const std::string& path, const std::string& what,
                    bool bag_folder = false) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    throw SetupError(key, fmt::format("{} '{}': {}", what, path, errno_text(errno)));
  }
  if (S_ISDIR(st.st_mode) &&
      !(bag_folder && driver::bag::detect_bag_format(path) == driver::bag::BagFormat::kRosbag2)) {
    throw SetupError(key, fmt::format("{} '{}' is a directory", what, path));
  }
  if (::access(path.c_str(), R_OK) != 0) {
    throw SetupError(key, fmt::format("{} '{}' cannot be read: {}", what, path, errno_text(errno)));
  }
  if (S_ISFIFO(st.st_mode)) check_fifo_writer(key, path, what);
}

// The Ouster metadata file parses and describes the configured model (if any).
void check_metadata(const std::string& key, const SensorOptions& sensor) {
  check_small_regular_file(key, sensor.metadata, "Ouster metadata file", kMaxCalibrationBytes);
  try {
    const driver::ouster::SensorInfo info = driver::ouster::load_metadata(sensor.metadata);
    const std::string described = driver::ouster::model_name(info);
    const std::string& want = sensor.ouster_model;
    if (!want.empty() && !driver::ouster::describes_model(info, want)) {
      throw SetupError(key, fmt::format("Ouster metadata file '{}' describes an {} ({}, {} beams), "
                                        "not the configured model {}",
                                        sensor.metadata, described, info.prod_line,
                                        info.pixels_per_column, want));
    }
  } catch (const driver::ouster::MetadataError& e) {
    throw SetupError(key, fmt::format("Ouster metadata file '{}': {}", sensor.metadata, e.what()));
  }
}

// The calibration file parses and fits the configured model; with model auto, some model (the
// packets decide which one later, and that model's check is repeated then).
void check_calibration(const std::string& key, const SensorOptions& sensor) {
  const std::string& path = sensor.calibration;
  check_small_regular_file(key, path, "calibration file", kMaxCalibrationBytes);
  try {
    if (sensor.model) {
      (void)velodyne::load_calibration_file(path, *sensor.model);
      return;
    }
    const YAML::Node root = YAML::LoadFile(path);
    const YAML::Node lasers = root.IsMap() ? root["lasers"] : YAML::Node();
    if (!lasers.IsDefined() || !lasers.IsSequence()) {
      // Not a calibration whatever the model: the loader says what is wrong with it.
      (void)velodyne::load_calibration_file(path, velodyne::all_models().front());
    }
    std::string models;
    for (const velodyne::Model model : velodyne::all_models()) {
      const auto& spec = velodyne::model_spec(model);
      models += fmt::format("{}{} {}", models.empty() ? "" : ", ", spec.name, spec.lasers);
      if (static_cast<size_t>(spec.lasers) != lasers.size()) continue;
      // The first model with this many lasers: the file's own faults show the same for all.
      (void)velodyne::load_calibration_file(path, model);
      return;
    }
    throw SetupError(key, fmt::format("calibration file '{}': {} lasers, but no model has that "
                                      "many ({})",
                                      path, lasers.size(), models));
  } catch (const velodyne::CalibrationError& e) {
    throw SetupError(key, e.what());
  } catch (const YAML::Exception& e) {
    throw SetupError(key, fmt::format("calibration file '{}': not valid YAML: {}", path, e.msg));
  } catch (const SetupError&) {
    throw;
  } catch (const std::exception& e) {
    // A read that fails below the parsers (/proc/self/mem: "basic_filebuf::underflow error").
    throw SetupError(key, fmt::format("calibration file '{}' cannot be read: {}", path, e.what()));
  }
}

bool is_multicast(uint32_t address) {
  return (address >> 28) == 0xE;
}

// Binds a probe socket the way UdpSource will, and closes it.
void check_udp_port(const std::string& key, const SourceOptions& src, uint16_t port) {
  uint32_t address = 0;
  if (!driver::parse_ipv4_address(src.bind_address, address)) return;  // config-checked
  const bool shared = src.share_port || is_multicast(address);
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw SetupError(key, "cannot open a UDP socket: " + errno_text(errno));
  const int on = 1;
  if (shared) ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof(on));
  sockaddr_in at{};
  at.sin_family = AF_INET;
  at.sin_port = htons(port);
  at.sin_addr.s_addr = htonl(address);
  const int rc = ::bind(fd, reinterpret_cast<const sockaddr*>(&at), sizeof(at));
  const int error = errno;
  ::close(fd);
  if (rc == 0) return;
  const std::string where = fmt::format("UDP {}:{}", src.bind_address, port);
  switch (error) {
    case EADDRINUSE:
      throw SetupError(
          key, shared ? fmt::format("{} is in use by another program that does not share it", where)
                      : fmt::format("{} is in use by another program (a second lidartagd, or a "
                                    "sensor driver): stop it, give this sensor another port, or "
                                    "set share_port: true here and share it there too "
                                    "(broadcast/multicast traffic only)",
                                    where));
    case EACCES:
      throw SetupError(key, fmt::format("{}: permission denied (ports below 1024 need "
                                        "CAP_NET_BIND_SERVICE)",
                                        where));
    case EADDRNOTAVAIL:
      throw SetupError(
          key, fmt::format("{}: {} is not an address of this host", where, src.bind_address));
    default:
      throw SetupError(key, fmt::format("{}: {}", where, errno_text(error)));
  }
}

// Two sensors of this daemon on one port: only when both share it (two sensors broadcasting to
// 2368 is common; sensor_address tells them apart).
void check_port_overlap(const DaemonOptions& options) {
  const auto& sensors = options.sensors;
  for (size_t j = 0; j < sensors.size(); ++j) {
    const SourceOptions& b = sensors[j].source;
    if (b.kind != SourceKind::kUdp) continue;
    for (size_t i = 0; i < j; ++i) {
      const SourceOptions& a = sensors[i].source;
      if (a.kind != SourceKind::kUdp) continue;
      const bool overlap = a.bind_address == b.bind_address || a.bind_address == "0.0.0.0" ||
                           b.bind_address == "0.0.0.0";
      uint32_t address_a = 0, address_b = 0;
      driver::parse_ipv4_address(a.bind_address, address_a);
      driver::parse_ipv4_address(b.bind_address, address_b);
      const bool shared =
          (a.share_port || is_multicast(address_a)) && (b.share_port || is_multicast(address_b));
      if (!overlap || shared) continue;
      for (const auto& [name, port] :
           {std::pair{"data_port", b.data_port}, std::pair{"position_port", b.position_port}}) {
        if (port != a.data_port && port != a.position_port) continue;
        throw SetupError(
            fmt::format("sensors[{}].source.{}", j, name),
            fmt::format("UDP port {} is also sensor '{}''s (sensors[{}]): give each sensor its "
                        "own port, or set share_port: true on both and sensor_address on each "
                        "to tell them apart",
                        port, sensors[i].name, i));
      }
    }
  }
}

}  // namespace

SetupError::SetupError(const std::string& key, const std::string& problem)
    : std::runtime_error(key + ": " + problem), key_(key) {}

void check_setup(const DaemonOptions& options) {
  check_lcm(options.lcm.url);
  if (!options.record_pcap.empty()) {
    check_plain_output("record_pcap", options.record_pcap, "the --record file");
    check_not_an_input(options, "record_pcap", options.record_pcap, "the --record file");
  }
  if (!options.mcap.empty()) {
    check_plain_output("mcap", options.mcap, "the --mcap file");
    check_not_an_input(options, "mcap", options.mcap, "the --mcap file");
  }
  if (!options.logging.file.empty()) {
    check_log_output(options.logging.file);
    try {
      check_not_an_input(options, "logging.file", options.logging.file, "the log file");
    } catch (const SetupError&) {
      throw ConfigError("logging.file", options.logging.file,
                        "is the file a sensor replays: it would be written while it is read");
    }
  }
  try {
    const LcmUrl url = parse_lcm_url(options.lcm.url);  // checked above
    if (url.provider == "file") check_not_an_input(options, "lcm.url", url.target, "the LCM log");
  } catch (const LcmError&) {
  }
  check_port_overlap(options);
  for (size_t i = 0; i < options.sensors.size(); ++i) {
    const SensorOptions& sensor = options.sensors[i];
    const std::string key = fmt::format("sensors[{}]", i);
    if (!sensor.calibration.empty()) check_calibration(key + ".calibration", sensor);
    if (!sensor.metadata.empty()) check_metadata(key + ".metadata", sensor);
    const SourceOptions& src = sensor.source;
    switch (src.kind) {
      case SourceKind::kUdp:
        check_udp_port(key + ".source.data_port", src, src.data_port);
        check_udp_port(key + ".source.position_port", src, src.position_port);
        break;
      case SourceKind::kPcap:
        check_readable(key + ".source.file", src.file, "replay file", true);
        break;
      case SourceKind::kLcm:
        check_readable(key + ".source.file", src.file, "replay file");
        break;
      case SourceKind::kInterface:
        break;  // opening the capture is the check (it needs CAP_NET_RAW)
    }
  }
}

}  // namespace lidartag::daemon
