#include "lidartag/commands.hpp"

namespace lidartag::cli {

std::vector<Command>& registry() {
  static std::vector<Command> commands;  // built during static initialisation, read by main
  return commands;
}

Registrar::Registrar(std::string name, std::string description, SetupFunction setup) {
  registry().push_back({std::move(name), std::move(description), std::move(setup)});
}

}  // namespace lidartag::cli
