// A bucket grid over the triangles of one or more tiles, for point location and overlap queries.
// Built once, read-only afterwards.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "tinstream/geo/tile_id.hpp"
#include "tinstream/tile/tin_tile.hpp"

namespace tinstream::lod::detail {

struct P2 {
  double x, y;
};

// One triangle with its corner positions and heights (counter-clockwise).
struct FlatTriangle {
  P2 p[3];
  double z[3];
  double min_x, min_y, max_x, max_y;
};

// Linear interpolation at q in triangle t with barycentric weights clamped to the triangle (q is
// inside up to rounding). *min_weight (optional) receives the smallest unclamped weight (≥ 0
// inside). Each corner's weight is the cross product of its opposite edge with q measured from
// that edge's end nearer q: small terms where q is near the edge, so a sliver reaching a far
// corner (a level-0 tile's corners at ±1, its data a few metres wide) does not see q on its
// side of a data edge that q lies 7 mm beyond (measured from the far corner, that corner's
// weight came out 5.5e-17 where it is -2.2e-10, and q read the edge's height, 0.03 m off).
inline double plane_at(const FlatTriangle& t, double qx, double qy, double* min_weight = nullptr) {
  const double det =
      (t.p[1].x - t.p[0].x) * (t.p[2].y - t.p[0].y) - (t.p[1].y - t.p[0].y) * (t.p[2].x - t.p[0].x);
  if (!(det != 0)) {
    if (min_weight) *min_weight = -std::numeric_limits<double>::infinity();
    return t.z[0];
  }
  double w[3];
  for (int k = 0; k < 3; ++k) {
    const P2& u = t.p[(k + 1) % 3];
    const P2& v = t.p[(k + 2) % 3];
    const double du = (qx - u.x) * (qx - u.x) + (qy - u.y) * (qy - u.y);
    const double dv = (qx - v.x) * (qx - v.x) + (qy - v.y) * (qy - v.y);
    const P2& o = du <= dv ? u : v;
    w[k] = ((v.x - u.x) * (qy - o.y) - (v.y - u.y) * (qx - o.x)) / det;
  }
  if (min_weight) *min_weight = std::min({w[0], w[1], w[2]});
  double s = 0, z = 0;
  for (int k = 0; k < 3; ++k) {
    const double c = std::max(w[k], 0.0);
    s += c, z += c * t.z[k];
  }
  return s > 0 ? z / s : t.z[0];
}

// Triangles of a tile, skipping those incident to a NODATA corner when skip_nodata.
inline void append_triangles(const tile::TinTile& tile, bool skip_nodata,
                             std::vector<FlatTriangle>& out) {
  const std::vector<tile::Vertex> v = tile.vertices();
  for (const auto& tr : tile.triangles) {
    bool nodata = false;
    for (auto i : tr) nodata = nodata || (i < 4 && tile.corner_nodata[i]);
    if (skip_nodata && nodata) continue;
    FlatTriangle f{};
    for (int k = 0; k < 3; ++k) {
      const auto& p = v[tr[static_cast<std::size_t>(k)]];
      f.p[k] = {p.x, p.y};
      f.z[k] = p.z;
    }
    f.min_x = std::min({f.p[0].x, f.p[1].x, f.p[2].x});
    f.max_x = std::max({f.p[0].x, f.p[1].x, f.p[2].x});
    f.min_y = std::min({f.p[0].y, f.p[1].y, f.p[2].y});
    f.max_y = std::max({f.p[0].y, f.p[1].y, f.p[2].y});
    out.push_back(f);
  }
}

class TriangleGrid {
 public:
  TriangleGrid(std::vector<FlatTriangle> tris, const geo::MercatorRect& r)
      : tris_(std::move(tris)), r_(r) {
    // The grid spans the small triangles only: at coarse levels the data may cover a tiny part of
    // the tile, and the few huge triangles fanning out to the tile corners would otherwise make
    // the grid one cell wide (quadratic queries). Big triangles are clamped into every cell.
    {
      const double limit = r.width() * r.height() / 256.0;
      geo::MercatorRect ext{
          std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
      for (const auto& t : tris_) {
        if ((t.max_x - t.min_x) * (t.max_y - t.min_y) > limit) continue;
        ext.min_x = std::min(ext.min_x, t.min_x), ext.min_y = std::min(ext.min_y, t.min_y);
        ext.max_x = std::max(ext.max_x, t.max_x), ext.max_y = std::max(ext.max_y, t.max_y);
      }
      if (ext.min_x < ext.max_x && ext.min_y < ext.max_y) r_ = ext;
    }
    const double n = static_cast<double>(tris_.size());
    g_ = static_cast<std::uint32_t>(std::clamp(std::ceil(std::sqrt(n / 2.0)), 1.0, 1024.0));
    sx_ = g_ / std::max(r_.width(), std::numeric_limits<double>::min());
    sy_ = g_ / std::max(r_.height(), std::numeric_limits<double>::min());
    offsets_.assign(static_cast<std::size_t>(g_) * g_ + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1) {
        for (std::size_t i = 1; i < offsets_.size(); ++i) offsets_[i] += offsets_[i - 1];
        items_.resize(offsets_.back());
        fill_ = std::vector<std::uint32_t>(offsets_.begin(), offsets_.end() - 1);
      }
      for (std::uint32_t t = 0; t < tris_.size(); ++t) {
        std::uint32_t x0, y0, x1, y1;
        cells(tris_[t].min_x, tris_[t].min_y, tris_[t].max_x, tris_[t].max_y, x0, y0, x1, y1);
        for (std::uint32_t cy = y0; cy <= y1; ++cy) {
          for (std::uint32_t cx = x0; cx <= x1; ++cx) {
            const std::size_t c = static_cast<std::size_t>(cy) * g_ + cx;
            if (pass == 0) {
              ++offsets_[c + 1];
            } else {
              items_[fill_[c]++] = t;
            }
          }
        }
      }
    }
    stamp_.assign(tris_.size(), 0);
  }

