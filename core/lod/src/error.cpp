// Exact overlay difference of two piecewise-linear surfaces, and the verification helpers.
#include "tinstream/lod/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>

#include "planar_index.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::lod {

using detail::FlatTriangle;
using detail::P2;
using detail::plane_at;
using detail::TriangleGrid;

double SurfaceDifference::rms() const { return area > 0 ? std::sqrt(sum_sq_area / area) : 0.0; }

double error_rounding_allowance(const tile::TinTile& coarse) {
  const double range =
      std::isfinite(coarse.max_z - coarse.min_z) ? coarse.max_z - coarse.min_z : 0.0;
  return 1e-6 + 1e-9 * std::abs(range) +
         1e-12 * std::max(std::abs(coarse.max_z), std::abs(coarse.min_z));
}

namespace {

// A plane as a value at a reference point and a gradient: two multiplications per evaluation.
// Degenerate triangles give the constant z of their first corner.
struct Plane {
  double x0 = 0, y0 = 0, z0 = 0, gx = 0, gy = 0;
  double at(double x, double y) const { return z0 + gx * (x - x0) + gy * (y - y0); }
};

Plane plane_of(const kernel::XY& a, double za, const kernel::XY& b, double zb, const kernel::XY& c,
               double zc) {
  const double bx = b.x - a.x, by = b.y - a.y;
  const double cx = c.x - a.x, cy = c.y - a.y;
  const double det = bx * cy - by * cx;
  if (!(det != 0)) return {a.x, a.y, za, 0, 0};
  const double dzb = zb - za, dzc = zc - za;
  return {a.x, a.y, za, (dzb * cy - dzc * by) / det, (dzc * bx - dzb * cx) / det};
}

// A tile's vertex positions and heights in the tile numbering (tin_tile.hpp).
void vertex_arrays(const tile::TinTile& tile, std::vector<kernel::XY>& p, std::vector<double>& z) {
  const std::size_t nv = tile.vertex_count();
  p.clear(), z.clear();
  p.reserve(nv), z.reserve(nv);
  auto add = [&](const tile::Vertex& v) { p.push_back({v.x, v.y}), z.push_back(v.z); };
  for (const auto& v : tile.corners) add(v);
  for (const auto* list : {&tile.north, &tile.east, &tile.south, &tile.west, &tile.interior}) {
    for (const auto& v : *list) add(v);
  }
}

// The coarse tile as an indexed mesh with neighbour links, for walks with exact orientation
// tests. Numbering as kernel::Mesh: n[i][k] is the triangle across the edge opposite corner k,
// i.e. the edge t[i][k+1] → t[i][k+2]; -1 on the tile border.
//
//              t[k]
//              /  \    n[k+1] across t[k+2] → t[k]
//     n[k+2]  /    \   n[k+2] across t[k] → t[k+1]
//            /      \  n[k]   across t[k+1] → t[k+2]
//      t[k+1] ────── t[k+2]
//               n[k]
struct WalkMesh {
  // What a walk step reads of a triangle, in one cache line: corner positions, neighbours, and
  // whether it has data (the walks are latency-bound on a mesh numbered in insertion order).
  struct alignas(64) Cell {
    kernel::XY q[3];
    std::int32_t n[3];
    std::uint32_t data;
  };
  static_assert(sizeof(Cell) == 64);
  std::vector<Cell> cell;
  std::vector<kernel::XY> p;
  std::vector<double> z;
  std::vector<tile::Triangle> t;
  std::vector<std::array<std::int32_t, 3>> n;
  std::vector<std::uint8_t> data;         // not incident to a NODATA corner
  std::vector<std::uint8_t> vertex_data;  // incident to a data triangle
  std::vector<Plane> plane;

