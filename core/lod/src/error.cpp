// Exact overlay difference of two piecewise-linear surfaces, and the verification helpers.
#include "tinstream/lod/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <string>

#include "planar_index.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::lod {

using detail::FlatTriangle;
using detail::plane_at;
using detail::TriangleGrid;

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

// Rounds a bound up to the next float (bounds are stored as floats and must stay bounds).
float round_up(double v) {
  if (!(v > -std::numeric_limits<double>::infinity())) return DeviationBound::kNone;
  auto f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
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
  // What a walk step reads of a triangle, in one cache line: corner positions and neighbours
  // (the walks are latency-bound on a mesh numbered in insertion order).
  struct alignas(64) Cell {
    kernel::XY q[3];
    std::int32_t n[3];
  };
  static_assert(sizeof(Cell) == 64);
  std::vector<Cell> cell;
  std::vector<kernel::XY> p;
  std::vector<double> z;
  std::vector<tile::Triangle> t;
  std::vector<Plane> plane;

  explicit WalkMesh(const tile::TinTile& tile) {
    vertex_arrays(tile, p, z);
    const std::size_t nv = p.size();
    t = tile.triangles;
    std::vector<std::array<std::int32_t, 3>> n(t.size(), {-1, -1, -1});
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
    cell.resize(t.size());
    for (std::uint32_t i = 0; i < t.size(); ++i) {
      const auto& tr = t[i];
      plane[i] = plane_of(p[tr[0]], z[tr[0]], p[tr[1]], z[tr[1]], p[tr[2]], z[tr[2]]);
      for (int k = 0; k < 3; ++k) cell[i].q[k] = p[tr[k]], cell[i].n[k] = n[i][k];
    }
    stamp_.assign(t.size(), 0);
  }

  const kernel::XY& corner(std::uint32_t i, int k) const { return cell[i].q[k]; }

  bool strictly_inside(std::uint32_t i, const kernel::XY& q) const {
    for (int k = 0; k < 3; ++k) {
      if (!(kernel::orient2d(corner(i, (k + 1) % 3), corner(i, (k + 2) % 3), q) > 0)) return false;
    }
    return true;
  }

  bool contains(std::uint32_t i, const kernel::XY& q) const {
    for (int k = 0; k < 3; ++k) {
      if (kernel::orient2d(corner(i, (k + 1) % 3), corner(i, (k + 2) % 3), q) < 0) return false;
    }
    return true;
  }

  // A triangle containing q (closed), walking from `from` by exact visibility tests; the edge
  // tested first rotates, so the walk cannot cycle. -1 when the walk leaves the mesh or exceeds its
  // step budget (not on a valid triangulation that covers q). With `strict`: whether q lies
  // strictly inside the triangle found (strictly_inside, from the same three exact tests).
  std::int64_t locate(std::uint32_t from, const kernel::XY& q, bool* strict = nullptr) const {
    std::uint32_t i = from;
    int r = 0;
    for (std::size_t steps = 0; steps <= 4 * t.size() + 8; ++steps) {
      int out = -1;
      bool inside = true;
      for (int j = 0; j < 3; ++j) {
        const int k = (r + j) % 3;
        const double o = kernel::orient2d(corner(i, (k + 1) % 3), corner(i, (k + 2) % 3), q);
        if (o < 0) {
          out = k;
          break;
        }
        inside = inside && o > 0;
      }
      if (out < 0) {
        if (strict) *strict = inside;
        return i;
      }
      if (cell[i].n[out] < 0) return -1;
      i = static_cast<std::uint32_t>(cell[i].n[out]);
      r = (r + 1) % 3;
    }
    return -1;
  }

  // Calls f(j) for every triangle containing q (closed), found from `i` (which contains it)
  // through neighbours that contain it too: one triangle for a point inside one, two on an edge,
  // the star of a vertex. Not thread-safe (marks on the mesh).
  template <typename F>
  void for_each_containing(std::uint32_t i, const kernel::XY& q, F&& f) const {
    if (strictly_inside(i, q)) {  // (the common case: no neighbour holds q)
      f(i);
      return;
    }
    if (++stamp_now_ == 0) std::fill(stamp_.begin(), stamp_.end(), 0), stamp_now_ = 1;
    queue_.clear();
    queue_.push_back(i);
    stamp_[i] = stamp_now_;
    for (std::size_t next = 0; next < queue_.size(); ++next) {
      const std::uint32_t c = queue_[next];
      f(c);
      for (const std::int32_t j : cell[c].n) {
        if (j < 0 || stamp_[static_cast<std::size_t>(j)] == stamp_now_) continue;
        const auto u = static_cast<std::uint32_t>(j);
        stamp_[u] = stamp_now_;
        if (contains(u, q)) queue_.push_back(u);
      }
    }
  }

 private:
  mutable std::vector<std::uint32_t> stamp_, queue_;
  mutable std::uint32_t stamp_now_ = 0;
};

