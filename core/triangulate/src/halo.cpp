#include "halo.hpp"

#include <algorithm>
#include <array>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace tinstream::triangulate::detail {
namespace {

// Above this many triangles with large circles in a halo round, ask per point (ConflictSearch).
constexpr std::size_t kFewLargeCircles = 16;

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
  ConflictSearch(const std::vector<XY>& v, const DelaunayMesh& mesh, const geo::MercatorRect& r)
      : v_(v), tri_(mesh.triangles), nb_(mesh.neighbours), r_(r), mark_(tri_.size(), 0) {}

  // True when p is inside the circle of a triangle meeting ∂R (conservatively true if the walk
  // made no progress, which cannot happen on a Delaunay mesh). `tests` counts in-circle tests.
  bool conflicts_near_r(const XY& p, std::uint64_t& tests) {
    if (tri_.empty()) return false;
    int exit_edge = -1;
    const std::uint32_t t = locate(p, exit_edge);
    if (t == kNoNeighbour) return true;
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
          std::tie(ct, ck) = next_hull_edge(ct, ck, forward);
          if (kernel::orient2d(at(ct, ck + 1), at(ct, ck + 2), p) > 0) break;
          push(ct);
        }
      }
    }
    // The queue grows while it is walked (push below): by index, not by iterator.
    for (std::size_t head = 0; head < queue_.size(); ++head) {  // NOLINT(modernize-loop-convert)
      const std::uint32_t q = queue_[head];
      ++tests;
      if (perturbed_incircle(at(q, 0), at(q, 1), at(q, 2), p) <= 0) continue;
      if (bbox_meets_border(at(q, 0), at(q, 1), at(q, 2), r_)) return true;
      for (std::uint32_t n : nb_[q]) {
        if (n != kNoNeighbour) push(n);
      }
    }
    return false;
  }

 private:
  // The triangle holding p (on its boundary included), or, for p outside the hull, the hull
  // triangle the walk left through (exit_edge: the edge, opposite that corner). kNoNeighbour when
  // the walk made no progress.
  std::uint32_t locate(const XY& p, int& exit_edge) const {
    std::uint32_t t = hint_;
    for (std::size_t steps = 0;; ++steps) {
      if (steps > tri_.size() + 8) return kNoNeighbour;
      int cross = -1;
      for (int j = 0; j < 3 && cross < 0; ++j) {
        const int k = (j + static_cast<int>(steps)) % 3;  // rotate the start: no cycling
        if (kernel::orient2d(at(t, k + 1), at(t, k + 2), p) < 0) cross = k;
      }
      if (cross < 0) return t;  // inside t or on its boundary
      const std::uint32_t next = nb_[t][static_cast<std::size_t>(cross)];
      if (next == kNoNeighbour) {
        exit_edge = cross;
        return t;
      }
      t = next;
    }
  }
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
  // adjacent_hull_edge, remembered: the points beyond one hull edge walk the same stretch of the
  // hull again and again (the turn around a hull vertex took a fifth of the halo's circle rule).
  std::pair<std::uint32_t, int> next_hull_edge(std::uint32_t t, int k, bool forward) {
    if (next_hull_.empty()) next_hull_.assign(tri_.size() * 6, kNoNeighbour);
    std::uint32_t& memo =
        next_hull_[(std::size_t{t} * 3 + static_cast<std::size_t>(k)) * 2 + (forward ? 1 : 0)];
    if (memo == kNoNeighbour) {
      const auto [nt, ne] = adjacent_hull_edge(t, k, forward);
      memo = nt * 3 + static_cast<std::uint32_t>(ne);
    }
    return {memo / 3, static_cast<int>(memo % 3)};
  }
  // The hull edge after (forward) or before the hull edge opposite corner k of t, counter-
  // clockwise along the hull, found by turning around its end (start) vertex.
  std::pair<std::uint32_t, int> adjacent_hull_edge(std::uint32_t t, int k, bool forward) const {
    const std::uint32_t pivot = tri_[t][static_cast<std::size_t>((k + (forward ? 2 : 1)) % 3)];
    const int turn = forward ? 2 : 1;  // the edge of a triangle leaving / entering the pivot
    int e = (k + (forward ? 1 : 2)) % 3;
    for (std::size_t i = 0; i < tri_.size(); ++i) {
      const std::uint32_t n = nb_[t][static_cast<std::size_t>(e)];
      if (n == kNoNeighbour) break;
      t = n;
      e = (index_of(t, pivot) + turn) % 3;
    }
    return {t, e};
  }

  const std::vector<XY>& v_;
  const std::vector<IndexTriangle>& tri_;
  const std::vector<std::array<std::uint32_t, 3>>& nb_;
  geo::MercatorRect r_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t stamp_ = 0, hint_ = 0;
  std::vector<std::uint32_t> queue_;
  // next_hull_edge's answers, 3·t + edge per (triangle, edge, direction); kNoNeighbour: not yet
  // asked. Filled on the first walk along the hull.
  std::vector<std::uint32_t> next_hull_;
};

}  // namespace

