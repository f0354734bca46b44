// Test helper: a real SQLite tile store holding a small synthetic layer (grid tiles of a smooth
// height function), with honest-looking geometric errors per level so that the client refines.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/geo/mercator.hpp"
#include "tinstream/geo/tile_id.hpp"
#include "tinstream/store/tile_store.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::client::testing {

// A fresh directory under the build tree, removed by the destructor.
struct TempDir {
  explicit TempDir(const std::string& name);
  ~TempDir();
  std::filesystem::path path;
};

struct SyntheticLayer {
  std::string name = "synth";
  geo::Projection projection = geo::Projection::spherical;
  // The finest tiles; their ancestors up to `min_level` are added.
  std::vector<geo::TileId> finest;
  std::uint32_t min_level = 10;
  int grid = 9;  // vertices per side of every tile
};

// finest = the 4×4 block of level-12 tiles at column 2120, row 1400 (near Luxembourg).
SyntheticLayer default_layer();
// Writes and publishes the layer; returns the tiles written. Throws on a store error.
std::vector<geo::TileId> write_layer(const std::filesystem::path& store,
                                     const SyntheticLayer& layer);
// The tile as write_layer() stores it.
tile::TinTile make_tile(const geo::TileId& id, const SyntheticLayer& layer);
// Writes and publishes imagery layer `info` over the bounds of the store's terrain layer
// `terrain` (info's name, projection, format and levels as given): one tile per id of `tiles`
// for which `bytes` gives a value (nullopt: the tile is left out). Throws on a store error.
using ImageBytes = std::function<std::optional<std::vector<std::uint8_t>>(const geo::TileId&)>;
void write_imagery(const std::filesystem::path& store, const std::string& terrain,
                   store::ImageryInfo info, const std::vector<geo::TileId>& tiles,
                   const ImageBytes& bytes);

}  // namespace tinstream::client::testing
