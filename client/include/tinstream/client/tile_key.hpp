// tinstream/client/tile_key.hpp — what the client's queues and caches are keyed by.
//
// A TileKey names one downloadable tile: its kind (terrain today; imagery tiles of the same
// quadtree will be another kind), the layer (an index into the viewer's layer table) and the
// quadtree tile. Every tier (request queue, loader, RAM, GPU, disk) is keyed by it, so a new tile
// kind adds a decoder and a renderer path, not another set of queues. Value type.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "tinstream/geo/tile_id.hpp"

namespace tinstream::client {

// imagery: a colour tile of the same quadtree draped over the terrain (imagery.hpp).
enum class TileKind : std::uint8_t { terrain = 0, imagery = 1 };

std::string_view to_string(TileKind kind);

struct TileKey {
  TileKind kind = TileKind::terrain;
  std::uint16_t layer = 0;  // index into the viewer's layer table
  geo::TileId tile;

  friend bool operator==(const TileKey&, const TileKey&) = default;
  // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy flags the defaulted comparison itself
  friend auto operator<=>(const TileKey&, const TileKey&) = default;
};

struct TileKeyHash {
  std::size_t operator()(const TileKey& k) const {
    // Level (5 bits), kind and layer above the Morton code of (x, y): unique for z ≤ 30 up to
    // the 60 Morton bits; mixed so that unordered containers spread neighbouring tiles.
    std::uint64_t h = k.tile.morton() ^ (std::uint64_t{k.tile.z} << 58) ^
                      (std::uint64_t{k.layer} << 40) ^ (static_cast<std::uint64_t>(k.kind) << 56);
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdULL;
    h ^= h >> 33;
    return static_cast<std::size_t>(h);
  }
};

}  // namespace tinstream::client
