// tinstream/lod/thinning.hpp — thinning one tile: greedy insertion, then error-ordered point
// removal (Lee 1989 drop heuristic).
//
// Contract (docs/DESIGN.md §3.5, pass 4):
//  * Border first, deterministically, from the border points alone. Each side (both corners
//    included, in the tile's edge order) is thinned in 1-D: a side point's error is the largest
//    vertical difference, over every point of the side's *input* between its surviving
//    neighbours, between that input point and the straight line joining the surviving neighbours.
//    The smallest effective error goes first (ties: the point nearer the side's start, by
//    position). Two neighbours hold bit-identical copies of their shared side (same points, same
//    order), so they compute bit-identical results: same-level tiles stay watertight.
//  * Then the border is held fixed (constrained). Large inputs (more than greedy_target points)
//    are first built up by greedy insertion: from the border alone, the interior point of
//    largest effective vertical error is inserted until greedy_target points (settling a little
//    past it while a just-raised error is above the lowest seen before); every other point
//    becomes an orphan. Then the interior is thinned in 2-D: a point's error is the largest
//    vertical difference that removing it would make at the point itself and at every input
//    point already out of the surface inside its star (the "orphans", kept with their original
//    z), evaluated on the re-triangulated star (Triangulation::removal_preview). Indexed
//    priority queue; after a removal the former neighbours are re-evaluated.
//  * Gridded input (interior points a complete rectilinear lattice of more than 4 × max_points,
//    LodOptions::lattice_scan):
//    both stages find the points inside a triangle by scanning its lattice cells row by row
//    rather than keeping every point filed under its triangle (in the drop stage every cell of
//    a removed star counts, its outline included).
//  * Stopping rule, for a side and for the interior alike: keep removing while the count is above
//    budget, and continue while the next effective error is < epsilon (flat areas and lakes go).
//    Corners are never removed.
//  * Coverage first (docs/tile-format.md §2.1): a point that the current surface leaves under a
//    triangle at a NODATA corner (outside its footprint; not one exactly on the triangle's data
//    edge, which the data triangle beside it covers) costs 10⁶ m more in the greedy stage, a
//    vertex next to a NODATA corner (or the side point next to a NODATA end of a side) as much
//    more in the drop stage: a coarse tile keeps its data's outline while its budget allows, so
//    no data hides under a fan.
//  * Weight rule: effective error = error + weight. A weight is thus "metres of vertical error
//    that this point is worth"; a point with weight w survives every point whose error is below
//    its own error + w, and is never removed by the epsilon rule when w ≥ epsilon.
//  * The errors used for decisions are vertex-sampled. The error *stored* in a tile
//    (geometric_error, rms_error) is measured separately and exactly (error.hpp).
//
// Threads: pure functions on values; call from any thread.
#pragma once

#include <array>
#include <cstddef>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/lod/lod_tile.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod {

struct LodOptions {
  std::size_t max_points = 16384;  // per tile, corners and edge points included
  double epsilon = 0.0;            // metres: keep thinning below budget while error < epsilon
  // Budget of one side's edge points (corners excluded). 0 = automatic: min(⌈√max_points⌉,
  // (max_points − 4) / 8) for a square (so the border never takes more than half of the budget),
  // spread over the perimeter by side length for a non-square rectangle (ThinInput::rect). Same
  // tile size ⇒ same budgets, so neighbours stay watertight.
  std::size_t border_points_per_side = 0;
  // Greedy preselection: when corners + (thinned) border + interior exceed the target
  // (greedy_target), the interior is first *built up* by greedy insertion to that many points,
  // and only those are thinned by the drop heuristic; every other point stays in the error
  // estimate as an orphan. 0 = drop from all points (slow on big grids).
  double greedy_factor = 1.25;
  // Gridded input: when the interior points (more than 4 × max_points) form a complete
  // rectilinear lattice (every column × row position once, e.g. a DEM's cells), both stages
  // find a triangle's points by scanning its lattice cells row by row instead of filing every
  // point under its triangle: the same greedy choices, a drop stage that also counts the cells
  // on a removed star's outline, less time and memory. false = always file (the general path).
  bool lattice_scan = true;
  // Error witnesses carried to the next coarser level (lod_tile.hpp): at most this many per
  // tile. 0 = none; SIZE_MAX (the default) = max_points / 8.
  std::size_t witnesses = std::numeric_limits<std::size_t>::max();
  // Exchange steps after the drop stage (0 = none): at most this many times, the k points of
  // largest vertical error go in and the k vertices whose removal then leaves the smallest largest
  // error go out (k = 1 … 8, the first that lowers the largest error; src/exchange.hpp); a vertex
  // next to a NODATA corner may go when the footprint still covers every point (coverage first).
  // The vertex count stays. build_from_sources sets it for a parent at the outline floor
  // (parent.hpp, "Budget").
  std::size_t exchange_steps = 0;
};

