// tinstream/client/tile_source.hpp — where tiles come from: a tinstream-server over HTTP or a
// tile store file read directly (the paper streams "from a hard disk, a local network or the
// Internet"). One interface, two implementations.
//
// A TileSource is shared by all threads (layers() and connect() are thread-safe). Each download
// worker gets its own TileConnection (a keep-alive HTTP/1.1 connection, or its own read-only
// SQLite connection) and is the only thread that uses it.
//
// HTTP (http_source.cpp, the only file that includes Boost.Beast/Asio): GET
// /tiles/{layer}/{quadkey} with `Accept-Encoding: deflate, gzip` and, when the disk cache holds the
// tile, `If-None-Match`. Every request has a timeout; connection errors, timeouts and 5xx answers
// are retried with exponential backoff (100 ms, 200 ms, … with jitter) up to
// HttpOptions::max_attempts; a reused keep-alive connection that the server closed meanwhile is
// reopened at once. 404 means "no tile here"; other 4xx answers fail without a retry. Imagery
// tiles (TileKind::imagery): GET /imagery/{layer}/{quadkey}, the same rules; from a store, its
// imagery tables.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/client/layer.hpp"
#include "tinstream/client/render_mesh.hpp"
#include "tinstream/client/tile_key.hpp"

namespace tinstream::client {

struct FetchRequest {
  TileKey key;
  const LayerDescription* layer = nullptr;   // the layer named by key.layer
  std::optional<std::string> if_none_match;  // an ETag held in the disk cache
};

struct FetchResponse {
  enum class Status { ok, not_modified, not_found, failed };
  Status status = Status::failed;
  std::vector<std::uint8_t> body;  // as sent (see encoding)
  ContentEncoding encoding = ContentEncoding::identity;
  std::string etag;              // quoted, as sent
  std::uint64_t wire_bytes = 0;  // response bytes received (headers and body), all attempts
  std::uint32_t attempts = 0;    // requests sent (retries = attempts − 1)
  std::uint32_t reconnects = 0;  // connections opened
  Error error;                   // when failed: what went wrong, naming the tile
  // When the last attempt's answer headers were read (HTTP only; default: unknown). For the
  // request timeline (timeline.hpp).
  std::chrono::steady_clock::time_point headers_at{};
};

class TileConnection {
 public:
  virtual ~TileConnection() = default;
  // Blocks for at most the source's timeouts and backoffs; returns early with `failed` once
  // `cancel` becomes true. Never throws.
  virtual FetchResponse fetch(const FetchRequest& request, const std::atomic<bool>& cancel) = 0;
};

class TileSource {
 public:
  virtual ~TileSource() = default;
  // "http://127.0.0.1:8080" or "store terrain.sqlite".
  virtual std::string describe() const = 0;
  // The named layers (in that order), or every published layer when `names` is empty.
  virtual Result<std::vector<LayerDescription>> layers(const std::vector<std::string>& names) = 0;
  // The imagery layer `name` (kind imagery); not_found naming it when the source has none.
  virtual Result<LayerDescription> imagery_layer(const std::string& name) = 0;
  virtual Result<std::unique_ptr<TileConnection>> connect() = 0;
  // Whether tiles travel over a network (then the disk cache is worth using).
  virtual bool remote() const = 0;
};

struct HttpOptions {
  int connect_timeout_ms = 5000;
  int request_timeout_ms = 10000;  // per attempt: writing the request and reading the answer
  int max_attempts = 4;
  int backoff_ms = 100;  // before the second attempt; doubles, ±25 % jitter
  std::size_t max_body_bytes = 64u << 20;
};

// `url`: http://HOST[:PORT][/PREFIX] (no https). Errors name what is wrong with the URL.
Result<std::shared_ptr<TileSource>> open_http_source(std::string_view url,
                                                     const HttpOptions& options = {});
// Opens the store read-only (each connection opens its own SQLite connection).
Result<std::shared_ptr<TileSource>> open_store_source(const std::filesystem::path& store);

}  // namespace tinstream::client
