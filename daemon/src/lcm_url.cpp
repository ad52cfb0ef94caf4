#include "lidartag/daemon/lcm_url.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>

#include "lidartag/daemon/config.hpp"
#include "lidartag/driver/io/udp_frame.hpp"

namespace lidartag::daemon {

namespace {

[[noreturn]] void fail(const LcmUrl& url, const std::string& reason) {
  throw LcmError(fmt::format("LCM URL '{}': {}", clip_text(url.text, 200), reason));
}

// A whole decimal number in [lo, hi].
bool whole_number(std::string_view text, long long lo, long long hi, long long& out) {
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, out);
  return ec == std::errc() && p == end && out >= lo && out <= hi;
}

std::vector<std::string_view> split(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  for (;;) {
    const size_t at = text.find(separator);
    parts.push_back(text.substr(0, at));
    if (at == std::string_view::npos) return parts;
    text.remove_prefix(at + 1);
  }
}

struct Group {
  uint32_t address = 0;  // host byte order
  uint16_t port = 0;
};

// udpm's target "GROUP[:PORT]"; LCM's defaults when parts are missing.
Group multicast_group(const LcmUrl& url) {
  const std::string_view target =
      url.target.empty() ? std::string_view("239.255.76.67:7667") : url.target;
  const size_t colon = target.find(':');
  const std::string_view address = target.substr(0, colon);
  Group group;
  group.port = 7667;
  if (!driver::parse_ipv4_address(address, group.address) || (group.address >> 28) != 0xE) {
    fail(url, fmt::format("'{}' is not an IPv4 multicast group (224.0.0.0 to 239.255.255.255)",
                          clip_text(address)));
  }
  if (colon != std::string_view::npos) {
    long long port = 0;
    if (!whole_number(target.substr(colon + 1), 1, 65535, port)) {
      fail(url,
           fmt::format("bad port '{}' (expected 1..65535)", clip_text(target.substr(colon + 1))));
    }
    group.port = static_cast<uint16_t>(port);
  }
  return group;
}

}  // namespace

std::optional<std::string> LcmUrl::option(std::string_view key) const {
  std::optional<std::string> value;
  for (const auto& [k, v] : options) {
    if (k == key) value = v;  // the last one counts, as in LCM's table
  }
  return value;
}

LcmUrl parse_lcm_url(const std::string& given) {
  LcmUrl url;
  url.text = given;
  if (url.text.empty()) {
    const char* env = std::getenv("LCM_DEFAULT_URL");
    url.text = env != nullptr && *env != '\0' ? env : std::string(kLcmDefaultUrl);
  }
  const size_t scheme = url.text.find("://");
  if (scheme == std::string::npos) fail(url, "expected PROVIDER://TARGET?OPTIONS");
  url.provider = url.text.substr(0, scheme);
  const std::string_view rest = std::string_view(url.text).substr(scheme + 3);
  const size_t query = rest.find('?');
  url.target = std::string(rest.substr(0, query));
  if (query != std::string_view::npos) {
    // LCM splits on '?' and '&' alike.
    for (std::string_view group : split(rest.substr(query + 1), '?')) {
      for (std::string_view pair : split(group, '&')) {
        if (pair.empty()) continue;
        const size_t eq = pair.find('=');
        url.options.emplace_back(
            std::string(pair.substr(0, eq)),
            eq == std::string_view::npos ? "" : std::string(pair.substr(eq + 1)));
      }
    }
  }

  const auto only_options = [&](std::initializer_list<std::string_view> allowed) {
    for (const auto& [key, value] : url.options) {
      bool known = false;
      for (auto a : allowed) known = known || key == a;
      if (!known) {
        std::string list;
        for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(url, fmt::format("unknown option '{}' for {}:// ({})", clip_text(key), url.provider,
                              list.empty() ? "it takes none" : "expected " + list));
      }
    }
  };

  if (url.provider == "udpm" || url.provider == "mpudpm") {
    (void)multicast_group(url);
    if (url.provider == "udpm") {
      only_options({"ttl", "recv_buf_size"});
    } else {
      only_options({"ttl", "recv_buf_size", "nports"});
    }
    long long n = 0;
    if (auto ttl = url.option("ttl"); ttl && !whole_number(*ttl, 0, 255, n)) {
      fail(url, fmt::format("ttl '{}': expected 0..255 (0: this host only)", clip_text(*ttl)));
    }
    if (auto size = url.option("recv_buf_size"); size && !whole_number(*size, 1, INT32_MAX, n)) {
      fail(url, fmt::format("recv_buf_size '{}': expected a number of bytes", clip_text(*size)));
    }
    if (auto ports = url.option("nports"); ports && !whole_number(*ports, 1, 65535, n)) {
      fail(url, fmt::format("nports '{}': expected 1..65535", clip_text(*ports)));
    }
  } else if (url.provider == "file") {
    if (url.target.empty()) fail(url, "no file name (file:///path/to/log.lcmlog?mode=w)");
    only_options({"mode"});
    const auto mode = url.option("mode");
    if (!mode || (*mode != "w" && *mode != "a")) {
      fail(url,
           "the daemon writes logs: add mode=w (create or truncate) or mode=a (append); "
           "without it LCM opens the file for reading");
    }
  } else if (url.provider == "memq") {
    if (!url.target.empty()) fail(url, "memq:// takes no target");
    only_options({});
  } else if (url.provider == "tcpq") {
    // LCM's tcpq client: HOST[:PORT] of an lcm-tcpq server; it checks the connection itself.
  } else {
    fail(url, fmt::format("unknown provider '{}' (LCM 1.3.1 has udpm, mpudpm, tcpq, memq, file)",
                          clip_text(url.provider)));
  }
  return url;
}

void check_multicast_route(const LcmUrl& url) {
  if (url.provider != "udpm" && url.provider != "mpudpm") return;
  const Group group = multicast_group(url);
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) fail(url, std::string("cannot open a UDP socket: ") + std::strerror(errno));
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(group.port);
  to.sin_addr.s_addr = htonl(group.address);
  // connect() on a UDP socket sends nothing: it looks up the route as every send would.
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&to), sizeof(to));
  const int error = errno;
  ::close(fd);
  if (rc != 0) {
    fail(url, fmt::format("no route to the multicast group {} ({}): add one, e.g. 'sudo ip route "
                          "add 224.0.0.0/4 dev lo' for this host only, or dev eth0 (the robot's "
                          "network) to reach other machines; see docs/daemon.md",
                          driver::ipv4_to_string(group.address), std::strerror(error)));
  }
}

}  // namespace lidartag::daemon
