// tinstream/tile/codec.hpp — the native tile blob (docs/tile-format.md is the specification).
//
// encode() produces the uncompressed little-endian binary form; the store compresses it with zlib
// (compress/decompress here too so that the server can send the stored bytes as-is with
// `Content-Encoding: deflate`). decode() reads every format version and validates everything it
// reads and never trusts counts: a malformed blob gives an Error naming what was wrong, never a
// crash or an unbounded allocation. Pure functions, thread-safe.
//
// Versions (docs/tile-format.md): 1 stores vertices as interleaved f64 (x, y, z, weight); 2, the
// one written by default, stores the same values losslessly as delta-coded, byte-shuffled columns
// (and delta-coded triangle indices), which deflate compresses faster and smaller. Both are
// canonical: a blob that decodes re-encodes, in its own version, to the same bytes.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::tile {

enum class FormatVersion : std::uint16_t { v1 = 1, v2 = 2 };
inline constexpr FormatVersion kCurrentFormat = FormatVersion::v2;

std::vector<std::uint8_t> encode(const TinTile& tile, FormatVersion version = kCurrentFormat);
Result<TinTile> decode(std::span<const std::uint8_t> bytes);

// zlib (RFC 1950) streams, made and read with libdeflate (levels 0–12; 2–3× zlib's speed, any
// zlib reader inflates them). decompress() refuses to inflate past max_output bytes.
std::vector<std::uint8_t> compress(std::span<const std::uint8_t> bytes, int level = 6);
// The same compressor with a gzip (RFC 1952) wrapper: the served Cesium terrain.
std::vector<std::uint8_t> compress_gzip(std::span<const std::uint8_t> bytes, int level = 6);
// A zlib stream made without string matching (core/tile/src/run_deflate.cpp): per 16 KiB block,
// runs of the previous byte and a Huffman code of the block's own byte counts, or the block
// stored. On version-2 tile blobs (byte-shuffled columns) about 2× faster than libdeflate's
// level 1 and a little smaller (bench/codec); it finds no repeated strings, so other data (text,
// version-1 blobs) belong to compress(). Never larger than the input stored plus 6 bytes per block.
std::vector<std::uint8_t> compress_runs(std::span<const std::uint8_t> bytes);
Result<std::vector<std::uint8_t>> decompress(std::span<const std::uint8_t> bytes,
                                             std::size_t max_output = 256u << 20);

}  // namespace tinstream::tile
