// Load and soak runs of lidartagd with figures. The daemon runs inside a private network namespace
// (this program re-executes itself under `unshare -n`), receives UDP on 127.0.0.1 from paced
// senders of real capture payloads (load_sender.hpp) and writes its LCM messages to a log that is
// read afterwards. Each scenario prints what was sent, what the kernel delivered (the namespace's
// /proc/net/snmp: datagrams read by sockets, dropped at full socket buffers, sent to ports nobody
// listens on), what the daemon counted (its final LIDARTAG_STATUS), RSS min/max, CPU, and
// rotations with tags; then checks the counters against each other.
//
//   bench_load run --daemon build/bin/lidartagd [--suite short|long|all] [--scenario NAME]...
//   bench_load send --capture pcaps/demo.pcap [--rate 1] [--seconds 10] [--junk 0] ...
//   bench_load list
//
// Checks (exit status 1 when one fails): every datagram the kernel handed to the daemon's sockets
// is in the daemon's counts (received + foreign sender); the daemon's published + dropped
// rotations = assembled; RSS stays under --rss-limit-mb; rotations with tags keep coming until
// the end of sending; in scenarios marked steady, RSS at the end of the flood is within 10 % of
// its value at 1x. With issue 10's status fields (duplicates, reordered, sequence gaps, kernel
// drops, foreign, malformed each once), those are checked exactly against what was sent.
#include <fcntl.h>
#include <pwd.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

// CLI11 1.9's split() trips GCC 12's -Wnull-dereference once inlined (a false positive inside
// libstdc++'s string, as in daemon/src/main.cpp); the code below keeps every other warning.
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon/process.hpp"
#include "lidartag/status_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "load_sender.hpp"

namespace lidartag::load {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// ---- The kernel's view (inside the namespace: only our traffic). ----

struct UdpMib {
  uint64_t in_datagrams = 0, no_ports = 0, in_errors = 0, rcvbuf_errors = 0;
};

UdpMib read_udp_mib() {
  std::ifstream in("/proc/net/snmp");
  std::string header, values;
  UdpMib m;
  while (std::getline(in, header)) {
    if (header.rfind("Udp:", 0) != 0) continue;
    std::getline(in, values);
    std::istringstream h(header), v(values);
    std::string name, value;
    h >> name, v >> value;
    while (h >> name && v >> value) {
      const uint64_t x = std::stoull(value);
      if (name == "InDatagrams") m.in_datagrams = x;
      if (name == "NoPorts") m.no_ports = x;
      if (name == "InErrors") m.in_errors = x;
      if (name == "RcvbufErrors") m.rcvbuf_errors = x;
    }
    break;
  }
  return m;
}

// Bytes waiting in the receive queues of the sockets bound to `ports`.
uint64_t receive_queue(const std::vector<uint16_t>& ports) {
  std::ifstream in("/proc/net/udp");
  std::string line;
  std::getline(in, line);
  uint64_t queued = 0;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string slot, local, remote, state, queues;
    s >> slot >> local >> remote >> state >> queues;
    const auto colon = local.find(':');
    const auto port = static_cast<uint16_t>(std::stoul(local.substr(colon + 1), nullptr, 16));
    if (std::find(ports.begin(), ports.end(), port) == ports.end()) continue;
    queued += std::stoull(queues.substr(queues.find(':') + 1), nullptr, 16);
  }
  return queued;
}

// ---- The daemon's process: RSS and CPU. ----

struct Usage {
  double rss_mb = 0, cpu_s = 0;
};