HaloGatherer::HaloGatherer(const geo::TileId& id, const PointCells& cells,
                           subdivide::SortedRunReader& reader, const FinestTileOptions& options,
                           TileBuffers& buffers)
    : id_(id),
      cells_(cells),
      reader_(reader),
      options_(options),
      buf_(buffers),
      r_(id.bounds()),
      cell_level_(cells.cell_level()),
      n_(std::int64_t{1} << cells.sub_shift()),
      cells_per_side_(std::int64_t{1} << cells.cell_level()),
      x0_(std::int64_t{id.x} * n_),
      y0_(std::int64_t{id.y} * n_),
      own_(cells.tile_index(id)),
      band_(band_fits()),
      cell_width_(r_.width() / static_cast<double>(n_)),
      inner_{r_.min_x - cell_width_, r_.min_y - cell_width_, r_.max_x + cell_width_,
             r_.max_y + cell_width_},
      hole_(hole_rect()),
      rmax_(options.max_circumradius_tiles * r_.width()),
      b_{r_.min_x - 2 * rmax_, r_.min_y - 2 * rmax_, r_.max_x + 2 * rmax_, r_.max_y + 2 * rmax_} {
  buf_.have.clear();
  buf_.in_s.clear();
  buf_.pending.clear();
  buf_.pts.clear();
  buf_.peeked.clear();
  buf_.peek_pool.clear();
  buf_.xy.clear();
  buf_.delaunay.clear();
  buf_.own.clear();
  // The first round: the tile's cells (but the band's hole) and the ring around them.
  for_each_cell_around([&](std::uint32_t cx, std::uint32_t cy) {
    if (!in_hole(cx, cy)) want(cx, cy);
  });
}

// Band mode only pays where ∂R is densely populated, and the argument needs an own point (its hull
// case): a tile with an empty own border cell (the data's edge, a gap) gathers all its own cells.
bool HaloGatherer::band_fits() const {
  if (own_ < 0 || n_ <= 2) return false;
  for (std::int64_t i = 0; i < n_; ++i) {
    for (const auto& [cx, cy] : {std::pair{x0_ + i, y0_}, std::pair{x0_ + i, y0_ + n_ - 1},
                                 std::pair{x0_, y0_ + i}, std::pair{x0_ + n_ - 1, y0_ + i}}) {
      if (cells_.cell_range(static_cast<std::uint32_t>(cx), static_cast<std::uint32_t>(cy))
              .second == 0) {
        return false;
      }
    }
  }
  return true;
}

// From the hole cells' own bounds (a circle missing this misses each).
geo::MercatorRect HaloGatherer::hole_rect() const {
  if (!band_) return geo::MercatorRect{};
  const auto sw = cell_rect(cell_level_, static_cast<std::uint32_t>(x0_ + 1),
                            static_cast<std::uint32_t>(y0_ + n_ - 2));
  const auto ne = cell_rect(cell_level_, static_cast<std::uint32_t>(x0_ + n_ - 2),
                            static_cast<std::uint32_t>(y0_ + 1));
  return geo::MercatorRect{sw.min_x, sw.min_y, ne.max_x, ne.max_y};
}

