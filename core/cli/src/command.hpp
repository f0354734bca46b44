// The `tinstream` command line: each subcommand lives in its own src/cmd_<name>.cpp and
// registers itself with a static CommandRegistration, so adding a command touches no other file.
//
//   static const CommandRegistration kRegistration{
//       "triangulate", "Delaunay-triangulate points into an OFF mesh",
//       [](CLI::App& sub) -> CommandRun {
//         auto opts = std::make_shared<Options>();
//         sub.add_option("--in", opts->in, "...")->required();
//         return [opts] { return run(*opts); };   // exit status
//       }};
//
// Runs on the main thread. A command returns its process exit status; errors are printed to
// stderr as one line naming what was wrong.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace tinstream::cli {

using CommandRun = std::function<int()>;
using CommandSetup = std::function<CommandRun(CLI::App&)>;

struct Command {
  std::string name;
  std::string description;
  CommandSetup setup;
};

std::vector<Command>& registered_commands();

struct CommandRegistration {
  CommandRegistration(std::string name, std::string description, CommandSetup setup) {
    registered_commands().push_back({std::move(name), std::move(description), std::move(setup)});
  }
};

}  // namespace tinstream::cli
