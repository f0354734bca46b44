#include "border_cut.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::triangulate::detail {
namespace {

// Where an edge crosses a border line.
struct Crossing {
  double along = 0;  // the coordinate along the border (x for north/south, y for east/west)
  double z = 0;
  // The smaller of the edge's two weights: an edge point is a point of the data's surface, as
  // important to the thinning as the data it lies between (with weight 0 beside inputs of weight
  // 1, every coarser level dropped the finest tiles' seam points first, whatever their error up
  // to 1 m: autzen's level 18 measured 0.24 m at them where thinning them like data gives
  // 0.036 m, bench/lod/RESULTS.md 2026-11-28).
  double weight = 0;
};

// The canonical intersection of edge (a, b) with the horizontal line y = Y (requires a proper
// crossing). Both tiles sharing the line compute exactly this.
Crossing cross_horizontal(const SortedPoint& a, const SortedPoint& b, double Y) {
  const SortedPoint& p = lex_less(a, b) ? a : b;
  const SortedPoint& q = lex_less(a, b) ? b : a;
  const double t = (Y - p.y) / (q.y - p.y);
  return {p.x + t * (q.x - p.x), p.z + t * (q.z - p.z), std::min<double>(p.weight, q.weight)};
}

Crossing cross_vertical(const SortedPoint& a, const SortedPoint& b, double X) {
  const SortedPoint& p = lex_less(a, b) ? a : b;
  const SortedPoint& q = lex_less(a, b) ? b : a;
  const double t = (X - p.x) / (q.x - p.x);
  return {p.y + t * (q.y - p.y), p.z + t * (q.z - p.z), std::min<double>(p.weight, q.weight)};
}

// Elevation of the global surface at corner c, from the triangle of `tris` containing it; the
// computation depends only on the containing triangle's (or edge's) vertices in canonical order.
std::optional<double> corner_elevation(const XY& c, const std::vector<SortedPoint>& pts,
                                       const std::vector<IndexTriangle>& tris) {
  for (const auto& t : tris) {
    const SortedPoint* v[3] = {&pts[t[0]], &pts[t[1]], &pts[t[2]]};
    const XY a{v[0]->x, v[0]->y}, b{v[1]->x, v[1]->y}, d{v[2]->x, v[2]->y};
    if (c.x < std::min({a.x, b.x, d.x}) || c.x > std::max({a.x, b.x, d.x}) ||
        c.y < std::min({a.y, b.y, d.y}) || c.y > std::max({a.y, b.y, d.y})) {
      continue;
    }
    const int s0 = kernel::sign(kernel::orient2d(a, b, c));
    const int s1 = kernel::sign(kernel::orient2d(b, d, c));
    const int s2 = kernel::sign(kernel::orient2d(d, a, c));
    if (s0 < 0 || s1 < 0 || s2 < 0) continue;
    for (const SortedPoint* p : v) {
      if (p->x == c.x && p->y == c.y) return p->z;
    }
    const int zeros = (s0 == 0) + (s1 == 0) + (s2 == 0);
    if (zeros == 1) {  // on an edge: interpolate along it, endpoints in canonical order
      const SortedPoint* e0 = s0 == 0 ? v[0] : s1 == 0 ? v[1] : v[2];
      const SortedPoint* e1 = s0 == 0 ? v[1] : s1 == 0 ? v[2] : v[0];
      if (lex_less(*e1, *e0)) std::swap(e0, e1);
      const double s = std::abs(e1->x - e0->x) >= std::abs(e1->y - e0->y)
                           ? (c.x - e0->x) / (e1->x - e0->x)
                           : (c.y - e0->y) / (e1->y - e0->y);
      return e0->z + s * (e1->z - e0->z);
    }
    std::sort(std::begin(v), std::end(v),
              [](const SortedPoint* l, const SortedPoint* r) { return lex_less(*l, *r); });
    const double d1x = v[1]->x - v[0]->x, d1y = v[1]->y - v[0]->y;
    const double d2x = v[2]->x - v[0]->x, d2y = v[2]->y - v[0]->y;
    const double det = d1x * d2y - d1y * d2x;
    const double px = c.x - v[0]->x, py = c.y - v[0]->y;
    const double u = (px * d2y - py * d2x) / det;
    const double w = (d1x * py - d1y * px) / det;
    return v[0]->z + u * (v[1]->z - v[0]->z) + w * (v[2]->z - v[0]->z);
  }
  return std::nullopt;
}

// The height of a NODATA corner (docs/tile-format.md §2.1): the input point nearest to `corner`
// (dx² + dy² in doubles; ties to the smaller x, then y), found by reading the sub-cells around the
// corner in square rings until no unread cell can hold a nearer point. Every tile around the
// corner reads the same cells in the same order, so all of them get the same height.
//
//   ring 1 ┌───┬───┬───┬───┐    ring r: the cells at Chebyshev cell distance r from the four
//          │   │   │   │   │    cells that meet at the corner (ring 0); every point of ring r is
//          ├───┼───┼───┼───┤    at least r cell widths from the corner.
//          │   │ 0 │ 0 │   │
//          ├───┼───●───┼───┤    ● the corner
//          │   │ 0 │ 0 │   │
//          ├───┼───┼───┼───┤
//          │   │   │   │   │
//          └───┴───┴───┴───┘
Result<double> nearest_input_height(const PointCells& cells, subdivide::SortedRunReader& reader,
                                    const geo::TileId& tile, int corner,
                                    std::vector<SortedPoint>& chunk) {
  const std::uint32_t shift = cells.sub_shift();
  const std::int64_t per_side = std::int64_t{1} << cells.cell_level();
  // The corner's position in cell units: the cells meeting there are columns gx − 1, gx and
  // rows gy − 1, gy (rows from the north, as tile rows).
  const std::int64_t gx = (std::int64_t{tile.x} + (corner & 1)) << shift;
  const std::int64_t gy = (std::int64_t{tile.y} + (corner >> 1)) << shift;
  const geo::MercatorRect r = tile.bounds();
  const XY c{(corner & 1) ? r.max_x : r.min_x, (corner >> 1) ? r.min_y : r.max_y};
  const double cell_width = 2.0 / static_cast<double>(per_side);
  bool found = false;
  double best_d2 = 0, best_x = 0, best_y = 0, best_z = 0;
  auto visit = [&](std::int64_t cx, std::int64_t cy) -> Status {
    if (cx < 0 || cy < 0 || cx >= per_side || cy >= per_side) return {};
    const auto [first, count] =
        cells.cell_range(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy));
    if (count == 0) return {};
    if (Status s = reader.read(first, count, chunk); !s) return s;
    for (const SortedPoint& p : chunk) {
      const double dx = p.x - c.x, dy = p.y - c.y, d2 = dx * dx + dy * dy;
      if (!found || d2 < best_d2 ||
          (d2 == best_d2 && (p.x < best_x || (p.x == best_x && p.y < best_y)))) {
        found = true, best_d2 = d2, best_x = p.x, best_y = p.y, best_z = p.z;
      }
    }
    return {};
  };
  for (std::int64_t ring = 0; ring <= per_side; ++ring) {
    const std::int64_t x0 = gx - 1 - ring, x1 = gx + ring, y0 = gy - 1 - ring, y1 = gy + ring;
    for (std::int64_t cx = x0; cx <= x1; ++cx) {
      for (const std::int64_t cy : {y0, y1}) {
        if (Status s = visit(cx, cy); !s) return s.error();
      }
    }
    for (std::int64_t cy = y0 + 1; cy < y1; ++cy) {
      for (const std::int64_t cx : {x0, x1}) {
        if (Status s = visit(cx, cy); !s) return s.error();
      }
    }
    // Every cell of the next ring lies (ring + 1) cell widths or more from the corner.
    const double reach = static_cast<double>(ring + 1) * cell_width;
    if (found && best_d2 < reach * reach * (1 - 1e-9)) return best_z;
  }
  if (found) return best_z;
  return Error(ErrorCode::internal,
               "tile " + tile.quadkey() + ": no input point for a NODATA corner");
}