// The witness count that `options` implies (LodOptions::witnesses).
std::size_t witness_count(const LodOptions& options);

// The point count the greedy stage builds up to, ⌈greedy_factor × max_points⌉ (0 = no greedy
// stage).
std::size_t greedy_target(const LodOptions& options);

// The per-side budget that `options` implies (see LodOptions::border_points_per_side).
std::size_t side_budget(const LodOptions& options);

// 1-D thinning of one side. `side` holds the side's points in edge order *including both
// corners* (TinTile::border order); `along_x` says whether the side runs along x (north, south)
// or along y (east, west). Returns the kept points (corners always kept), in order.
// `removed`, when given, receives the dropped points. `nodata_ends`: the side's first / last
// corner is NODATA; the point next to it, where the data begin, then goes last (coverage first,
// as in the interior: it costs kCoverageCost = 10⁶ m more).
// Requires: side.size() ≥ 2, positions strictly monotone along the side.
std::vector<tile::Vertex> thin_border_side(std::span<const tile::Vertex> side, bool along_x,
                                           std::size_t budget, double epsilon,
                                           std::vector<tile::Vertex>* removed = nullptr,
                                           std::array<bool, 2> nodata_ends = {false, false});

// What thin_tile works on: a tile's corners and border lists (tile order, corners excluded),
// interior points, and `orphans` — points of the surface being approximated that are not
// candidates themselves (e.g. deeper sources' points on a parent's border); they only
// feed the error estimate.
struct ThinInput {
  geo::TileId id;
  std::array<tile::Vertex, 4> corners{};
  std::array<bool, 4> corner_nodata{};
  std::vector<tile::Vertex> north, east, south, west;
  std::vector<tile::Vertex> interior;
  std::vector<tile::Vertex> orphans;
  // The rectangle the corners span; default id.bounds(). Lets a caller thin a grid in its own
  // coordinates (e.g. metres, bench/lod) rather than a quadtree tile.
  std::optional<geo::MercatorRect> rect;
};

// A tile's own points as the input of thin_tile (no orphans, the tile's rectangle).
ThinInput thin_input(const tile::TinTile& tile);

struct ThinStats {
  std::size_t input_points = 0;  // corners + border + interior given
  std::size_t border_removed = 0;
  std::size_t interior_removed = 0;
  std::size_t duplicates = 0;       // interior points dropped as exact (x, y) duplicates
  std::size_t greedy_inserted = 0;  // interior points selected by the greedy stage (0: none)
  // When it ran: the largest effective error of an interior point it left out, against the
  // surface it handed to the drop stage (before any removal).
  double greedy_error = 0;
  double last_error = 0;      // effective error of the last removal (0 when none)
  bool lattice = false;       // the greedy and drop stages scanned the interior as a lattice
  std::size_t exchanged = 0;  // exchange steps made (LodOptions::exchange_steps)
};

// Triangulates the input with the border constrained and thins it (border first, then
// interior). The result has corners, border lists, surviving interior, CCW triangles, z range;
// its geometric_error / rms_error are left 0 (the caller measures them, error.hpp).
// Errors: a broken triangulation (reported, never a crash), invalid options.
// What a parent's thinning knows beyond its own candidates (parent.hpp): more points of the
// surface (its finer tiles' vertices) and the finer tiles' triangles. thin_tile breaks Delaunay
// ties (a grid's exactly cocircular cells) once, against its candidates and these together.
struct TieContext {
  std::vector<std::span<const tile::Vertex>> known;
  std::vector<const tile::TinTile*> drawn;  // a tie the points cannot settle takes their diagonal
};

Result<tile::TinTile> thin_tile(const ThinInput& input, const LodOptions& options,
                                ThinStats* stats = nullptr, const TieContext* ties = nullptr);

// "Reduced TIN" at the finest level (gridded input): thins an unreduced finest tile the same
// way and measures it against the original exactly (error.hpp: bounds per triangle,
// geometric_error their largest, the RMS), with witnesses among the original's interior points
// (lod_tile.hpp).
Result<LodTile> reduce_finest(const tile::TinTile& finest, const LodOptions& options,
                              ThinStats* stats = nullptr);
// The same in place, for callers that need the tile only. The tile is replaced only on success.
Status reduce_finest_tile(tile::TinTile& tile, double epsilon, std::size_t max_points,
                          ThinStats* stats = nullptr);
Status reduce_finest_tile(tile::TinTile& tile, const LodOptions& options,
                          ThinStats* stats = nullptr);

}  // namespace tinstream::lod