// A finer tile as the walk sees it: vertex arrays, and which triangles hold residual finest data
// (walked through the coarse mesh) with, per vertex, the largest residual bounds around it.
struct FineSide {
  std::vector<kernel::XY> p;
  std::vector<double> z;
  std::vector<std::uint8_t> data;    // by vertex: a finest data point (not a NODATA corner)
  std::vector<std::uint8_t> walked;  // by triangle: holds residual data (its cells are bounded)
  std::vector<double> above, below;  // by vertex: max over its walked triangles (or -inf)
  // Directed edges of the walked triangles, to walk each shared edge once: the ends of the edges
  // from vertex a are edge_to[edge_from[a], edge_from[a + 1]) (grouped by a counting sort: until
  // 2026-11-28 a sorted vector of pairs, whose sort was ~2 % of pass 4 at --max-points 1024).
  std::vector<std::uint32_t> edge_from, edge_to;

  // NODATA triangles whose residual points reach only part of the way to their NODATA corners
  // (error.hpp, ResidualReach): walked as that part, not through their own edges and vertices.
  std::vector<ResidualReach> reached;

  FineSide(const tile::TinTile& tile, const DeviationBounds& bounds,
           std::span<const ResidualReach> reaches) {
    vertex_arrays(tile, p, z);
    data.assign(p.size(), 1);
    for (std::size_t c = 0; c < 4; ++c) data[c] = tile.corner_nodata[c] ? 0 : 1;
    const double none = -std::numeric_limits<double>::infinity();
    above.assign(p.size(), none), below.assign(p.size(), none);
    walked.assign(tile.triangles.size(), 0);
    std::vector<std::uint8_t> in_part(tile.triangles.size(), 0);
    for (const ResidualReach& b : reaches) {
      if (b.triangle < bounds.size() && bounds[b.triangle].has_data()) {
        reached.push_back(b);
        in_part[b.triangle] = 1;
      }
    }
    for (std::size_t i = 0; i < bounds.size() && i < tile.triangles.size(); ++i) {
      if (!bounds[i].has_data() || in_part[i]) continue;
      walked[i] = 1;
      const auto& tr = tile.triangles[i];
      for (int k = 0; k < 3; ++k) {
        above[tr[k]] = std::max(above[tr[k]], static_cast<double>(bounds[i].above));
        below[tr[k]] = std::max(below[tr[k]], static_cast<double>(bounds[i].below));
      }
    }
    index_walked_edges(tile);
  }
  bool near_walked(std::uint32_t v) const {
    return above[v] > -std::numeric_limits<double>::infinity();
  }
  // Whether the directed edge w → u is an edge of a walked triangle (the one beyond u → w).
  bool walked_beyond(std::uint32_t u, std::uint32_t w) const {
    const std::uint32_t* const to = edge_to.data();
    return std::find(to + edge_from[w], to + edge_from[w + 1], u) != to + edge_from[w + 1];
  }

 private:
  // edge_from, edge_to from the walked triangles.
  void index_walked_edges(const tile::TinTile& tile) {
    edge_from.assign(p.size() + 1, 0);
    for (std::size_t i = 0; i < walked.size(); ++i) {
      if (!walked[i]) continue;
      for (const std::uint32_t a : tile.triangles[i]) ++edge_from[a + 1];
    }
    for (std::size_t v = 0; v < p.size(); ++v) edge_from[v + 1] += edge_from[v];
    edge_to.resize(edge_from.back());
    std::vector<std::uint32_t> next(edge_from.begin(), edge_from.end() - 1);
    for (std::size_t i = 0; i < walked.size(); ++i) {
      if (!walked[i]) continue;
      const auto& tr = tile.triangles[i];
      for (int k = 0; k < 3; ++k) edge_to[next[tr[k]]++] = tr[(k + 1) % 3];
    }
  }
};

