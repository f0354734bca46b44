// Test fixtures shared by the tile and store tests: valid random tiles built on a jittered grid.
#pragma once

#include <cstdint>
#include <random>

#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::tile::testing {

// A valid tile (passes check_structure): an (nx × ny)-cell grid whose column and row positions
// are random doubles strictly inside the tile, two CCW triangles per cell with a random diagonal,
// random heights and weights, random NODATA corners (z = 0) when `nodata` is true, random triangle
// order and rotation. Requires nx, ny ≥ 1 and the tile wide enough for nx−1 distinct doubles.
TinTile make_grid_tile(const geo::TileId& id, std::uint32_t nx, std::uint32_t ny,
                       std::mt19937_64& rng, bool nodata = true);

// A random valid tile id at a random level in [0, max_level].
geo::TileId random_tile_id(std::mt19937_64& rng, std::uint32_t max_level = 30);

// Bitwise equality of every field (doubles compared by their bits).
bool same_tile(const TinTile& a, const TinTile& b);

}  // namespace tinstream::tile::testing
