// tinstream/server/handler.hpp — request → response, without sockets.
//
// handle() is the whole request logic: route parsing, authorisation, store lookups, content
// negotiation, ETags, CORS. The session code (src/server.cpp) only moves bytes. handle() is
// called concurrently from every io thread; everything it touches through Context is either
// immutable, thread-safe (Metrics, JobManager, TerrainCache) or per-thread (the store).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/server/config.hpp"
#include "tinstream/server/http_types.hpp"
#include "tinstream/server/jobs.hpp"
#include "tinstream/server/metrics.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::server {

class TerrainCache;
class LayerCache;

struct Context {
  ServerConfig config;
  std::string admin_token;  // resolved; empty: admin API disabled
  // The calling thread's own read-only store (never shared between threads).
  std::function<Result<store::TileStore*>()> store;
  Metrics* metrics = nullptr;
  JobManager* jobs = nullptr;
  TerrainCache* terrain_cache = nullptr;  // may be null
  LayerCache* layer_cache = nullptr;      // may be null: every request reads the layer row
  std::filesystem::path scratch_dir;      // private folder for ingest jobs' temporary files
  // Server paths and what answers say instead (server_path_redactions()); empty: handle()
  // derives them from `config` on each error answer.
  std::vector<std::pair<std::string, std::string>> path_redactions;
};

// The paths of a configuration that no answer may show (the store, its folder, the data root,
// the upload directory; as given, absolute and canonical), each with its replacement: folders
// followed by '/' vanish (a file under the data root is named relative to it), the rest become
// words ("the store"). Longest first. Reads the file system (canonical paths).
std::vector<std::pair<std::string, std::string>> server_path_redactions(const ServerConfig& config);

// Replaces every server path in `text` (and "/proc/self/fd/N/" prefixes: how the ingest names
// sources opened by descriptor) as server_path_redactions() says.
void redact_server_paths(std::string& text,
                         const std::vector<std::pair<std::string, std::string>>& redactions);

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

// An encoded response body and its ETag: one representation (gzip, or inflated for clients that
// take no gzip) of a terrain tile or layer.json.
struct CachedBody {
  std::string etag;
  std::string bytes;
  // Every header of the 200 answer with these bytes as they are, when the cache owner built it;
  // null: the handler formats the headers per request.
  std::shared_ptr<const HeaderBlock> head;
};

// A bounded LRU of encoded quantized-mesh tiles (gzip, and inflated for clients without gzip) and
// layer.json documents, keyed by layer *version*, tile, extensions and encoding — a new version
// of a layer never hits old entries.
//
// Budget: an entry costs its bytes, ETag, key, shared header block (HeaderBlock::memory_bytes)
// and the bookkeeping around them (nodes, control blocks); bytes() ≤ max_bytes always. An entry
// larger than its partition's budget is not stored.
//
// Thread-safe. Entries are spread by key over `partitions()` independent LRUs, each with its own
// mutex and an equal share of the budget (one partition, an exact LRU, below 16 MiB), so that io
// threads fetching different tiles neither wait for one lock nor pass one list head between
// their cores on every hit.
class TerrainCache {
 public:
  explicit TerrainCache(std::uint64_t max_bytes);
  ~TerrainCache();
  std::shared_ptr<const CachedBody> get(std::string_view key);
  void put(std::string_view key, std::shared_ptr<const CachedBody> value);
  std::uint64_t bytes() const;
  std::size_t partitions() const;
  // What put() charges for `value` under `key`.
  static std::uint64_t cost(std::string_view key, const CachedBody& value);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Layer metadata for the terrain hot path, so that a cached .terrain answer needs no SQLite
// query. Entries live at most `ttl_ms`; clear() (after an admin ingest or delete) drops them at
// once. A layer changed by another process is seen after at most ttl_ms. Thread-safe.
//
// A row read from the store just before an ingest publishes (or a delete commits) must not be
// cached after the clear() that follows it: readers take generation() before reading the row
// and hand it to put(), which drops the row when a clear() came in between.
class LayerCache {
 public:
  explicit LayerCache(std::uint32_t ttl_ms = 1000);
  ~LayerCache();
  std::shared_ptr<const store::LayerInfo> get(const std::string& name);  // null: absent or stale
  std::uint64_t generation() const;                                      // clear() calls so far
  // Caches `info` unless clear() was called since generation() returned `generation`.
  void put(const store::LayerInfo& info, std::uint64_t generation);
  void clear();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tinstream::server