// The running residual maxima of one coarse tile, by triangle (before rounding), and for its
// NODATA triangles how far the cells that fed them reach towards their NODATA vertices.
struct CoarseBounds {
  const WalkMesh& mesh;
  std::vector<double> above, below, reach;
  std::vector<std::uint8_t> nodata;  // by triangle: bit k set when vertex k is a NODATA corner
  CoarseBounds(const WalkMesh& m, const tile::TinTile& tile)
      : mesh(m),
        above(tile.triangles.size(), -std::numeric_limits<double>::infinity()),
        below(tile.triangles.size(), -std::numeric_limits<double>::infinity()),
        reach(tile.triangles.size(), 0.0),
        nodata(tile.triangles.size(), 0) {
    for (std::size_t i = 0; i < tile.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        if (tile.is_nodata_vertex(tile.triangles[i][static_cast<std::size_t>(k)])) {
          nodata[i] |= static_cast<std::uint8_t>(1u << k);
        }
      }
    }
  }
  // Residual finest data in coarse triangle i, in a cell with the vertex `at`, deviates by at most
  // (delta + fine_above) above and (fine_below − delta) below the coarse surface.
  void add(std::uint32_t i, const kernel::XY& at, double delta, double fine_above,
           double fine_below) {
    above[i] = std::max(above[i], delta + fine_above);
    below[i] = std::max(below[i], fine_below - delta);
    if (nodata[i]) reach[i] = std::max(reach[i], nodata_weight(i, at));
  }
  // The barycentric weight of triangle i's NODATA vertices at q (clamped to [0, 1]).
  double nodata_weight(std::uint32_t i, const kernel::XY& q) const {
    const kernel::XY &a = mesh.p[mesh.t[i][0]], &b = mesh.p[mesh.t[i][1]],
                     &c = mesh.p[mesh.t[i][2]];
    auto cross = [](const kernel::XY& o, const kernel::XY& e, const kernel::XY& r) {
      return (e.x - o.x) * (r.y - o.y) - (e.y - o.y) * (r.x - o.x);
    };
    const double area = cross(a, b, c);
    if (!(area > 0)) return 1.0;
    const double w[3] = {cross(b, c, q) / area, cross(c, a, q) / area, cross(a, b, q) / area};
    double sum = 0;
    for (int k = 0; k < 3; ++k) {
      if (nodata[i] & (1u << k)) sum += w[k];
    }
    return std::clamp(sum, 0.0, 1.0);
  }
};

// The part of triangle (p[0], p[1], p[2]) where the weight of its NODATA vertices (bits of
// `nodata`) is at most `reach` (ResidualReach): the triangle clipped by one line, a polygon in
// the triangle's (counter-clockwise) order.
std::vector<kernel::XY> clip_to_reach(const std::array<kernel::XY, 3>& p, std::uint8_t nodata,
                                      double reach) {
  if (reach >= 1) return {p.begin(), p.end()};
  std::vector<kernel::XY> poly;
  auto excess = [&](int k) { return ((nodata >> k) & 1 ? 1.0 : 0.0) - reach; };
  for (int k = 0; k < 3; ++k) {
    const int n = (k + 1) % 3;
    const double fk = excess(k), fn = excess(n);
    if (fk <= 0) poly.push_back(p[static_cast<std::size_t>(k)]);
    if ((fk <= 0) != (fn <= 0)) {
      const double t = fk / (fk - fn);
      const kernel::XY &a = p[static_cast<std::size_t>(k)], &b = p[static_cast<std::size_t>(n)];
      poly.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
    }
  }
  return poly;
}

// A finest data point the coarse tile knows exactly (a finer tile's vertex or witness) and how
// far the coarse surface is from it there (coarse − z), with the coarse triangle holding it.
struct KnownPoint {
  tile::Vertex v;
  double deviation;
  std::uint32_t triangle;
  // `triangle` alone holds v (strictly inside it): the residual bounds need no search for the
  // other triangles holding it (WalkMesh::for_each_containing), done once when v was located.
  bool alone = false;
};

// The known points of one chain (chain_error), as they are found: the `capacity` worst of those
// strictly inside the coarse tile's rectangle (by `worse`: deviation, then position) are kept as
// its witnesses; every other feeds the residual bounds of the coarse triangles holding it at once
// (the bounds are maxima: the order of the additions does not matter). The same witnesses as
// ranking every known point and keeping the worst (until 2026-11-28: stored, then nth_element),
// without storing the ~860k finest vertices that a coarse level chains against. Null `acc`: the
// points are only counted (surface_difference).
class KnownPoints {
 public:
  KnownPoints(const WalkMesh& c, CoarseBounds* acc, const geo::MercatorRect& r,
              std::size_t capacity)
      : c_(c), acc_(acc), r_(r), capacity_(capacity) {
    kept_.reserve(capacity);
  }

  // Ranks a's deviation above b's (ties by position: a strict order on distinct points).
  static bool worse(const KnownPoint& a, const KnownPoint& b) {
    const double da = std::abs(a.deviation), db = std::abs(b.deviation);
    if (da != db) return da > db;
    if (a.v.x != b.v.x) return a.v.x < b.v.x;
    return a.v.y < b.v.y;
  }