tile::Vertex to_vertex(const SortedPoint& p) { return {p.x, p.y, p.z, p.weight}; }

// A tile's vertices while it is cut: the points on each side (data points, then edge points) and
// the data points moved onto a side (they go in last, see add_moved), plus the interior points
// and the corners that are data points, in `out`.
class BorderVertices {
 public:
  BorderVertices(const geo::MercatorRect& r, tile::TinTile& out)
      : r_(r),
        out_(out),
        corner_xy_{
            {{r.min_x, r.max_y}, {r.max_x, r.max_y}, {r.min_x, r.min_y}, {r.max_x, r.min_y}}} {}

  // Sorts a data point in or around R into the interior, a side or a corner (points outside R
  // are left out). A data point closer than kMinVertexDistance to a side (either way, not near a
  // corner) is that side's vertex, moved onto it: the edges from it would cross the side a
  // rounding error away from it (two edge points beside it, and it beside the side:
  // near-duplicate vertices in any quantised encoding). Both neighbours see it (their rings share
  // its cell) and move it alike; the crossings beside it are left out (add_moved).
  void classify(const SortedPoint& p) {
    if (move_to_side(p)) return;
    const bool in_x = p.x > r_.min_x && p.x < r_.max_x;
    const bool in_y = p.y > r_.min_y && p.y < r_.max_y;
    if (in_x && in_y) {
      out_.interior.push_back(to_vertex(p));
    } else if (in_x && p.y == r_.max_y) {
      north_.push_back(to_vertex(p));
    } else if (in_x && p.y == r_.min_y) {
      south_.push_back(to_vertex(p));
    } else if (in_y && p.x == r_.min_x) {
      west_.push_back(to_vertex(p));
    } else if (in_y && p.x == r_.max_x) {
      east_.push_back(to_vertex(p));
    } else {
      for (std::size_t k = 0; k < 4; ++k) {
        if (p.x == corner_xy_[k].x && p.y == corner_xy_[k].y) {
          out_.corners[k] = to_vertex(p);
          corner_found_[k] = true;
        }
      }
    }
  }

