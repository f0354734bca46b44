// Private: the halo of one finest tile (pass 3) — the points a tile needs beyond its own so that
// its triangles meeting the border are those of the global Delaunay triangulation.
//
// The halo S is a set of sub-cells (PointCells' cells, 2^sub_shift per tile side). It starts
// from the tile's cells and a ring of one cell around it and grows in rounds: each round inserts
// the new cells' points into one triangulation (DelaunayBuilder) and asks it what is missing —
//   (hull)   beyond a local hull edge meeting R while the global hull lies beyond it: the
//            nearest non-empty cells beyond it (searched in doubling boxes);
//   (circle) once the hull has settled: the cells holding a point inside the circle of a local
//            triangle meeting ∂R (perturbed in-circle, exactly as the triangulation decides).
// It stops when a round asks for nothing. Only points within B = R ⊕ 2·rmax are ever examined
// (triangles with circumradius > rmax are not surface, finest_tiles.hpp).
//
// Why the triangles meeting ∂R are then global (and why triangles strictly inside R need not be
// asked): the tile's output depends only on the global triangles meeting ∂R (edge points,
// corners) and on the own points.
//  - A local triangle t′ meeting ∂R with circumradius ≤ rmax has its circle inside B; if no point
//    of B outside S lies in it, it is empty of all points, so it is global.
//  - A global triangle t (circumradius ≤ rmax) meeting ∂R at x with a vertex missing from S
//    (cavity argument): let S′ = S ∪ vertices(t); t ∈ DT(S′), since its circle is empty. If x is
//    inside conv(S), the triangles of DT(S) containing x cover a neighbourhood of x; were all of
//    them still in DT(S′), t would overlap one of them and equal it, so t would be in DT(S).
//    Hence inserting S′ \ S (Bowyer–Watson, under the same perturbation) destroys one of them,
//    t′, and the point whose insertion first does is in t′'s circle; it lies in t's circle ⊂ B,
//    outside S, and t′ contains x ∈ ∂R — so the circle test asks for it. On conv(S)'s boundary
//    the same holds unless t lies beyond the hull edge through x near x; outside conv(S) the
//    segment from x to an own point (every tile has one, and R is convex) leaves conv(S) through
//    a hull edge meeting R. Either way a vertex of t lies beyond a local hull edge meeting R, and
//    the hull search finds a missing point there.
// Checking triangles strictly inside R would only add work (most of it: the slivers of the
// data's hull where it runs through R, whose circles are huge).
//
// Band mode: where ∂R is densely populated (every own border cell holds points) the first round
// leaves out the own cells a cell or more inside ∂R, the "hole"; the circle test treats them like
// any cell not yet gathered (a circle reaching one pulls it in), so the argument above holds for
// the band as it stands, and the own points the output needs come from the tile's records.
//
//   r r r r r r    r  the ring: neighbours' cells along R     } gathered in the first round
//   r b b b b r    b  own border cells (each holds points)    }
//   r b h h b r    h  the hole: own cells a cell or more inside ∂R, gathered only when a
//   r b h h b r       circle of a triangle meeting ∂R reaches them (in band mode)
//   r b b b b r
//   r r r r r r    (n × n own cells; n = 16 but for the deepest levels)
//
// Determinism: the cells a round asks for are a set, the triangulation is canonical (unique), and
// every scan visits cells in a fixed order, so a tile's halo is the same on every run.
#pragma once

#include <cstdint>
#include <span>

#include "tile_buffers.hpp"
#include "tile_geometry.hpp"
#include "tinstream/base/result.hpp"
#include "tinstream/triangulate/finest_tiles.hpp"

namespace tinstream::triangulate::detail {

class HaloGatherer {
 public:
  // Requires: id is a tile at cells.level(); reader reads the run cells indexes. Uses (and
  // clears) buffers' halo parts: have, in_s, pending, pts, own, chunk, peeked, peek_pool, xy,
  // delaunay, hull.
  HaloGatherer(const geo::TileId& id, const PointCells& cells, subdivide::SortedRunReader& reader,
               const FinestTileOptions& options, TileBuffers& buffers);