  void add(const KnownPoint& p) {
    if (!acc_) return;
    max_known_ = std::max(max_known_, std::abs(p.deviation));
    const bool inside =
        p.v.x > r_.min_x && p.v.x < r_.max_x && p.v.y > r_.min_y && p.v.y < r_.max_y;
    if (!inside || capacity_ == 0) return bound(p);
    if (kept_.size() < capacity_) {
      kept_.push_back(p);
      std::push_heap(kept_.begin(), kept_.end(), worse);  // front: the least bad kept
      return;
    }
    if (!worse(p, kept_.front())) return bound(p);
    std::pop_heap(kept_.begin(), kept_.end(), worse);
    bound(kept_.back());
    kept_.back() = p;
    std::push_heap(kept_.begin(), kept_.end(), worse);
  }

  // The witnesses (the kept points, in no particular order) and max |deviation| of every point.
  std::vector<KnownPoint>& kept() { return kept_; }
  double max_known() const { return max_known_; }

 private:
  // A point that is no witness: the residual bounds of the coarse triangles holding it.
  void bound(const KnownPoint& p) {
    if (p.alone) {
      acc_->add(p.triangle, {p.v.x, p.v.y}, p.deviation, 0.0, 0.0);
      return;
    }
    c_.for_each_containing(p.triangle, {p.v.x, p.v.y}, [&](std::uint32_t j) {
      acc_->add(j, {p.v.x, p.v.y}, p.deviation, 0.0, 0.0);
    });
  }

  const WalkMesh& c_;
  CoarseBounds* acc_;
  geo::MercatorRect r_;
  std::size_t capacity_;
  std::vector<KnownPoint> kept_;  // a heap by worse()
  double max_known_ = 0;
};

// Walks one finer tile through the coarse mesh (error.hpp, "Chaining"): every finer vertex with
// data is located and becomes a known point (unless it is a coarse vertex); every edge of a
// triangle holding residual data is walked, and every cell vertex of such a triangle feeds the
// residual bounds of the coarse triangles holding it. `d` receives max |coarse − finer| at the
// cell vertices, the vertex RMS and the crossings.
class FinerTileWalk {
 public:
  FinerTileWalk(const WalkMesh& c, const tile::TinTile& fine, const DeviationBounds& bounds,
                std::span<const ResidualReach> reaches, CoarseBounds& out, KnownPoints& known,
                SurfaceDifference& d, std::uint32_t& hint,
                std::vector<std::uint8_t>& coarse_matched)
      : c_(c),
        fine_(fine),
        bounds_(bounds),
        f_(fine, bounds, reaches),
        out_(out),
        known_(known),
        d_(d),
        hint_(hint),
        matched_(coarse_matched),
        where_(f_.p.size(), -1),
        dv_(f_.p.size(), 0.0) {}

  void run() {
    const bool lost = !locate_vertices() ||
                      !walk_edges([&](std::uint32_t u) { return where_[u]; }) || !walk_reached();
    if (lost) brute_force();
    add_rms();
  }

 private:
  // Every finer vertex with data or on a walked triangle (a NODATA corner of one is a cell vertex
  // too), in vertex order: tiles number their interior points in Morton order (and parents keep
  // their children's order), so each walk is short.
  bool locate_vertices() {
    for (std::uint32_t v = 0; v < f_.p.size(); ++v) {
      // (NODATA corners too: a coarse vertex there is a finer vertex, not a cell vertex inside a
      // finer triangle, coarse_vertices_over_finer)
      if (!f_.data[v] && !f_.near_walked(v) && v >= 4) continue;
      bool strict = false;
      const std::int64_t i = c_.locate(hint_, f_.p[v], &strict);
      if (i < 0) return false;
      settle(v, static_cast<std::uint32_t>(i), strict);
    }
    return true;
  }

  // Vertex v lies in coarse triangle i (strictly inside it: `alone`, as c_.strictly_inside(i, …)
  // says): the difference there (for a data vertex, a finest data point that the finer surface
  // interpolates, exact), fed to every coarse triangle holding it.
  void settle(std::uint32_t v, std::uint32_t i, bool alone) {
    hint_ = i;
    where_[v] = i;
    const kernel::XY& q = f_.p[v];
    dv_[v] = c_.plane[i].at(q.x, q.y) - f_.z[v];
    bool coarse_vertex = false;
    auto visit = [&](std::uint32_t j) {
      for (int k = 0; k < 3; ++k) {
        if (c_.corner(j, k).x == q.x && c_.corner(j, k).y == q.y) {
          matched_[c_.t[j][k]] = 1;
          coarse_vertex = true;
        }
      }
      if (f_.near_walked(v)) out_.add(j, q, dv_[v], f_.above[v], f_.below[v]);
    };
    if (alone) {  // (for_each_containing's own first test, known from the locate)
      visit(i);
    } else {
      c_.for_each_containing(i, q, visit);
    }
    if (f_.near_walked(v)) d_.max_abs = std::max(d_.max_abs, std::abs(dv_[v]));
    if (f_.data[v] && !coarse_vertex) {
      const tile::Vertex& fv = fine_.vertex(v);
      known_.add({fv, dv_[v], i, alone});
    }
  }

