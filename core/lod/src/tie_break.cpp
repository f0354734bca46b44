#include "tie_break.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "tinstream/kernel/predicates.hpp"

namespace tinstream::lod::detail {

namespace {

using tile::Vertex;

kernel::XY xy(const Vertex& v) { return {v.x, v.y}; }

// The points, bucketed on a uniform grid over their bounding box.
class PointGrid {
 public:
  explicit PointGrid(std::span<const std::span<const Vertex>> lists) {
    std::size_t count = 0;
    for (const auto& list : lists) {
      for (const Vertex& p : list) {
        if (count++ == 0) min_x_ = max_x_ = p.x, min_y_ = max_y_ = p.y;
        min_x_ = std::min(min_x_, p.x), max_x_ = std::max(max_x_, p.x);
        min_y_ = std::min(min_y_, p.y), max_y_ = std::max(max_y_, p.y);
      }
    }
    if (count == 0) return;
    const auto side = static_cast<std::size_t>(std::sqrt(static_cast<double>(count) / 4.0));
    n_ = std::clamp<std::size_t>(side, 1, 1024);
    first_.assign(n_ * n_ + 1, 0);
    for (const auto& list : lists) {
      for (const Vertex& p : list) ++first_[cell(p.x, p.y) + 1];
    }
    for (std::size_t i = 1; i < first_.size(); ++i) first_[i] += first_[i - 1];
    points_.resize(count);
    std::vector<std::size_t> next(first_.begin(), first_.end() - 1);
    for (const auto& list : lists) {
      for (const Vertex& p : list) points_[next[cell(p.x, p.y)]++] = &p;
    }
  }

  // Calls f(point) for every point whose bucket meets the box [x0, x1] × [y0, y1].
  template <typename F>
  void for_each_in(double x0, double y0, double x1, double y1, F&& f) const {
    if (points_.empty() || x1 < min_x_ || x0 > max_x_ || y1 < min_y_ || y0 > max_y_) return;
    const std::size_t i0 = index(x0, min_x_, max_x_), i1 = index(x1, min_x_, max_x_);
    const std::size_t j0 = index(y0, min_y_, max_y_), j1 = index(y1, min_y_, max_y_);
    for (std::size_t j = j0; j <= j1; ++j) {
      for (std::size_t i = i0; i <= i1; ++i) {
        const std::size_t c = j * n_ + i;
        for (std::size_t k = first_[c]; k < first_[c + 1]; ++k) f(*points_[k]);
      }
    }
  }

 private:
  std::size_t index(double v, double lo, double hi) const {
    if (!(hi > lo)) return 0;
    const double f = (v - lo) / (hi - lo) * static_cast<double>(n_);
    if (!(f > 0)) return 0;
    return std::min(n_ - 1, static_cast<std::size_t>(f));
  }
  std::size_t cell(double x, double y) const {
    return index(y, min_y_, max_y_) * n_ + index(x, min_x_, max_x_);
  }

  double min_x_ = 0, max_x_ = 0, min_y_ = 0, max_y_ = 0;
  std::size_t n_ = 1;
  std::vector<std::size_t> first_;     // bucket c holds points_[first_[c] … first_[c + 1])
  std::vector<const Vertex*> points_;  // by bucket
};

// A triangle (counter-clockwise) named from its lowest vertex (by x, then y), so that the same
// triangle gives the same bits whichever vertex it was named from. Otherwise the rounding of the
// two drawings of a quadrilateral differs (by ~1e-12 m), and a quadrilateral whose diagonals are
// equally good flipped on every sweep (each drawing made the other look better).
class Drawn {
 public:
  Drawn(const Vertex& a, const Vertex& b, const Vertex& c) {
    const auto lower = [](const Vertex& u, const Vertex& w) {
      return u.x < w.x || (u.x == w.x && u.y < w.y);
    };
    if (lower(b, a) && !lower(c, b)) {
      a_ = &b, b_ = &c, c_ = &a;
    } else if (lower(c, a) && lower(c, b)) {
      a_ = &c, b_ = &a, c_ = &b;
    } else {
      a_ = &a, b_ = &b, c_ = &c;
    }
  }

