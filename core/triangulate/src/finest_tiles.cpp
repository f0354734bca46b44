#include "tinstream/triangulate/finest_tiles.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <optional>
#include <span>
#include <thread>
#include <tuple>
#include <type_traits>
#include <unordered_set>

#include "delaunay.hpp"
#include "tinstream/base/worker_threads.hpp"
#include "tinstream/kernel/predicates.hpp"

namespace tinstream::triangulate {
namespace {

using kernel::XY;
using subdivide::SortedPoint;

constexpr std::uint32_t kKeyLevel = 30;
constexpr std::uint32_t kDefaultSubShift = 4;
// Above this many triangles with large circles in a halo round, ask per point (ConflictSearch).
constexpr std::size_t kFewLargeCircles = 16;
// No edge point closer than this to a corner (normalised units; `tinstream verify` rejects two
// vertices of a tile closer than that).
constexpr double kMinVertexDistance = 1e-12;

std::uint64_t pack(std::uint32_t x, std::uint32_t y) {
  return (static_cast<std::uint64_t>(x) << 32) | y;
}

struct Circle {
  double cx = 0, cy = 0, r2 = 0;
  bool unbounded = false;  // degenerate or enormous: reaches everything on one side
};

Circle circumcircle(const XY& a, const XY& b, const XY& c) {
  const double bx = b.x - a.x, by = b.y - a.y;
  const double qx = c.x - a.x, qy = c.y - a.y;
  const double d = 2.0 * (bx * qy - by * qx);
  const double b2 = bx * bx + by * by, q2 = qx * qx + qy * qy;
  const double ux = (qy * b2 - by * q2) / d;
  const double uy = (bx * q2 - qx * b2) / d;
  Circle circle{a.x + ux, a.y + uy, ux * ux + uy * uy, false};
  if (!std::isfinite(circle.cx) || !std::isfinite(circle.cy) || !std::isfinite(circle.r2) ||
      circle.r2 > 16.0) {
    circle.unbounded = true;
  }
  return circle;
}

// Conservative: true whenever the circle may meet the closed rectangle.
// The radius with the relative margin every halo test of a circle uses.
double padded_radius(const Circle& c) { return std::sqrt(c.r2) * (1.0 + 1e-9); }

bool circle_meets(const Circle& c, const geo::MercatorRect& r) {
  if (c.unbounded) return true;
  const double dx = std::max({r.min_x - c.cx, 0.0, c.cx - r.max_x});
  const double dy = std::max({r.min_y - c.cy, 0.0, c.cy - r.max_y});
  return dx * dx + dy * dy <= c.r2 * (1.0 + 1e-9) + 1e-300;
}

bool bbox_meets(const XY& a, const XY& b, const XY& c, const geo::MercatorRect& r) {
  return std::max({a.x, b.x, c.x}) >= r.min_x && std::min({a.x, b.x, c.x}) <= r.max_x &&
         std::max({a.y, b.y, c.y}) >= r.min_y && std::min({a.y, b.y, c.y}) <= r.max_y;
}

// Conservative: true whenever triangle abc may meet the border ∂R of the closed rectangle — its
// bounding box meets R and does not lie in R's open interior. (A triangle meeting R with a vertex
// on or outside ∂R meets ∂R, since it is convex; one with all vertices strictly inside R does not.)
bool bbox_meets_border(const XY& a, const XY& b, const XY& c, const geo::MercatorRect& r) {
  if (!bbox_meets(a, b, c, r)) return false;
  const bool strictly_inside =
      std::min({a.x, b.x, c.x}) > r.min_x && std::max({a.x, b.x, c.x}) < r.max_x &&
      std::min({a.y, b.y, c.y}) > r.min_y && std::max({a.y, b.y, c.y}) < r.max_y;
  return !strictly_inside;
}

geo::MercatorRect cell_rect(std::uint32_t level, std::uint32_t cx, std::uint32_t cy) {
  return geo::TileId{level, cx, cy}.bounds();
}

bool lex_less(const SortedPoint& a, const SortedPoint& b) {
  return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// Elevation where the segment p→q (canonical lexicographic order) meets the line at parameter t.
struct Crossing {
  double along = 0;  // the coordinate along the border (x for north/south, y for east/west)
  double z = 0;
};

// The canonical intersection of edge (a, b) with the horizontal line y = Y (requires a proper
// crossing). Both tiles sharing the line compute exactly this.
Crossing cross_horizontal(const SortedPoint& a, const SortedPoint& b, double Y) {
  const SortedPoint& p = lex_less(a, b) ? a : b;
  const SortedPoint& q = lex_less(a, b) ? b : a;
  const double t = (Y - p.y) / (q.y - p.y);
  return {p.x + t * (q.x - p.x), p.z + t * (q.z - p.z)};
}

Crossing cross_vertical(const SortedPoint& a, const SortedPoint& b, double X) {
  const SortedPoint& p = lex_less(a, b) ? a : b;
  const SortedPoint& q = lex_less(a, b) ? b : a;
  const double t = (X - p.x) / (q.x - p.x);
  return {p.y + t * (q.y - p.y), p.z + t * (q.z - p.z)};
}

// Elevation of the global surface at corner c, from the triangle of `tris` containing it; the
// computation depends only on the containing triangle's (or edge's) vertices in canonical order.
std::optional<double> corner_elevation(const XY& c, const std::vector<SortedPoint>& pts,
                                       const std::vector<detail::IndexTriangle>& tris) {
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

tile::Vertex to_vertex(const SortedPoint& p) { return {p.x, p.y, p.z, p.weight}; }

// Andrew's monotone chain with exact orientation; collinear points dropped; counter-clockwise.
std::vector<XY> convex_hull(std::vector<XY> points) {
  std::sort(points.begin(), points.end(),
            [](const XY& a, const XY& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  points.erase(std::unique(points.begin(), points.end(),
                           [](const XY& a, const XY& b) { return a.x == b.x && a.y == b.y; }),
               points.end());
  if (points.size() < 3) return points;
  std::vector<XY> hull(2 * points.size());
  std::size_t k = 0;
  for (const XY& p : points) {
    while (k >= 2 && kernel::orient2d(hull[k - 2], hull[k - 1], p) <= 0.0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && kernel::orient2d(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  hull.shrink_to_fit();  // kept per tile while PointCells::build runs: not 2 × the tile's points
  return hull;
}

// Whether a point lies in the (perturbed) circumcircle of some triangle of a canonical Delaunay
// mesh that meets the border ∂R of the rectangle R — the halo's question, answered per point:
// locate the point by a visibility walk (from the previous answer's triangle), then search its
// conflict region, the triangles whose circle holds it. That region is connected (Bowyer–Watson's
// cavity; for a point outside the hull it hangs off the hull edges the point sees), so a
// breadth-first search through conflicting triangles finds all of it. Cost: the walk plus the
// region, instead of one test per (circle, point) pair — which a dense, slightly curved line of
// points (thousands of slivers whose huge circles sweep along the whole halo band) makes quadratic.
class ConflictSearch {
 public:
  ConflictSearch(const std::vector<XY>& v, const detail::DelaunayMesh& mesh,
                 const geo::MercatorRect& r)
      : v_(v), tri_(mesh.triangles), nb_(mesh.neighbours), r_(r), mark_(tri_.size(), 0) {}

  // True when p is inside the circle of a triangle meeting ∂R (conservatively true if the walk
  // made no progress, which cannot happen on a Delaunay mesh). `tests` counts in-circle tests.
  bool conflicts_near_r(const XY& p, std::uint64_t& tests) {
    if (tri_.empty()) return false;
    std::uint32_t t = hint_;
    int exit_edge = -1;
    for (std::size_t steps = 0;; ++steps) {
      if (steps > tri_.size() + 8) return true;
      int cross = -1;
      for (int j = 0; j < 3 && cross < 0; ++j) {
        const int k = (j + static_cast<int>(steps)) % 3;  // rotate the start: no cycling
        if (kernel::orient2d(at(t, k + 1), at(t, k + 2), p) < 0) cross = k;
      }
      if (cross < 0) break;  // inside t or on its boundary
      const std::uint32_t next = nb_[t][static_cast<std::size_t>(cross)];
      if (next == detail::kNoNeighbour) {
        exit_edge = cross;
        break;
      }
      t = next;
    }
    hint_ = t;
    if (++stamp_ == 0) {  // wrapped: clear the marks
      std::fill(mark_.begin(), mark_.end(), 0);
      stamp_ = 1;
    }
    queue_.clear();
    push(t);
    if (exit_edge >= 0) {
      // The hull edges p sees, both ways along the hull from the one the walk left through.
      for (const bool forward : {true, false}) {
        std::uint32_t ct = t;
        int ck = exit_edge;
        for (std::size_t i = 0; i < tri_.size(); ++i) {
          std::tie(ct, ck) = adjacent_hull_edge(ct, ck, forward);
          if (kernel::orient2d(at(ct, ck + 1), at(ct, ck + 2), p) > 0) break;
          push(ct);
        }
      }
    }
    // The queue grows while it is walked (push below): by index, not by iterator.
    for (std::size_t head = 0; head < queue_.size(); ++head) {  // NOLINT(modernize-loop-convert)
      const std::uint32_t q = queue_[head];
      ++tests;
      if (detail::perturbed_incircle(at(q, 0), at(q, 1), at(q, 2), p) <= 0) continue;
      if (bbox_meets_border(at(q, 0), at(q, 1), at(q, 2), r_)) return true;
      for (std::uint32_t n : nb_[q]) {
        if (n != detail::kNoNeighbour) push(n);
      }
    }
    return false;
  }

 private:
  const XY& at(std::uint32_t t, int k) const {
    return v_[tri_[t][static_cast<std::size_t>(k % 3)]];
  }
  int index_of(std::uint32_t t, std::uint32_t vertex) const {
    return tri_[t][0] == vertex ? 0 : tri_[t][1] == vertex ? 1 : 2;
  }
  void push(std::uint32_t t) {
    if (mark_[t] == stamp_) return;
    mark_[t] = stamp_;
    queue_.push_back(t);
  }
  // The hull edge after (forward) or before the hull edge opposite corner k of t, counter-
  // clockwise along the hull, found by turning around its end (start) vertex.
  std::pair<std::uint32_t, int> adjacent_hull_edge(std::uint32_t t, int k, bool forward) const {
    const std::uint32_t pivot = tri_[t][static_cast<std::size_t>((k + (forward ? 2 : 1)) % 3)];
    const int turn = forward ? 2 : 1;  // the edge of a triangle leaving / entering the pivot
    int e = (k + (forward ? 1 : 2)) % 3;
    for (std::size_t i = 0; i < tri_.size(); ++i) {
      const std::uint32_t n = nb_[t][static_cast<std::size_t>(e)];
      if (n == detail::kNoNeighbour) break;
      t = n;
      e = (index_of(t, pivot) + turn) % 3;
    }
    return {t, e};
  }

  const std::vector<XY>& v_;
  const std::vector<detail::IndexTriangle>& tri_;
  const std::vector<std::array<std::uint32_t, 3>>& nb_;
  geo::MercatorRect r_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t stamp_ = 0, hint_ = 0;
  std::vector<std::uint32_t> queue_;
};

}  // namespace

double canonical_circumradius2(XY a, XY b, XY c) {
  auto less = [](const XY& l, const XY& r) { return l.x < r.x || (l.x == r.x && l.y < r.y); };
  if (less(b, a)) std::swap(a, b);
  if (less(c, b)) std::swap(b, c);
  if (less(b, a)) std::swap(a, b);
  const Circle circle = circumcircle(a, b, c);
  return circle.unbounded ? std::numeric_limits<double>::infinity() : circle.r2;
}

// ── PointCells ─────────────────────────────────────────────────────────────────────────────────

Result<std::shared_ptr<const PointCells>> PointCells::build(const subdivide::SortedRun& run,
                                                            unsigned threads) {
  auto cells = std::make_shared<PointCells>();
  cells->level_ = run.finest_level;
  cells->sub_shift_ = std::min(kDefaultSubShift, kKeyLevel - run.finest_level);
  cells->tiles_ = run.tiles;
  cells->run_path_ = run.path;
  const std::uint32_t per_tile = 1u << (2 * cells->sub_shift_);
  const std::size_t tiles = cells->tiles_.size();
  cells->cell_offsets_.assign(tiles * (per_tile + 1), 0);
  for (std::uint32_t i = 0; i < tiles; ++i) {
    cells->index_.emplace(pack(cells->tiles_[i].id.x, cells->tiles_[i].id.y), i);
  }
  const std::uint32_t cell_shift = 2 * (kKeyLevel - cells->cell_level());
  // Calls visit(t, points) for each tile index in `which`, on `threads` readers, each taking the
  // next tile.
  auto for_each_tile = [&](const std::vector<std::uint32_t>& which, const auto& visit) -> Status {
    std::atomic<std::size_t> next{0};
    std::mutex mutex;
    Status failure;
    auto read_tiles = [&] {
      // The exception barrier (this runs on the workers and on the calling thread). Fault point
      // "pass3.cells": one tile.
      Status s = guarded("pass 3 cell index", [&]() -> Status {
        auto reader = subdivide::SortedRunReader::open(run.path);
        if (!reader) return reader.error();
        std::vector<SortedPoint> chunk;
        for (std::size_t i; (i = next.fetch_add(1)) < which.size();) {
          fault::point("pass3.cells");
          const auto& range = cells->tiles_[which[i]];
          if (Status r = reader->read(range.first, range.count, chunk); !r) return r;
          visit(which[i], chunk);
        }
        return {};
      });
      if (s.ok()) return;
      next.store(which.size());  // the other readers stop too
      std::lock_guard lock(mutex);
      if (failure.ok()) failure = s;
    };
    WorkerThreads pool("pass 3 cell index", "pass3.cells");
    Status started;
    for (unsigned t = 1; t < std::max(1u, threads) && started.ok(); ++t) {
      started = pool.start(read_tiles);
    }
    if (started.ok()) {
      read_tiles();
    } else {
      next.store(which.size());  // those started stop at once
    }
    (void)pool.join();  // read_tiles keeps its own failures
    return started.ok() ? failure : started;
  };
  // Every tile: its cell offsets and the bounding box of its points.
  std::vector<std::uint32_t> all(tiles);
  for (std::uint32_t t = 0; t < tiles; ++t) all[t] = t;
  std::vector<geo::MercatorRect> boxes(tiles);
  Status read = for_each_tile(all, [&](std::uint32_t t, const std::vector<SortedPoint>& chunk) {
    std::uint32_t* counts = &cells->cell_offsets_[std::size_t{t} * (per_tile + 1)];
    geo::MercatorRect box{chunk[0].x, chunk[0].y, chunk[0].x, chunk[0].y};
    for (const SortedPoint& p : chunk) {
      const auto local = static_cast<std::uint32_t>((p.key >> cell_shift) & (per_tile - 1));
      ++counts[local + 1];
      box.min_x = std::min(box.min_x, p.x), box.max_x = std::max(box.max_x, p.x);
      box.min_y = std::min(box.min_y, p.y), box.max_y = std::max(box.max_y, p.y);
    }
    for (std::uint32_t i = 1; i <= per_tile; ++i) counts[i] += counts[i - 1];
    boxes[t] = box;
  });
  if (!read.ok()) return read.error();
  // The data's hull is the hull of the tiles' hulls. A tile whose four diagonal neighbours' points
  // all lie strictly beyond its own in both coordinates has no point on it: for every direction,
  // one neighbour's points lie strictly further that way. Only the other tiles are read again.
  auto enclosed = [&](std::uint32_t t) {
    const geo::TileId& id = cells->tiles_[t].id;
    const geo::MercatorRect& b = boxes[t];
    for (const int dx : {-1, 1}) {
      for (const int dy : {-1, 1}) {  // rows count from the north: dy = -1 is north, +y
        const std::ptrdiff_t n = cells->tile_index(
            {id.z, static_cast<std::uint32_t>(static_cast<std::int64_t>(id.x) + dx),
             static_cast<std::uint32_t>(static_cast<std::int64_t>(id.y) + dy)});
        if (n < 0) return false;
        const geo::MercatorRect& o = boxes[static_cast<std::size_t>(n)];
        const bool beyond_x = dx > 0 ? o.min_x > b.max_x : o.max_x < b.min_x;
        const bool beyond_y = dy < 0 ? o.min_y > b.max_y : o.max_y < b.min_y;
        if (!beyond_x || !beyond_y) return false;
      }
    }
    return true;
  };
  std::vector<std::uint32_t> open;
  for (std::uint32_t t = 0; t < tiles; ++t) {
    if (!enclosed(t)) open.push_back(t);
  }
  std::vector<std::vector<XY>> tile_hulls(tiles);
  read = for_each_tile(open, [&](std::uint32_t t, const std::vector<SortedPoint>& chunk) {
    std::vector<XY> points(chunk.size());
    for (std::size_t i = 0; i < chunk.size(); ++i) points[i] = {chunk[i].x, chunk[i].y};
    tile_hulls[t] = convex_hull(std::move(points));
  });
  if (!read.ok()) return read.error();
  std::vector<XY> hull_candidates;
  for (const auto& h : tile_hulls) {
    hull_candidates.insert(hull_candidates.end(), h.begin(), h.end());
  }
  cells->hull_ = convex_hull(std::move(hull_candidates));
  return std::shared_ptr<const PointCells>(std::move(cells));
}

std::ptrdiff_t PointCells::tile_index(const geo::TileId& id) const {
  if (id.z != level_) return -1;
  const auto it = index_.find(pack(id.x, id.y));
  return it == index_.end() ? -1 : static_cast<std::ptrdiff_t>(it->second);
}

std::pair<std::uint64_t, std::uint64_t> PointCells::cell_range(std::uint32_t cx,
                                                               std::uint32_t cy) const {
  const std::ptrdiff_t t = tile_index({level_, cx >> sub_shift_, cy >> sub_shift_});
  if (t < 0) return {0, 0};
  const std::uint32_t mask = (1u << sub_shift_) - 1;
  const auto local = static_cast<std::uint32_t>(subdivide::morton_interleave(cx & mask, cy & mask));
  const std::uint32_t per_tile = 1u << (2 * sub_shift_);
  const std::uint32_t* offsets = &cell_offsets_[static_cast<std::size_t>(t) * (per_tile + 1)];
  const auto& range = tiles_[static_cast<std::size_t>(t)];
  return {range.first + offsets[local], offsets[local + 1] - offsets[local]};
}

// ── One tile ───────────────────────────────────────────────────────────────────────────────────

namespace {

// The working memory of one tile, kept by a worker from tile to tile so that its capacity is
// reused (contents never carry over: build_tile clears each before use). One per thread.
struct TileBuffers {
  std::unordered_set<std::uint64_t> have;  // cells in S or pending
  // Cells whose points are in S → (first, count): where their points are in pts.
  std::unordered_map<std::uint64_t, std::pair<std::size_t, std::size_t>> in_s;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pending;
  std::vector<SortedPoint> pts;    // S, in gathering order
  std::vector<SortedPoint> own;    // the tile's own records, read at once
  std::vector<SortedPoint> chunk;  // one cell's records
  // Points of candidate cells (peek_pool[first, first + count) per cell key).
  std::unordered_map<std::uint64_t, std::pair<std::size_t, std::size_t>> peeked;
  std::vector<XY> peek_pool;
  std::vector<XY> xy;
  std::vector<detail::IndexTriangle> tris;
  // The halo rounds' triangulation (extended round by round), then the final one.
  detail::DelaunayBuilder delaunay;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> hull;   // grow_halo's local hull edges
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // edges crossing the border lines

  // Gives back what one unusual tile (a huge halo) grew, so a worker's memory between tiles stays
  // that of a typical tile.
  void release_oversized() {
    constexpr std::size_t kKeepBytes = std::size_t{16} << 20;
    auto release = [](auto& v) {
      if (v.capacity() * sizeof(v[0]) > kKeepBytes) std::decay_t<decltype(v)>().swap(v);
    };
    release(pts), release(own), release(chunk), release(peek_pool), release(xy), release(tris);
    release(hull), release(edges), release(pending);
    if (delaunay.memory_bytes() > kKeepBytes) delaunay = detail::DelaunayBuilder();
  }
};

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

Result<tile::TinTile> build_tile(const geo::TileId& id, const PointCells& cells,
                                 subdivide::SortedRunReader& reader,
                                 const FinestTileOptions& options, FinestTileStats* stats,
                                 TileBuffers& buffers) {
  if (id.z != cells.level()) {
    return invalid_argument("tile " + id.to_string() + " is not at the finest level " +
                            std::to_string(cells.level()));
  }
  const geo::MercatorRect R = id.bounds();
  const std::uint32_t cell_level = cells.cell_level();
  const std::uint32_t n = 1u << cells.sub_shift();
  const std::int64_t cells_per_side = std::int64_t{1} << cell_level;

  auto& have = buffers.have;
  auto& in_s = buffers.in_s;
  auto& pending = buffers.pending;
  have.clear();
  in_s.clear();
  pending.clear();
  auto want = [&](std::int64_t cx, std::int64_t cy) {
    if (cx < 0 || cy < 0 || cx >= cells_per_side || cy >= cells_per_side) return;
    const auto ux = static_cast<std::uint32_t>(cx), uy = static_cast<std::uint32_t>(cy);
    if (have.insert(pack(ux, uy)).second) pending.emplace_back(ux, uy);
  };
  const std::int64_t x0 = std::int64_t{id.x} * n, y0 = std::int64_t{id.y} * n;
  const std::ptrdiff_t own = cells.tile_index(id);
  // The halo's triangulation starts from a band along ∂R — the ring of neighbour cells and the
  // own cells touching ∂R — not from all own points: the output depends only on the global
  // triangles meeting ∂R and on the own points (taken from the tile's records below), and the
  // halo test (grow_halo) treats the own cells left out, the "hole", like any cell not yet
  // gathered: a circle that reaches one pulls it in, so its argument holds for the band as it
  // stands. The band needs an own point (the argument's hull case) and only pays where ∂R is
  // densely populated, so a tile with an empty own border cell (the data's edge, a gap) starts
  // from all its own cells, as before.
  //
  //   r r r r r r    r  the ring: neighbours' cells along R     } gathered in the first round
  //   r b b b b r    b  own border cells (each holds points)    }
  //   r b h h b r    h  the hole: own cells a cell or more inside ∂R, gathered only when a
  //   r b h h b r       circle of a triangle meeting ∂R reaches them (in band mode)
  //   r b b b b r
  //   r r r r r r    (n × n own cells; n = 16 but for the deepest levels)
  const bool band = own >= 0 && n > 2 && [&] {
    for (std::int64_t i = 0; i < n; ++i) {
      for (const auto& [cx, cy] : {std::pair{x0 + i, y0}, std::pair{x0 + i, y0 + n - 1},
                                   std::pair{x0, y0 + i}, std::pair{x0 + n - 1, y0 + i}}) {
        if (cells.cell_range(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy))
                .second == 0) {
          return false;
        }
      }
    }
    return true;
  }();
  auto in_hole = [&](std::int64_t cx, std::int64_t cy) {
    return band && cx > x0 && cx < x0 + n - 1 && cy > y0 && cy < y0 + n - 1;
  };
  for (std::int64_t cy = y0 - 1; cy <= y0 + n; ++cy) {
    for (std::int64_t cx = x0 - 1; cx <= x0 + n; ++cx) {
      if (!in_hole(cx, cy)) want(cx, cy);
    }
  }

  std::uint64_t circle_tests = 0;
  auto& pts = buffers.pts;
  auto& chunk = buffers.chunk;
  pts.clear();
  // Points of candidate cells, read once per tile and tested exactly before a cell joins.
  auto& peeked = buffers.peeked;
  auto& peek_pool = buffers.peek_pool;
  peeked.clear();
  peek_pool.clear();
  Status peek_error;
  // The span stays valid until the next peek (the pool may grow).
  auto peek = [&](std::uint32_t cx, std::uint32_t cy) -> std::span<const XY> {
    auto [it, fresh] = peeked.try_emplace(pack(cx, cy));
    if (fresh) {
      const auto [first, count] = cells.cell_range(cx, cy);
      it->second = {peek_pool.size(), 0};
      // After a failed read the chunk holds nothing of this cell: the cell stays empty, the
      // first error is kept (later peeks read nothing) and the round ends with it.
      if (count > 0 && peek_error.ok()) {
        if (Status st = reader.read(first, count, chunk); !st) {
          peek_error = st;
        } else {
          for (const auto& p : chunk) peek_pool.push_back({p.x, p.y});
          it->second.second = chunk.size();
        }
      }
    }
    return {peek_pool.data() + it->second.first, it->second.second};
  };
  // The initial gather (own cells + a ring of one cell) covers R grown by one cell width.
  const double cell_width = R.width() / n;
  const geo::MercatorRect inner{R.min_x - cell_width, R.min_y - cell_width, R.max_x + cell_width,
                                R.max_y + cell_width};
  // The band's hole cells together, from their own bounds (a circle missing this misses each).
  const geo::MercatorRect hole = [&] {
    if (!band) return geo::MercatorRect{};
    const auto sw = cell_rect(cell_level, static_cast<std::uint32_t>(x0 + 1),
                              static_cast<std::uint32_t>(y0 + n - 2));
    const auto ne = cell_rect(cell_level, static_cast<std::uint32_t>(x0 + n - 2),
                              static_cast<std::uint32_t>(y0 + 1));
    return geo::MercatorRect{sw.min_x, sw.min_y, ne.max_x, ne.max_y};
  }();
  // B: the only region whose points can matter for triangles kept in this tile.
  const double rmax = options.max_circumradius_tiles * R.width();
  const double rmax2 = rmax * rmax;
  const geo::MercatorRect B{R.min_x - 2 * rmax, R.min_y - 2 * rmax, R.max_x + 2 * rmax,
                            R.max_y + 2 * rmax};
  // Calls visit(cx, cy, points) for the not-yet-gathered, non-empty cells inside `box` (∩ B)
  // that meet `touches`.
  auto scan_cells = [&](geo::MercatorRect box, const auto& touches, const auto& visit) {
    box.min_x = std::max(box.min_x, B.min_x);
    box.min_y = std::max(box.min_y, B.min_y);
    box.max_x = std::min(box.max_x, B.max_x);
    box.max_y = std::min(box.max_y, B.max_y);
    if (box.min_x > box.max_x || box.min_y > box.max_y) return;
    const geo::TileId lo = geo::TileId::containing({box.min_x, box.max_y}, cells.level());
    const geo::TileId hi = geo::TileId::containing({box.max_x, box.min_y}, cells.level());
    for (std::uint32_t ty = lo.y; ty <= hi.y; ++ty) {
      for (std::uint32_t tx = lo.x; tx <= hi.x; ++tx) {
        const geo::TileId tid{cells.level(), tx, ty};
        if (cells.tile_index(tid) < 0 || !touches(tid.bounds())) continue;
        for (std::uint32_t cy = ty * n; cy < (ty + 1) * n; ++cy) {
          for (std::uint32_t cx = tx * n; cx < (tx + 1) * n; ++cx) {
            if (in_s.count(pack(cx, cy)) || !touches(cell_rect(cell_level, cx, cy))) continue;
            const std::span<const XY> cell_points = peek(cx, cy);
            if (!cell_points.empty()) visit(cx, cy, cell_points);
          }
        }
      }
    }
  };
  // Gathers what the current local triangulation says is missing: points inside the circumcircle
  // of a triangle meeting R's border ∂R, or beyond a local hull edge touching R (both only within
  // B).
  auto grow_halo = [&](const std::vector<XY>& v, const detail::DelaunayMesh& mesh) {
    const auto& tri = mesh.triangles;
    if (tri.empty()) {
      // Fewer than three points, or all on one line (a tile with one or two points of its own
      // at the data's edge): no triangle to ask, so everything in B may matter — gather it.
      scan_cells(
          B, [](const geo::MercatorRect&) { return true; },
          [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY>) { want(cx, cy); });
      return;
    }
    // The local hull's edges, directed counter-clockwise (no triangle beyond them), visited in
    // (from, to) order so that the cells are gathered in the same order on every run.
    auto& hull = buffers.hull;
    hull.clear();
    for (std::size_t t = 0; t < tri.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        if (mesh.neighbours[t][k] == detail::kNoNeighbour)
          hull.emplace_back(tri[t][(k + 1) % 3], tri[t][(k + 2) % 3]);
      }
    }
    std::sort(hull.begin(), hull.end());
    for (const auto& [ia, ib] : hull) {
      const XY &a = v[ia], &b = v[ib];
      if (!bbox_meets(a, b, b, R)) continue;
      // Nothing lies beyond an edge that no vertex of the global convex hull lies beyond.
      if (std::none_of(cells.hull().begin(), cells.hull().end(),
                       [&](const XY& h) { return kernel::orient2d(a, b, h) < 0.0; })) {
        continue;
      }
      // Outside is to the right of a→b (triangles are counter-clockwise).
      auto beyond = [&](const geo::MercatorRect& rect) {
        const XY corners[4] = {{rect.min_x, rect.min_y},
                               {rect.max_x, rect.min_y},
                               {rect.min_x, rect.max_y},
                               {rect.max_x, rect.max_y}};
        return std::any_of(std::begin(corners), std::end(corners),
                           [&](const XY& c) { return kernel::orient2d(a, b, c) <= 0.0; });
      };
      // Search outward from the edge in doubling steps: the points that matter are the nearest
      // ones beyond it; the circles of the triangles they form then pull in the rest.
      bool found = false;
      for (double d = 2 * cell_width;; d *= 2) {
        const geo::MercatorRect near{std::min(a.x, b.x) - d, std::min(a.y, b.y) - d,
                                     std::max(a.x, b.x) + d, std::max(a.y, b.y) + d};
        scan_cells(
            near, beyond, [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
              if (std::any_of(points.begin(), points.end(),
                              [&](const XY& p) { return kernel::orient2d(a, b, p) < 0.0; })) {
                want(cx, cy);
                found = true;
              }
            });
        if (found || (near.min_x <= B.min_x && near.min_y <= B.min_y && near.max_x >= B.max_x &&
                      near.max_y >= B.max_y)) {
          break;
        }
      }
    }
    // While the local hull still moves near R, the circles of its slivers are meaningless (and
    // huge): settle the hull first.
    if (!pending.empty()) return;
    // The triangles meeting ∂R whose circle reaches beyond `inner` (only there can a point not
    // yet gathered lie inside it). Small circles: test the points of the few cells each meets.
    // Many large ones (a dense, slightly curved line of points gives thousands of slivers whose
    // circles sweep along all of B): ask per point instead (ConflictSearch), once for the cells
    // their boxes cover.
    const double large_r = 2 * cell_width;
    std::vector<std::pair<Circle, std::size_t>> large;  // (circle, its triangle)
    auto scan_circle = [&](const XY& a, const XY& b, const XY& c, const Circle& circle) {
      geo::MercatorRect box = B;
      if (!circle.unbounded) {
        const double r = padded_radius(circle);
        box = {circle.cx - r, circle.cy - r, circle.cx + r, circle.cy + r};
      }
      scan_cells(
          box, [&](const geo::MercatorRect& rect) { return circle_meets(circle, rect); },
          [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
            if (std::any_of(points.begin(), points.end(), [&](const XY& p) {
                  ++circle_tests;
                  return detail::perturbed_incircle(a, b, c, p) > 0;
                })) {
              want(cx, cy);
            }
          });
    };
    for (std::size_t ti = 0; ti < tri.size(); ++ti) {
      const auto& t = tri[ti];
      const XY &a = v[t[0]], &b = v[t[1]], &c = v[t[2]];
      // Only triangles meeting the border ∂R are asked, not all triangles meeting R: the tile's
      // output depends only on the global triangles meeting ∂R (edge points, corners) and on the
      // own points, and those triangles are right once no missing point lies in the circle of a
      // local triangle meeting ∂R (with the hull test below, which is unchanged):
      //  - A local triangle t′ meeting ∂R with circumradius ≤ rmax has its circle inside B; if no
      //    point of B outside S lies in it, it is empty of all points, so it is global.
      //  - A global triangle t (circumradius ≤ rmax) meeting ∂R at x with a vertex missing from S
      //    (cavity argument): let S' = S ∪ vertices(t); t ∈ DT(S'), since its circle is empty.
      //    If x is inside conv(S), the triangles of DT(S) containing x cover a neighbourhood of x;
      //    were all of them still in DT(S'), t would overlap one of them and equal it, so t would
      //    be in DT(S). Hence inserting S' \ S (Bowyer–Watson, under the same perturbation)
      //    destroys one of them, t′, and the point whose insertion first does is in t′'s circle;
      //    it lies in t's circle ⊂ B, outside S, and t′ contains x ∈ ∂R. On conv(S)'s boundary
      //    the same holds unless t lies beyond the hull edge through x near x; outside conv(S)
      //    the segment from x to an own point (every tile has one, and R is convex) leaves
      //    conv(S) through a hull edge meeting R. Either way a vertex of t lies beyond a local
      //    hull edge meeting R, and the hull search below finds a missing point there.
      // So checking triangles strictly inside R only added work (and most of it: the slivers of
      // the data's hull where it runs through R, whose circles are huge).
      if (!bbox_meets_border(a, b, c, R)) continue;
      const Circle circle = circumcircle(a, b, c);
      // Circles inside R grown by one cell lie in cells gathered from the start (own + ring),
      // unless they reach the band's hole.
      if (!circle.unbounded) {
        const double r = padded_radius(circle);
        if (circle.cx - r > inner.min_x && circle.cx + r < inner.max_x &&
            circle.cy - r > inner.min_y && circle.cy + r < inner.max_y &&
            (!band || !circle_meets(circle, hole))) {
          continue;
        }
        if (r <= large_r) {
          scan_circle(a, b, c, circle);
          continue;
        }
      }
      large.emplace_back(circle, ti);
    }
    if (large.size() <= kFewLargeCircles) {
      for (const auto& [circle, ti] : large) {
        const auto& t = tri[ti];
        scan_circle(v[t[0]], v[t[1]], v[t[2]], circle);
      }
      return;
    }
    geo::MercatorRect cover{B.max_x, B.max_y, B.min_x, B.min_y};  // empty
    for (const auto& [circle, ti] : large) {
      if (circle.unbounded) {
        cover = B;
        break;
      }
      const double r = padded_radius(circle);
      cover.min_x = std::min(cover.min_x, circle.cx - r);
      cover.min_y = std::min(cover.min_y, circle.cy - r);
      cover.max_x = std::max(cover.max_x, circle.cx + r);
      cover.max_y = std::max(cover.max_y, circle.cy + r);
    }
    ConflictSearch search(v, mesh, R);
    scan_cells(
        cover, [](const geo::MercatorRect&) { return true; },
        [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
          for (const XY& p : points) {
            if (search.conflicts_near_r(p, circle_tests)) {
              want(cx, cy);
              break;
            }
          }
        });
  };
  auto& xy = buffers.xy;
  auto& tris = buffers.tris;
  auto& delaunay = buffers.delaunay;
  xy.clear();
  delaunay.clear();
  // The own cells' records come from one read of the whole tile (cells are contiguous ranges of
  // it), not one read per cell; they are appended in the same (gathering) order as before.
  auto& own_points = buffers.own;
  own_points.clear();
  std::uint64_t own_first = 0;
  if (own >= 0) {
    const auto& range = cells.tiles()[static_cast<std::size_t>(own)];
    own_first = range.first;
    if (Status s = reader.read(range.first, range.count, own_points); !s) return s.error();
  }
  auto is_own_cell = [&](std::uint32_t cx, std::uint32_t cy) {
    return own >= 0 && cx >= x0 && cx < x0 + n && cy >= y0 && cy < y0 + n;
  };
  int round = 0;
  for (;; ++round) {
    if (round >= options.max_rounds) {
      return Error(ErrorCode::internal, "tile " + id.quadkey() + ": halo did not converge in " +
                                            std::to_string(options.max_rounds) + " rounds");
    }
    for (const auto& [cx, cy] : pending) {
      const auto [first, count] = cells.cell_range(cx, cy);
      in_s.emplace(pack(cx, cy), std::pair{pts.size(), static_cast<std::size_t>(count)});
      if (count == 0) continue;
      if (is_own_cell(cx, cy)) {
        const auto begin = own_points.begin() + static_cast<std::ptrdiff_t>(first - own_first);
        pts.insert(pts.end(), begin, begin + static_cast<std::ptrdiff_t>(count));
        continue;
      }
      if (Status s = reader.read(first, count, chunk); !s) return s.error();
      pts.insert(pts.end(), chunk.begin(), chunk.end());
    }
    pending.clear();
    if (pts.size() > options.max_gathered_points) {
      return Error(ErrorCode::unsupported,
                   "tile " + id.quadkey() + ": its halo needs more than " +
                       std::to_string(options.max_gathered_points) +
                       " points (very uneven density); raise max_gathered_points");
    }
    // Each round inserts only its new cells' points into the same triangulation: the canonical
    // triangulation is unique, so it holds the triangles a fresh one of all points would (in
    // another order, which changes nothing: the cells a round asks for are a set, see grow_halo).
    for (std::size_t i = xy.size(); i < pts.size(); ++i) xy.push_back({pts[i].x, pts[i].y});
    delaunay.extend(xy);
    grow_halo(xy, delaunay.mesh());
    if (!peek_error.ok()) return peek_error.error();
    // Only cells that hold points matter.
    std::erase_if(pending, [&](const auto& cell) {
      return cells.cell_range(cell.first, cell.second).second == 0;
    });
    if (pending.empty()) break;
  }
  tris = delaunay.mesh().triangles;
  if (stats) {
    stats->gathered_points = pts.size();
    stats->rounds = round + 1;
    stats->circle_tests = circle_tests;
  }

  // ── Cut at the tile border ──
  tile::TinTile out;
  out.id = id;
  const XY corner_xy[4] = {
      {R.min_x, R.max_y}, {R.max_x, R.max_y}, {R.min_x, R.min_y}, {R.max_x, R.min_y}};
  bool corner_found[4] = {false, false, false, false};
  std::vector<tile::Vertex> north, east, south, west;
  out.source_points = own >= 0 ? cells.tiles()[static_cast<std::size_t>(own)].count : 0;
  // A data point closer than kMinVertexDistance to a side (either way, not near a corner) is
  // that side's vertex, moved onto it: the edges from it would cross the side a rounding error
  // away from it (two edge points beside it, and it beside the side: near-duplicate vertices in
  // any quantised encoding). Both neighbours see it (their rings share its cell) and move it
  // alike; the crossings beside it are left out below.
  std::vector<tile::Vertex> moved_north, moved_east, moved_south, moved_west;
  auto near = [](double a, double b) { return a != b && std::abs(a - b) < kMinVertexDistance; };
  auto inside_side = [](double v, double lo, double hi) {
    return v - lo >= kMinVertexDistance && hi - v >= kMinVertexDistance;
  };
  auto move_to_side = [&](const SortedPoint& p) {
    const bool along_x = inside_side(p.x, R.min_x, R.max_x);
    const bool along_y = inside_side(p.y, R.min_y, R.max_y);
    if (along_x && near(p.y, R.max_y)) {
      moved_north.push_back({p.x, R.max_y, p.z, p.weight});
    } else if (along_x && near(p.y, R.min_y)) {
      moved_south.push_back({p.x, R.min_y, p.z, p.weight});
    } else if (along_y && near(p.x, R.min_x)) {
      moved_west.push_back({R.min_x, p.y, p.z, p.weight});
    } else if (along_y && near(p.x, R.max_x)) {
      moved_east.push_back({R.max_x, p.y, p.z, p.weight});
    } else {
      return false;
    }
    return true;
  };
  auto classify = [&](const SortedPoint& p) {
    if (move_to_side(p)) return;
    const bool in_x = p.x > R.min_x && p.x < R.max_x;
    const bool in_y = p.y > R.min_y && p.y < R.max_y;
    if (in_x && in_y) {
      out.interior.push_back(to_vertex(p));
    } else if (in_x && p.y == R.max_y) {
      north.push_back(to_vertex(p));
    } else if (in_x && p.y == R.min_y) {
      south.push_back(to_vertex(p));
    } else if (in_y && p.x == R.min_x) {
      west.push_back(to_vertex(p));
    } else if (in_y && p.x == R.max_x) {
      east.push_back(to_vertex(p));
    } else {
      for (int k = 0; k < 4; ++k) {
        if (p.x == corner_xy[k].x && p.y == corner_xy[k].y) {
          out.corners[static_cast<std::size_t>(k)] = to_vertex(p);
          corner_found[k] = true;
        }
      }
    }
  };
  // The points in and on R come from the cells around it, visited row by row as the first halo
  // round once gathered them (the interior points' order is part of the output): own cells from
  // the tile's records (the band's hole is not in S), the ring's from S. Cells beyond the ring
  // lie a cell width away from R.
  for (std::int64_t cy = y0 - 1; cy <= y0 + n; ++cy) {
    for (std::int64_t cx = x0 - 1; cx <= x0 + n; ++cx) {
      if (cx < 0 || cy < 0 || cx >= cells_per_side || cy >= cells_per_side) continue;
      const auto ux = static_cast<std::uint32_t>(cx), uy = static_cast<std::uint32_t>(cy);
      std::span<const SortedPoint> cell_points;
      if (is_own_cell(ux, uy)) {
        const auto [first, count] = cells.cell_range(ux, uy);
        cell_points = {own_points.data() + (first - own_first), count};
      } else if (const auto it = in_s.find(pack(ux, uy)); it != in_s.end()) {
        cell_points = {pts.data() + it->second.first, it->second.second};
      }
      for (const SortedPoint& p : cell_points) classify(p);
    }
  }
  // Only triangles with circumradius ≤ rmax are part of the surface (larger ones span data gaps
  // or hug the data's outer boundary; both neighbours decide this identically). Of those, only
  // the ones that may meet ∂R matter below: an edge crossing a border segment strictly inside it
  // and a triangle holding a corner both meet ∂R, so the rest (most of them, inside R) go first,
  // before their circumradius is computed.
  std::erase_if(tris, [&](const detail::IndexTriangle& t) {
    return !bbox_meets_border(xy[t[0]], xy[t[1]], xy[t[2]], R) ||
           !(canonical_circumradius2(xy[t[0]], xy[t[1]], xy[t[2]]) <= rmax2);
  });
  // Edges crossing the four border lines: every undirected edge once (hull edges included — the
  // data's outer boundary may run through R).
  auto& edges = buffers.edges;
  edges.clear();
  for (const auto& t : tris) {
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t ia = t[k], ib = t[(k + 1) % 3];
      const SortedPoint& a = pts[ia];
      const SortedPoint& b = pts[ib];
      const bool spans_y = (a.y < R.max_y) != (b.y < R.max_y) || (a.y < R.min_y) != (b.y < R.min_y);
      const bool spans_x = (a.x < R.min_x) != (b.x < R.min_x) || (a.x < R.max_x) != (b.x < R.max_x);
      if (spans_x || spans_y) edges.emplace_back(std::min(ia, ib), std::max(ia, ib));
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  // Where an edge crosses a border line is decided exactly, from the orientation of the side's
  // two corners against the edge: through a corner (orientation 0) the corner itself is the
  // vertex there (corner_elevation interpolates it on the edge), so no edge point is made a
  // rounding error away from it; beyond the side, none either. Only the position along the side
  // is computed in floating point, and a crossing closer than kMinVertexDistance to a corner is
  // left out as well: on a lattice whose squares are centred on tile corners up to the rounding
  // of the input's coordinates (a DEM aligned with the tiles, its coordinates converted from
  // metres), the diagonals miss the corners by 1e-14, and such an edge point would be a
  // duplicate of the corner in any quantised encoding. Both neighbours decide it alike (the
  // same numbers), and the corner's interpolated height differs from the dropped point's by the
  // slope times that distance.
  auto crosses_side = [](const SortedPoint& a, const SortedPoint& b, const XY& from, const XY& to) {
    const double o_from = kernel::orient2d({a.x, a.y}, {b.x, b.y}, from);
    const double o_to = kernel::orient2d({a.x, a.y}, {b.x, b.y}, to);
    return o_from != 0 && o_to != 0 && (o_from > 0) != (o_to > 0);
  };
  for (const auto& [ia, ib] : edges) {
    const SortedPoint& a = pts[ia];
    const SortedPoint& b = pts[ib];
    for (double Y : {R.max_y, R.min_y}) {
      if (((a.y < Y && b.y > Y) || (a.y > Y && b.y < Y)) &&
          crosses_side(a, b, {R.min_x, Y}, {R.max_x, Y})) {
        const Crossing c = cross_horizontal(a, b, Y);
        if (c.along - R.min_x >= kMinVertexDistance && R.max_x - c.along >= kMinVertexDistance) {
          (Y == R.max_y ? north : south).push_back({c.along, Y, c.z, 0.0});
        }
      }
    }
    for (double X : {R.min_x, R.max_x}) {
      if (((a.x < X && b.x > X) || (a.x > X && b.x < X)) &&
          crosses_side(a, b, {X, R.min_y}, {X, R.max_y})) {
        const Crossing c = cross_vertical(a, b, X);
        if (c.along - R.min_y >= kMinVertexDistance && R.max_y - c.along >= kMinVertexDistance) {
          (X == R.min_x ? west : east).push_back({X, c.along, c.z, 0.0});
        }
      }
    }
  }
  // The crossings beside a moved point go; of moved points closer than kMinVertexDistance to
  // each other, the first in the side's order stays (both neighbours have the same lists).
  auto add_moved = [](std::vector<tile::Vertex>& side, std::vector<tile::Vertex>& moved,
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
  };
  add_moved(north, moved_north, true);
  add_moved(south, moved_south, true);
  add_moved(west, moved_west, false);
  add_moved(east, moved_east, false);
  auto by_x = [](const tile::Vertex& a, const tile::Vertex& b) {
    return a.x < b.x || (a.x == b.x && a.z < b.z);
  };
  auto by_y_desc = [](const tile::Vertex& a, const tile::Vertex& b) {
    return a.y > b.y || (a.y == b.y && a.z < b.z);
  };
  auto same_xy = [](const tile::Vertex& a, const tile::Vertex& b) {
    return a.x == b.x && a.y == b.y;
  };
  for (auto* side : {&north, &south}) {
    std::sort(side->begin(), side->end(), by_x);
    side->erase(std::unique(side->begin(), side->end(), same_xy), side->end());
  }
  for (auto* side : {&east, &west}) {
    std::sort(side->begin(), side->end(), by_y_desc);
    side->erase(std::unique(side->begin(), side->end(), same_xy), side->end());
  }
  for (int k = 0; k < 4; ++k) {
    if (corner_found[k]) continue;
    auto z = corner_elevation(corner_xy[k], pts, tris);
    const bool nodata = !z.has_value();
    if (nodata) {  // outside the data: a height continued from it, never 0 (a wall)
      auto nearest = nearest_input_height(cells, reader, id, k, chunk);
      if (!nearest) return nearest.error();
      z = *nearest;
    }
    out.corners[static_cast<std::size_t>(k)] = {corner_xy[k].x, corner_xy[k].y, *z, 0.0};
    out.corner_nodata[static_cast<std::size_t>(k)] = nodata;
  }
  out.north = std::move(north);
  out.east = std::move(east);
  out.south = std::move(south);
  out.west = std::move(west);

  // ── Re-triangulate corners + edge points + interior (the border is the hull) ──
  const std::vector<tile::Vertex> vertices = out.vertices();
  xy.resize(vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) xy[i] = {vertices[i].x, vertices[i].y};
  delaunay.clear();  // a cleared builder triangulates exactly as a new one (same order)
  delaunay.extend(xy);
  const auto& final_tris = delaunay.mesh().triangles;
  out.triangles.assign(final_tris.begin(), final_tris.end());
  out.update_z_range();
  return out;
}

}  // namespace

Result<tile::TinTile> build_finest_tile(const geo::TileId& id, const PointCells& cells,
                                        subdivide::SortedRunReader& reader,
                                        const FinestTileOptions& options, FinestTileStats* stats) {
  TileBuffers buffers;
  return build_tile(id, cells, reader, options, stats, buffers);
}

// ── All tiles, in parallel ─────────────────────────────────────────────────────────────────────

Result<TriangulateSummary> build_finest_tiles(const subdivide::SortedRun& run, unsigned threads,
                                              const TileSink& sink,
                                              const FinestTileOptions& options,
                                              const ProgressSink& progress) {
  auto cells_or = PointCells::build(run, threads);
  if (!cells_or) return cells_or.error();
  const std::shared_ptr<const PointCells> cells = *cells_or;
  const std::size_t total = cells->tiles().size();
  threads = std::max(
      1u, std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::size_t>(total, 1))));

  std::mutex mutex;
  std::condition_variable changed;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  TriangulateSummary summary;  // guarded by mutex, as are the two below
  Status failure;              // the first error
  unsigned finished = 0;       // workers that have returned
  auto fail = [&](Status s) {
    std::lock_guard lock(mutex);
    if (failure.ok()) failure = std::move(s);
    stop.store(true);
    changed.notify_all();
  };

  auto work = [&] {
    auto reader = subdivide::SortedRunReader::open(cells->run_path());
    TileBuffers buffers;  // this worker's, reused from tile to tile
    if (!reader) fail(reader.error());
    while (reader) {
      const std::size_t i = next.fetch_add(1);
      if (i >= total || stop.load()) break;
      fault::point("pass3.tile");
      FinestTileStats stats;
      auto tile = build_tile(cells->tiles()[i].id, *cells, *reader, options, &stats, buffers);
      buffers.release_oversized();
      if (!tile) {
        fail(tile.error());
        break;
      }
      if (stop.load()) break;
      if (Status s = sink(std::move(*tile)); !s) {
        fail(s);
        break;
      }
      std::lock_guard lock(mutex);
      ++summary.tiles;
      summary.gathered_points += stats.gathered_points;
      summary.max_rounds = std::max(summary.max_rounds, stats.rounds);
      summary.circle_tests += stats.circle_tests;
      changed.notify_all();
    }
  };
  // The exception barrier: whatever a tile or the sink throws is the run's error, and the worker
  // still counts as finished.
  auto worker = [&] {
    if (Status s = guarded("pass 3 worker", work); !s) fail(std::move(s));
    std::lock_guard lock(mutex);
    ++finished;
    changed.notify_all();
  };
  WorkerThreads pool("pass 3 worker", "pass3.tile");
  unsigned started = 0;
  for (; started < threads; ++started) {
    if (Status s = pool.start(worker); !s) {
      fail(std::move(s));  // the started workers stop at their next tile
      break;
    }
  }

  std::uint64_t reported = ~std::uint64_t{0};
  for (;;) {
    std::uint64_t done = 0;
    bool all_returned = false;
    {
      std::unique_lock lock(mutex);
      changed.wait(lock, [&] { return finished == started || summary.tiles != reported; });
      done = summary.tiles;
      all_returned = finished == started;
    }
    if (progress && done != reported && !progress({"triangulate", done, total, "tiles"})) {
      fail(Error(ErrorCode::cancelled, "ingest cancelled while triangulating"));
    }
    reported = done;
    if (all_returned) break;
  }
  (void)pool.join();  // the workers' failures went to fail()
  if (!failure.ok()) return failure.error();
  return summary;
}

}  // namespace tinstream::triangulate