  const std::vector<FlatTriangle>& triangles() const { return tris_; }

  // Calls f(index) once for every triangle whose bounding box meets the given box.
  template <typename F>
  void for_each_overlapping(double min_x, double min_y, double max_x, double max_y, F&& f) {
    if (++query_ == 0) {
      std::fill(stamp_.begin(), stamp_.end(), 0);
      query_ = 1;
    }
    std::uint32_t x0, y0, x1, y1;
    cells(min_x, min_y, max_x, max_y, x0, y0, x1, y1);
    for (std::uint32_t cy = y0; cy <= y1; ++cy) {
      for (std::uint32_t cx = x0; cx <= x1; ++cx) {
        const std::size_t c = static_cast<std::size_t>(cy) * g_ + cx;
        for (std::uint32_t k = offsets_[c]; k < offsets_[c + 1]; ++k) {
          const std::uint32_t t = items_[k];
          if (stamp_[t] == query_) continue;
          stamp_[t] = query_;
          const auto& T = tris_[t];
          if (T.max_x < min_x || T.min_x > max_x || T.max_y < min_y || T.min_y > max_y) continue;
          f(t);
        }
      }
    }
  }

  // The triangle containing (x, y) best (largest smallest barycentric weight, so ≥ 0 when inside
  // up to rounding), or -1 when no triangle's box holds the point.
  std::int64_t locate(double x, double y, double* min_weight) {
    std::int64_t best = -1;
    double best_w = -std::numeric_limits<double>::infinity();
    for_each_overlapping(x, y, x, y, [&](std::uint32_t t) {
      double w;
      plane_at(tris_[t], x, y, &w);
      if (w > best_w) best_w = w, best = t;
    });
    if (min_weight) *min_weight = best_w;
    return best;
  }

 private:
  void cells(double min_x, double min_y, double max_x, double max_y, std::uint32_t& x0,
             std::uint32_t& y0, std::uint32_t& x1, std::uint32_t& y1) const {
    auto cell = [&](double v, double origin, double scale) {
      const double c = std::floor((v - origin) * scale);
      return static_cast<std::uint32_t>(std::clamp(c, 0.0, static_cast<double>(g_ - 1)));
    };
    x0 = cell(min_x, r_.min_x, sx_), x1 = cell(max_x, r_.min_x, sx_);
    y0 = cell(min_y, r_.min_y, sy_), y1 = cell(max_y, r_.min_y, sy_);
  }

  std::vector<FlatTriangle> tris_;
  geo::MercatorRect r_;
  std::uint32_t g_ = 1;
  double sx_ = 1, sy_ = 1;
  std::vector<std::uint32_t> offsets_, items_, fill_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t query_ = 0;
};

}  // namespace tinstream::lod::detail