  // |z − the plane at p| when p lies in the triangle (its edges included), else a negative
  // number.
  double error(const Vertex& p) const {
    const Vertex &a = *a_, &b = *b_, &c = *c_;
    const double w0 = (b.x - p.x) * (c.y - p.y) - (b.y - p.y) * (c.x - p.x);
    const double w1 = (c.x - p.x) * (a.y - p.y) - (c.y - p.y) * (a.x - p.x);
    const double w2 = (a.x - p.x) * (b.y - p.y) - (a.y - p.y) * (b.x - p.x);
    if (w0 < 0 || w1 < 0 || w2 < 0) return -1;
    const double sum = w0 + w1 + w2;
    if (!(sum > 0)) return -1;
    return std::abs((w0 * a.z + w1 * b.z + w2 * c.z) / sum - p.z);
  }

 private:
  const Vertex* a_;
  const Vertex* b_;
  const Vertex* c_;
};

// The maximum error over the points inside the quadrilateral, drawn as triangles (a, b, c) and
// (b, a, d) (diagonal a-b) and as (a, d, c) and (d, b, c) (diagonal c-d); -1 where no point is.
std::array<double, 2> quad_errors(const PointGrid& grid, const Vertex& a, const Vertex& b,
                                  const Vertex& c, const Vertex& d) {
  std::array<double, 2> worst{-1, -1};
  const double x0 = std::min({a.x, b.x, c.x, d.x}), x1 = std::max({a.x, b.x, c.x, d.x});
  const double y0 = std::min({a.y, b.y, c.y, d.y}), y1 = std::max({a.y, b.y, c.y, d.y});
  const Drawn abc(a, b, c), bad(b, a, d), adc(a, d, c), dbc(d, b, c);
  grid.for_each_in(x0, y0, x1, y1, [&](const Vertex& p) {
    if (p.x < x0 || p.x > x1 || p.y < y0 || p.y > y1) return;  // a bucket's point outside
    const double now = std::max(abc.error(p), bad.error(p));
    if (now < 0) return;  // outside the quadrilateral
    worst[0] = std::max(worst[0], now);
    worst[1] = std::max(worst[1], std::max(adc.error(p), dbc.error(p)));
  });
  return worst;
}

// Which pairs of this tile's vertices the finer tiles join by an edge (vertices matched by their
// coordinates, bit for bit).
class FinerEdges {
 public:
  FinerEdges(const std::vector<Vertex>& own, std::span<const tile::TinTile* const> finer) {
    std::unordered_map<std::pair<double, double>, std::uint32_t, XYHash> index;
    index.reserve(own.size());
    for (std::size_t i = 0; i < own.size(); ++i)
      index.emplace(std::pair{own[i].x, own[i].y}, static_cast<std::uint32_t>(i));
    std::vector<std::uint32_t> mapped;
    for (const tile::TinTile* t : finer) {
      mapped.assign(t->vertex_count(), kAbsent);
      for (std::size_t i = 0; i < mapped.size(); ++i) {
        const Vertex& p = t->vertex(i);
        if (auto it = index.find({p.x, p.y}); it != index.end()) mapped[i] = it->second;
      }
      for (const auto& tri : t->triangles) {
        for (std::size_t i = 0; i < 3; ++i) {
          const std::uint32_t p = mapped[tri[i]], q = mapped[tri[(i + 1) % 3]];
          if (p != kAbsent && q != kAbsent) keys_.push_back(key(p, q));
        }
      }
    }
    std::sort(keys_.begin(), keys_.end());
    keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
  }
  bool contains(std::uint32_t p, std::uint32_t q) const {
    return std::binary_search(keys_.begin(), keys_.end(), key(p, q));
  }