  // Walks the edges of the triangles holding residual data, each once, from a coarse triangle
  // containing its first vertex (start_of); false when a walk fails.
  template <typename StartOf>
  bool walk_edges(StartOf&& start_of) {
    const geo::MercatorRect fr = fine_.id.bounds();
    auto on_border = [&](std::uint32_t a, std::uint32_t b) {
      const kernel::XY &pa = f_.p[a], &pb = f_.p[b];
      return (pa.x == pb.x && (pa.x == fr.min_x || pa.x == fr.max_x)) ||
             (pa.y == pb.y && (pa.y == fr.min_y || pa.y == fr.max_y));
    };
    for (std::size_t t = 0; t < fine_.triangles.size(); ++t) {
      if (!f_.walked[t]) continue;
      const auto& tr = fine_.triangles[t];
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t u = tr[k], w = tr[(k + 1) % 3];
        // Each shared edge once, from its triangle with u < w; border edges and edges against a
        // triangle without residual data have no walked triangle on the other side.
        if (!(u < w || on_border(u, w) || !f_.walked_beyond(u, w))) continue;
        const std::int64_t from = start_of(u);
        if (from < 0 || walk(u, w, static_cast<std::uint32_t>(from)) < 0) return false;
      }
    }
    return true;
  }

  // Walks the finer edge u → w through the coarse mesh from `from` (a triangle containing u),
  // evaluating the difference where it crosses coarse edges; returns the triangle where the walk
  // ends (it contains w), or -1.
  std::int64_t walk(std::uint32_t u, std::uint32_t w, std::uint32_t from) {
    // The walked triangles on both sides of the edge contain u and w: their bounds are at most
    // the smaller of the two vertices' maxima.
    return walk_segment(f_.p[u], f_.z[u], f_.p[w], f_.z[w], from,
                        std::min(f_.above[u], f_.above[w]), std::min(f_.below[u], f_.below[w]));
  }

  // The same for any segment pu → pw of the finer surface (heights zu, zw at its ends, linear
  // between them), whose cells have the finer bounds (fa, fb).
  std::int64_t walk_segment(const kernel::XY& pu, double zu, const kernel::XY& pw, double zw,
                            std::uint32_t from, double fa, double fb) {
    std::uint32_t i = from;
    int entry = -1;
    for (std::size_t steps = 0; steps <= c_.t.size() + 8; ++steps) {
      int exit = -1;
      for (int k = 0; k < 3 && exit < 0; ++k) {
        if (k == entry) continue;
        const kernel::XY &a = c_.corner(i, (k + 1) % 3), &b = c_.corner(i, (k + 2) % 3);
        if (kernel::orient2d(a, b, pw) >= 0) continue;
        // w is beyond this edge; the segment leaves through it when a is on the right of u → w
        // and b on the left (or on the line).
        if (kernel::orient2d(pu, pw, a) <= 0 && kernel::orient2d(pu, pw, b) >= 0) exit = k;
      }
      if (exit < 0) return static_cast<std::int64_t>(i);  // w is in triangle i
      const std::int32_t next = c_.cell[i].n[exit];
      const std::uint32_t ia = c_.t[i][(exit + 1) % 3], ib = c_.t[i][(exit + 2) % 3];
      // The crossing point, as a fraction s along the coarse edge a → b and a fraction r along
      // the finer edge u → w (floating point: error_rounding_allowance covers the rounding).
      const kernel::XY &a = c_.p[ia], &b = c_.p[ib];
      auto cross = [](const kernel::XY& o, const kernel::XY& e, const kernel::XY& q) {
        return (e.x - o.x) * (q.y - o.y) - (e.y - o.y) * (q.x - o.x);
      };
      const double oa = cross(pu, pw, a), ob = cross(pu, pw, b);
      const double ou = cross(a, b, pu), ow = cross(a, b, pw);
      double s = oa - ob != 0 ? oa / (oa - ob) : 0.5;
      double r = ou - ow != 0 ? ou / (ou - ow) : 0.0;
      s = std::clamp(s, 0.0, 1.0), r = std::clamp(r, 0.0, 1.0);
      const double delta = (c_.z[ia] + s * (c_.z[ib] - c_.z[ia])) - (zu + r * (zw - zu));
      d_.max_abs = std::max(d_.max_abs, std::abs(delta));
      ++d_.crossings;
      const kernel::XY at{a.x + s * (b.x - a.x), a.y + s * (b.y - a.y)};
      out_.add(i, at, delta, fa, fb);
      if (next < 0) return std::int64_t{-1};
      const auto j = static_cast<std::uint32_t>(next);
      out_.add(j, at, delta, fa, fb);
      const auto& nj = c_.cell[j].n;
      entry = nj[0] == static_cast<std::int32_t>(i)
                  ? 0
                  : (nj[1] == static_cast<std::int32_t>(i) ? 1 : 2);
      i = j;
    }
    return std::int64_t{-1};
  }

  // The NODATA triangles with a reach (FineSide::reached): the part of each where its residual
  // points lie, its vertices located and its edges walked; the finer surface there is the
  // triangle's plane. False when a walk fails.
  bool walk_reached() {
    for (const ResidualReach& part : f_.reached) {
      const auto& tr = fine_.triangles[part.triangle];
      const Plane plane =
          plane_of(f_.p[tr[0]], f_.z[tr[0]], f_.p[tr[1]], f_.z[tr[1]], f_.p[tr[2]], f_.z[tr[2]]);
      std::uint8_t nodata = 0;
      for (int k = 0; k < 3; ++k) {
        if (fine_.is_nodata_vertex(tr[static_cast<std::size_t>(k)])) {
          nodata |= static_cast<std::uint8_t>(1u << k);
        }
      }
      const std::vector<kernel::XY> poly =
          clip_to_reach({f_.p[tr[0]], f_.p[tr[1]], f_.p[tr[2]]}, nodata, part.reach);
      const double fa = bounds_[part.triangle].above, fb = bounds_[part.triangle].below;
      std::vector<std::int64_t> at(poly.size());
      for (std::size_t k = 0; k < poly.size(); ++k) {
        at[k] = c_.locate(hint_, poly[k]);
        if (at[k] < 0) return false;
        hint_ = static_cast<std::uint32_t>(at[k]);
        const double delta =
            c_.plane[hint_].at(poly[k].x, poly[k].y) - plane.at(poly[k].x, poly[k].y);
        d_.max_abs = std::max(d_.max_abs, std::abs(delta));
        c_.for_each_containing(hint_, poly[k],
                               [&](std::uint32_t j) { out_.add(j, poly[k], delta, fa, fb); });
      }
      for (std::size_t k = 0; k < poly.size(); ++k) {
        const kernel::XY &p = poly[k], &q = poly[(k + 1) % poly.size()];
        if (walk_segment(p, plane.at(p.x, p.y), q, plane.at(q.x, q.y),
                         static_cast<std::uint32_t>(at[k]), fa, fb) < 0) {
          return false;
        }
      }
    }
    return true;
  }

  // Not reached on valid tiles: every vertex located by brute force, so that the bound stays
  // honest. (Known points and bounds already added are kept: more never hurts a bound.)
  void brute_force() {
    auto brute_locate = [&](const kernel::XY& q) -> std::int64_t {
      for (std::uint32_t i = 0; i < c_.t.size(); ++i) {
        if (c_.contains(i, q)) return i;
      }
      return -1;
    };
    for (std::uint32_t v = 0; v < f_.p.size(); ++v) {
      if ((!f_.data[v] && !f_.near_walked(v)) || where_[v] >= 0) continue;
      if (const std::int64_t i = brute_locate(f_.p[v]); i >= 0) {
        const auto t = static_cast<std::uint32_t>(i);
        settle(v, t, c_.strictly_inside(t, f_.p[v]));
      }
    }
    walk_edges([&](std::uint32_t u) { return brute_locate(f_.p[u]); });
  }

  // The RMS: each finer data vertex weighted by a third of the area of its triangles.
  // (Summed in locals, in the same order: d_ stays in memory across the loop otherwise.)
  void add_rms() {
    double sum_sq_area = d_.sum_sq_area, area = d_.area;
    for (const auto& tr : fine_.triangles) {
      const kernel::XY &a = f_.p[tr[0]], &b = f_.p[tr[1]], &q = f_.p[tr[2]];
      const double third = std::abs((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x)) / 6.0;
      for (auto v : tr) {
        if (where_[v] < 0 || !f_.data[v]) continue;
        sum_sq_area += third * dv_[v] * dv_[v];
        area += third;
      }
    }
    d_.sum_sq_area = sum_sq_area, d_.area = area;
  }

  const WalkMesh& c_;
  const tile::TinTile& fine_;
  const DeviationBounds& bounds_;
  const FineSide f_;
  CoarseBounds& out_;
  KnownPoints& known_;
  SurfaceDifference& d_;
  std::uint32_t& hint_;
  std::vector<std::uint8_t>& matched_;
  std::vector<std::int64_t> where_;  // by finer vertex: a coarse triangle containing it
  std::vector<double> dv_;           // by finer vertex: coarse − finer there
};

