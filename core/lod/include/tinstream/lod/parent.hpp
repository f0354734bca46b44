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
//                     + error_rounding_allowance(parent),
//   raised to nodata_band_bound(parent) + allowance when a child has NODATA triangles
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
#include <limits>
#include <optional>

#include "tinstream/base/result.hpp"
#include "tinstream/lod/thinning.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

// The range of heights of the finest surface (the input points' heights: every finest vertex is
// an input point or an interpolation between them). Empty (NaN) when unknown.
struct HeightRange {
  double min = std::numeric_limits<double>::quiet_NaN();
  double max = std::numeric_limits<double>::quiet_NaN();
  bool known() const { return min <= max; }
};

// NODATA band: where a tile has a triangle at a NODATA corner, it has no surface, yet the finest
// surface may have data there (a thinned tile's NODATA fan reaches over data that its finer
// levels triangulate), and a coarser tile's data triangles may cover it. The chained bound says
// nothing about such places, so a tile whose finer tile (a child, or the original of a reduced
// tile) has NODATA triangles also bounds its error by the farthest its heights lie from the
// finest surface's range: max(max_z − range.min, range.max − min_z). Honest, and coarse: it
// applies only to tiles at the data's outer edge. Returns 0 when the range is unknown.
double nodata_band_bound(const tile::TinTile& tile, const HeightRange& finest);

// children[i] is parent.children()[i] (NW, NE, SW, SE) or nullopt when it has no data.
// `finest`: the finest surface's height range, for the NODATA-band term (see above).
// Errors: every child missing, a child with the wrong id, a broken triangulation.
Result<tile::TinTile> build_parent(const geo::TileId& parent,
                                   std::array<std::optional<tile::TinTile>, 4> children,
                                   const LodOptions& options = {}, ThinStats* stats = nullptr,
                                   const HeightRange& finest = {});

}  // namespace tinstream::lod
