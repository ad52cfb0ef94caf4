// lidartag: the project's command-line tool. Subcommands register themselves (commands.hpp).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <exception>

#include "lidartag/cli11.hpp"
#include "lidartag/commands.hpp"

int main(int argc, char** argv) {
  spdlog::set_pattern("lidartag: %l: %v");
  CLI::App app{"lidartag: Velodyne driver and LiDARTag tools"};
  app.require_subcommand(1);

  auto commands = lidartag::cli::registry();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  std::vector<std::pair<CLI::App*, lidartag::cli::RunFunction>> runs;
  for (const auto& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    runs.emplace_back(sub, command.setup(*sub));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Help and version exit 0; every usage error exits 2.
    return app.exit(e) == 0 ? 0 : 2;
  }
  for (auto& [sub, run] : runs) {
    if (!sub->parsed()) continue;
    try {
      return run();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lidartag: error: %s\n", e.what());
      return 1;
    }
  }
  return 2;  // unreachable: a subcommand is required
}
