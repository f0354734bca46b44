// export_cesium.hpp — the hook through which `tinstream export --dir DIR` (a static Cesium
// quantized-mesh tree: layer.json + {z}/{x}/{y}.terrain) plugs into cmd_export_tile.cpp.
//
// cmd_export_tile.cpp owns the `export` subcommand and chooses the mode from the options given:
//   --tile QUADKEY  → one tile as OBJ or JSON (cmd_export_tile.cpp)
//   --dir DIR       → run_export_cesium_dir() below
// The Cesium exporter adds its own extra options in add_cesium_dir_options() and implements
// run_export_cesium_dir(); cmd_export_cesium_stub.cpp is the placeholder until it exists
// (replace that file; it is compiled because core/cli globs src/cmd_*.cpp).
// Runs on the main thread.
#pragma once

#include <filesystem>
#include <string>

namespace CLI {
class App;
}

namespace tinstream::cli {

struct CesiumDirExport {
  std::filesystem::path store;  // --store
  std::string layer;            // --layer
  std::filesystem::path dir;    // --dir: output directory
  // The Cesium exporter may add fields here, filled by the options it registers below.
};

// Registers options specific to the --dir mode on the `export` subcommand (called once, at
// start-up).
void add_cesium_dir_options(CLI::App& export_command, CesiumDirExport& request);

// Runs the export; returns the process exit status, printing one-line errors to stderr.
int run_export_cesium_dir(const CesiumDirExport& request);

}  // namespace tinstream::cli