void HaloGatherer::want(std::int64_t cx, std::int64_t cy) {
  if (cx < 0 || cy < 0 || cx >= cells_per_side_ || cy >= cells_per_side_) return;
  const auto ux = static_cast<std::uint32_t>(cx), uy = static_cast<std::uint32_t>(cy);
  if (buf_.have.insert(pack(ux, uy)).second) buf_.pending.emplace_back(ux, uy);
}

bool HaloGatherer::in_hole(std::int64_t cx, std::int64_t cy) const {
  return band_ && cx > x0_ && cx < x0_ + n_ - 1 && cy > y0_ && cy < y0_ + n_ - 1;
}

bool HaloGatherer::is_own_cell(std::uint32_t cx, std::uint32_t cy) const {
  return own_ >= 0 && cx >= x0_ && cx < x0_ + n_ && cy >= y0_ && cy < y0_ + n_;
}

std::span<const XY> HaloGatherer::peek(std::uint32_t cx, std::uint32_t cy) {
  auto [it, fresh] = buf_.peeked.try_emplace(pack(cx, cy));
  if (fresh) {
    const auto [first, count] = cells_.cell_range(cx, cy);
    it->second = {buf_.peek_pool.size(), 0};
    // After a failed read the chunk holds nothing of this cell: the cell stays empty, the first
    // error is kept (later peeks read nothing) and the round ends with it.
    if (count > 0 && peek_error_.ok()) {
      if (Status st = reader_.read(first, count, buf_.chunk); !st) {
        peek_error_ = st;
      } else {
        for (const auto& p : buf_.chunk) buf_.peek_pool.push_back({p.x, p.y});
        it->second.second = buf_.chunk.size();
      }
    }
  }
  return {buf_.peek_pool.data() + it->second.first, it->second.second};
}

template <typename Touches, typename Visit>
void HaloGatherer::scan_cells(geo::MercatorRect box, const Touches& touches, const Visit& visit) {
  box.min_x = std::max(box.min_x, b_.min_x);
  box.min_y = std::max(box.min_y, b_.min_y);
  box.max_x = std::min(box.max_x, b_.max_x);
  box.max_y = std::min(box.max_y, b_.max_y);
  if (box.min_x > box.max_x || box.min_y > box.max_y) return;
  const geo::TileId lo = geo::TileId::containing({box.min_x, box.max_y}, cells_.level());
  const geo::TileId hi = geo::TileId::containing({box.max_x, box.min_y}, cells_.level());
  const auto n = static_cast<std::uint32_t>(n_);
  for (std::uint32_t ty = lo.y; ty <= hi.y; ++ty) {
    for (std::uint32_t tx = lo.x; tx <= hi.x; ++tx) {
      const geo::TileId tid{cells_.level(), tx, ty};
      if (cells_.tile_index(tid) < 0 || !touches(tid.bounds())) continue;
      for (std::uint32_t cy = ty * n; cy < (ty + 1) * n; ++cy) {
        for (std::uint32_t cx = tx * n; cx < (tx + 1) * n; ++cx) {
          if (buf_.in_s.count(pack(cx, cy)) || !touches(cell_rect(cell_level_, cx, cy))) continue;
          const std::span<const XY> cell_points = peek(cx, cy);
          if (!cell_points.empty()) visit(cx, cy, cell_points);
        }
      }
    }
  }
}

Status HaloGatherer::gather() {
  // The own cells' records come from one read of the whole tile (cells are contiguous ranges of
  // it), not one read per cell.
  if (own_ >= 0) {
    const auto& range = cells_.tiles()[static_cast<std::size_t>(own_)];
    own_first_ = range.first;
    if (Status s = reader_.read(range.first, range.count, buf_.own); !s) return s;
  }
  for (rounds_ = 0;; ++rounds_) {
    if (rounds_ >= options_.max_rounds) {
      return Error(ErrorCode::internal, "tile " + id_.quadkey() + ": halo did not converge in " +
                                            std::to_string(options_.max_rounds) + " rounds");
    }
    if (Status s = read_pending(); !s) return s;
    // Each round inserts only its new cells' points into the same triangulation: the canonical
    // triangulation is unique, so it holds the triangles a fresh one of all points would (in
    // another order, which changes nothing: the cells a round asks for are a set).
    for (std::size_t i = buf_.xy.size(); i < buf_.pts.size(); ++i) {
      buf_.xy.push_back({buf_.pts[i].x, buf_.pts[i].y});
    }
    buf_.delaunay.extend(buf_.xy);
    grow_halo();
    if (!peek_error_.ok()) return peek_error_;
    // Only cells that hold points matter.
    std::erase_if(buf_.pending, [&](const auto& cell) {
      return cells_.cell_range(cell.first, cell.second).second == 0;
    });
    if (buf_.pending.empty()) break;
  }
  ++rounds_;
  return {};
}

