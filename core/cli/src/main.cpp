// tinstream — the command-line front end over the core libraries. Thin: parsing and dispatch.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <map>

#include "command.hpp"

namespace tinstream::cli {

std::vector<Command>& registered_commands() {
  static std::vector<Command> commands;
  return commands;
}

}  // namespace tinstream::cli

int main(int argc, char** argv) {
  using tinstream::cli::registered_commands;
  CLI::App app{"tinstream — constrained Delaunay TIN tiles for virtual globes"};
  app.set_version_flag("--version", std::string("tinstream ") + TINSTREAM_VERSION);
  app.require_subcommand(1);

  auto& commands = registered_commands();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  std::map<CLI::App*, tinstream::cli::CommandRun> runs;
  for (const auto& command : commands) {
    CLI::App* sub = app.add_subcommand(command.name, command.description);
    runs[sub] = command.setup(*sub);
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  for (auto& [sub, run] : runs) {
    if (sub->parsed()) {
      try {
        return run();
      } catch (const std::exception& e) {
        std::cerr << "tinstream " << sub->get_name() << ": " << e.what() << "\n";
        return 1;
      }
    }
  }
  return 2;
}
