// tinstream/lod/error.hpp — how far a coarse tile is from the finest level's data, and the checks
// `tinstream verify` runs on a pyramid.
//
// What is measured (docs/tile-format.md §2.1): the vertical difference between a tile's surface —
// any of its triangles, NODATA triangles included, since a client such as Cesium draws them — and
// the finest level's *data points*: the vertices of its data triangles (the input points, and the
// edge points and corners on the data). Where the finest level has no data nothing is measured,
// so the fans towards NODATA corners count only where they cover data, at their continued
// heights (never down to the ellipsoid). A coarse tile's vertices are finest data points, so the
// difference is 0 there.
//
// Chaining. A parent is built from its children, not from the finest level, so its stored error
// is chained. What a tile knows about the finest data under it, it hands to its parent in two
// parts (lod_tile.hpp):
//  * witnesses: up to LodOptions::witnesses finest data points strictly inside it, not its
//    vertices, where it deviates most — carried exactly (x, y and the finest z);
//  * per triangle t, DeviationBounds of the *residual* points, every other finest data point
//    under t that is not a vertex of the tile:  above(t) ≥ max(tile − z),  below(t) ≥ max(z −
//    tile) over them (none where t has no residual point).
// A finest tile has neither (every finest data point is one of its vertices). For a coarse tile
// P over finer tiles C, the finest data points under P are: C's vertices and C's witnesses —
// known exactly, so P − z is computed there exactly — and C's residual points, where
// P − z = (P − C) + (C − z): on every cell of the overlay of the two meshes P − C is linear, so
// its extremes are at the cell's vertices, and C − z lies within the bounds of the C triangle
// holding the cell. Hence, for every coarse triangle T,
//   above(T) = max over the cell vertices x in T of (P − C)(x) + max above(t), t ∋ x walked,
//   below(T) = max over the same x of (C − P)(x) + max below(t), t ∋ x walked,
// over the cells of C's triangles that have residual points (an upper bound: each cell's own t
// is one of them); the cell vertices are C's vertices, P's vertices and the points where a P edge
// crosses an edge of such a triangle, found without building the overlay by walking those edges
// through P's mesh with exact orientation tests. P's own witnesses are the known points where it
// deviates most; the other known points join the residual bounds of the triangles holding them.
// The tile's geometric error is the largest of its witnesses' deviations and of its residual
// bounds, plus a rounding allowance for the floating-point evaluations
// (error_rounding_allowance). Where a child is exact (the finest level) the chain is exact; above,
// it adds the children's residual bounds only cell by cell, where the parent deviates, which keeps
// it close to the error measured against the finest data (bench/lod: recorded / measured per
// level).
//
// RMS: the root mean square of (P − C) at the finer tiles' data vertices, each weighted by a third
// of the area of its triangles, plus the finer tiles' own RMS (Minkowski).
//
// Threads: pure functions on values.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

// The bounds of one triangle's residual deviation (metres, rounded up to float; see above).
struct DeviationBound {
  static constexpr float kNone = -std::numeric_limits<float>::infinity();
  float above = kNone;  // ≥ max(tile − z) over the triangle's residual finest data points
  float below = kNone;  // ≥ max(z − tile)
  bool has_data() const { return above != kNone; }
  double max_abs() const;  // max(above, below, 0); 0 without residual points
};
// One per triangle of a tile, in its triangle order; empty: no residual point anywhere.
using DeviationBounds = std::vector<DeviationBound>;

// How far the residual points of a NODATA triangle reach towards its NODATA corner(s): every
// point of every cell that gave the triangle its bounds has a barycentric weight of the NODATA
// vertices (together) of at most `reach`, so they all lie in the part of the triangle between
// its data side and the line at that fraction of the way to the corner. A fan's residual points
// come from finer data it overlaps near its data edge; without the reach, the next level would
// take them anywhere in the fan, up to its NODATA corner, whose continued height the next level's
// surface does not follow, and the chained bound would grow by the relief level after level.
//
//        c (NODATA)          reach 1: the whole triangle
//       ╱ ╲
//      ╱ · ╲  ← reach: the residual points lie below this line
//     a ──── b (data)
struct ResidualReach {
  std::uint32_t triangle = 0;
  double reach = 1;  // in [0, 1]
};