  explicit WalkMesh(const tile::TinTile& tile) {
    vertex_arrays(tile, p, z);
    const std::size_t nv = p.size();
    t = tile.triangles;
    n.assign(t.size(), {-1, -1, -1});
    data.resize(t.size());
    vertex_data.assign(nv, 0);
    plane.resize(t.size());
    // Neighbour links: every edge is filed under its lower vertex (a counting sort) with its
    // higher vertex and its place (4 × triangle + the corner opposite it); the two sides of an
    // edge then meet in one short bucket, scanned sequentially.
    struct Side {
      std::uint32_t other;  // the edge's higher vertex
      std::uint32_t place;  // 4 × triangle + the corner opposite the edge
    };
    std::vector<std::uint32_t> start(nv + 1, 0);
    for (const auto& tr : t) {
      for (int k = 0; k < 3; ++k) ++start[std::min(tr[(k + 1) % 3], tr[(k + 2) % 3]) + 1];
    }
    for (std::size_t i = 1; i <= nv; ++i) start[i] += start[i - 1];
    std::vector<Side> sides(3 * t.size());
    {
      std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
      for (std::uint32_t i = 0; i < t.size(); ++i) {
        for (std::uint32_t k = 0; k < 3; ++k) {
          const std::uint32_t a = t[i][(k + 1) % 3], b = t[i][(k + 2) % 3];
          sides[fill[std::min(a, b)]++] = {std::max(a, b), 4 * i + k};
        }
      }
    }
    for (std::size_t v = 0; v < nv; ++v) {
      for (std::uint32_t s = start[v]; s < start[v + 1]; ++s) {
        for (std::uint32_t u = s + 1; u < start[v + 1]; ++u) {
          if (sides[u].other != sides[s].other) continue;
          const std::uint32_t i = sides[s].place >> 2, j = sides[u].place >> 2;
          n[i][sides[s].place & 3] = static_cast<std::int32_t>(j);
          n[j][sides[u].place & 3] = static_cast<std::int32_t>(i);
          break;
        }
      }
    }
    for (std::uint32_t i = 0; i < t.size(); ++i) {
      const auto& tr = t[i];
      bool nodata = false;
      for (auto v : tr) nodata = nodata || (v < 4 && tile.corner_nodata[v]);
      data[i] = nodata ? 0 : 1;
      if (!nodata) {
        for (auto v : tr) vertex_data[v] = 1;
      }
      plane[i] = plane_of(p[tr[0]], z[tr[0]], p[tr[1]], z[tr[1]], p[tr[2]], z[tr[2]]);
    }
    cell.resize(t.size());
    for (std::uint32_t i = 0; i < t.size(); ++i) {
      for (int k = 0; k < 3; ++k) cell[i].q[k] = p[t[i][k]], cell[i].n[k] = n[i][k];
      cell[i].data = data[i];
    }
  }

  const kernel::XY& corner(std::uint32_t i, int k) const { return cell[i].q[k]; }

  bool contains(std::uint32_t i, const kernel::XY& q) const {
    for (int k = 0; k < 3; ++k) {
      if (kernel::orient2d(corner(i, (k + 1) % 3), corner(i, (k + 2) % 3), q) < 0) return false;
    }
    return true;
  }

  // A triangle containing q (closed), walking from `from` by exact visibility tests; the edge
  // tested first rotates, so the walk cannot cycle. -1 when the walk leaves the mesh or exceeds its
  // step budget (not on a valid triangulation that covers q).
  std::int64_t locate(std::uint32_t from, const kernel::XY& q) const {
    std::uint32_t i = from;
    int r = 0;
    for (std::size_t steps = 0; steps <= 4 * t.size() + 8; ++steps) {
      int out = -1;
      for (int j = 0; j < 3; ++j) {
        const int k = (r + j) % 3;
        if (kernel::orient2d(corner(i, (k + 1) % 3), corner(i, (k + 2) % 3), q) < 0) {
          out = k;
          break;
        }
      }
      if (out < 0) return i;
      if (cell[i].n[out] < 0) return -1;
      i = static_cast<std::uint32_t>(cell[i].n[out]);
      r = (r + 1) % 3;
    }
    return -1;
  }

