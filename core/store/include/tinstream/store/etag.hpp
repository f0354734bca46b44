// tinstream/store/etag.hpp — content-derived strong ETags (stored tiles; the server's layer.json).
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace tinstream::store {

// FNV-1a, 64 bit, over the bytes.
std::uint64_t fnv1a64(std::span<const std::uint8_t> bytes);

// A strong HTTP entity tag for compressed tile bytes: "\"" + 16 hex digits of fnv1a64 + "-" +
// the byte length in hex + "\"", e.g. "\"af63bd4c8601b7df-1f4\"".
std::string make_etag(std::span<const std::uint8_t> compressed);

}  // namespace tinstream::store
