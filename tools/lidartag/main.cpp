// lidartag: the project's command-line tool. Subcommands register themselves (commands.hpp).
// Standard output carries only results; logs, warnings, errors and progress go to standard error.
// Exit status: exit_codes.hpp (0 ok, 1 runtime failure, 2 usage or configuration).
#include <spdlog/sinks/stdout_color_sinks.h>  // also declares stderr_color_mt
#include <spdlog/spdlog.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <exception>
#include <string>

#include "lidartag/cli11.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/exit_codes.hpp"
#include "lidartag/version.hpp"

int main(int argc, char** argv) {
  namespace cli = lidartag::cli;
  // Under a file-size limit a write past it fails with EFBIG (an error naming the file, exit 1)
  // instead of SIGXFSZ killing the tool mid-file.
  std::signal(SIGXFSZ, SIG_IGN);
  // spdlog's default logger writes to standard output, where it would break --json.
  auto log = spdlog::stderr_color_mt("lidartag");
  spdlog::set_default_logger(log);
  spdlog::set_pattern("lidartag: %l: %v");

  CLI::App app{"lidartag: Velodyne driver and LiDARTag tools", "lidartag"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("lidartag ") + lidartag::kVersionString,
                       "Print the version and exit");

  auto commands = cli::registry();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  std::vector<std::pair<CLI::App*, cli::RunFunction>> runs;
  for (const auto& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    runs.emplace_back(sub, command.setup(*sub));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Help and version exit 0. Errors are one line with the program's prefix, like every other
    // error: an input file that does not exist is an input that cannot be read (1), the rest
    // usage errors (2).
    if (e.get_exit_code() == 0) return app.exit(e) == 0 ? cli::kExitOk : cli::kExitUsage;
    const std::string what = e.what();
    const bool missing = what.find("does not exist") != std::string::npos;
    std::fprintf(stderr, "lidartag: error: %s%s\n", what.c_str(),
                 missing ? "" : " (run with --help for the options)");
    return missing ? cli::kExitRuntime : cli::kExitUsage;
  }
  for (auto& [sub, run] : runs) {
    if (!sub->parsed()) continue;
    try {
      return run();
    } catch (const std::exception& e) {
      spdlog::default_logger()->flush();
      std::fprintf(stderr, "lidartag: error: %s\n", e.what());
      return cli::exit_code_of(e);
    }
  }
  return cli::kExitUsage;  // unreachable: a subcommand is required
}