std::optional<Usage> usage_of(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  if (!status || !stat) return std::nullopt;
  Usage u;
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) u.rss_mb = std::stod(line.substr(6)) / 1024.0;
  std::string text;
  std::getline(stat, text);
  std::istringstream s(text.substr(text.rfind(')') + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && s >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  u.cpu_s = (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
  return u;
}

// systemd's notification socket, played by us: READY=1 tells that the daemon's sockets are open.
class NotifySocket {
 public:
  explicit NotifySocket(std::string path) : path_(std::move(path)) {
    unlink(path_.c_str());
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    path_.copy(a.sun_path, sizeof(a.sun_path) - 1);
    if (bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0)
      throw std::runtime_error("cannot bind " + path_);
    chmod(path_.c_str(), 0666);  // an unprivileged daemon must be able to write to it
  }
  ~NotifySocket() {
    close(fd_);
    unlink(path_.c_str());
  }
  // READY=1 within `timeout`; false as soon as process `pid` has ended.
  bool wait_ready(std::chrono::milliseconds timeout, pid_t pid) {
    const auto end = Clock::now() + timeout;
    while (Clock::now() < end) {
      std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
      std::string text;
      std::getline(stat, text);
      if (text.empty() || text.substr(text.rfind(')') + 2, 1) == "Z") return false;
      timeval tv{0, 100'000};
      setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
      char buf[4096];
      const ssize_t n = recv(fd_, buf, sizeof(buf), 0);
      if (n > 0 && std::string(buf, static_cast<size_t>(n)).find("READY=1") != std::string::npos)
        return true;
    }
    return false;
  }
  std::string env() const { return "NOTIFY_SOCKET=" + path_; }
  // Reads (and forgets) every later message until `stop`: like systemd, never let the daemon's
  // sd_notify block on a full socket.
  void drain(const std::atomic<bool>& stop) {
    while (!stop) {
      timeval tv{0, 100'000};
      setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
      char buf[4096];
      (void)recv(fd_, buf, sizeof(buf), 0);
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
};

// ---- Scenarios. ----

struct Scenario {
  std::string name;
  std::string what;
  std::string capture;  // key: vlp32c, vls128, vls128_real, ...
  double seconds = 5;
  double rate = 1;
  double junk_ratio = 0;  // junk datagrams per capture packet
  double loss = 0, reorder = 0, duplicate = 0;
  double restart_after_s = 0;
  bool second_sensor = false;   // another sensor (127.0.0.2, outdoor capture) on the same port
  uint64_t probe_junk = 0;      // 1206-byte junk datagrams before the sensor (SenderOptions)
  // With second_sensor: the second sensor is a sensor entry of the daemon too (sharing the ports,
  // each entry with its sensor_address), its status on SECOND_LIDARTAG_STATUS.
  bool second_entry = false;
  bool expect_tags = true;      // the capture holds tags
  double min_tag_fraction = 0;  // of published rotations (clean scenarios)
};

std::vector<Scenario> scenarios(const std::string& suite) {
  const bool s = suite == "short";
  const double t = s ? 4.0 : 30.0;  // seconds per scenario
  std::vector<Scenario> v = {
      {"vlp32c_1x", "VLP-32C (demo) at its rate", "vlp32c", t, 1},
      {"vlp32c_10x", "VLP-32C at 10x its rate", "vlp32c", t, 10},
      {"vlp32c_max", "VLP-32C as fast as the sender goes", "vlp32c", s ? 2.0 : t, 0},
      {"vlp32c_junk", "VLP-32C at 1x, junk at 10x the data rate (0-65,507 B, 10 % to 2368)",
       "vlp32c", t, 1, 10},
      {"vlp32c_loss", "VLP-32C at 1x, 20 % of the data packets lost", "vlp32c", t, 1, 0, 0.2},
      {"vlp32c_reorder_dup", "VLP-32C at 1x, 5 % reordered, 5 % duplicated", "vlp32c", t, 1, 0, 0,
       0.05, 0.05},
      {"vlp32c_restart", "VLP-32C at 1x, the sensor restarts (2 s silence, clock back)", "vlp32c",
       t + 2, 1, 0, 0, 0, 0, s ? 1.5 : 10},
      {"two_sensors", "VLP-32C at 1x from .1 and another sensor from .2 on the same port", "vlp32c",
       t, 1},
      {"vls128_1x", "VLS-128 (simulated) at its rate", "vls128", t, 1},
      {"junk_before_sensor",
       "VLP-32C at 1x after 64 zero datagrams of the probe's size (one with a VLP-16 byte)",
       "vlp32c", t, 1},
      {"two_sensors_shared",
       "VLP-32C from .1 and another sensor from .2, unicast to one port, one sensor entry each",
       "vlp32c", t, 1},
  };
  v[0].min_tag_fraction = 0.8;
  v[7].second_sensor = true;
  v[9].probe_junk = 64;  // once: every packet undecodable, or decoded as a VLP-16, "healthy"
  v[9].min_tag_fraction = 0.8;
  v[10].second_sensor = true;  // once: one entry heard nothing, the other counted its packets
  v[10].second_entry = true;   // foreign
  v[10].min_tag_fraction = 0.8;
  if (s) return v;
  v.push_back({"vls128_10x", "VLS-128 at 10x its rate", "vls128", t, 10});
  v.push_back({"vls128_max", "VLS-128 as fast as the sender goes", "vls128", t, 0});
  v.push_back({"vlp32c_loss_50", "VLP-32C at 1x, 50 % lost", "vlp32c", t, 1, 0, 0.5});
  v.push_back({"flood_1x", "VLP-32C at 1x for 60 s (the flood's reference)", "vlp32c", 60, 1});
  v.push_back(
      {"flood_10x_junk", "VLP-32C at 10x + junk at 10x the data rate, 60 s", "vlp32c", 60, 10, 1});
  v.push_back(
      {"soak_1x_junk", "10-minute soak: VLP-32C at 1x with junk at 10x", "vlp32c", 600, 1, 10});
  return v;
}

// ---- One run. ----

struct Options {
  std::string daemon;
  std::map<std::string, std::string> captures;  // key -> file
  std::string second_capture;
  std::string user;  // run the daemon as this user (setpriv), "" = as we are
  double rss_limit_mb = 400;
  int workers = 2;
  std::string work_dir;
};

struct Result {
  Scenario scenario;
  SenderCounts sent, second;
  UdpMib kernel;  // deltas
  std::optional<status_t> status;
  std::optional<status_t> second_status;  // the second sensor entry's (second_entry)
  uint64_t detection_messages = 0, with_tags = 0, tags_late = 0;
  // Status messages that said healthy although data packets had arrived since the one before and
  // none of them was decoded (a blind sensor reported as well).
  uint64_t healthy_blind = 0;
  double rss_min = 1e9, rss_max = 0, rss_end = 0, cpu_percent = 0;
  int exit_status = -1;
  std::vector<std::string> failures;
  std::string stderr_tail;
};

UdpMib delta(const UdpMib& a, const UdpMib& b) {
  return {b.in_datagrams - a.in_datagrams, b.no_ports - a.no_ports, b.in_errors - a.in_errors,
          b.rcvbuf_errors - a.rcvbuf_errors};
}

std::string tail(const std::string& text, size_t lines) {
  std::vector<std::string> all = test::lines_of(text);
  std::string out;
  for (size_t i = all.size() > lines ? all.size() - lines : 0; i < all.size(); ++i)
    out += "    " + all[i] + "\n";
  return out;
}

Result run(const Scenario& sc, const Options& o) {
  Result r;
  r.scenario = sc;
  const fs::path dir = fs::path(o.work_dir) / sc.name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::permissions(dir, fs::perms::all);  // the daemon may run as another user
  const std::string log = (dir / "daemon.lcmlog").string();
  const std::string config = (dir / "lidartagd.yaml").string();
  {
    std::ofstream c(config);
    c << "sensors:\n  - name: load\n    source:\n      kind: udp\n"
         "      bind_address: 127.0.0.1\n      data_port: 2368\n      position_port: 8308\n"
      << (sc.second_sensor ? "      sensor_address: 127.0.0.1\n" : "")
      << (sc.second_entry ? "      share_port: true\n"
                            "  - name: second\n    channel_prefix: SECOND_\n    source:\n"
                            "      kind: udp\n      bind_address: 127.0.0.1\n"
                            "      data_port: 2368\n      position_port: 8308\n"
                            "      sensor_address: 127.0.0.2\n      share_port: true\n"
                          : "")
      << "lcm:\n  url: \"file://"
      << log << "?mode=w\"\n"
      << "pipeline:\n  worker_threads: " << o.workers << "\n"
      << "status:\n  period_s: 0.5\n"
         "detector:\n  tag_sizes_m: [0.8, 0.6]\n  families: [tag16h5]\n";
  }
  const Capture capture = load_capture(o.captures.at(sc.capture));
  std::optional<Capture> second;
  if (sc.second_sensor) second = load_capture(o.second_capture);

  NotifySocket notify((dir / "notify.sock").string());
  std::vector<std::string> argv;
  if (!o.user.empty()) {
    // setpriv execs the daemon itself (runuser would fork): the pid measured is the daemon's.
    const passwd* pw = getpwnam(o.user.c_str());
    if (pw == nullptr) throw std::runtime_error("no user " + o.user);
    argv = {"/usr/bin/setpriv",
            "--reuid=" + std::to_string(pw->pw_uid),
            "--regid=" + std::to_string(pw->pw_gid),
            "--clear-groups",
            "--inh-caps=-all",
            "--bounding-set=-all",
            "--no-new-privs",
            "--"};
  }
  argv.insert(argv.end(), {o.daemon, "--config", config});
  const UdpMib before = read_udp_mib();
  test::Process daemon(argv, {notify.env()}, (dir / "daemon").string());
  if (!notify.wait_ready(30s, daemon.pid())) {
    r.failures.push_back("no READY=1 (the daemon ended, or 30 s passed)");
    daemon.signal(SIGTERM);
    r.exit_status = daemon.wait(10s);
    r.stderr_tail = tail(daemon.err(), 10);
    return r;
  }
  std::atomic<bool> stop_notify{false};
  std::thread notify_reader([&] { notify.drain(stop_notify); });
  const pid_t pid = daemon.pid();
  const auto cpu0 = usage_of(pid);
  const auto t0 = Clock::now();

  std::atomic<bool> stop{false}, sampling{true};
  std::thread sampler([&] {
    while (sampling) {
      if (const auto u = usage_of(pid)) {
        r.rss_min = std::min(r.rss_min, u->rss_mb);
        r.rss_max = std::max(r.rss_max, u->rss_mb);
        r.rss_end = u->rss_mb;
      }
      std::this_thread::sleep_for(100ms);
    }
  });
  SenderOptions so;
  so.rate = sc.rate;
  so.seconds = sc.seconds;
  so.junk_ratio = sc.junk_ratio;
  so.loss = sc.loss;
  so.reorder = sc.reorder;
  so.duplicate = sc.duplicate;
  so.restart_after_s = sc.restart_after_s;
  so.restart_silence_s = 2.0;
  so.probe_junk = sc.probe_junk;
  std::thread second_thread;
  if (second) {
    second_thread = std::thread([&] {
      SenderOptions s2 = so;
      s2.source_address = "127.0.0.2";
      s2.junk_ratio = 0;
      s2.seed = 2;
      r.second = send(*second, s2, stop);
    });
  }
  r.sent = send(capture, so, stop);
  if (second_thread.joinable()) second_thread.join();
  const auto sent_at = Clock::now();
  // Let the daemon read what is queued (bounded), then look at the kernel's counts.
  for (int i = 0; i < 100 && receive_queue({2368, 8308}) > 0; ++i)
    std::this_thread::sleep_for(50ms);
  std::this_thread::sleep_for(700ms);  // the last rotations through detection
  r.kernel = delta(before, read_udp_mib());
  if (const auto u = usage_of(pid); u && cpu0)
    r.cpu_percent =
        100.0 * (u->cpu_s - cpu0->cpu_s) / std::chrono::duration<double>(Clock::now() - t0).count();
  sampling = false;
  sampler.join();
  daemon.signal(SIGTERM);
  r.exit_status = daemon.wait(30s);
  stop_notify = true;
  notify_reader.join();
  r.stderr_tail = tail(daemon.err(), 8);

  // What the daemon published.
  lcm::LogFile in(log, "r");
  if (!in.good()) {
    r.failures.push_back("no LCM log " + log);
    return r;
  }
  const double send_s = std::chrono::duration<double>(sent_at - t0).count();
  int64_t first_utime = 0;
  while (const lcm::LogEvent* e = in.readNextEvent()) {
    if (first_utime == 0) first_utime = e->timestamp;
    try {
      if (e->channel == "LIDARTAG_STATUS") {
        status_t s;
        if (s.decode(e->data, 0, e->datalen) != e->datalen) continue;
        if (r.status && s.healthy && s.packets_data > r.status->packets_data + 100 &&
            s.packets_decoded == r.status->packets_decoded) {
          ++r.healthy_blind;
        }
        r.status = s;
      } else if (e->channel == "SECOND_LIDARTAG_STATUS") {
        status_t s;
        if (s.decode(e->data, 0, e->datalen) == e->datalen) r.second_status = s;
      } else if (e->channel == "LIDARTAG_DETECTIONS") {
        tag_detections_t d;
        if (d.decode(e->data, 0, e->datalen) != e->datalen) continue;
        ++r.detection_messages;
        if (d.ndetections > 0) {
          ++r.with_tags;
          // Tags in the last 2 s of sending: detection went on to the end.
          if (static_cast<double>(e->timestamp - first_utime) * 1e-6 > send_s - 2.0) ++r.tags_late;
        }
      }
    } catch (const std::exception&) {
      r.failures.push_back("undecodable message on " + e->channel);
    }
  }
  return r;
}

// ---- Checks. ----

// status_t before and after issue 10's counters: packets from another sender than
// sensor_address were `packets_ignored`, they are `packets_foreign` (and `packets_ignored` other
// traffic); the kernel's drops were inside `packets_dropped` with the sequence gaps, they are
// `packets_kernel_dropped` (gaps: `packets_missing`). Chosen at compile time, so this program
// builds and checks against either.
template <class S>
int64_t foreign_of(const S& s) {
  if constexpr (requires { s.packets_foreign; })
    return s.packets_foreign;
  else
    return s.packets_ignored;
}
template <class S>
int64_t dropped_of(const S& s) {
  if constexpr (requires { s.packets_kernel_dropped; })
    return s.packets_kernel_dropped + s.packets_missing;
  else
    return s.packets_dropped;
}

// Issue 10's exact counters against what the senders did (each packet counted once, in one
// counter). Compiled in once status_t has those fields; before, there is nothing to check. Exact
// where no datagram was dropped at a full socket buffer (which packets those were is unknown).
template <class S>
void check_exact_counters(Result& r, const S& s, const std::function<void(std::string)>& fail) {
  if constexpr (requires {
                  s.packets_duplicate;
                  s.packets_reordered;
                  s.packets_missing;
                  s.packets_kernel_dropped;
                  s.packets_inconsistent;
                  s.packets_model_mismatch;
                }) {
    auto expect = [&](const char* what, int64_t got, uint64_t want) {
      if (got != static_cast<int64_t>(want))
        fail(std::string(what) + " " + std::to_string(got) + ", expected " + std::to_string(want));
    };
    if (static_cast<uint64_t>(s.packets_kernel_dropped) > r.kernel.rcvbuf_errors)
      fail("kernel drops " + std::to_string(s.packets_kernel_dropped) + " > the kernel's " +
           std::to_string(r.kernel.rcvbuf_errors));
    if (r.kernel.rcvbuf_errors != 0) return;
    expect("packets_kernel_dropped", s.packets_kernel_dropped, 0);
    expect("packets_duplicate", s.packets_duplicate, r.sent.duplicated);
    expect("packets_reordered", s.packets_reordered, r.sent.reordered);
    // A capture looped at packet granularity is whole rotations only to within a packet: at a
    // seam the sender's stream may step by a fraction of a packet in azimuth or time, which no
    // sensor does. The daemon may then drop one packet per seam as stray (inconsistent) and see
    // the step as a gap: at most one of each per seam is the sender's, not the daemon's.
    auto expect_seams = [&](const char* what, int64_t got, uint64_t want) {
      if (got < static_cast<int64_t>(want) || got > static_cast<int64_t>(want + r.sent.loops))
        fail(std::string(what) + " " + std::to_string(got) + ", expected " + std::to_string(want) +
             " (+ at most one per seam, " + std::to_string(r.sent.loops) + " seams)");
    };
    expect_seams("packets_missing", s.packets_missing, r.sent.lost);
    expect("packets_malformed", s.packets_malformed, r.sent.junk_sensor_port);
    expect("packets_foreign", s.packets_foreign,
           r.scenario.second_entry ? 0 : r.second.data + r.second.position);
    expect("packets_model_mismatch", s.packets_model_mismatch, 0);
    if (r.sent.restarts == 0) expect_seams("packets_inconsistent", s.packets_inconsistent, 0);
  }
}

void check(Result& r, const Options& o) {
  auto fail = [&](const std::string& m) { r.failures.push_back(m); };
  if (r.exit_status != 0) fail("exit status " + std::to_string(r.exit_status));
  if (r.healthy_blind > 0)
    fail(std::to_string(r.healthy_blind) +
         " status messages said healthy while data packets arrived and none was decoded");
  if (!r.status) {
    fail("no status message");
    return;
  }
  const status_t& s = *r.status;
  uint64_t read_by_daemon =
      static_cast<uint64_t>(s.packets_received) + static_cast<uint64_t>(foreign_of(s));
  if (r.scenario.second_entry) {
    // Each sensor entry's socket takes its own sender's datagrams (steered by source address).
    if (!r.second_status) {
      fail("no status message of the second sensor entry");
      return;
    }
    const status_t& s2 = *r.second_status;
    read_by_daemon +=
        static_cast<uint64_t>(s2.packets_received) + static_cast<uint64_t>(foreign_of(s2));
    if (foreign_of(s2) != 0)
      fail("the second entry took " + std::to_string(foreign_of(s2)) + " foreign packets");
    if (r.kernel.rcvbuf_errors == 0 &&
        static_cast<uint64_t>(s2.packets_received) != r.second.data + r.second.position)
      fail("the second entry received " + std::to_string(s2.packets_received) + " of its " +
           std::to_string(r.second.data + r.second.position) + " packets");
  }
  // Every datagram a socket of the daemon read (the namespace holds no other reader) is counted.
  // Truncated datagrams are counted among the malformed; none of ours exceeds the buffer.
  if (read_by_daemon != r.kernel.in_datagrams)
    fail("daemon received + foreign = " + std::to_string(read_by_daemon) + ", kernel delivered " +
         std::to_string(r.kernel.in_datagrams));
  // What reached the ports: read, dropped at a full buffer, or lost before (loopback backlog).
  const uint64_t to_ports = r.sent.to_sensor_ports() + r.second.to_sensor_ports();
  if (r.kernel.in_datagrams + r.kernel.rcvbuf_errors > to_ports)
    fail("the kernel delivered more than was sent");
  if (r.kernel.no_ports < r.sent.junk_wrong_port * 99 / 100)
    fail("junk to closed ports: sent " + std::to_string(r.sent.junk_wrong_port) + ", kernel saw " +
         std::to_string(r.kernel.no_ports));
  if (s.rotations_published + s.rotations_dropped != s.rotations_assembled)
    fail("published " + std::to_string(s.rotations_published) + " + dropped " +
         std::to_string(s.rotations_dropped) + " != assembled " +
         std::to_string(s.rotations_assembled));
  if (r.rss_max > o.rss_limit_mb)
    fail("RSS " + std::to_string(r.rss_max) + " MB > " + std::to_string(o.rss_limit_mb) + " MB");
  if (r.scenario.expect_tags) {
    if (r.tags_late == 0) fail("no rotation with tags in the last 2 s of sending");
    const double fraction = r.detection_messages ? static_cast<double>(r.with_tags) /
                                                       static_cast<double>(r.detection_messages)
                                                 : 0.0;
    if (fraction < r.scenario.min_tag_fraction)
      fail("rotations with tags " + std::to_string(fraction) + " < " +
           std::to_string(r.scenario.min_tag_fraction));
  }
  if (r.second.data > 0 && !r.scenario.second_entry && static_cast<uint64_t>(foreign_of(s)) <
                               r.second.data + r.second.position - r.kernel.rcvbuf_errors)
    fail("the second sensor's packets were not set apart (sensor_address)");
  check_exact_counters(r, s, fail);
}

void print_header() {
  std::printf(
      "%-20s %8s %7s %7s %9s | %9s %6s %6s | %8s %7s %7s %7s | %6s %6s %6s %6s | %5s %5s %5s | "
      "%s\n",
      "scenario", "pkt/s", "sent", "junk", "junk@2368", "delivered", "bufdrp", "noport", "received",
      "foreign", "malform", "dropped", "rotasm", "rotpub", "rotdrp", "w/tags", "RSSmn", "RSSmx",
      "CPU%", "result");
}

void print(const Result& r) {
  const status_t s = r.status.value_or(status_t{});
  const double rate =
      static_cast<double>(r.sent.data + r.sent.position + r.second.data + r.second.position) /
      std::max(r.sent.seconds, 1e-9);
  std::printf(
      "%-20s %8.0f %7llu %7llu %9llu | %9llu %6llu %6llu | %8lld %7lld %7lld %7lld | %6lld %6lld "
      "%6lld %6llu | %5.0f %5.0f %5.0f | %s\n",
      r.scenario.name.c_str(), rate,
      static_cast<unsigned long long>(r.sent.data + r.sent.position + r.second.data +
                                      r.second.position),
      static_cast<unsigned long long>(r.sent.junk_wrong_port + r.sent.junk_sensor_port),
      static_cast<unsigned long long>(r.sent.junk_sensor_port),
      static_cast<unsigned long long>(r.kernel.in_datagrams),
      static_cast<unsigned long long>(r.kernel.rcvbuf_errors),
      static_cast<unsigned long long>(r.kernel.no_ports),
      static_cast<long long>(s.packets_received), static_cast<long long>(foreign_of(s)),
      static_cast<long long>(s.packets_malformed), static_cast<long long>(dropped_of(s)),
      static_cast<long long>(s.rotations_assembled), static_cast<long long>(s.rotations_published),
      static_cast<long long>(s.rotations_dropped), static_cast<unsigned long long>(r.with_tags),
      r.rss_min > 1e8 ? 0.0 : r.rss_min, r.rss_max, r.cpu_percent,
      r.failures.empty() ? "ok" : "FAIL");
  if (r.sent.lost || r.sent.reordered || r.sent.duplicated || r.sent.restarts)
    std::printf("%-20s sender: %llu lost, %llu reordered, %llu duplicated, %llu restart(s)\n", "",
                static_cast<unsigned long long>(r.sent.lost),
                static_cast<unsigned long long>(r.sent.reordered),
                static_cast<unsigned long long>(r.sent.duplicated),
                static_cast<unsigned long long>(r.sent.restarts));
  for (const auto& f : r.failures) std::printf("%-20s   failed: %s\n", "", f.c_str());
  if (!r.failures.empty()) std::printf("%s", r.stderr_tail.c_str());
  std::fflush(stdout);
}

// Runs this program again inside a new network namespace with lo up and a multicast route.
int reexec_in_namespace(int argc, char** argv) {
  std::vector<std::string> args = {"/usr/bin/unshare",
                                   "-n",
                                   "--",
                                   "/bin/sh",
                                   "-c",
                                   "ip link set lo up && ip route add 224.0.0.0/4 dev lo && "
                                   "exec \"$@\"",
                                   "sh",
                                   fs::read_symlink("/proc/self/exe").string()};
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  std::vector<char*> c;
  for (auto& a : args) c.push_back(a.data());
  c.push_back(nullptr);
  setenv("LIDARTAG_LOAD_NETNS", "1", 1);
  execv(c[0], c.data());
  std::perror("unshare");
  return 77;
}

int run_command(const std::vector<std::string>& suites, const std::vector<std::string>& names,
                Options o, double rss_steady_tolerance) {
  std::vector<Scenario> chosen;
  for (const auto& suite : suites)
    for (const auto& sc : scenarios(suite == "all" ? "long" : suite))
      if (names.empty() || std::find(names.begin(), names.end(), sc.name) != names.end())
        if (o.captures.count(sc.capture) && (!sc.second_sensor || !o.second_capture.empty()))
          chosen.push_back(sc);
  if (chosen.empty()) {
    std::fprintf(stderr, "bench_load: no scenario to run\n");
    return 2;
  }
  fs::create_directories(o.work_dir);
  fs::permissions(o.work_dir, fs::perms::all);
  std::printf("lidartagd %s%s, %d worker(s), %u cores, RSS limit %.0f MB\n", o.daemon.c_str(),
              o.user.empty() ? "" : (" as " + o.user).c_str(), o.workers,
              std::thread::hardware_concurrency(), o.rss_limit_mb);
  print_header();
  int failed = 0;
  std::map<std::string, Result> results;
  for (const auto& sc : chosen) {
    Result r = run(sc, o);
    check(r, o);
    print(r);
    failed += r.failures.empty() ? 0 : 1;
    results[sc.name] = r;
  }
  // The flood keeps its memory: RSS at the end of 60 s at 10x with junk within the tolerance of
  // the same time at 1x.
  if (results.count("flood_1x") && results.count("flood_10x_junk")) {
    const double a = results["flood_1x"].rss_end, b = results["flood_10x_junk"].rss_end;
    const bool ok = std::fabs(b - a) <= rss_steady_tolerance * a;
    std::printf("flood RSS: %.1f MB at 1x, %.1f MB at 10x with junk (%+.1f %%): %s\n", a, b,
                100.0 * (b - a) / a, ok ? "ok" : "FAIL");
    failed += ok ? 0 : 1;
  }
  std::printf("%zu scenario(s), %d failed\n", chosen.size(), failed);
  return failed ? 1 : 0;
}

}  // namespace
}  // namespace lidartag::load

int main(int argc, char** argv) {
  using namespace lidartag::load;
  CLI::App app{"lidartagd load and soak runs (docs/robustness.md)"};
  app.require_subcommand(1);
  Options o;
  std::vector<std::string> suites, names, capture_args;
  double tolerance = 0.10;
  auto* run_cmd = app.add_subcommand("run", "Run scenarios against lidartagd");
  run_cmd->add_option("--daemon", o.daemon, "lidartagd binary")->required();
  run_cmd->add_option("--suite", suites, "short (the default; the test command), long, all");
  run_cmd->add_option("--scenario", names, "only these scenarios");
  run_cmd->add_option("--capture", capture_args,
                      "KEY=FILE: the capture of a kind (vlp32c, vls128; vlp32c also needs "
                      "second=FILE for two_sensors)");
  run_cmd->add_option("--user", o.user, "run the daemon as this user (needs root)");
  run_cmd->add_option("--rss-limit-mb", o.rss_limit_mb, "largest RSS allowed")->default_val(400);
  run_cmd->add_option("--workers", o.workers, "detector threads")->default_val(2);
  run_cmd->add_option("--work-dir", o.work_dir, "configs, logs, outputs")
      ->default_val("/tmp/lidartag-load");
  run_cmd->add_option("--rss-tolerance", tolerance, "flood RSS vs 1x")->default_val(0.10);

  SenderOptions so;
  auto* send_cmd = app.add_subcommand("send", "Send a capture to a UDP port (loopback)");
  send_cmd->add_option("--capture", so.capture, "pcap")->required();
  send_cmd->add_option("--rate", so.rate, "x the capture's pace; 0 = max")->default_val(1.0);
  send_cmd->add_option("--seconds", so.seconds)->default_val(10.0);
  send_cmd->add_option("--destination", so.destination)->default_val("127.0.0.1");
  send_cmd->add_option("--source", so.source_address)->default_val("127.0.0.1");
  send_cmd->add_option("--port", so.data_port)->default_val(2368);
  send_cmd->add_option("--position-port", so.position_port)->default_val(8308);
  send_cmd->add_option("--junk", so.junk_ratio, "junk datagrams per packet")->default_val(0.0);
  send_cmd->add_option("--loss", so.loss)->default_val(0.0);
  send_cmd->add_option("--reorder", so.reorder)->default_val(0.0);
  send_cmd->add_option("--duplicate", so.duplicate)->default_val(0.0);
  send_cmd->add_option("--restart-after", so.restart_after_s)->default_val(0.0);
  auto* list_cmd = app.add_subcommand("list", "List the scenarios");
  CLI11_PARSE(app, argc, argv);

  try {
    if (*list_cmd) {
      for (const char* suite : {"short", "long"})
        for (const auto& sc : scenarios(suite))
          std::printf("%-6s %-20s %s\n", suite, sc.name.c_str(), sc.what.c_str());
      return 0;
    }
    if (*send_cmd) {
      const Capture c = load_capture(so.capture, 2368, 8308);
      std::atomic<bool> stop{false};
      const SenderCounts n = send(c, so, stop);
      std::printf("sent %llu data, %llu position, %llu junk in %.1f s (%llu send errors)\n",
                  static_cast<unsigned long long>(n.data),
                  static_cast<unsigned long long>(n.position),
                  static_cast<unsigned long long>(n.junk_wrong_port + n.junk_sensor_port),
                  n.seconds, static_cast<unsigned long long>(n.send_errors));
      return 0;
    }
    if (!o.user.empty() && geteuid() != 0) {
      std::printf("skipped: --user %s needs root (to switch to that user)\n", o.user.c_str());
      return 77;
    }
    if (std::getenv("LIDARTAG_LOAD_NETNS") == nullptr) {
      if (std::system("/usr/bin/unshare -n true 2>/dev/null") != 0) {
        std::printf(
            "skipped: unshare -n is not permitted here; the load runs need their own "
            "network namespace\n");
        return 77;
      }
      return reexec_in_namespace(argc, argv);
    }
    if (suites.empty()) suites = {"short"};
    for (const auto& a : capture_args) {
      const auto eq = a.find('=');
      if (eq == std::string::npos) throw std::runtime_error("--capture KEY=FILE: " + a);
      if (a.substr(0, eq) == "second")
        o.second_capture = a.substr(eq + 1);
      else
        o.captures[a.substr(0, eq)] = a.substr(eq + 1);
    }
    return run_command(suites, names, o, tolerance);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_load: %s\n", e.what());
    return 1;
  }
}
