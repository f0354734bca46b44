// `tinstream modules`: what this build contains (formats, libraries), as JSON.
#include <gdal_version.h>
#include <proj.h>
#include <sqlite3.h>

#include <CLI/CLI.hpp>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command.hpp"

namespace tinstream::cli {
namespace {

int run_modules() {
  nlohmann::json j;
  j["tinstream"] = TINSTREAM_VERSION;
  j["proj"] = std::to_string(PROJ_VERSION_MAJOR) + "." + std::to_string(PROJ_VERSION_MINOR) + "." +
              std::to_string(PROJ_VERSION_PATCH);
  j["gdal"] = GDAL_RELEASE_NAME;
  j["sqlite"] = SQLITE_VERSION;
  j["commands"] = nlohmann::json::array();
  for (const auto& c : registered_commands()) j["commands"].push_back(c.name);
  std::cout << j.dump(2) << "\n";
  return 0;
}

const CommandRegistration kRegistration{"modules",
                                        "Print the libraries and commands in this build as JSON",
                                        [](CLI::App&) -> CommandRun { return run_modules; }};

}  // namespace
}  // namespace tinstream::cli
