// tinstream/tile/tin_tile.hpp — one constrained-Delaunay TIN tile, as stored and served.
//
// A tile is a rectangle of the quadtree (geo::TileId) with an exact border: its four corners,
// the points where the triangulation meets each border (edge points), interior points and the
// triangles over all of them (docs/DESIGN.md §3.3, pass 3).
//
// Vertex numbering used by `triangles` (and by the render mesh of every encoding):
//
//   index 0..3            corners, in quadkey-digit order: 0 NW, 1 NE, 2 SW, 3 SE
//   then north edge       west → east   (strictly between the NW and NE corners)
//   then east edge        north → south (strictly between NE and SE)
//   then south edge       west → east   (strictly between SW and SE)
//   then west edge        north → south (strictly between NW and SW)
//   then interior         any order (ingest writes them in Morton order)
//
//        0 ──north──▶ 1
//        │            │
//      west         east        ▶/▼ = order of the edge lists
//        ▼            ▼
//        2 ──south──▶ 3
//
// Coordinates are normalised Mercator doubles (x, y) and metres above the WGS84 ellipsoid (z):
// the source form is lossless (millimetres survive). Edge points lie exactly on the border
// (x or y equal to the exact tile bound). Triangles are counter-clockwise seen from above
// (positive orientation in x-east, y-north) and cover the tile rectangle exactly.
//
// NODATA and the data footprint (docs/tile-format.md §2.1). Only corners can be NODATA: a corner
// outside the data keeps the tile a rectangle. It is flagged (corner_nodata) and carries a height
// continued from the data — the height of the input point nearest to it, never 0 — so that no
// triangle drops to the ellipsoid. The tile's *data footprint* is the set of its triangles none
// of whose vertices is NODATA; the others (the fans towards NODATA corners) are *NODATA
// triangles*: they stay in the tile (clients need whole rectangles), a client may leave them out
// or fill them from another layer, and errors are measured over the data only.
//
//        NW (NODATA) ───────── edge points ── NE
//        │  ╲   NODATA triangles  /           │
//        │    ╲       (fan)     /   footprint │
//        │      ● ─── ● ─── ● ─── ● ─── ●     │      ● data vertices
//        │      footprint: triangles of data vertices only
//        SW ──────────────────────────────── SE
//
// Value type; no invariants are enforced on construction — `check_structure` tests them.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "tinstream/base/result.hpp"
#include "tinstream/geo/tile_id.hpp"

namespace tinstream::tile {

struct Vertex {
  double x = 0;       // normalised Mercator
  double y = 0;       // normalised Mercator
  double z = 0;       // metres above the WGS84 ellipsoid
  double weight = 0;  // importance for thinning (≥ 0; higher = kept longer)
};

enum class VertexRole : std::uint8_t { corner, north, east, south, west, interior };

using Triangle = std::array<std::uint32_t, 3>;

struct TinTile {
  geo::TileId id;
  std::array<Vertex, 4> corners{};               // 0 NW, 1 NE, 2 SW, 3 SE
  std::array<bool, 4> corner_nodata{};           // true: no data there (z continued, see above)
  std::vector<Vertex> north, east, south, west;  // ordered as drawn above, corners excluded
  std::vector<Vertex> interior;
  std::vector<Triangle> triangles;  // indices in the numbering above, CCW

  // Statistics, filled by the producer.
  double min_z = 0, max_z = 0;  // over all vertices with data
  double geometric_error = 0;   // max vertical error vs the finest surface (0 at the finest level)
  double rms_error = 0;         // RMS vertical error vs the finest surface
  std::uint64_t source_points = 0;  // input points that fell in this tile (finest level)

  std::size_t vertex_count() const;
  // Requires: i < vertex_count().
  const Vertex& vertex(std::size_t i) const;
  VertexRole role(std::size_t i) const;
  // All vertices in the numbering above (a copy).
  std::vector<Vertex> vertices() const;
  // The lists of one side including both of its corners, in edge order (e.g. north: NW, …, NE).
  std::vector<Vertex> border(geo::Direction side) const;
  // Recomputes min_z / max_z from the vertices (NODATA corners excluded).
  void update_z_range();

  // The data footprint (see the top of this file). Requires: i < vertex_count().
  bool is_nodata_vertex(std::size_t i) const { return i < 4 && corner_nodata[i]; }
  // Whether triangle t has a NODATA vertex, i.e. lies outside the footprint.
  // Requires: t < triangles.size(), its indices < vertex_count().
  bool is_nodata_triangle(std::size_t t) const;
  // One flag per triangle, 1 for a footprint (data) triangle, 0 for a NODATA triangle.
  std::vector<std::uint8_t> footprint_mask() const;
  // Whether any triangle is a NODATA triangle (the tile lies at the data's edge).
  bool has_nodata_triangles() const;
};

// Cheap structural checks: indices in range, edge points exactly on their border and strictly
// ordered, interior points strictly inside, corners at the exact tile corners, triangles CCW
// (exact orientation), total triangle area equals the tile area within rounding.
Status check_structure(const TinTile& tile);

}  // namespace tinstream::tile