// The largest bound (0 when no triangle has residual points).
double max_bound(const DeviationBounds& bounds);

// A finer tile as the chain reads it: its surface, its residual bounds (null or empty: none, as
// for an unreduced finest tile) and its witnesses.
struct ChainInput {
  const tile::TinTile* tile = nullptr;
  const DeviationBounds* bounds = nullptr;
  std::span<const tile::Vertex> witnesses;
  std::span<const ResidualReach> reaches;  // of its NODATA triangles with residual points
};

struct ChainedError {
  DeviationBounds bounds;               // residual, by coarse triangle, allowance included
  std::vector<ResidualReach> reaches;   // of its NODATA triangles with residual points
  std::vector<tile::Vertex> witnesses;  // in Morton order of their position
  double geometric_error = 0;           // max(witness deviations, bounds) + allowance
  double rms_error = 0;
  double max_known = 0;       // max |coarse − z| at the known points (witnesses included)
  std::size_t crossings = 0;  // coarse-edge / finer-edge crossings evaluated
};

// The coarse tile's error over `finer` (its children, or the original of a reduced tile), with at
// most `witness_count` witnesses. Requires: every finer tile lies inside `coarse`'s rectangle and
// is a valid triangulation covering its own rectangle (tile::check_structure), with bounds of
// one entry per triangle when given; `coarse` covers its rectangle.
ChainedError chain_error(const tile::TinTile& coarse, std::span<const ChainInput> finer,
                         std::size_t witness_count);

// The difference of two surfaces: max |coarse − fine| over the fine tiles' data triangles (every
// point of them, not only their vertices: their edges are walked through the coarse mesh as
// above), the vertex RMS and the fine data's area. For tests and benchmarks.
struct SurfaceDifference {
  double max_abs = 0;         // max |coarse − fine| over the fine data
  double sum_sq_area = 0;     // Σ (coarse − fine)² × vertex area (a third of its triangles')
  double area = 0;            // measured area (normalised Mercator units²)
  std::size_t crossings = 0;  // coarse-edge / fine-edge crossings evaluated
  double rms() const;
};
SurfaceDifference surface_difference(const tile::TinTile& coarse,
                                     std::span<const tile::TinTile* const> fines);

// Rounding allowance added to every stored bound (metres): the overlay is evaluated in floating
// point, so the exact maximum may exceed the computed one by a few ulps of the heights involved.
// 1 µm + 1e-9 × the tile's height range.
double error_rounding_allowance(const tile::TinTile& coarse);

// Shared borders of same-level neighbours are identical: for every pair of tiles in the list that
// are east/west or north/south neighbours, the two border() lists match exactly (x, y, z bits).
// Pairs across the antimeridian are not compared. Errors name the pair and the first differing
// point. Requires: all tiles of one level.
Status check_level_watertight(const std::vector<tile::TinTile>& tiles_of_one_level);

// The largest |coarse − finest| found by sampling: every vertex of the finest tiles' data
// triangles located in the coarse tile (any of its triangles), and every coarse vertex located in
// the finest tiles' data triangles (an independent lower bound of the true maximum; verify checks
// stored geometric_error ≥ this). Errors: a finest tile outside the coarse tile, an empty list.
Result<double> measured_max_error(const tile::TinTile& coarse,
                                  const std::vector<tile::TinTile>& finest_tiles_under_it);

// The tile holds at most max_points vertices (corners and edge points included).
Status check_budget(const tile::TinTile& tile, std::size_t max_points);

}  // namespace tinstream::lod
