// negotiation.hpp — HTTP header values as the handlers read them: case folding, list items,
// Accept-Encoding qualities, quantized-mesh extensions, ETags. Pure functions; no allocation on
// the paths a tile request takes. Private to the server.
#pragma once

#include <string>
#include <string_view>

namespace tinstream::server {

// ASCII case folding, as std::tolower in the "C" locale does, without a library call per byte.
constexpr char ascii_lower(char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c + 32) : c; }

bool iequals(std::string_view a, std::string_view b);

// `s` without leading and trailing spaces and tabs.
std::string_view trim(std::string_view s);

// The next `sep`-separated item of `rest`, trimmed; `rest` moves past it. Walks a header list
// without allocating.
std::string_view next_item(std::string_view& rest, char sep);

// Calls fn(item) for every `sep`-separated item of s (trimmed, possibly empty); stops early when
// fn returns true, and returns whether it did.
template <typename Fn>
bool any_item(std::string_view s, char sep, Fn fn) {
  while (true) {
    const bool last = s.find(sep) == std::string_view::npos;
    if (fn(next_item(s, sep))) return true;
    if (last) return false;
  }
}

// Quality of `coding` in an Accept-Encoding header: 0 when not acceptable.
double accept_quality(std::string_view header, std::string_view coding);

// True when the Accept header asks for the quantized-mesh extension `ext`.
bool accept_wants_extension(std::string_view accept, std::string_view ext);

// True when an If-None-Match header names `etag` (weak or strong) or is `*`.
bool etag_matches(std::string_view if_none_match, std::string_view etag);

// The ETag of one encoding of a resource. A strong ETag names one representation (RFC 9110
// §8.8.3), and the gzip, deflate and identity bodies of a tile are different representations:
// the canonical encoding keeps the stored tag, another gets a suffix inside the quotes
// ("abc" -> "abc-gz"), so a cache revalidating its gzip copy never gets a 304 for an identity
// request.
std::string representation_etag(std::string_view etag, std::string_view suffix);

}  // namespace tinstream::server