  // Grows the halo until nothing is missing. After it: buffers.pts is S in gathering order,
  // buffers.xy their positions, buffers.delaunay.mesh() the canonical triangulation of S (indices
  // into pts), buffers.own the tile's own records. Errors: a read failure, more than
  // options.max_gathered_points points, or no convergence in options.max_rounds rounds.
  Status gather();

  // The points of cell (cx, cy) as the first round gathered them: an own cell's from the tile's
  // records (also a hole cell's), another's from S (empty when not gathered). Valid until the
  // buffers change.
  std::span<const SortedPoint> cell_points(std::uint32_t cx, std::uint32_t cy) const;

  // The cells of R and of the ring around it (those that exist), row by row from the north-west:
  // calls visit(cx, cy). Every point in or on R lies in one of them.
  template <typename Visit>
  void for_each_cell_around(const Visit& visit) const {
    for (std::int64_t cy = y0_ - 1; cy <= y0_ + n_; ++cy) {
      for (std::int64_t cx = x0_ - 1; cx <= x0_ + n_; ++cx) {
        if (cx < 0 || cy < 0 || cx >= cells_per_side_ || cy >= cells_per_side_) continue;
        visit(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy));
      }
    }
  }

  const geo::MercatorRect& rect() const { return r_; }
  double rmax() const { return rmax_; }
  // Index of the tile in cells.tiles(), or -1 when it has no points of its own.
  std::ptrdiff_t own_tile() const { return own_; }
  int rounds() const { return rounds_; }
  std::uint64_t circle_tests() const { return circle_tests_; }

 private:
  void want(std::int64_t cx, std::int64_t cy);
  bool in_hole(std::int64_t cx, std::int64_t cy) const;
  bool is_own_cell(std::uint32_t cx, std::uint32_t cy) const;
  bool band_fits() const;
  geo::MercatorRect hole_rect() const;
  // The points of a candidate cell, read once per tile. The span stays valid until the next peek
  // (the pool may grow). A failed read leaves the cell empty and keeps the first error.
  std::span<const XY> peek(std::uint32_t cx, std::uint32_t cy);
  // Calls visit(cx, cy, points) for the not-yet-gathered, non-empty cells inside box ∩ B that
  // meet `touches` (a rectangle predicate).
  template <typename Touches, typename Visit>
  void scan_cells(geo::MercatorRect box, const Touches& touches, const Visit& visit);
  Status read_pending();
  // One round's question to the local triangulation: what is missing (the rules above).
  void grow_halo();
  void settle_hull(const std::vector<XY>& v, const DelaunayMesh& mesh);
  void pull_circles(const std::vector<XY>& v, const DelaunayMesh& mesh);
  void scan_circle(const XY& a, const XY& b, const XY& c, const Circle& circle);

  const geo::TileId id_;
  const PointCells& cells_;
  subdivide::SortedRunReader& reader_;
  const FinestTileOptions& options_;
  TileBuffers& buf_;
  geo::MercatorRect r_;
  std::uint32_t cell_level_;
  std::int64_t n_;  // cells per tile side
  std::int64_t cells_per_side_;
  std::int64_t x0_, y0_;  // the tile's first cell
  std::ptrdiff_t own_;
  bool band_;
  double cell_width_;
  geo::MercatorRect inner_;  // R grown by one cell: what the first round covers
  geo::MercatorRect hole_;   // the band's hole cells together (empty without a band)
  double rmax_;
  geo::MercatorRect b_;  // B = R ⊕ 2·rmax
  std::uint64_t own_first_ = 0;
  int rounds_ = 0;
  std::uint64_t circle_tests_ = 0;
  Status peek_error_;
};

}  // namespace tinstream::triangulate::detail
