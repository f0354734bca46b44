// tinstream/server/handler.hpp — request → response, without sockets.
//
// handle() is the whole request logic: route parsing, authorisation, store lookups, content
// negotiation, ETags, CORS. The session code (src/session.cpp) only moves bytes. handle() is
// called concurrently from every io thread; everything it touches through Context is either
// immutable, thread-safe (Metrics, JobManager, TerrainCache) or per-thread (the store).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "tinstream/base/result.hpp"
#include "tinstream/server/config.hpp"
#include "tinstream/server/http_types.hpp"
#include "tinstream/server/jobs.hpp"
#include "tinstream/server/metrics.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::server {

class TerrainCache;

struct Context {
  ServerConfig config;
  std::string admin_token;  // resolved; empty: admin API disabled
  // The calling thread's own read-only store (never shared between threads).
  std::function<Result<store::TileStore*>()> store;
  Metrics* metrics = nullptr;
  JobManager* jobs = nullptr;
  TerrainCache* terrain_cache = nullptr;  // may be null
};

Response handle(const Request& request, Context& context);

// Admin authorisation of a request's Authorization header: nullopt when allowed, else the
// 401/403 response. Constant-time comparison. Used by handle() and, before an upload body is
// read, by the session.
std::optional<Response> check_admin(const Request& request, const Context& context);

// True when a POST /admin/ingest request carries a file upload (any Content-Type but JSON) whose
// body the session must stream to disk instead of memory.
bool is_upload(const Request& request_head);

// Applies CORS headers (when configured) to any response.
void add_cors(Response& response, const ServerConfig& config);

// A bounded LRU of encoded (gzip) quantized-mesh tiles keyed by layer version, tile and
// extensions. Thread-safe (one mutex).
class TerrainCache {
 public:
  explicit TerrainCache(std::uint64_t max_bytes);
  ~TerrainCache();
  std::shared_ptr<const std::string> get(const std::string& key);
  void put(const std::string& key, std::shared_ptr<const std::string> value);
  std::uint64_t bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tinstream::server