// Appends the pending cells' points to S (own cells' from the tile's records).
Status HaloGatherer::read_pending() {
  for (const auto& [cx, cy] : buf_.pending) {
    const auto [first, count] = cells_.cell_range(cx, cy);
    buf_.in_s.emplace(pack(cx, cy), std::pair{buf_.pts.size(), static_cast<std::size_t>(count)});
    if (count == 0) continue;
    if (is_own_cell(cx, cy)) {
      const auto begin = buf_.own.begin() + static_cast<std::ptrdiff_t>(first - own_first_);
      buf_.pts.insert(buf_.pts.end(), begin, begin + static_cast<std::ptrdiff_t>(count));
      continue;
    }
    if (Status s = reader_.read(first, count, buf_.chunk); !s) return s;
    buf_.pts.insert(buf_.pts.end(), buf_.chunk.begin(), buf_.chunk.end());
  }
  buf_.pending.clear();
  if (buf_.pts.size() > options_.max_gathered_points) {
    return Error(ErrorCode::unsupported,
                 "tile " + id_.quadkey() + ": its halo needs more than " +
                     std::to_string(options_.max_gathered_points) +
                     " points (very uneven density); raise max_gathered_points");
  }
  return {};
}

std::span<const SortedPoint> HaloGatherer::cell_points(std::uint32_t cx, std::uint32_t cy) const {
  if (is_own_cell(cx, cy)) {
    const auto [first, count] = cells_.cell_range(cx, cy);
    return {buf_.own.data() + (first - own_first_), count};
  }
  if (const auto it = buf_.in_s.find(pack(cx, cy)); it != buf_.in_s.end()) {
    return {buf_.pts.data() + it->second.first, it->second.second};
  }
  return {};
}

void HaloGatherer::grow_halo() {
  const std::vector<XY>& v = buf_.xy;
  const DelaunayMesh& mesh = buf_.delaunay.mesh();
  if (mesh.triangles.empty()) {
    // Fewer than three points, or all on one line (a tile with one or two points of its own at
    // the data's edge): no triangle to ask, so everything in B may matter — gather it.
    scan_cells(
        b_, [](const geo::MercatorRect&) { return true; },
        [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY>) { want(cx, cy); });
    return;
  }
  settle_hull(v, mesh);
  // While the local hull still moves near R, the circles of its slivers are meaningless (and
  // huge): settle the hull first.
  if (!buf_.pending.empty()) return;
  pull_circles(v, mesh);
}

