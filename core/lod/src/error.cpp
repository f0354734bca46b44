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

FlatTriangle translated(const FlatTriangle& t, P2 o) {
  FlatTriangle r = t;
  for (auto& p : r.p) p = {p.x - o.x, p.y - o.y};
  return r;
}

// Sutherland–Hodgman: keeps the part of `poly` left of (or on) the directed line a → b.
int clip(const std::array<P2, 12>& poly, int n, P2 a, P2 b, std::array<P2, 12>& out) {
  const double ex = b.x - a.x, ey = b.y - a.y;
  auto side = [&](P2 p) { return ex * (p.y - a.y) - ey * (p.x - a.x); };
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const P2 s = poly[static_cast<std::size_t>(i)], e = poly[static_cast<std::size_t>((i + 1) % n)];
    const double ds = side(s), de = side(e);
    if (ds >= 0) out[static_cast<std::size_t>(m++)] = s;
    if ((ds >= 0) != (de >= 0) && m < 12) {
      const double f = ds / (ds - de);
      out[static_cast<std::size_t>(m++)] = {s.x + (e.x - s.x) * f, s.y + (e.y - s.y) * f};
    }
    if (m >= 11) break;  // a triangle clipped by three lines has at most 6 vertices
  }
  return m;
}

// Whether the fine triangle lies inside (or on the boundary of) the coarse triangle: exact
// orientation tests of its three vertices against the coarse triangle's three edges.
bool contains(const FlatTriangle& c, const FlatTriangle& f) {
  if (f.min_x < c.min_x || f.max_x > c.max_x || f.min_y < c.min_y || f.max_y > c.max_y) {
    return false;
  }
  for (int e = 0; e < 3; ++e) {
    const kernel::XY a{c.p[e].x, c.p[e].y}, b{c.p[(e + 1) % 3].x, c.p[(e + 1) % 3].y};
    for (const P2& q : f.p) {
      if (kernel::orient2d(a, b, {q.x, q.y}) < 0) return false;
    }
  }
  return true;
}

// Adds one overlay cell (polygon q[0..n), coordinates relative to the fine triangle's first
// vertex) with the difference values v[k] at its vertices.
void accumulate(SurfaceDifference& d, const std::array<P2, 12>& q, const std::array<double, 12>& v,
                int n) {
  for (int k = 0; k < n; ++k)
    d.max_abs = std::max(d.max_abs, std::abs(v[static_cast<std::size_t>(k)]));
  ++d.polygons;
  for (int k = 1; k + 1 < n; ++k) {
    const P2 p0 = q[0], p1 = q[static_cast<std::size_t>(k)],
             p2 = q[static_cast<std::size_t>(k + 1)];
    const double area =
        0.5 * std::abs((p1.x - p0.x) * (p2.y - p0.y) - (p1.y - p0.y) * (p2.x - p0.x));
    const double v0 = v[0], v1 = v[static_cast<std::size_t>(k)],
                 v2 = v[static_cast<std::size_t>(k + 1)];
    d.area += area;
    d.sum_sq_area += area / 6.0 * (v0 * v0 + v1 * v1 + v2 * v2 + v0 * v1 + v1 * v2 + v2 * v0);
  }
}

