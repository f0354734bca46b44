// Private: cutting the global triangulation at a finest tile's border (pass 3), once its halo is
// gathered: the tile's interior points, the points on its sides, the edge points where surface
// edges cross the sides, and the four corners (interpolated in the global surface, or NODATA).
// Both tiles beside a side compute its vertices from the same numbers in the same order, so
// they agree bit for bit (finest_tiles.hpp, "Watertightness").
#pragma once

#include "halo.hpp"
#include "tile_buffers.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::triangulate::detail {

// The tile's vertices (corners, sides in the tile format's order, interior in the order the first
// halo round gathered their cells), without triangles. Requires: halo.gather() succeeded. Uses
// buffers.tris, buffers.edges and buffers.chunk (and reads the halo's pts, xy and mesh).
Result<tile::TinTile> cut_at_border(const geo::TileId& id, const PointCells& cells,
                                    subdivide::SortedRunReader& reader, const HaloGatherer& halo,
                                    TileBuffers& buffers);

}  // namespace tinstream::triangulate::detail