  // A data triangle containing q (closed), searched among the triangles around `i` (which
  // contains q) that contain q too; -1 when q has no data triangle (inside the NODATA region).
  std::int64_t data_triangle_at(std::uint32_t i, const kernel::XY& q) const {
    if (data[i]) return i;
    std::array<std::uint32_t, 64> seen{};
    std::size_t count = 0, next = 0;
    seen[count++] = i;
    while (next < count) {
      const std::uint32_t c = seen[next++];
      for (int k = 0; k < 3; ++k) {
        const std::int32_t j = n[c][k];
        if (j < 0) continue;
        const auto u = static_cast<std::uint32_t>(j);
        if (std::find(seen.begin(), seen.begin() + static_cast<std::ptrdiff_t>(count), u) !=
                seen.begin() + static_cast<std::ptrdiff_t>(count) ||
            !contains(u, q)) {
          continue;
        }
        if (data[u]) return u;
        if (count < seen.size()) seen[count++] = u;
      }
    }
    return -1;
  }
};

// The fine tile's vertices in the tile numbering.
struct FineVertices {
  std::vector<kernel::XY> p;
  std::vector<double> z;
  explicit FineVertices(const tile::TinTile& tile) { vertex_arrays(tile, p, z); }
};

void difference_one(const WalkMesh& c, const tile::TinTile& fine, SurfaceDifference& d,
                    std::uint32_t& hint, std::vector<std::uint8_t>& coarse_matched) {
  const FineVertices f(fine);
  const std::size_t nv = f.p.size();
  constexpr std::int64_t kUnknown = -2;  // not located yet; -1: outside every data triangle
  std::vector<std::int64_t> where(nv, kUnknown);  // containing coarse triangle
  std::vector<double> dv(nv, 0.0);                // coarse − fine at the vertex
  const geo::MercatorRect fr = fine.id.bounds();

  auto nodata_tri = [&](const tile::Triangle& tr) {
    return (tr[0] < 4 && fine.corner_nodata[tr[0]]) || (tr[1] < 4 && fine.corner_nodata[tr[1]]) ||
           (tr[2] < 4 && fine.corner_nodata[tr[2]]);
  };
  // Directed edges of the fine NODATA triangles (sorted): an edge of a data triangle whose other
  // side is NODATA is walked from the data side whatever its direction. Only edges between two
  // vertices of NODATA triangles are looked up.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> nodata_edges;
  std::vector<std::uint8_t> near_nodata;
  for (const auto& tr : fine.triangles) {
    if (!nodata_tri(tr)) continue;
    if (near_nodata.empty()) near_nodata.assign(nv, 0);
    for (int k = 0; k < 3; ++k) {
      nodata_edges.emplace_back(tr[k], tr[(k + 1) % 3]);
      near_nodata[tr[k]] = 1;
    }
  }
  std::sort(nodata_edges.begin(), nodata_edges.end());
  auto nodata_beyond = [&](std::uint32_t u, std::uint32_t w) {
    return !near_nodata.empty() && near_nodata[u] && near_nodata[w] &&
           std::binary_search(nodata_edges.begin(), nodata_edges.end(), std::make_pair(w, u));
  };
  auto on_border = [&](std::uint32_t a, std::uint32_t b) {
    const kernel::XY &pa = f.p[a], &pb = f.p[b];
    return (pa.x == pb.x && (pa.x == fr.min_x || pa.x == fr.max_x)) ||
           (pa.y == pb.y && (pa.y == fr.min_y || pa.y == fr.max_y));
  };

  // Locates vertex v in triangle i (containing it) and evaluates the difference there: inside[v]
  // is i, where[v] a data triangle containing v (or -1).
  std::vector<std::uint32_t> inside(nv, 0);
  std::uint32_t located_in = hint;
  auto settle = [&](std::uint32_t v, std::uint32_t i) {
    located_in = i;
    inside[v] = i;
    const kernel::XY& q = f.p[v];
    for (int k = 0; k < 3; ++k) {
      if (c.corner(i, k).x == q.x && c.corner(i, k).y == q.y) coarse_matched[c.t[i][k]] = 1;
    }
    const std::int64_t di = c.data_triangle_at(i, q);
    where[v] = di;
    if (di >= 0) dv[v] = c.plane[static_cast<std::size_t>(di)].at(q.x, q.y) - f.z[v];
  };
  // Walks the fine edge u → w through the coarse mesh from `from` (a triangle containing u),
  // evaluating the difference where it crosses coarse edges when `measure`; returns the triangle
  // where the walk ends (it contains w), or -1.
  auto walk = [&](std::uint32_t u, std::uint32_t w, std::uint32_t from, bool measure) {
    const kernel::XY &pu = f.p[u], &pw = f.p[w];
    std::uint32_t i = from;
    int entry = -1;
    for (std::size_t steps = 0; steps <= c.t.size() + 8; ++steps) {
      int exit = -1;
      for (int k = 0; k < 3 && exit < 0; ++k) {
        if (k == entry) continue;
        const kernel::XY &a = c.corner(i, (k + 1) % 3), &b = c.corner(i, (k + 2) % 3);
        if (kernel::orient2d(a, b, pw) >= 0) continue;
        // w is beyond this edge; the segment leaves through it when a is on the right of u → w
        // and b on the left (or on the line).
        if (kernel::orient2d(pu, pw, a) <= 0 && kernel::orient2d(pu, pw, b) >= 0) exit = k;
      }
      if (exit < 0) return static_cast<std::int64_t>(i);  // w is in triangle i
      const std::int32_t next = c.cell[i].n[exit];
      if (measure && (c.cell[i].data || (next >= 0 && c.data[static_cast<std::size_t>(next)]))) {
        const std::uint32_t ia = c.t[i][(exit + 1) % 3], ib = c.t[i][(exit + 2) % 3];
        // The crossing point, as a fraction s along the coarse edge a → b and a fraction r along
        // the fine edge u → w (floating point: error_rounding_allowance covers the rounding).
        const kernel::XY &a = c.p[ia], &b = c.p[ib];
        auto cross = [](const kernel::XY& o, const kernel::XY& e, const kernel::XY& q) {
          return (e.x - o.x) * (q.y - o.y) - (e.y - o.y) * (q.x - o.x);
        };
        const double oa = cross(pu, pw, a), ob = cross(pu, pw, b);
        const double ou = cross(a, b, pu), ow = cross(a, b, pw);
        double s = oa - ob != 0 ? oa / (oa - ob) : 0.5;
        double r = ou - ow != 0 ? ou / (ou - ow) : 0.0;
        s = std::clamp(s, 0.0, 1.0), r = std::clamp(r, 0.0, 1.0);
        const double zc = c.z[ia] + s * (c.z[ib] - c.z[ia]);
        const double zf = f.z[u] + r * (f.z[w] - f.z[u]);
        d.max_abs = std::max(d.max_abs, std::abs(zc - zf));
        ++d.crossings;
      }
      if (next < 0) return std::int64_t{-1};
      const auto j = static_cast<std::uint32_t>(next);
      const auto& nj = c.cell[j].n;
      entry = nj[0] == static_cast<std::int32_t>(i)
                  ? 0
                  : (nj[1] == static_cast<std::int32_t>(i) ? 1 : 2);
      i = j;
    }
    return std::int64_t{-1};
  };

  // Every vertex of a data triangle is located first, in vertex order: tiles number their
  // interior points in Morton order (and parents keep their children's order), so each walk
  // starts from the previous vertex's triangle and is short. Then every fine edge is walked from
  // its first vertex's triangle.
  bool lost = false;  // a walk failed (not a valid covering triangulation): whole-tile fallback
  std::vector<std::uint8_t> used(nv, 0);
  for (const auto& tr : fine.triangles) {
    if (!nodata_tri(tr)) used[tr[0]] = used[tr[1]] = used[tr[2]] = 1;
  }
  for (std::uint32_t v = 0; v < nv && !lost; ++v) {
    if (!used[v]) continue;
    const std::int64_t i = c.locate(located_in, f.p[v]);
    if (i < 0) {
      lost = true;
    } else {
      settle(v, static_cast<std::uint32_t>(i));
    }
  }
  for (const auto& tr : fine.triangles) {
    if (lost) break;
    if (nodata_tri(tr)) continue;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tr[k], w = tr[(k + 1) % 3];
      // Each interior edge is measured once, from its triangle with u < w; border edges and
      // edges against a NODATA triangle have no data triangle on the other side.
      if (!(u < w || on_border(u, w) || nodata_beyond(u, w))) continue;
      const std::uint32_t from = where[u] >= 0 ? static_cast<std::uint32_t>(where[u]) : inside[u];
      if (walk(u, w, from, true) < 0) {
        lost = true;
        break;
      }
    }
  }
  hint = located_in;
  if (lost) {
    // Not reached on valid tiles; measured by brute force instead so that the bound stays honest.
    std::fill(where.begin(), where.end(), kUnknown);
    for (std::uint32_t v = 0; v < nv; ++v) {
      for (std::uint32_t i = 0; i < c.t.size(); ++i) {
        if (c.contains(i, f.p[v])) {
          settle(v, i);
          break;
        }
      }
    }
    for (const auto& tr : fine.triangles) {
      if (nodata_tri(tr)) continue;
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t u = tr[k], w = tr[(k + 1) % 3];
        for (std::uint32_t i = 0; i < c.t.size(); ++i) {
          if (c.contains(i, f.p[u])) {
            walk(u, w, i, true);
            break;
          }
        }
      }
    }
  }

  // Vertices: the maximum, and the RMS with each vertex weighted by a third of the area of its
  // data triangles.
  for (const auto& tr : fine.triangles) {
    if (nodata_tri(tr)) continue;
    const kernel::XY &a = f.p[tr[0]], &b = f.p[tr[1]], &q = f.p[tr[2]];
    const double third = std::abs((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x)) / 6.0;
    for (auto v : tr) {
      if (where[v] < 0) continue;
      d.max_abs = std::max(d.max_abs, std::abs(dv[v]));
      d.sum_sq_area += third * dv[v] * dv[v];
      d.area += third;
    }
  }
}

}  // namespace