// Spreads the low 16 bits of v to the even bit positions.
std::uint32_t spread_bits(std::uint32_t v) {
  v &= 0xFFFFu;
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

// Puts triangles in Z order of their centroids within r, so that consecutive fine triangles are
// neighbours: most then lie in the previous one's coarse triangle (the hint), and the grid cells
// a query touches are still in cache.
void sort_spatially(std::vector<FlatTriangle>& ts, const geo::MercatorRect& r) {
  const double sx = 65535.0 / std::max(r.width(), std::numeric_limits<double>::min());
  const double sy = 65535.0 / std::max(r.height(), std::numeric_limits<double>::min());
  auto cell = [](double v) {
    return static_cast<std::uint32_t>(std::clamp(v, 0.0, 65535.0));
  };
  std::vector<std::pair<std::uint32_t, std::uint32_t>> keys(ts.size());
  for (std::size_t i = 0; i < ts.size(); ++i) {
    const FlatTriangle& t = ts[i];
    const double cx = (t.p[0].x + t.p[1].x + t.p[2].x) / 3.0;
    const double cy = (t.p[0].y + t.p[1].y + t.p[2].y) / 3.0;
    keys[i] = {spread_bits(cell((cx - r.min_x) * sx)) |
                   (spread_bits(cell((cy - r.min_y) * sy)) << 1),
               static_cast<std::uint32_t>(i)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<FlatTriangle> sorted;
  sorted.reserve(ts.size());
  for (const auto& k : keys) sorted.push_back(ts[k.second]);
  ts = std::move(sorted);
}

// A triangle's plane as a value at its first corner and a gradient, so that evaluating it costs
// two multiplications (no division per point). Degenerate triangles: constant z[0], as plane_at.
struct Plane {
  double z0 = 0, gx = 0, gy = 0;
  double at(double dx, double dy) const { return z0 + gx * dx + gy * dy; }  // relative to p[0]
};

Plane plane_of(const FlatTriangle& t) {
  const double bx = t.p[1].x - t.p[0].x, by = t.p[1].y - t.p[0].y;
  const double cx = t.p[2].x - t.p[0].x, cy = t.p[2].y - t.p[0].y;
  const double det = bx * cy - by * cx;
  if (!(det != 0)) return {t.z[0], 0, 0};
  const double dzb = t.z[1] - t.z[0], dzc = t.z[2] - t.z[0];
  return {t.z[0], (dzb * cy - dzc * by) / det, (dzc * bx - dzb * cx) / det};
}

}  // namespace

SurfaceDifference surface_difference(const tile::TinTile& coarse,
                                     std::span<const tile::TinTile* const> fines) {
  SurfaceDifference d;
  std::vector<FlatTriangle> ct;
  // NODATA triangles (incident to a NODATA corner, z = 0 by convention) are not surface on either
  // side: the error is measured where both surfaces have data (see error.hpp).
  detail::append_triangles(coarse, true, ct);
  TriangleGrid grid(std::move(ct), coarse.id.bounds());
  std::vector<Plane> planes;
  planes.reserve(grid.triangles().size());
  for (const FlatTriangle& t : grid.triangles()) planes.push_back(plane_of(t));
  std::vector<FlatTriangle> ft;
  std::vector<std::uint32_t> candidates;
  std::int64_t hint = -1;  // the coarse triangle that held the previous fine triangle
  for (const tile::TinTile* fine : fines) {
    ft.clear();
    detail::append_triangles(*fine, true, ft);
    sort_spatially(ft, coarse.id.bounds());
    for (const FlatTriangle& f0 : ft) {
      const P2 o = f0.p[0];
      const FlatTriangle f = translated(f0, o);
      const Plane fp = plane_of(f);
      // Fast path: most fine triangles lie inside one coarse triangle (the overlay cell is the
      // fine triangle itself; the other candidates meet it at most on their boundary, adding
      // no area and the same values there). Decided with exact orientation tests.
      std::int64_t inside = -1;
      if (hint >= 0 && contains(grid.triangles()[static_cast<std::size_t>(hint)], f0)) {
        inside = hint;
      } else {
        candidates.clear();
        grid.for_each_overlapping(f0.min_x, f0.min_y, f0.max_x, f0.max_y,
                                  [&](std::uint32_t ci) { candidates.push_back(ci); });
        for (std::uint32_t ci : candidates) {
          if (contains(grid.triangles()[ci], f0)) {
            inside = ci;
            break;
          }
        }
        if (inside < 0) {
          for (std::uint32_t ci : candidates) {
            const FlatTriangle c = translated(grid.triangles()[ci], o);
            const Plane& cp = planes[ci];
            std::array<P2, 12> a, b;  // not zeroed: only the first n entries are read
            a[0] = f.p[0], a[1] = f.p[1], a[2] = f.p[2];
            int n = 3;
            n = clip(a, n, c.p[0], c.p[1], b);
            if (n == 0) continue;
            n = clip(b, n, c.p[1], c.p[2], a);
            if (n == 0) continue;
            n = clip(a, n, c.p[2], c.p[0], b);
            if (n == 0) continue;
            std::array<double, 12> v;
            for (int k = 0; k < n; ++k) {
              const P2 q = b[static_cast<std::size_t>(k)];
              v[static_cast<std::size_t>(k)] =
                  cp.at(q.x - c.p[0].x, q.y - c.p[0].y) - fp.at(q.x, q.y);
            }
            accumulate(d, b, v, n);
          }
          continue;
        }
      }
      hint = inside;
      const FlatTriangle& c = grid.triangles()[static_cast<std::size_t>(inside)];
      const Plane& cp = planes[static_cast<std::size_t>(inside)];
      const P2 co{c.p[0].x - o.x, c.p[0].y - o.y};  // the coarse corner relative to o
      std::array<P2, 12> q;
      std::array<double, 12> v;
      for (std::size_t k = 0; k < 3; ++k) {
        q[k] = f.p[k];
        v[k] = cp.at(q[k].x - co.x, q[k].y - co.y) - f.z[k];
      }
      accumulate(d, q, v, 3);
    }
  }
  return d;
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
