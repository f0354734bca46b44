// tinstream/server/server.hpp — the HTTP server: Boost.Beast/Asio, one io_context per io thread.
//
// Each connection is an asynchronous session owned by shared_from_this. The listener hands every
// accepted connection, round robin, to one io thread (its own io_context), where the session stays
// until it closes: no strand, lock or thread hand-off per request. Keep-alive, pipelined requests
// answered in order, a timeout on every read and write (deadlines checked by each thread's sweep
// timer, so up to one sweep interval late), header and body limits, at most max_connections
// sessions (more get 503 and are closed). Each io thread opens its own read-only TileStore.
// stop() (also on SIGINT/SIGTERM when handle_signals) closes the listener, closes idle keep-alive
// connections, answers requests already received (with `Connection: close`, up to
// shutdown_grace_ms) and returns from run().
//
// Threads: create() and run() on the caller's thread (run() makes threads-1 more); run() blocks
// until stopped; stop() from any thread. Beast is kept out of this header (pimpl).
#pragma once

#include <cstdint>
#include <memory>

#include "tinstream/base/result.hpp"
#include "tinstream/server/config.hpp"
#include "tinstream/server/jobs.hpp"

namespace tinstream::server {

class Server {
 public:
  // Binds the listening socket (so port() is known before run()). Errors name address/port or
  // the store.
  static Result<std::unique_ptr<Server>> create(const ServerConfig& config, IngestRunner runner);
  ~Server();

  std::uint16_t port() const;
  // max_connections as the server applies it: the configured value, or less when the open-files
  // limit (raised to its hard limit by create()) leaves too little room.
  std::uint32_t max_connections() const;
  // The admin listener's port (config admin_address); 0 when there is none.
  std::uint16_t admin_port() const;
  // Serves until stop(). When handle_signals, SIGINT/SIGTERM call stop().
  void run(bool handle_signals = false);
  void stop();

  struct Impl;

 private:
  explicit Server(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The runner used by the `tinstream-server` executable (server/src/default_ingest_runner.cpp).
IngestRunner default_ingest_runner();

}  // namespace tinstream::server
