// tinstream/terrain/gzip.hpp — gzip (RFC 1952) helpers for HTTP and static export.
// Pure functions, thread-safe.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"

namespace tinstream::terrain {

// Compressed with libdeflate (tile::compress_gzip; levels 0–12).
std::vector<std::uint8_t> gzip_compress(std::span<const std::uint8_t> bytes, int level = 6);
// Inflates gzip data; refuses to produce more than max_output bytes.
Result<std::vector<std::uint8_t>> gzip_decompress(std::span<const std::uint8_t> bytes,
                                                  std::size_t max_output = 256u << 20);
// Rewraps a zlib (RFC 1950) stream as gzip without recompressing: the raw deflate data is kept,
// the gzip trailer's CRC-32 and size come from inflating once. corrupt_data when `zlib` is not
// a complete zlib stream.
Result<std::vector<std::uint8_t>> zlib_to_gzip(std::span<const std::uint8_t> zlib,
                                               std::size_t max_output = 256u << 20);

}  // namespace tinstream::terrain