// Coarse vertices that are not vertices of the finer tile but lie on one of its triangles with
// residual data (a parent's vertex taken from a child's witnesses, or two unrelated meshes) are
// cell vertices too: the finer surface is evaluated there directly, with the largest bounds of
// the walked triangles holding the point.
void coarse_vertices_over_finer(const WalkMesh& c, const tile::TinTile& fine,
                                const DeviationBounds& bounds,
                                const std::vector<std::uint8_t>& matched, CoarseBounds& out,
                                SurfaceDifference& d) {
  const geo::MercatorRect fr = fine.id.bounds();
  std::vector<std::uint32_t> extra;
  for (std::uint32_t v = 0; v < c.p.size(); ++v) {
    const kernel::XY& q = c.p[v];
    if (!matched[v] && q.x >= fr.min_x && q.x <= fr.max_x && q.y >= fr.min_y && q.y <= fr.max_y) {
      extra.push_back(v);
    }
  }
  if (extra.empty()) return;
  std::vector<FlatTriangle> ft;
  std::vector<std::uint32_t> source;  // by flat triangle: the finer triangle
  {
    std::vector<FlatTriangle> all;
    detail::append_triangles(fine, false, all);
    for (std::uint32_t i = 0; i < all.size() && i < bounds.size(); ++i) {
      if (!bounds[i].has_data()) continue;
      ft.push_back(all[i]);
      source.push_back(i);
    }
  }
  if (ft.empty()) return;
  TriangleGrid grid(std::move(ft), fr);
  std::uint32_t hint = 0;
  for (std::uint32_t v : extra) {
    const kernel::XY& q = c.p[v];
    double best_w = -std::numeric_limits<double>::infinity();
    double zf = 0, fa = -std::numeric_limits<double>::infinity(), fb = fa;
    grid.for_each_overlapping(q.x, q.y, q.x, q.y, [&](std::uint32_t k) {
      double w;
      const double z = plane_at(grid.triangles()[k], q.x, q.y, &w);
      if (w > best_w) best_w = w, zf = z;
      if (w >= -1e-9) {  // holds q up to rounding: its bounds count
        fa = std::max(fa, static_cast<double>(bounds[source[k]].above));
        fb = std::max(fb, static_cast<double>(bounds[source[k]].below));
      }
    });
    if (!(best_w >= -1e-9)) continue;  // not on a walked triangle
    const double delta = c.z[v] - zf;
    d.max_abs = std::max(d.max_abs, std::abs(delta));
    const std::int64_t i = c.locate(hint, q);
    if (i < 0) continue;
    hint = static_cast<std::uint32_t>(i);
    c.for_each_containing(hint, q, [&](std::uint32_t j) { out.add(j, q, delta, fa, fb); });
  }
}