  // The edge points of a surface edge ab on the sides it crosses. Where an edge crosses a border
  // line is decided exactly, from the orientation of the side's two corners against the edge:
  // through a corner (orientation 0) the corner itself is the vertex there (corner_elevation
  // interpolates it on the edge), so no edge point is made a rounding error away from it; beyond
  // the side, none either. Only the position along the side is computed in floating point, and a
  // crossing closer than kMinVertexDistance to a corner is left out as well: on a lattice whose
  // squares are centred on tile corners up to the rounding of the input's coordinates (a DEM
  // aligned with the tiles, its coordinates converted from metres), the diagonals miss the
  // corners by 1e-14, and such an edge point would be a duplicate of the corner in any quantised
  // encoding. Both neighbours decide it alike (the same numbers), and the corner's interpolated
  // height differs from the dropped point's by the slope times that distance.
  void add_crossings(const SortedPoint& a, const SortedPoint& b) {
    for (double Y : {r_.max_y, r_.min_y}) {
      if (((a.y < Y && b.y > Y) || (a.y > Y && b.y < Y)) &&
          crosses_side(a, b, {r_.min_x, Y}, {r_.max_x, Y})) {
        const Crossing c = cross_horizontal(a, b, Y);
        if (c.along - r_.min_x >= kMinVertexDistance && r_.max_x - c.along >= kMinVertexDistance) {
          (Y == r_.max_y ? north_ : south_).push_back({c.along, Y, c.z, c.weight});
        }
      }
    }
    for (double X : {r_.min_x, r_.max_x}) {
      if (((a.x < X && b.x > X) || (a.x > X && b.x < X)) &&
          crosses_side(a, b, {X, r_.min_y}, {X, r_.max_y})) {
        const Crossing c = cross_vertical(a, b, X);
        if (c.along - r_.min_y >= kMinVertexDistance && r_.max_y - c.along >= kMinVertexDistance) {
          (X == r_.min_x ? west_ : east_).push_back({X, c.along, c.z, c.weight});
        }
      }
    }
  }

