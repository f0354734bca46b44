// stored_tiles.hpp — what the handlers may trust of a store row, checked before use. Private to
// the server.
//
// The store is a file: whoever can write it (another process, a restored backup, an attacker
// with write access to the data) decides its bytes. So before a blob is sent or inflated on an
// io thread its header is read (84 bytes inflated, never more): it must name the requested tile
// and declare a size of at most kMaxTileBytes, and it is then inflated to that size and no
// further. A stored ETag goes into response headers only when it is a valid entity tag. A layer
// row's levels are checked before anything is sized by them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/store/tile_store.hpp"

namespace tinstream::server {

// The largest inflated tile an io thread handles. A tile of the 65,535-point budget is about
// 4 MiB (84 + 32 bytes a vertex + 12 a triangle); four times that leaves room for any honest one.
inline constexpr std::size_t kMaxTileBytes = 16u << 20;

// Reads the blob's header: magic, format version, that it holds tile `expected`, and its
// declared inflated size (returned), at most kMaxTileBytes. corrupt_data naming the tile
// otherwise.
Result<std::size_t> check_blob(const store::StoredTile& stored, const geo::TileId& expected);

// The blob inflated, after check_blob: never more than its declared size.
Result<std::vector<std::uint8_t>> inflate_blob(const store::StoredTile& stored,
                                               const geo::TileId& expected);

// The blob rewrapped as gzip (terrain::zlib_to_gzip), after check_blob, bounded the same way.
Result<std::vector<std::uint8_t>> blob_as_gzip(const store::StoredTile& stored,
                                               const geo::TileId& expected);

// The stored ETag when it is a strong entity tag of 1-256 allowed characters (RFC 9110 §8.8.3:
// '!' and '#'-'~' between the quotes), else a tag made from the blob (store::make_etag).
std::string safe_etag(const store::StoredTile& stored);

// A layer row whose levels cannot be right (min_level > max_level, or beyond level 30) is a
// corrupt layer: corrupt_data naming the layer and the fields.
Status check_layer_row(const store::LayerInfo& info);

}  // namespace tinstream::server
