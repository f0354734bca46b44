// The plain HTTP values of http_types.hpp: header blocks, response heads, JSON answers.
#include "tinstream/server/http_types.hpp"

#include <array>
#include <boost/beast/http/status.hpp>
#include <charconv>
#include <nlohmann/json.hpp>

#include "negotiation.hpp"

namespace tinstream::server {
namespace {

void append_number(std::string& out, std::uint64_t v) {
  std::array<char, 24> digits{};
  auto [end, ec] = std::to_chars(digits.data(), digits.data() + digits.size(), v);
  out.append(digits.data(), end);
}

}  // namespace

std::size_t string_heap_bytes(const std::string& s) {
  return s.capacity() > std::string().capacity() ? s.capacity() + 1 : 0;
}

void format_response_head(std::string& out, int status, unsigned http_version,
                          const std::vector<std::pair<std::string, std::string>>& headers,
                          const HeaderBlock* prebuilt, bool close_after,
                          std::size_t content_length) {
  namespace http = boost::beast::http;
  out.clear();
  out.append(http_version == 10 ? "HTTP/1.0 " : "HTTP/1.1 ");
  append_number(out, static_cast<std::uint64_t>(status));
  out.push_back(' ');
  const auto reason = http::obsolete_reason(http::int_to_status(static_cast<unsigned>(status)));
  out.append(reason.data(), reason.size());
  out.append("\r\nServer: tinstream\r\n");
  for (const auto& [k, v] : headers) out.append(k).append(": ").append(v).append("\r\n");
  if (prebuilt) out.append(prebuilt->wire);
  if (close_after && http_version != 10) out.append("Connection: close\r\n");
  if (!close_after && http_version == 10) out.append("Connection: keep-alive\r\n");
  if (status != 304 && status != 204) {
    out.append("Content-Length: ");
    append_number(out, content_length);
    out.append("\r\n");
  }
  out.append("\r\n");
}

HeaderBlock::HeaderBlock(std::vector<std::pair<std::string, std::string>> f, std::size_t length)
    : fields(std::move(f)), content_length(length) {
  for (const auto& [k, v] : fields) wire.append(k).append(": ").append(v).append("\r\n");
  format_response_head(keep_alive_head, 200, 11, {}, this, /*close_after=*/false, content_length);
}

std::size_t HeaderBlock::memory_bytes() const {
  std::size_t n = sizeof(HeaderBlock) + fields.capacity() * sizeof(fields.front()) +
                  string_heap_bytes(wire) + string_heap_bytes(keep_alive_head);
  for (const auto& [k, v] : fields) n += string_heap_bytes(k) + string_heap_bytes(v);
  return n;
}

const std::string* Response::header(std::string_view name) const {
  for (const auto& [k, v] : headers) {
    if (iequals(k, name)) return &v;
  }
  if (prebuilt) {
    for (const auto& [k, v] : prebuilt->fields) {
      if (iequals(k, name)) return &v;
    }
  }
  return nullptr;
}

void Response::set(std::string name, std::string value) {
  for (auto& [k, v] : headers) {
    if (iequals(k, name)) {
      v = std::move(value);
      return;
    }
  }
  headers.emplace_back(std::move(name), std::move(value));
}

Response json_response(int status, std::string body) {
  Response r;
  r.status = status;
  r.body = std::move(body);
  r.set("Content-Type", "application/json");
  return r;
}

Response json_error(int status, std::string_view message) {
  // The message may quote the request (a path, a header): invalid UTF-8 there is replaced
  // (U+FFFD) instead of throwing from dump() (request_fuzzer found the throw: std::terminate).
  return json_response(status, nlohmann::json{{"error", message}, {"status", status}}.dump(
                                   -1, ' ', false, nlohmann::json::error_handler_t::replace));
}

}  // namespace tinstream::server