std::vector<SurfaceDifference> surface_differences(const tile::TinTile& coarse,
                                                   std::span<const tile::TinTile* const> fines) {
  std::vector<SurfaceDifference> out(fines.size());
  if (coarse.triangles.empty()) return out;
  const WalkMesh c(coarse);
  std::uint32_t hint = 0;
  for (std::size_t f = 0; f < fines.size(); ++f) {
    const tile::TinTile* fine = fines[f];
    SurfaceDifference& d = out[f];
    std::vector<std::uint8_t> matched(c.p.size(), 0);
    difference_one(c, *fine, d, hint, matched);
    // Coarse vertices that are not fine vertices (never the case for parents and reduced tiles,
    // whose vertices are a subset of the fine ones) are overlay vertices too: the fine surface
    // is evaluated there directly.
    const geo::MercatorRect fr = fine->id.bounds();
    std::vector<std::uint32_t> extra;
    for (std::uint32_t v = 0; v < c.p.size(); ++v) {
      const kernel::XY& q = c.p[v];
      if (!matched[v] && c.vertex_data[v] && q.x >= fr.min_x && q.x <= fr.max_x &&
          q.y >= fr.min_y && q.y <= fr.max_y) {
        extra.push_back(v);
      }
    }
    if (extra.empty()) continue;
    std::vector<FlatTriangle> ft;
    detail::append_triangles(*fine, true, ft);
    TriangleGrid grid(std::move(ft), fr);
    for (std::uint32_t v : extra) {
      double w;
      const std::int64_t i = grid.locate(c.p[v].x, c.p[v].y, &w);
      if (i < 0 || w < -1e-9) continue;
      const double zf = plane_at(grid.triangles()[static_cast<std::size_t>(i)], c.p[v].x, c.p[v].y);
      d.max_abs = std::max(d.max_abs, std::abs(c.z[v] - zf));
    }
  }
  return out;
}