  // Puts the moved points in, sorts each side in the tile format's order (north and south by x,
  // east and west by descending y; ties by z) and drops repeated positions.
  void finish_sides() {
    add_moved(north_, moved_north_, true);
    add_moved(south_, moved_south_, true);
    add_moved(west_, moved_west_, false);
    add_moved(east_, moved_east_, false);
    auto by_x = [](const tile::Vertex& a, const tile::Vertex& b) {
      return a.x < b.x || (a.x == b.x && a.z < b.z);
    };
    auto by_y_desc = [](const tile::Vertex& a, const tile::Vertex& b) {
      return a.y > b.y || (a.y == b.y && a.z < b.z);
    };
    auto same_xy = [](const tile::Vertex& a, const tile::Vertex& b) {
      return a.x == b.x && a.y == b.y;
    };
    for (auto* side : {&north_, &south_}) {
      std::sort(side->begin(), side->end(), by_x);
      side->erase(std::unique(side->begin(), side->end(), same_xy), side->end());
    }
    for (auto* side : {&east_, &west_}) {
      std::sort(side->begin(), side->end(), by_y_desc);
      side->erase(std::unique(side->begin(), side->end(), same_xy), side->end());
    }
    out_.north = std::move(north_);
    out_.east = std::move(east_);
    out_.south = std::move(south_);
    out_.west = std::move(west_);
  }

  const XY& corner(std::size_t k) const { return corner_xy_[k]; }
  bool corner_found(std::size_t k) const { return corner_found_[k]; }

 private:
  static bool near(double a, double b) { return a != b && std::abs(a - b) < kMinVertexDistance; }
  static bool inside_side(double v, double lo, double hi) {
    return v - lo >= kMinVertexDistance && hi - v >= kMinVertexDistance;
  }
  static bool crosses_side(const SortedPoint& a, const SortedPoint& b, const XY& from,
                           const XY& to) {
    const double o_from = kernel::orient2d({a.x, a.y}, {b.x, b.y}, from);
    const double o_to = kernel::orient2d({a.x, a.y}, {b.x, b.y}, to);
    return o_from != 0 && o_to != 0 && (o_from > 0) != (o_to > 0);
  }

  bool move_to_side(const SortedPoint& p) {
    const bool along_x = inside_side(p.x, r_.min_x, r_.max_x);
    const bool along_y = inside_side(p.y, r_.min_y, r_.max_y);
    if (along_x && near(p.y, r_.max_y)) {
      moved_north_.push_back({p.x, r_.max_y, p.z, p.weight});
    } else if (along_x && near(p.y, r_.min_y)) {
      moved_south_.push_back({p.x, r_.min_y, p.z, p.weight});
    } else if (along_y && near(p.x, r_.min_x)) {
      moved_west_.push_back({r_.min_x, p.y, p.z, p.weight});
    } else if (along_y && near(p.x, r_.max_x)) {
      moved_east_.push_back({r_.max_x, p.y, p.z, p.weight});
    } else {
      return false;
    }
    return true;
  }

  // The crossings beside a moved point go; of moved points closer than kMinVertexDistance to
  // each other, the first in the side's order stays (both neighbours have the same lists).
  static void add_moved(std::vector<tile::Vertex>& side, std::vector<tile::Vertex>& moved,
                        bool along_x) {
    if (moved.empty()) return;
    auto pos = [along_x](const tile::Vertex& v) { return along_x ? v.x : v.y; };
    std::sort(moved.begin(), moved.end(), [&](const tile::Vertex& a, const tile::Vertex& b) {
      return pos(a) < pos(b) || (pos(a) == pos(b) && a.z < b.z);
    });
    std::vector<tile::Vertex> kept;
    for (const auto& m : moved) {
      if (kept.empty() || pos(m) - pos(kept.back()) >= kMinVertexDistance) kept.push_back(m);
    }
    std::erase_if(side, [&](const tile::Vertex& c) {
      return std::any_of(kept.begin(), kept.end(), [&](const tile::Vertex& m) {
        return std::abs(pos(c) - pos(m)) < kMinVertexDistance;
      });
    });
    side.insert(side.end(), kept.begin(), kept.end());
  }

