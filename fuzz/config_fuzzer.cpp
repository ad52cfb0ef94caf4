// Fuzz target: lidartagd's YAML configuration through parse_config, as `--config FILE` reads it.
// Checks: fuzz/config_round_trip.hpp.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "config_round_trip.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  fuzz::check_config([&] { return daemon::parse_config(text); });
  return 0;
}