SurfaceDifference surface_difference(const tile::TinTile& coarse,
                                     std::span<const tile::TinTile* const> fines) {
  SurfaceDifference total;
  for (const SurfaceDifference& d : surface_differences(coarse, fines)) {
    total.max_abs = std::max(total.max_abs, d.max_abs);
    total.sum_sq_area += d.sum_sq_area;
    total.area += d.area;
    total.crossings += d.crossings;
  }
  return total;
}

Status check_level_watertight(const std::vector<tile::TinTile>& tiles) {
  std::map<geo::TileId, std::size_t> by_id;
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    if (!tiles.empty() && tiles[i].id.z != tiles[0].id.z) {
      return invalid_argument("watertight: tiles of different levels given (" +
                              tiles[0].id.to_string() + ", " + tiles[i].id.to_string() + ")");
    }
    by_id.emplace(tiles[i].id, i);
  }
  auto compare = [&](const tile::TinTile& a, geo::Direction da, const tile::TinTile& b,
                     geo::Direction db) -> Status {
    const auto pa = a.border(da), pb = b.border(db);
    const std::string pair = "watertight: " + a.id.to_string() + " and " + b.id.to_string();
    if (pa.size() != pb.size()) {
      return corrupt_data(pair + ": shared border has " + std::to_string(pa.size()) + " vs " +
                          std::to_string(pb.size()) + " points");
    }
    for (std::size_t i = 0; i < pa.size(); ++i) {
      if (pa[i].x != pb[i].x || pa[i].y != pb[i].y || pa[i].z != pb[i].z) {
        return corrupt_data(pair + ": shared border point #" + std::to_string(i) + " differs");
      }
    }
    return {};
  };
  for (const auto& t : tiles) {
    // East/west pairs across the antimeridian (x = +1 / −1) are not compared: their border
    // coordinates differ by design.
    if (auto e = t.id.neighbour(geo::Direction::east); e && e->x == t.id.x + 1) {
      if (auto it = by_id.find(*e); it != by_id.end()) {
        if (Status s = compare(t, geo::Direction::east, tiles[it->second], geo::Direction::west);
            !s)
          return s;
      }
    }
    if (auto s_id = t.id.neighbour(geo::Direction::south)) {
      if (auto it = by_id.find(*s_id); it != by_id.end()) {
        if (Status s = compare(t, geo::Direction::south, tiles[it->second], geo::Direction::north);
            !s)
          return s;
      }
    }
  }
  return {};
}

