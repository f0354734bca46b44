// Delaunay ties broken by error. Where four vertices of a tile lie exactly on one circle (the
// lattice points of a gridded DEM do, cell after cell), both diagonals of their quadrilateral
// are Delaunay, and the kernel picks one by a symbolic perturbation that follows vertex ids — not
// the terrain. On a grid one diagonal of a cell can be metres worse than the other, so two tiles
// with the very same vertices (a parent that keeps its only child's) measured 14.7 and 23.3 m
// (bench/lod/RESULTS.md, 2026-11-27 18:25). This pass keeps, for each such quadrilateral, the
// diagonal with the smaller maximum vertical error at the known points under it; the result is
// still an exact Delaunay triangulation of the same vertices (the circle through the four holds
// no other vertex, whichever diagonal is drawn).
//
// Threads: pure function on values.
#pragma once

#include <cstddef>
#include <span>

#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::detail {

// Flips the diagonal of every exactly cocircular, strictly convex quadrilateral of two data
// triangles (no NODATA corner among its four vertices) whose other diagonal has a strictly
// smaller maximum |z − surface| over the points (of every list in `points`) inside it, or, where
// the points cannot tell (none inside, or equal), whose other diagonal is an edge of a `finer`
// tile and its own is not (a finer tile saw more of the data: a parent keeps its children's
// choices), and where neither settles it, whose other diagonal has a strictly smaller maximum
// error over the points of `own` (the tile's own candidates, a subset of `points`). Repeats until
// no flip applies (at most 8 sweeps). Returns the number of flips.
std::size_t break_delaunay_ties(tile::TinTile& tile,
                                std::span<const std::span<const tile::Vertex>> points,
                                std::span<const tile::TinTile* const> finer,
                                std::span<const std::span<const tile::Vertex>> own = {});

}  // namespace tinstream::lod::detail