// Witnesses of a finer tile (finest data points inside it that are not its vertices): located in
// the coarse mesh, they are known points like its vertices.
void locate_witnesses(const WalkMesh& c, std::span<const tile::Vertex> witnesses,
                      KnownPoints& known, std::uint32_t& hint) {
  for (const tile::Vertex& w : witnesses) {
    const kernel::XY q{w.x, w.y};
    std::int64_t i = c.locate(hint, q);
    if (i < 0) {  // not on a valid coarse tile: by brute force
      for (std::uint32_t j = 0; j < c.t.size() && i < 0; ++j) {
        if (c.contains(j, q)) i = j;
      }
      if (i < 0) continue;
    }
    hint = static_cast<std::uint32_t>(i);
    bool coarse_vertex = false;
    for (int k = 0; k < 3; ++k)
      coarse_vertex = coarse_vertex || (c.corner(hint, k).x == q.x && c.corner(hint, k).y == q.y);
    if (coarse_vertex) continue;  // the coarse tile took it as a vertex: no deviation there
    known.add({w, c.plane[hint].at(q.x, q.y) - w.z, hint});
  }
}

}  // namespace

double DeviationBound::max_abs() const {
  return has_data() ? std::max(0.0, static_cast<double>(std::max(above, below))) : 0.0;
}

double max_bound(const DeviationBounds& bounds) {
  double m = 0;
  for (const auto& b : bounds) m = std::max(m, b.max_abs());
  return m;
}

double SurfaceDifference::rms() const { return area > 0 ? std::sqrt(sum_sq_area / area) : 0.0; }

