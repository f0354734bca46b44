// tinstream/server/http_types.hpp — the HTTP request and response as the handler sees them.
// Plain values with no Boost.Beast in sight, so the request logic is testable without sockets.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace tinstream::server {

struct Request {
  std::string method;  // "GET", "HEAD", "POST", "DELETE", "OPTIONS", …
  std::string target;  // as received: path and query, percent-encoded
  std::string accept;
  std::string accept_encoding;
  std::string if_none_match;
  std::string authorization;
  std::string content_type;
  std::string body;                 // small bodies (JSON)
  std::filesystem::path body_file;  // an upload streamed to disk; empty otherwise
  std::uint64_t body_file_size = 0;
};

// Header fields shared by every identical answer (the 200 of a cached tile), built once: the
// session sends `wire` as it is, without formatting a header per request.
struct HeaderBlock {
  std::vector<std::pair<std::string, std::string>> fields;
  std::string wire;  // "Name: value\r\n" for each field, in order
  // The whole head of a 200 with this block and nothing else on a keep-alive HTTP/1.1
  // connection (status line to blank line, Content-Length keep_alive_length), formatted by the
  // session the first time it sends one, then sent as it is.
  mutable std::once_flag keep_alive_once;
  mutable std::string keep_alive_head;
  mutable std::size_t keep_alive_length = 0;
  // keep_alive_head is `wire` and at most this many bytes more (status line, Server,
  // Content-Length, blank line).
  static constexpr std::size_t kKeepAliveExtra = 96;

  explicit HeaderBlock(std::vector<std::pair<std::string, std::string>> f);
  // Memory this block holds once its keep-alive head is formatted (an upper bound), for cache
  // budgets: the object, its fields, `wire` and the head.
  std::size_t memory_bytes() const;
};

struct Response {
  int status = 200;
  std::vector<std::pair<std::string, std::string>> headers;
  // When set, sent after `headers`. It already holds every header of the answer that does not
  // depend on the connection (CORS included): nothing may be added to `headers` that repeats one
  // of its fields (add_cors leaves such a response alone).
  std::shared_ptr<const HeaderBlock> prebuilt;
  std::string body;  // bytes
  // When set, sent instead of `body`: shared, immutable bytes (cached tiles), sent without a copy.
  std::shared_ptr<const std::string> shared_body;
  std::string_view payload() const { return shared_body ? std::string_view(*shared_body) : body; }
  std::string route = "other";  // metrics label of the matched route

  // Case-insensitive, in `headers` then `prebuilt`; nullptr if absent.
  const std::string* header(std::string_view name) const;
  void set(std::string name, std::string value);  // replaces a header in `headers`
};

// `{"error": message, "status": status}` with Content-Type application/json.
Response json_error(int status, std::string_view message);
Response json_response(int status, std::string body);

}  // namespace tinstream::server
