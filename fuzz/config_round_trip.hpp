// The checks the two configuration targets share (config_fuzzer, config_set_fuzzer): a refused
// configuration throws ConfigError, one line without control characters, never another exception;
// an accepted one passes validate() and survives --print-config (printed, parsed again and printed
// again, it gives the same text: print_config's promise).
#pragma once

#include <string>

#include "fuzz_util.hpp"
#include "lidartag/daemon/config.hpp"

namespace lidartag::fuzz {

template <class Parse>
void check_config(Parse&& parse) {
  daemon::DaemonOptions options;
  try {
    options = parse();
  } catch (const daemon::ConfigError& e) {
    check(one_line(e.what()), std::string("a config error that is not one line: ") + e.what());
    return;
  }
  daemon::validate(options);  // throws (a finding) if parsing let a bad value through
  const std::string printed = daemon::print_config(options);
  std::string again;
  try {
    again = daemon::print_config(daemon::parse_config(printed));
  } catch (const daemon::ConfigError& e) {
    fail(std::string("--print-config output refused: ") + e.what() + "\n" + printed);
  }
  check(again == printed, "--print-config does not round-trip:\n" + printed + "\n" + again);
}

}  // namespace lidartag::fuzz
