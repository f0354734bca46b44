// tinstream/lod/parent.hpp — one parent tile from its four children (docs/DESIGN.md §3.5, pass 4).
//
// Merge rule: the children's interior points, plus the children's edge points that lie on the
// parent's outer border, plus the children's corners at the midpoints of the parent's sides
// (unless NODATA), plus the children's witnesses (lod_tile.hpp: finest data points where a child
// deviates most), become the parent's candidates. The children's points on the internal cross
// (the two lines that split the parent) are cut artefacts: they are not candidates, but they do
// feed the thinning's error estimate as orphans, since they are part of the surface.
//
// Corners: the parent's corner k is child k's corner k, NODATA flag and height. An absent child
// (no data) gives a NODATA corner whose height the caller supplies (Children::absent_corner_z):
// docs/tile-format.md §2.1 takes it from the tiles of the children's level around that corner,
// which the pyramid reads; deciding it from the children alone could disagree with the tile
// across the corner, whose children are different tiles.
//
// Error (error.hpp): per-triangle bounds chained over the overlay with the children and their
// bounds, measured over the finest level's data against every triangle of the parent (NODATA
// triangles included); geometric_error is their largest, rms_error by Minkowski. Both are upper
// bounds of the error against the finest data, monotone non-decreasing towards the root.
// Witnesses: among the candidates and the cross points, the ones the parent deviates most from.
//
// Threads: pure function on values.
#pragma once

#include <array>
#include <optional>

#include "tinstream/base/result.hpp"
#include "tinstream/lod/lod_tile.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

struct Children {
  std::array<std::optional<LodTile>, 4> tiles;  // parent.children()[i]: NW, NE, SW, SE
  // Where tiles[k] is absent: the height of the parent's corner k (NODATA there).
  std::array<double, 4> absent_corner_z{};
};

// Errors: every child missing, a child with the wrong id, a broken triangulation.
Result<LodTile> build_parent(const geo::TileId& parent, Children children,
                             const LodOptions& options = {}, ThinStats* stats = nullptr);

// The same for unreduced finest children (their bounds are exact), the parent's tile only; an
// absent child's corner takes the height of the data vertex of the present children nearest to
// it (a stand-alone rule: the pyramid applies the one of docs/tile-format.md §2.1).
Result<tile::TinTile> build_parent(const geo::TileId& parent,
                                   std::array<std::optional<tile::TinTile>, 4> children,
                                   const LodOptions& options = {}, ThinStats* stats = nullptr);

}  // namespace tinstream::lod
