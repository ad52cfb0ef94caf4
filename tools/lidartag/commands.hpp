// Subcommand registry of the `lidartag` tool. A subcommand lives in its own cmd_<name>.cpp and
// registers itself with a file-scope Registrar; CMake globs cmd_*.cpp, main.cpp adds every
// registered command to the CLI11 app. No file but the new one changes to add a subcommand:
//
//   namespace {
//   const lidartag::cli::Registrar kInfo("info", "Summarise a capture", [](CLI::App& app) {
//     auto path = std::make_shared<std::string>();
//     app.add_option("capture", *path, "pcap file")->required();
//     return [path] { return run(*path); };  // runs after parsing; returns the exit code
//   });
//   }
//
// The run function may throw on setup errors; main prints "lidartag: error: <message>" and exits
// with the status of exit_codes.hpp (2 for usage and configuration errors, 1 for the rest).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "lidartag/cli11.hpp"

namespace lidartag::cli {

using RunFunction = std::function<int()>;
// Declares the subcommand's options on `app` and returns what to run once they are parsed.
using SetupFunction = std::function<RunFunction(CLI::App& app)>;

struct Command {
  std::string name;
  std::string description;
  SetupFunction setup;
};

// Every registered command, in registration order (main sorts them by name).
std::vector<Command>& registry();

struct Registrar {
  Registrar(std::string name, std::string description, SetupFunction setup);
};

}  // namespace lidartag::cli