 private:
  static constexpr std::uint32_t kAbsent = ~std::uint32_t{0};
  struct XYHash {
    std::size_t operator()(const std::pair<double, double>& p) const {
      // The bits, mixed (std::hash<double> hashes the bytes one by one); + 0.0 makes -0 into +0,
      // which compares equal.
      const std::uint64_t h = std::bit_cast<std::uint64_t>(p.first + 0.0) * 0x9E3779B97F4A7C15ULL ^
                              std::bit_cast<std::uint64_t>(p.second + 0.0);
      return static_cast<std::size_t>(h ^ h >> 29);
    }
  };
  static std::uint64_t key(std::uint32_t p, std::uint32_t q) {
    return std::uint64_t{std::min(p, q)} << 32 | std::max(p, q);
  }
  std::vector<std::uint64_t> keys_;  // sorted, unique (a hash set's node per edge cost more)
};

}  // namespace

std::size_t break_delaunay_ties(tile::TinTile& tile,
                                std::span<const std::span<const Vertex>> points,
                                std::span<const tile::TinTile* const> finer,
                                std::span<const std::span<const Vertex>> own) {
  if (tile.triangles.size() < 2) return 0;
  const std::vector<Vertex> v = tile.vertices();
  std::vector<std::uint8_t> nodata(v.size(), 0);
  for (std::size_t c = 0; c < 4 && c < v.size(); ++c) nodata[c] = tile.corner_nodata[c] ? 1 : 0;
  // Built on first use: most tiles (LiDAR, reprojected grids) have no exact tie at all.
  std::optional<PointGrid> grid, own_grid;
  std::optional<FinerEdges> finer_edges;
  std::size_t flips = 0;
  std::vector<std::size_t> start, fill, out;  // half-edges t * 3 + i grouped by start vertex
  for (int sweep = 0; sweep < 8; ++sweep) {
    // The half-edges by start vertex (edge i of t runs v[i] → v[i + 1]), so that each interior
    // edge p → q (p < q) finds its other side q → p among q's few.
    start.assign(v.size() + 1, 0);
    for (const auto& tri : tile.triangles) {
      for (const std::uint32_t p : tri) ++start[p + 1];
    }
    for (std::size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
    out.resize(tile.triangles.size() * 3);
    fill.assign(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < tile.triangles.size(); ++t) {
      for (std::size_t i = 0; i < 3; ++i) out[fill[tile.triangles[t][i]]++] = t * 3 + i;
    }
    std::vector<std::uint8_t> touched(tile.triangles.size(), 0);
    std::size_t flipped = 0;
    for (std::size_t h = 0; h < out.size(); ++h) {
      const std::size_t t = out[h] / 3, i = out[h] % 3;
      const std::uint32_t p0 = tile.triangles[t][i], q0 = tile.triangles[t][(i + 1) % 3];
      if (p0 > q0) continue;  // each edge once, from its smaller end
      std::size_t u = 0, j = 3;
      for (std::size_t k = start[q0]; k < start[q0 + 1]; ++k) {
        const std::size_t w = out[k] / 3, m = out[k] % 3;
        if (tile.triangles[w][(m + 1) % 3] == p0) u = w, j = m;
      }
      if (j == 3) continue;  // on the tile's border
      if (touched[t] || touched[u]) continue;
      // t has the edge as a → b with c opposite; u has it as b → a with d opposite.
      const std::uint32_t a = p0, b = q0, c = tile.triangles[t][(i + 2) % 3];
      const std::uint32_t d = tile.triangles[u][(j + 2) % 3];
      if (tile.triangles[u][j] != b || tile.triangles[u][(j + 1) % 3] != a) continue;
      if (nodata[a] || nodata[b] || nodata[c] || nodata[d]) continue;
      const kernel::XY pa = xy(v[a]), pb = xy(v[b]), pc = xy(v[c]), pd = xy(v[d]);
      if (!(kernel::orient2d(pa, pb, pc) > 0) || kernel::incircle(pa, pb, pc, pd) != 0) continue;
      // Strictly convex: a and b on opposite sides of c-d (else one diagonal is outside).
      if (!(kernel::orient2d(pc, pd, pa) < 0 && kernel::orient2d(pc, pd, pb) > 0)) continue;
      // The other diagonal when it is better at the known points; on a tie there (or with no
      // point inside), when a finer tile drew it and not this one (it saw more of the data).
      if (!grid) grid.emplace(points);
      const auto e = quad_errors(*grid, v[a], v[b], v[c], v[d]);
      bool flip = e[1] < e[0];
      bool settled = flip || e[1] > e[0];
      if (!settled && !finer.empty()) {
        if (!finer_edges) finer_edges.emplace(v, finer);
        const bool other = finer_edges->contains(c, d);
        settled = other != finer_edges->contains(a, b);
        flip = settled && other;
      }
      if (!settled && !own.empty()) {
        if (!own_grid) own_grid.emplace(own);
        const auto o = quad_errors(*own_grid, v[a], v[b], v[c], v[d]);
        flip = o[1] < o[0];
      }
      if (!flip) continue;
      tile.triangles[t] = {a, d, c};
      tile.triangles[u] = {d, b, c};
      touched[t] = touched[u] = 1;
      ++flipped;
    }
    flips += flipped;
    if (flipped == 0) break;
  }
  return flips;
}

}  // namespace tinstream::lod::detail
