// Greedy insertion (Garland–Heckbert style), the first stage of the interior thinning when a tile
// has many more candidates than its budget (thinning.hpp, LodOptions::greedy_factor).
//
// Starting from the triangulation of the fixed points (corners and the thinned border, border
// constrained), it repeatedly inserts the candidate of largest effective error (vertical
// distance to the current surface + weight). Every point not in the triangulation is filed
// under the live triangle that contains it (intrusive lists, the same layout the drop stage
// uses for its orphans):
//
//   head[t] ──▶ point i ──next[i]──▶ point j ──▶ … ──▶ kNone
//
// Each triangle slot knows its best candidate; the slots are in a max-heap on that error.
// Inserting p changes only triangles that end up incident to p (Lawson flips all pivot on p, and
// the kernel rewrites split and flipped triangles in their own slots), so the points to re-file
// are exactly those listed under the slots of p's new star, and they land in that star.
//
// Threads: pure function on values.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "lattice.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/kernel/triangulation.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::detail {

// Points of the surface filed under the live triangle slot that contains them.
struct FiledPoints {
  std::vector<std::uint32_t> head;  // by triangle slot; kernel::kNone = empty
  std::vector<std::uint32_t> next;  // by point
  std::vector<double> x, y, z;      // by point

  std::size_t size() const { return x.size(); }
  void push(double px, double py, double pz, kernel::TriangleId t) {
    if (t >= head.size()) head.resize(static_cast<std::size_t>(t) + 1, kernel::kNone);
    const auto i = static_cast<std::uint32_t>(x.size());
    x.push_back(px), y.push_back(py), z.push_back(pz);
    next.push_back(head[t]);
    head[t] = i;
  }
};

struct GreedyResult {
  // By candidate index: the inserted vertex, or kernel::kNone (not selected, or a duplicate).
  std::vector<kernel::VertexId> vertex;
  std::size_t inserted = 0;
  std::size_t duplicates = 0;  // candidates at exactly the (x, y) of a vertex already there
  // The largest effective error of a candidate left out, against the kernel's final mesh.
  double max_error = 0;
  // Every candidate not inserted (duplicates excepted) and every extra point inside the
  // triangulation, filed by triangle (their original z).
  FiledPoints orphans;
};

// Coverage first (docs/tile-format.md §2.1): a point of the surface lying in a triangle at a
// NODATA corner (outside the current footprint) costs this many metres more than its vertical
// error — not a point exactly on such a triangle's data edge (exact orient2d = 0 with its two
// data vertices), which the data triangle beside it covers: a straight data outline (a raster's
// row of cell centres) then needs a few vertices, not every cell — in the greedy stage (a
// candidate there goes in before any other) and in the drop stage
// (a vertex next to a NODATA corner, whose removal would widen the corner's fan over the data,
// goes after every other). So a coarse tile keeps its data's outline while its budget allows, and
// no data hides under a fan whose continued heights only roughly follow it. A point within
// `outline_tolerance` (greedy_insert) of the fan's data edge counts as covered too: thin_tile
// passes one quantized-mesh step of the tile (its width / 32767), so that a data outline that is
// straight to within what a client can show (a UTM raster's row of cell centres, a little curved
// in Mercator) needs a few vertices, not every cell (until 2026-11-28 every one: Big Tujunga's
// ~3,700 outline cells took a coarse tile's whole budget at --max-points 1024).
// Among the points outside the footprint, the greedy stage takes first the one farthest beyond
// its fan's data edge (a hull vertex of what the fan hides), not the one of largest vertical
// error against the fan's continued heights (greedy.cpp FanEdge::rank; until 2026-11-28).
inline constexpr double kCoverageCost = 1e6;

// Inserts candidates into `tri` (already holding the fixed points) until it has `max_vertices`
// vertices, or until the largest effective error is 0 or below `epsilon`. A candidate's effective
// error is its vertical distance to the surface + its weight (+ kCoverageCost in a triangle at
// one of `nodata_vertices`, the NODATA corners). `extra` points are
// filed and carried along but never inserted (dropped border points, deep sources' points on a
// parent's border, ThinInput::orphans): they only feed the drop stage's error estimate
// (GreedyResult::orphans).
// With `lattice` (the candidates form it, lattice.hpp), the candidates are not filed: each
// triangle's best one is found by scanning its lattice cells, and GreedyResult::orphans holds the
// extra points only.
// Errors: a candidate outside the triangulation or not finite (invalid_argument), a kernel
// failure (internal).
// Requires: tri.dimension() == 2, uncut.
Result<GreedyResult> greedy_insert(kernel::Triangulation& tri,
                                   std::span<const tile::Vertex> candidates,
                                   std::span<const tile::Vertex> extra, std::size_t max_vertices,
                                   double epsilon, const Lattice* lattice = nullptr,
                                   std::span<const kernel::VertexId> nodata_vertices = {},
                                   double outline_tolerance = 0);

}  // namespace tinstream::lod::detail