Result<double> measured_max_error(const tile::TinTile& coarse,
                                  const std::vector<tile::TinTile>& finest) {
  if (finest.empty())
    return invalid_argument("measured_max_error: no finest tiles under " + coarse.id.to_string());
  const geo::MercatorRect r = coarse.id.bounds();
  std::vector<FlatTriangle> ct, ft;
  detail::append_triangles(coarse, true, ct);
  for (const auto& f : finest) {
    const geo::MercatorRect fr = f.id.bounds();
    if (f.id.z < coarse.id.z || fr.min_x < r.min_x || fr.max_x > r.max_x || fr.min_y < r.min_y ||
        fr.max_y > r.max_y) {
      return invalid_argument("measured_max_error: " + f.id.to_string() + " is not under " +
                              coarse.id.to_string());
    }
    detail::append_triangles(f, true, ft);
  }
  TriangleGrid cg(std::move(ct), r);
  TriangleGrid fg(std::move(ft), r);
  double worst = 0;
  // Finest vertices (of data triangles) against the coarse surface.
  for (const auto& t : fg.triangles()) {
    for (int k = 0; k < 3; ++k) {
      double w;
      const std::int64_t c = cg.locate(t.p[k].x, t.p[k].y, &w);
      // Not under a coarse data triangle (only NODATA-corner triangles there): not measured.
      if (c < 0 || w < -1e-9) continue;
      worst = std::max(worst, std::abs(plane_at(cg.triangles()[static_cast<std::size_t>(c)],
                                                t.p[k].x, t.p[k].y) -
                                       t.z[k]));
    }
  }
  // Coarse vertices against the finest surface, where there is one.
  for (const auto& t : cg.triangles()) {
    for (int k = 0; k < 3; ++k) {
      double w;
      const std::int64_t f = fg.locate(t.p[k].x, t.p[k].y, &w);
      if (f < 0 || w < -1e-9) continue;
      worst = std::max(worst, std::abs(plane_at(fg.triangles()[static_cast<std::size_t>(f)],
                                                t.p[k].x, t.p[k].y) -
                                       t.z[k]));
    }
  }
  return worst;
}

Status check_budget(const tile::TinTile& tile, std::size_t max_points) {
  if (tile.vertex_count() > max_points) {
    return corrupt_data("budget: " + tile.id.to_string() + " holds " +
                        std::to_string(tile.vertex_count()) + " vertices, more than " +
                        std::to_string(max_points));
  }
  return {};
}

}  // namespace tinstream::lod