  geo::MercatorRect r_;
  tile::TinTile& out_;
  std::array<XY, 4> corner_xy_;  // north-west, north-east, south-west, south-east
  std::array<bool, 4> corner_found_{};
  std::vector<tile::Vertex> north_, east_, south_, west_;
  std::vector<tile::Vertex> moved_north_, moved_east_, moved_south_, moved_west_;
};

// Keeps the surface triangles (circumradius ≤ rmax: larger ones span data gaps or hug the data's
// outer boundary; both neighbours decide this identically) that may meet ∂R: an edge crossing a
// border segment strictly inside it and a triangle holding a corner both meet ∂R, so the rest
// (most of them, inside R) go first, before their circumradius is computed.
void keep_surface_at_border(std::vector<IndexTriangle>& tris, const std::vector<XY>& xy,
                            const geo::MercatorRect& r, double rmax) {
  const double rmax2 = rmax * rmax;
  std::erase_if(tris, [&](const IndexTriangle& t) {
    return !bbox_meets_border(xy[t[0]], xy[t[1]], xy[t[2]], r) ||
           !(canonical_circumradius2(xy[t[0]], xy[t[1]], xy[t[2]]) <= rmax2);
  });
}

// The edges of `tris` that cross one of the four border lines, each undirected edge once, sorted
// (hull edges included — the data's outer boundary may run through R).
void edges_across_border_lines(const std::vector<IndexTriangle>& tris,
                               const std::vector<SortedPoint>& pts, const geo::MercatorRect& r,
                               std::vector<std::pair<std::uint32_t, std::uint32_t>>& edges) {
  edges.clear();
  for (const auto& t : tris) {
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t ia = t[k], ib = t[(k + 1) % 3];
      const SortedPoint& a = pts[ia];
      const SortedPoint& b = pts[ib];
      const bool spans_y = (a.y < r.max_y) != (b.y < r.max_y) || (a.y < r.min_y) != (b.y < r.min_y);
      const bool spans_x = (a.x < r.min_x) != (b.x < r.min_x) || (a.x < r.max_x) != (b.x < r.max_x);
      if (spans_x || spans_y) edges.emplace_back(std::min(ia, ib), std::max(ia, ib));
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
}

}  // namespace

Result<tile::TinTile> cut_at_border(const geo::TileId& id, const PointCells& cells,
                                    subdivide::SortedRunReader& reader, const HaloGatherer& halo,
                                    TileBuffers& buffers) {
  const geo::MercatorRect& r = halo.rect();
  tile::TinTile out;
  out.id = id;
  out.source_points =
      halo.own_tile() >= 0 ? cells.tiles()[static_cast<std::size_t>(halo.own_tile())].count : 0;
  BorderVertices border(r, out);
  // The points in and on R, cell by cell as the first halo round gathered them (the interior
  // points' order is part of the output). Cells beyond the ring lie a cell width away from R.
  halo.for_each_cell_around([&](std::uint32_t cx, std::uint32_t cy) {
    for (const SortedPoint& p : halo.cell_points(cx, cy)) border.classify(p);
  });
  auto& tris = buffers.tris;
  tris = buffers.delaunay.mesh().triangles;
  keep_surface_at_border(tris, buffers.xy, r, halo.rmax());
  edges_across_border_lines(tris, buffers.pts, r, buffers.edges);
  for (const auto& [ia, ib] : buffers.edges) border.add_crossings(buffers.pts[ia], buffers.pts[ib]);
  border.finish_sides();
  for (std::size_t k = 0; k < 4; ++k) {
    if (border.corner_found(k)) continue;
    auto z = corner_elevation(border.corner(k), buffers.pts, tris);
    const bool nodata = !z.has_value();
    if (nodata) {  // outside the data: a height continued from it, never 0 (a wall)
      auto nearest = nearest_input_height(cells, reader, id, static_cast<int>(k), buffers.chunk);
      if (!nearest) return nearest.error();
      z = *nearest;
    }
    out.corners[k] = {border.corner(k).x, border.corner(k).y, *z, 0.0};
    out.corner_nodata[k] = nodata;
  }
  return out;
}

}  // namespace tinstream::triangulate::detail
