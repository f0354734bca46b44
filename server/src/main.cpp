// tinstream-server — serves a tinstream SQLite store over HTTP. Thin: options, logging, run.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "tinstream/server/config.hpp"
#include "tinstream/server/server.hpp"

int main(int argc, char** argv) {
  using namespace tinstream::server;
  CLI::App app{"tinstream-server — constrained Delaunay TIN tiles and Cesium terrain over HTTP"};
  std::string config_path;
  std::string store, address;
  int port = -1;
  int threads = -1;
  app.add_option("--config,-c", config_path, "JSON configuration file (config/server.json)");
  app.add_option("--store", store, "SQLite tile store (overrides \"store\")");
  app.add_option("--port,-p", port, "TCP port; 0 = any free port (overrides \"port\")")
      ->check(CLI::Range(0, 65535));
  app.add_option("--address", address, "listen address (overrides \"address\")");
  app.add_option("--threads", threads, "io threads; 0 = one per core (overrides \"threads\")")
      ->check(CLI::Range(0, 1024));
  CLI11_PARSE(app, argc, argv);

  ServerConfig config;
  if (!config_path.empty()) {
    auto loaded = load_config(config_path);
    if (!loaded) {
      std::cerr << "tinstream-server: " << loaded.error().message << "\n";
      return 2;
    }
    config = std::move(*loaded);
  }
  if (!store.empty()) config.store = store;
  if (port >= 0) config.port = static_cast<std::uint16_t>(port);
  if (!address.empty()) config.address = address;
  if (threads >= 0) config.threads = static_cast<unsigned>(threads);

  // Logs go to stderr: stdout carries only the machine-readable "listening on" line below (spdlog's
  // default logger would write to stdout).
  spdlog::set_default_logger(spdlog::stderr_color_mt("tinstream-server"));
  spdlog::set_level(spdlog::level::from_str(config.log_level));
  spdlog::set_pattern("[%Y-%m-%dT%H:%M:%S.%e] [%l] %v");

  auto server = Server::create(config, default_ingest_runner());
  if (!server) {
    std::cerr << "tinstream-server: " << server.error().message << "\n";
    return 1;
  }
  // Machine-readable first line for scripts and tests that start the server on port 0.
  std::cout << "listening on " << config.address << ":" << (*server)->port() << std::endl;
  (*server)->run(/*handle_signals=*/true);
  return 0;
}
