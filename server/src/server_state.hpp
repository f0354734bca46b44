// server_state.hpp — what the sessions of a server share: its state, and the shard (io thread)
// each one lives on. Private to the server.
//
//   acceptor (shard 0) ──round robin──▶ shard k: io_context k, run by thread k
//                                        └─ its sessions, its deadline sweep, its BodyFile
#pragma once

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "blocking_worker.hpp"
#include "body_file.hpp"
#include "tinstream/server/config.hpp"
#include "tinstream/server/handler.hpp"
#include "tinstream/server/metrics.hpp"

namespace tinstream::server {

using Clock = std::chrono::steady_clock;
class Session;

// One io_context, run by one thread, and the sessions on it.
struct Shard {
  Shard(std::chrono::milliseconds sweep_every, std::uint64_t body_file_bytes)
      : ioc(1),
        work(boost::asio::make_work_guard(ioc)),
        sweep(ioc),
        every(sweep_every),
        bodies(body_file_bytes) {}

  // Touched only by the shard's own thread (or, once no thread runs the shard, by the thread
  // destroying the server). Declared before ioc: it outlives the handlers ioc destroys.
  std::unordered_set<Session*> sessions;
  boost::asio::io_context ioc;
  // Keeps run() going while the shard has no session; dropped by stop().
  std::optional<boost::asio::executor_work_guard<boost::asio::io_context::executor_type>> work;
  boost::asio::steady_timer sweep;  // checks the sessions' deadlines, collects unused bodies
  std::chrono::milliseconds every;
  BodyFile bodies;  // cached bodies this shard's sessions send with sendfile
};

// Open connections per peer address (config max_connections_per_ip). Thread-safe: acquire() on
// the accepting thread, release() from the session's shard when it closes.
class AddressCounts {
 public:
  // Counts one more connection from `address` unless it has `limit` already (false then).
  bool acquire(const std::string& address, std::uint32_t limit);
  void release(const std::string& address);

 private:
  std::mutex mutex_;  // guards counts_
  std::unordered_map<std::string, std::uint32_t> counts_;
};

// The server-wide state every session reads. `config` and `ctx` are fixed once the server runs;
// the rest is atomic or thread-safe.
struct ServerState {
  explicit ServerState(const ServerConfig& c) : config(c) {}
  ServerConfig config;
  Metrics metrics;
  Context ctx;  // the handler's view of the server (handler.hpp)
  std::atomic<bool> stopping{false};
  std::atomic<std::int64_t> live_sessions{0};
  std::atomic<std::int64_t> lingering{0};   // sessions draining before their close
  std::atomic<std::uint64_t> uploading{0};  // bytes reserved by uploads in progress
  AddressCounts addresses;
  BlockingWorker* blocking = nullptr;  // runs deferred answers (Response::deferred)
};

}  // namespace tinstream::server
