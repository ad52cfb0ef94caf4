// Fuzz target: lidartagd's YAML configuration through parse_config, as `--config FILE` reads it.
// Checks: bad files throw ConfigError (one line without control characters: key, value, reason),
// never another exception;
// a configuration accepted passes validate() and survives --print-config: printed, parsed again
// and printed again, it gives the same text (print_config's promise).
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "lidartag/daemon/config.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  daemon::DaemonOptions options;
  try {
    options = daemon::parse_config(text);
  } catch (const daemon::ConfigError& e) {
    fuzz::check(fuzz::one_line(e.what()),
                std::string("a config error that is not one line: ") + e.what());
    return 0;
  }
  daemon::validate(options);  // throws (a finding) if parse_config let a bad value through
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
