// tinstream/lod/parent.hpp — one parent tile from its four children (DESIGN.md §3, pass 4).
//
// Merge rule: the children's interior points, plus the children's edge points that lie on the
// parent's outer border, plus the children's corners at the midpoints of the parent's sides
// (unless NODATA), become the parent's candidates. The children's points on the internal cross
// (the two lines that split the parent) are cut artefacts: they are not candidates, but they do
// feed the thinning's error estimate as orphans, since they are part of the surface.
//
// Corners: the parent's corner k is child k's corner k. A missing child (no data) gives a NODATA
// corner at z = 0, as pass 3 does where no triangle covers a corner: deterministic, and decided
// from the child alone. (Interpolating from a neighbouring child would invent data and could
// disagree with the tile across the corner, whose children are different tiles.)
//
// Error (an honest upper bound of the max vertical error against the finest surface):
//   geometric_error = max over the overlay |parent − children| + max children geometric_error
//                     + error_rounding_allowance(parent)
// (triangle inequality, since each child's error bounds its distance to the finest surface);
// monotone non-decreasing towards the root by construction. The overlay term is measured where
// the parent and a child both have data: triangles incident to a NODATA corner are skipped on
// both sides (error.hpp), so the chain is an honest bound over the area where every level of the
// subtree has data, and near the data's outer edge it may not cover all finest data (see the
// note in error.hpp). rms_error likewise by Minkowski:
// RMS(parent − children) over the children's data area + area-weighted RMS of the children.
//
// Threads: pure function on values.
#pragma once

#include <array>
#include <optional>

#include "tinstream/base/result.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

// children[i] is parent.children()[i] (NW, NE, SW, SE) or nullopt when it has no data.
// Errors: every child missing, a child with the wrong id, a broken triangulation.
Result<tile::TinTile> build_parent(const geo::TileId& parent,
                                   std::array<std::optional<tile::TinTile>, 4> children,
                                   const LodOptions& options = {}, ThinStats* stats = nullptr);

}  // namespace tinstream::lod