ChainedError chain_error(const tile::TinTile& coarse, std::span<const ChainInput> finer,
                         std::size_t witness_count) {
  ChainedError e;
  e.bounds.assign(coarse.triangles.size(), {});
  if (coarse.triangles.empty()) return e;
  const WalkMesh c(coarse);
  CoarseBounds acc(c, coarse);
  const geo::MercatorRect r = coarse.id.bounds();
  // The known points where the coarse tile deviates most become its witnesses (strictly inside
  // its rectangle); the others feed the residual bounds of the triangles holding them.
  KnownPoints known(c, &acc, r, witness_count);
  std::uint32_t hint = 0;
  double child_sq_area = 0;
  SurfaceDifference total;
  static const DeviationBounds kNoResidual;
  for (const ChainInput& in : finer) {
    const DeviationBounds& bounds = in.bounds ? *in.bounds : kNoResidual;
    SurfaceDifference d;
    std::vector<std::uint8_t> matched(c.p.size(), 0);
    FinerTileWalk(c, *in.tile, bounds, in.reaches, acc, known, d, hint, matched).run();
    coarse_vertices_over_finer(c, *in.tile, bounds, matched, acc, d);
    locate_witnesses(c, in.witnesses, known, hint);
    total.max_abs = std::max(total.max_abs, d.max_abs);
    total.sum_sq_area += d.sum_sq_area;
    total.area += d.area;
    total.crossings += d.crossings;
    child_sq_area += d.area * in.tile->rms_error * in.tile->rms_error;
  }
  // The witnesses in Morton order of their position in the tile (whose parent locates them one
  // after the other, each from the previous one's triangle): short walks.
  auto morton = [&](const tile::Vertex& v) {
    auto cell = [](double t) {
      return static_cast<std::uint32_t>(std::clamp(t, 0.0, 1.0) * 65535.0);
    };
    std::uint64_t key = 0;
    const std::uint32_t cx = cell((v.x - r.min_x) / r.width()),
                        cy = cell((v.y - r.min_y) / r.height());
    for (int b = 15; b >= 0; --b) key = (key << 2) | (((cy >> b) & 1u) << 1) | ((cx >> b) & 1u);
    return key;
  };
  std::vector<KnownPoint>& kept = known.kept();
  std::sort(kept.begin(), kept.end(), [&](const KnownPoint& a, const KnownPoint& b) {
    const auto ka = morton(a.v), kb = morton(b.v);
    return ka != kb ? ka < kb : KnownPoints::worse(a, b);
  });
  for (const KnownPoint& p : kept) e.witnesses.push_back(p.v);
  e.max_known = known.max_known();
  const double allowance = error_rounding_allowance(coarse);
  e.geometric_error = e.max_known + allowance;
  for (std::size_t i = 0; i < e.bounds.size(); ++i) {
    if (!(acc.above[i] > -std::numeric_limits<double>::infinity())) continue;
    // A triangle with residual data has both bounds; each alone may be negative (the data may
    // lie entirely below or above the tile there), not their maximum.
    e.bounds[i] = {round_up(acc.above[i] + allowance), round_up(acc.below[i] + allowance)};
    e.geometric_error = std::max(e.geometric_error, e.bounds[i].max_abs());
    if (acc.nodata[i]) {
      // (rounded up a little: the weights are computed in floating point)
      e.reaches.push_back(
          {static_cast<std::uint32_t>(i), std::min(1.0, acc.reach[i] * (1 + 1e-9) + 1e-12)});
    }
  }
  const double child_rms = total.area > 0 ? std::sqrt(child_sq_area / total.area) : 0.0;
  e.rms_error = total.rms() + child_rms;
  e.crossings = total.crossings;
  return e;
}

SurfaceDifference surface_difference(const tile::TinTile& coarse,
                                     std::span<const tile::TinTile* const> fines) {
  // The surface's difference: every data triangle of the finer tile is walked, with bounds 0.
  SurfaceDifference total;
  if (coarse.triangles.empty()) return total;
  const WalkMesh c(coarse);
  CoarseBounds acc(c, coarse);
  KnownPoints known(c, nullptr, coarse.id.bounds(), 0);  // (not used here)
  std::uint32_t hint = 0;
  for (const tile::TinTile* fine : fines) {
    DeviationBounds surface(fine->triangles.size());
    for (std::size_t i = 0; i < surface.size(); ++i) {
      if (!fine->is_nodata_triangle(i)) surface[i] = {0.0f, 0.0f};
    }
    SurfaceDifference d;
    std::vector<std::uint8_t> matched(c.p.size(), 0);
    FinerTileWalk(c, *fine, surface, {}, acc, known, d, hint, matched).run();
    coarse_vertices_over_finer(c, *fine, surface, matched, acc, d);
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
  detail::append_triangles(coarse, false, ct);  // all of the coarse surface: what clients draw
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
      if (c < 0) continue;  // (not on a valid coarse tile, which covers its rectangle)
      worst = std::max(worst, std::abs(plane_at(cg.triangles()[static_cast<std::size_t>(c)],
                                                t.p[k].x, t.p[k].y) -
                                       t.z[k]));
    }
  }
  // Coarse vertices against the finest data, where there is some.
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
