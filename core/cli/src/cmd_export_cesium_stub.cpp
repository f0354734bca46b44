// Placeholder for the Cesium static export (`tinstream export --dir DIR`); see export_cesium.hpp.
// The engineer writing the exporter replaces this file.
#include <iostream>

#include "export_cesium.hpp"

namespace tinstream::cli {

void add_cesium_dir_options(CLI::App& /*export_command*/, CesiumDirExport& /*request*/) {}

int run_export_cesium_dir(const CesiumDirExport& /*request*/) {
  std::cerr << "tinstream export: --dir (Cesium static export) is not built yet\n";
  return 1;
}

}  // namespace tinstream::cli
