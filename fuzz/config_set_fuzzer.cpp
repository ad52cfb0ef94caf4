// Fuzz target: `--set KEY=VALUE` overrides (one per line of the input) applied to the shipped
// config/lidartagd.yaml, as `lidartagd --config /etc/lidartag/lidartagd.yaml --set ...` does.
// Checks as for the file (fuzz/config_round_trip.hpp).
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "config_round_trip.hpp"
#include "fuzz_util.hpp"

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
  fuzz::check_config([&] { return daemon::parse_config(base, overrides); });
  return 0;
}
