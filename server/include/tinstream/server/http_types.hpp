// tinstream/server/http_types.hpp — the HTTP request and response as the handler sees them.
// Plain values with no Boost.Beast in sight, so the request logic is testable without sockets.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
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
  std::string remote;           // the peer's address ("127.0.0.1", "::1"); empty when unknown
  bool admin_listener = false;  // received on the admin listener (config admin_address)
};

// Heap bytes of a string beyond the object itself (short strings live inside it): for the cache
// budgets' memory accounting.
std::size_t string_heap_bytes(const std::string& s);

// Header fields shared by every identical answer (the 200 of a cached tile), built once, with the
// length of the body they go with: the session sends `keep_alive_head` as it is on a keep-alive
// HTTP/1.1 connection, and `wire` after a status line it formats in every other case. A plain
// value: immutable once built, shared between io threads without synchronisation.
struct HeaderBlock {
  HeaderBlock(std::vector<std::pair<std::string, std::string>> fields, std::size_t content_length);

  std::vector<std::pair<std::string, std::string>> fields;
  std::string wire;                // "Name: value\r\n" for each field, in order
  std::size_t content_length = 0;  // of the body this block was built for
  // The whole head of a 200 with this block and nothing else, `Content-Length: content_length`,
  // on a keep-alive HTTP/1.1 connection: status line to blank line.
  std::string keep_alive_head;

  // Memory this block holds, for cache budgets: the object, its fields, `wire` and the head.
  std::size_t memory_bytes() const;
};

// The status line and header block of an answer, into `out` (cleared first): the status line,
// `Server`, `headers`, the prebuilt block's `wire`, the connection token the version needs
// (`Connection: close` on HTTP/1.1 when `close_after`, `Connection: keep-alive` on HTTP/1.0 when
// not), `Content-Length` unless the status has no body (204, 304), and the blank line.
void format_response_head(std::string& out, int status, unsigned http_version,
                          const std::vector<std::pair<std::string, std::string>>& headers,
                          const HeaderBlock* prebuilt, bool close_after,
                          std::size_t content_length);

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
  // When set, the answer is not ready yet: the session runs `deferred` on the server's blocking
  // worker (never on an io thread) and sends what it returns instead. For work that may wait on
  // a lock or a disk (removing a layer). Callers without a session (tests) call it themselves.
  std::function<Response()> deferred;

  // Case-insensitive, in `headers` then `prebuilt`; nullptr if absent.
  const std::string* header(std::string_view name) const;
  void set(std::string name, std::string value);  // replaces a header in `headers`
};

// `{"error": message, "status": status}` with Content-Type application/json.
Response json_error(int status, std::string_view message);
Response json_response(int status, std::string body);

}  // namespace tinstream::server