// The (hull) rule: for each local hull edge meeting R that some vertex of the global hull lies
// beyond, the nearest non-empty cells beyond it.
void HaloGatherer::settle_hull(const std::vector<XY>& v, const DelaunayMesh& mesh) {
  // The local hull's edges, directed counter-clockwise (no triangle beyond them), visited in
  // (from, to) order so that the cells are gathered in the same order on every run.
  const auto& tri = mesh.triangles;
  auto& hull = buf_.hull;
  hull.clear();
  for (std::size_t t = 0; t < tri.size(); ++t) {
    for (std::size_t k = 0; k < 3; ++k) {
      if (mesh.neighbours[t][k] == kNoNeighbour)
        hull.emplace_back(tri[t][(k + 1) % 3], tri[t][(k + 2) % 3]);
    }
  }
  std::sort(hull.begin(), hull.end());
  for (const auto& [ia, ib] : hull) {
    const XY &a = v[ia], &b = v[ib];
    if (!bbox_meets(a, b, b, r_)) continue;
    // Nothing lies beyond an edge that no vertex of the global convex hull lies beyond.
    if (std::none_of(cells_.hull().begin(), cells_.hull().end(),
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
    for (double d = 2 * cell_width_;; d *= 2) {
      const geo::MercatorRect near{std::min(a.x, b.x) - d, std::min(a.y, b.y) - d,
                                   std::max(a.x, b.x) + d, std::max(a.y, b.y) + d};
      scan_cells(near, beyond, [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
        if (std::any_of(points.begin(), points.end(),
                        [&](const XY& p) { return kernel::orient2d(a, b, p) < 0.0; })) {
          want(cx, cy);
          found = true;
        }
      });
      if (found || (near.min_x <= b_.min_x && near.min_y <= b_.min_y && near.max_x >= b_.max_x &&
                    near.max_y >= b_.max_y)) {
        break;
      }
    }
  }
}

// The (circle) rule: the triangles meeting ∂R whose circle reaches beyond `inner` (only there can
// a point not yet gathered lie inside it). Small circles: test the points of the few cells each
// meets. Many large ones (a dense, slightly curved line of points gives thousands of slivers whose
// circles sweep along all of B): ask per point instead (ConflictSearch), once for the cells their
// boxes cover.
void HaloGatherer::pull_circles(const std::vector<XY>& v, const DelaunayMesh& mesh) {
  const auto& tri = mesh.triangles;
  const double large_r = 2 * cell_width_;
  std::vector<std::pair<Circle, std::size_t>> large;  // (circle, its triangle)
  for (std::size_t ti = 0; ti < tri.size(); ++ti) {
    const auto& t = tri[ti];
    const XY &a = v[t[0]], &b = v[t[1]], &c = v[t[2]];
    if (!bbox_meets_border(a, b, c, r_)) continue;  // see the header: only ∂R is asked
    const Circle circle = circumcircle(a, b, c);
    // Circles inside R grown by one cell lie in cells gathered from the start (own + ring),
    // unless they reach the band's hole.
    if (!circle.unbounded) {
      const double r = padded_radius(circle);
      if (circle.cx - r > inner_.min_x && circle.cx + r < inner_.max_x &&
          circle.cy - r > inner_.min_y && circle.cy + r < inner_.max_y &&
          (!band_ || !circle_meets(circle, hole_))) {
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
  geo::MercatorRect cover{b_.max_x, b_.max_y, b_.min_x, b_.min_y};  // empty
  for (const auto& [circle, ti] : large) {
    if (circle.unbounded) {
      cover = b_;
      break;
    }
    const double r = padded_radius(circle);
    cover.min_x = std::min(cover.min_x, circle.cx - r);
    cover.min_y = std::min(cover.min_y, circle.cy - r);
    cover.max_x = std::max(cover.max_x, circle.cx + r);
    cover.max_y = std::max(cover.max_y, circle.cy + r);
  }
  ConflictSearch search(v, mesh, r_);
  scan_cells(
      cover, [](const geo::MercatorRect&) { return true; },
      [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
        for (const XY& p : points) {
          if (search.conflicts_near_r(p, circle_tests_)) {
            want(cx, cy);
            break;
          }
        }
      });
}

// The cells holding a point inside the circle of abc (perturbed, as the triangulation decides).
void HaloGatherer::scan_circle(const XY& a, const XY& b, const XY& c, const Circle& circle) {
  geo::MercatorRect box = b_;
  if (!circle.unbounded) {
    const double r = padded_radius(circle);
    box = {circle.cx - r, circle.cy - r, circle.cx + r, circle.cy + r};
  }
  scan_cells(
      box, [&](const geo::MercatorRect& rect) { return circle_meets(circle, rect); },
      [&](std::uint32_t cx, std::uint32_t cy, std::span<const XY> points) {
        if (std::any_of(points.begin(), points.end(), [&](const XY& p) {
              ++circle_tests_;
              return perturbed_incircle(a, b, c, p) > 0;
            })) {
          want(cx, cy);
        }
      });
}

}  // namespace tinstream::triangulate::detail
