// Fuzz target: `--set KEY=VALUE` overrides (one per line of the input) applied to the shipped
// config/lidartagd.yaml, as `lidartagd --config /etc/lidartag/lidartagd.yaml --set ...` does.
// Checks as for the file: ConfigError only, one line; accepted options validate and round-trip
// through --print-config.
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "lidartag/daemon/config.hpp"

using namespace lidartag;

namespace {
std::string shipped_config() {
  std::ifstream in(LIDARTAG_SOURCE_DIR "/config/lidartagd.yaml");
  fuzz::check(in.good(), "cannot read " LIDARTAG_SOURCE_DIR "/config/lidartagd.yaml");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string base = shipped_config();
  std::vector<std::string> overrides;
  std::string line;
  for (size_t i = 0; i <= size; ++i) {
    if (i == size || data[i] == '\n') {
      overrides.push_back(line);
      line.clear();
    } else {
      line.push_back(static_cast<char>(data[i]));
    }
  }
  daemon::DaemonOptions options;
  try {
    options = daemon::parse_config(base, overrides);
  } catch (const daemon::ConfigError& e) {
    fuzz::check(fuzz::one_line(e.what()),
                std::string("a config error that is not one line: ") + e.what());
    return 0;
  }
  daemon::validate(options);
  const std::string printed = daemon::print_config(options);
  std::string again;
  try {
    again = daemon::print_config(daemon::parse_config(printed));
  } catch (const daemon::ConfigError& e) {
    fuzz::fail(std::string("--print-config output refused: ") + e.what() + "\n" + printed);
  }
  fuzz::check(again == printed, "--print-config does not round-trip:\n" + printed + "\n" + again);
  return 0;
}
