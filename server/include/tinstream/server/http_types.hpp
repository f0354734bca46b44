// tinstream/server/http_types.hpp — the HTTP request and response as the handler sees them.
// Plain values with no Boost.Beast in sight, so the request logic is testable without sockets.
#pragma once

#include <cstdint>
#include <filesystem>
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
};

struct Response {
  int status = 200;
  std::vector<std::pair<std::string, std::string>> headers;
  std::string body;  // bytes
  // When set, sent instead of `body`: shared, immutable bytes (cached tiles), sent without a copy.
  std::shared_ptr<const std::string> shared_body;
  std::string_view payload() const { return shared_body ? std::string_view(*shared_body) : body; }
  std::string route = "other";  // metrics label of the matched route

  const std::string* header(std::string_view name) const;  // case-insensitive; nullptr if absent
  void set(std::string name, std::string value);           // replaces an existing header
};

// `{"error": message, "status": status}` with Content-Type application/json.
Response json_error(int status, std::string_view message);
Response json_response(int status, std::string body);

}  // namespace tinstream::server
