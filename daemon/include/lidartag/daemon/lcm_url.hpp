// LCM provider URLs ("provider://target?key=value&..."), read the way LCM 1.3.1 reads them, and
// checked before the daemon starts: LCM itself only warns on standard error about what it cannot
// use (an unknown option, a bad number) and, without a multicast route, prints a page of advice
// and fails.
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lidartag::daemon {

// An LCM URL that cannot be used, LCM could not be opened with it, or its log file cannot be
// created. One line, naming the URL.
class LcmError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// LCM's own default, used when neither the configuration nor $LCM_DEFAULT_URL gives a URL.
inline constexpr std::string_view kLcmDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";

struct LcmUrl {
  std::string text;      // the URL used: the given one, else $LCM_DEFAULT_URL, else the default
  std::string provider;  // udpm, mpudpm, tcpq, memq or file
  std::string target;    // between "://" and "?": udpm "GROUP:PORT", file a path, tcpq "HOST:PORT"
  std::vector<std::pair<std::string, std::string>> options;  // after "?", in order

  std::optional<std::string> option(std::string_view key) const;
};

// Reads `url` (empty: $LCM_DEFAULT_URL or kLcmDefaultUrl) and checks what LCM would only warn
// about or misuse. Throws LcmError:
// - a provider LCM 1.3.1 does not have;
// - udpm/mpudpm: a group that is not an IPv4 multicast address (224.0.0.0/4), a bad port, an
//   option other than ttl (0..255), recv_buf_size (bytes > 0) and, for mpudpm, nports;
// - file: no path, a mode other than w (write) or a (append): the daemon only writes logs (LCM's
//   default mode, r, would open the file for reading and drop every message), any other option;
// - memq: a target or an option.
LcmUrl parse_lcm_url(const std::string& url);

// udpm/mpudpm: the kernel has a route for the group (the lookup sending does), else LcmError
// saying how to add one. Other providers: nothing to check.
void check_multicast_route(const LcmUrl& url);

}  // namespace lidartag::daemon
